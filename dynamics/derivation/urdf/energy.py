"""Kinetic and potential energy of a URDF tree on a planar base, symbolically.

The root link moves in SE(2): q = (x, y, θ, s) with s the joint coordinates. Velocities are
propagated in body frames (as in Featherstone's recursion), starting from the root's body
velocity ν = (u, w, θ̇, ṡ) with u = cos θ ẋ + sin θ ẏ, w = −sin θ ẋ + cos θ ẏ; for body b moved
by joint j from parent a, with the constant joint frame (R₀, p₀) in a and the joint rotation
R_j (angle q_j about the unit axis e) or translation e q_j,

    ω_b = R_jᵀ R₀ᵀ ω_a + e q̇_j                       (revolute, continuous)
    v_b = R_jᵀ R₀ᵀ (v_a + ω_a × p₀)                  (origin velocity, body frame)
    ω_b = R₀ᵀ ω_a,  v_b = R₀ᵀ (v_a + ω_a × (p₀ + R₀ e q_j)) + e q̇_j   (prismatic)

so v_b = J_v(s) ν and ω_b = J_ω(s) ν depend on the joint coordinates only. With the body's
mass m, centre of mass c and inertia I_o about its origin (body frame),

    T_b = ½ m v_bᵀ v_b − m v_bᵀ [c]× ω_b + ½ ω_bᵀ I_o ω_b,   T = ½ νᵀ K(s) ν,   K = Σ_b K_b.

The uu and ww entries of K are the total mass and the uw entry is 0 (a rotation keeps
|v_root|²), so in q̇ the metric is M = Bᵀ K B with B(θ) the map q̇ → ν, and its xx, yy entries
are the total mass exactly. V = g Σ_b m_b z_b with z_b the height of body b's centre of mass
above the root frame's z = 0 plane (the ground). Every entry is simplified on its own
(in the canonical form of :mod:`.fourier`: products of sines and cosines written as sums,
terms below 1e-13 of the largest coefficient dropped).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from .fourier import canonical_trig

#: relative size below which a numeric coefficient is rounding noise (dropped or snapped)
NOISE = 1e-13
#: entries of constant rotation matrices this close to 0 or ±1 are taken as exact
SNAP = 1e-10
#: expand the metric entry by entry up to this :func:`expansion_size` (about 2 s); larger trees
#: keep T as a sum over bodies of squared velocity components
EXPANSION_BUDGET = 10_000


@dataclass(frozen=True)
class BodyKinematics:
    """Symbolic kinematics of one body: rotation ``R`` and origin ``p`` in the root frame,
    velocity Jacobians ``Jv`` and ``Jw`` (3×len(ν), body frame)."""

    R: sp.Matrix
    p: sp.Matrix
    Jv: sp.Matrix
    Jw: sp.Matrix


def snapped(matrix) -> sp.Matrix:
    """A numeric matrix as sympy Floats, entries within SNAP of 0 or ±1 exact."""
    out = []
    for value in np.asarray(matrix, dtype=float).ravel():
        if abs(value) < SNAP:
            out.append(sp.Integer(0))
        elif abs(abs(value) - 1) < SNAP:
            out.append(sp.Integer(int(np.sign(value))))
        else:
            out.append(sp.Float(float(value)))
    rows = np.asarray(matrix).shape
    return sp.Matrix(rows[0], rows[1] if len(rows) > 1 else 1, out)


def exact(value: float):
    """A number as an sympy Integer when it is one (keeps ``sin(phi)`` from becoming
    ``sin(1.0*phi)``), else a Float."""
    return sp.Integer(int(value)) if float(value).is_integer() else sp.Float(float(value))


def axis_rotation(axis: sp.Matrix, angle) -> sp.Matrix:
    """Rodrigues' formula with a symbolic angle: cos·E + sin·[a]× + (1 − cos)·a aᵀ."""
    c, s = sp.cos(angle), sp.sin(angle)
    return (c * sp.eye(3) + s * skew(axis) + (1 - c) * axis * axis.T).applyfunc(sp.expand)


def skew(a) -> sp.Matrix:
    """[a]×, the matrix of a × ·."""
    return sp.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


def clean(expr):
    """The canonical trigonometric form of :func:`.fourier.canonical_trig` (terms below NOISE
    of the largest coefficient dropped)."""
    return canonical_trig(expr, NOISE)


def body_kinematics(bodies, joint_symbols) -> list:
    """:class:`BodyKinematics` of every body (root first) over ν = (u, w, θ̇, ṡ)."""
    width = 3 + len(joint_symbols)
    root_v = sp.zeros(3, width)
    root_v[0, 0] = root_v[1, 1] = 1
    root_w = sp.zeros(3, width)
    root_w[2, 2] = 1
    out = [BodyKinematics(sp.eye(3), sp.zeros(3, 1), root_v, root_w)]
    for body in bodies[1:]:
        parent = out[body.parent]
        axis = snapped(body.joint.axis)
        r0, p0 = snapped(body.rotation), snapped(body.translation)
        multiplier = exact(body.multiplier)
        value = multiplier * joint_symbols[body.coordinate] + exact(body.offset)
        column = 3 + body.coordinate
        rate = sp.zeros(3, width)
        rate[:, column] = axis * multiplier
        if body.joint.type == "prismatic":
            lever = p0 + r0 * axis * value
            w = r0.T * parent.Jw
            v = r0.T * (parent.Jv - skew(lever) * parent.Jw) + rate
            rotation, origin = parent.R * r0, parent.p + parent.R * lever
        else:
            rj = axis_rotation(axis, value)
            to_body = (r0 * rj).T.applyfunc(sp.expand)
            w = to_body * parent.Jw + rate
            v = to_body * (parent.Jv - skew(p0) * parent.Jw)
            rotation, origin = parent.R * r0 * rj, parent.p + parent.R * p0
        out.append(BodyKinematics(rotation.applyfunc(clean), origin.applyfunc(clean),
                                  v.applyfunc(clean), w.applyfunc(clean)))
    return out


def expansion_size(kinematics) -> int:
    """Σ over bodies and velocity components of (terms of the component)²: the number of products
    that expanding K(s) = Σ J_vᵀ m J_v + ... costs, the measure of :data:`EXPANSION_BUDGET`."""
    size = 0
    for kin in kinematics:
        for J in (kin.Jv, kin.Jw):
            for i in range(3):
                terms = sum(len(sp.Add.make_args(e)) for e in J[i, :])
                size += terms * terms
    return size


def nested_kinetic_energy(bodies, kinematics, nu) -> sp.Expr:
    """T = Σ_b ½ m |v_b + ω_b × c|² + ½ ω_bᵀ I_c ω_b with v_b = J_v ν, ω_b = J_ω ν left as sums
    (not expanded): the form for trees whose expanded metric exceeds :data:`EXPANSION_BUDGET`."""
    nu = sp.Matrix(nu)
    total = sp.Integer(0)
    for body, kin in zip(bodies, kinematics, strict=True):
        if body.mass == 0 and not np.any(body.inertia):
            continue
        w = kin.Jw * nu
        v = kin.Jv * nu + w.cross(snapped(body.com))
        total += sp.Float(body.mass) * (v.T * v)[0] / 2 + (w.T * snapped(body.inertia) * w)[0] / 2
    return total


def metric_in_nu(bodies, kinematics) -> sp.Matrix:
    """K(s) of T = ½ νᵀ K ν, each entry simplified."""
    width = kinematics[0].Jv.shape[1]
    K = sp.zeros(width, width)
    for body, kin in zip(bodies, kinematics, strict=True):
        if body.mass == 0 and not np.any(body.inertia):
            continue
        c = body.com
        inertia_origin = body.inertia + body.mass * (c @ c * np.eye(3) - np.outer(c, c))
        cross = kin.Jv.T * skew(snapped(c)) * kin.Jw * body.mass
        K += body.mass * kin.Jv.T * kin.Jv - cross - cross.T + kin.Jw.T * snapped(inertia_origin) * kin.Jw
    return K.applyfunc(clean)


def metric_in_qdot(K: sp.Matrix, theta, total_mass: float) -> sp.Matrix:
    """M(q) = Bᵀ K B in q̇ = (ẋ, ẏ, θ̇, ṡ); the translational block is the total mass."""
    width = K.shape[0]
    c, s = sp.cos(theta), sp.sin(theta)
    M = sp.zeros(width, width)
    M[0, 0] = M[1, 1] = sp.Float(total_mass)
    for j in range(2, width):
        M[0, j] = M[j, 0] = clean(c * K[0, j] - s * K[1, j])
        M[1, j] = M[j, 1] = clean(s * K[0, j] + c * K[1, j])
        for i in range(2, width):
            M[i, j] = K[i, j]
    return M


def potential(bodies, kinematics, gravity: float):
    """V(s) = g Σ m_b z_b (heights in the root frame)."""
    total = sp.Integer(0)
    for body, kin in zip(bodies, kinematics, strict=True):
        if body.mass:
            total += body.mass * (kin.p + kin.R * snapped(body.com))[2]
    return clean(gravity * total)


def lagrangian(M: sp.Matrix, V, q_dot) -> sp.Expr:
    """L = ½ q̇ᵀ M q̇ − V written as Σ_i ½ M_ii q̇_i² + Σ_{i<j} M_ij q̇_i q̇_j − V."""
    n = len(q_dot)
    terms = [M[i, i] * q_dot[i] ** 2 / 2 for i in range(n) if M[i, i] != 0]
    terms += [M[i, j] * q_dot[i] * q_dot[j] for i in range(n) for j in range(i + 1, n) if M[i, j] != 0]
    return sp.Add(*terms) - V
