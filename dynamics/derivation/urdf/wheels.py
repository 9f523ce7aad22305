"""Constraints of wheels on the ground plane (the root frame's z = 0 plane, z up).

A wheel is a joint whose axis is its axle. With the wheel centre's velocity v_c, the wheel's
angular velocity ω, the axle direction a and the up direction n (all in the wheel's body frame)
and the radius ρ, the contact point's velocity is v_P = v_c − ρ ω × n and

* a **rolling** wheel (``rolling = [...]``, the joint a coordinate) neither slips sideways nor
  skids:  v_P · a = 0  and  v_P · (n × a) = 0;
* a **skate** (``skates = [...]``, e.g. the wheel axles of the snakeboard; the joint's spin is
  not modelled and it may be locked) does not slip sideways:  v_c · a = 0.

Both need a horizontal axle (a · n = 0 at every configuration); a rolling wheel's centre must be
at height ρ. The rows are linear in ν = (u, w, θ̇, ṡ) with coefficients in s; they are written in
q̇ like the metric (:func:`~.energy.metric_in_qdot`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import sympy as sp

from .energy import clean, skew, snapped

#: a wheel's axle is horizontal when |a·n| stays below this at random joint values
HORIZONTAL = 1e-9


class WheelFrame(NamedTuple):
    """Where a wheel's frame sits: the index of its ``body``, the ``rotation`` and
    ``translation`` of the frame in that body."""

    body: int
    rotation: object
    translation: object


class WheelRows(NamedTuple):
    """A wheel's constraint rows in ν: ``side`` (no sliding along the axle) and ``rolling``
    (no slipping along the ground; None for a skate)."""

    side: object
    rolling: object


def wheel_frame(bodies, child_link) -> WheelFrame:
    """Link ``child_link``'s frame in the body it belongs to (identity for the link that is its
    body's own)."""
    for index, body in enumerate(bodies):
        if child_link in body.frames:
            rotation, translation = body.frames[child_link]
            return WheelFrame(index, rotation, translation)
    raise KeyError(child_link)


def wheel_rows(kin, rotation, translation, axis, radius) -> WheelRows:
    """The rows of a wheel whose child frame is (rotation, translation) in a body with
    kinematics ``kin``; ``radius`` None for a skate."""
    r, p = snapped(rotation), snapped(translation)
    a = r * snapped(axis)
    up = kin.R.T * sp.Matrix([0, 0, 1])
    centre = kin.Jv - skew(p) * kin.Jw
    if radius is None:
        return WheelRows((a.T * centre).applyfunc(clean), None)
    contact = centre + skew(up) * kin.Jw * radius         # −ρ ω × n = ρ n × ω
    forward = skew(up) * a
    return WheelRows((a.T * contact).applyfunc(clean), (forward.T * contact).applyfunc(clean))


def axle_tilt(kin, rotation, axis, joint_symbols, samples):
    """Largest |a · n| at the sampled joint values (0 for a horizontal axle)."""
    a = snapped(rotation) * snapped(axis)
    tilt = (kin.R * a)[2]
    f = sp.lambdify([joint_symbols], tilt, "numpy")
    return max(abs(float(f(s))) for s in samples)


def centre_heights(kin, translation, joint_symbols, samples) -> np.ndarray:
    """Height of the wheel centre above the ground at the sampled joint values."""
    height = (kin.p + kin.R * snapped(translation))[2]
    f = sp.lambdify([joint_symbols], height, "numpy")
    return np.array([float(f(s)) for s in samples])


def in_qdot(row_nu: sp.Matrix, theta, q_dot) -> sp.Expr:
    """A row in ν written as an expression in q̇ (u = cos θ ẋ + sin θ ẏ, w = −sin θ ẋ + cos θ ẏ)."""
    c, s = sp.cos(theta), sp.sin(theta)
    coefficients = [clean(c * row_nu[0] - s * row_nu[1]), clean(s * row_nu[0] + c * row_nu[1])]
    coefficients += list(row_nu[2:])
    return sp.Add(*[k * v for k, v in zip(coefficients, q_dot, strict=True)])


def independent_rows(rows, theta_and_joints, count=4, seed=3):
    """Indices of rows kept when each row that is (generically) a combination of the earlier ones
    is dropped: the row raises the rank of ω at random configurations, or it goes."""
    rng = np.random.default_rng(seed)
    qs, qd = theta_and_joints
    matrix = sp.Matrix([[sp.diff(r, v) for v in qd] for r in rows])
    f = sp.lambdify([qs], matrix, "numpy")
    samples = [np.array(f(rng.uniform(-1.2, 1.2, len(qs))), dtype=float) for _ in range(count)]
    kept = []
    for i in range(len(rows)):
        trial = kept + [i]
        if any(np.linalg.matrix_rank(m[trial], tol=1e-9 * max(1.0, np.abs(m).max())) == len(trial)
               for m in samples):
            kept = trial
    return kept
