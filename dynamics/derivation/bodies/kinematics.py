"""Kinematics of a tree of rigid bodies on a planar base, by the product of exponentials.

The base frame moves in SE(2) on the ground: q = (x, y, ψ, s) with s the joint angles and the
wheel spins. Everything is written in the **base frame**, so nothing below depends on x, y, ψ
(the group acts on the base only). A body b moved by the revolute joint j (unit axis a_j
through the point c_j, both in the reference configuration) from its parent maps a point x of
the reference configuration to

    F_b(x) = F_parent(c_j + R(a_j, s_j)(x − c_j)),   F_base = identity,

so R_b = R_parent R(a_j, s_j) (Brockett's product of exponentials). The joint's current axis
is R_parent a_j through F_parent(c_j). With the base's body velocity ν = (u, w, ψ̇, ṡ),
u = cos ψ ẋ + sin ψ ẏ, w = −sin ψ ẋ + cos ψ ẏ, a point p = F_b(x) of body b moves with

    v = (u, w, 0) + ψ̇ e_z × p + Σ_{j ∈ chain(b)} ṡ_j a_j × (p − c_j),
    ω_b = ψ̇ e_z + Σ_{j ∈ chain(b)} ṡ_j a_j                (current axes and points),

i.e. v = J_v(s) ν and ω_b = J_ω(s) ν with the columns written directly (no differentiation).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ..urdf.energy import axis_rotation, skew
from .statement import BASE

__all__ = ["Frame", "frames", "point_jacobian", "EZ"]

EZ = sp.Matrix([0, 0, 1])


@dataclass(frozen=True)
class Frame:
    """A body's placement: x_current = R x_ref + t; ``joints``: the current (axis, point,
    column of ν) of every joint of its chain, base first."""

    R: sp.Matrix
    t: sp.Matrix
    joints: tuple

    def place(self, x_ref: sp.Matrix) -> sp.Matrix:
        return self.R * x_ref + self.t

    def angular_jacobian(self, width: int) -> sp.Matrix:
        """J_ω (3 × width): e_z in column 2 (ψ̇), the current axes in their joint columns."""
        J = sp.zeros(3, width)
        J[:, 2] = EZ
        for axis, _, column in self.joints:
            J[:, column] += axis
        return J


def frames(multibody, columns: dict) -> dict:
    """The :class:`Frame` of the base and of every body (name → Frame); ``columns`` maps a
    coordinate name to its column of ν."""
    out = {BASE: Frame(sp.eye(3), sp.zeros(3, 1), ())}
    for body in multibody.bodies:
        parent = out[body.parent]
        if body.joint is None:
            out[body.name] = parent
            continue
        angle = sp.Symbol(body.joint, real=True)
        rotation = axis_rotation(body.axis, angle)
        R = parent.R * rotation
        t = parent.R * (body.point - rotation * body.point) + parent.t
        axis, point = parent.R * body.axis, parent.place(body.point)
        out[body.name] = Frame(R, t, parent.joints + ((axis, point, columns[body.joint]),))
    return out


def point_jacobian(frame: Frame, p: sp.Matrix, width: int) -> sp.Matrix:
    """J_v (3 × width) of the point at current position ``p`` fixed in the body of ``frame``."""
    J = sp.zeros(3, width)
    J[0, 0] = J[1, 1] = 1
    J[:, 2] = EZ.cross(p)
    for axis, point, column in frame.joints:
        J[:, column] += axis.cross(p - point)
    return J


def spin_jacobian(frame: Frame, axle: sp.Matrix, column: int, width: int) -> sp.Matrix:
    """J_ω of a wheel spinning about ``axle`` (current) at ``column`` on the body of ``frame``."""
    J = frame.angular_jacobian(width)
    J[:, column] += axle
    return J


def cross_matrix(v: sp.Matrix) -> sp.Matrix:
    """[v]×."""
    return skew(v)
