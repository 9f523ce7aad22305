"""A :class:`~nhgait.dynamics.derivation.system.System` from rigid bodies and wheels
(docs/bodies.md): L = T − V from the bodies, the rolling constraints of the wheels (Pfaffian
rows and, where a wheel's contact height is not fixed by the coordinates, a holonomic
constraint).

Energy. With J_v, J_ω of :mod:`.kinematics` (ν = (u, w, ψ̇, ṡ)), a body of mass m and inertia
I (reference configuration, about its mass centre) contributes m J_vᵀJ_v + J_ωᵀ(R I Rᵀ)J_ω to
the metric K(s) of T = ½ νᵀ K ν (J_v of its mass centre); a thin axisymmetric wheel
contributes the same with J_ω = J_ω(parent) + e_spin a and the inertia I_d E + (I_a − I_d) a aᵀ
(a its current axle: the spin does not enter T, so the wheel angle is cyclic). In q̇, M = BᵀKB
with B(ψ) the map q̇ → ν (the uu and ww entries of K are the total mass). V = g Σ m z_com.

A rolling wheel (centre c, current unit axle a, radius ρ, up n = e_z): its lowest point is
P = c + ρ d with d = (a (a·n) − n)/√(1 − (a·n)²), at height h = c_z − ρ √(1 − a_z²). Rolling
without slip: the wheel's material point at P does not move, v_P = v_c + ω × ρd = 0. Its two
horizontal components are Pfaffian rows; the vertical one is ḣ = 0, so the wheel adds the
holonomic constraint h(q) = 0 — unless h vanishes identically (at random configurations), as
for a wheel whose contact point is the base point (the bicycle's rear wheel).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import sympy as sp

from ...errors import ModelError
from ..urdf.energy import lagrangian, skew
from .kinematics import EZ, frames, point_jacobian, spin_jacobian
from .statement import Multibody, read_multibody

__all__ = ["bodies_system", "multibody_energy", "wheel_contacts", "IDENTICALLY_ZERO", "KEYS"]

#: a wheel's contact height below this at every sampled configuration holds identically
IDENTICALLY_ZERO = 1e-12
#: [system] keys of a scene stated with bodies
KEYS = {"name", "description", "base", "bodies", "wheels", "gravity", "constraints", "holonomic", "dependent",
        "forces", "parameters", "inputs", "fiber"}


def bodies_system(table: dict, source: str = "<scene>"):
    """The System of a ``[system]`` table with ``bodies`` (and ``wheels``); one
    :class:`ModelError` lists every problem."""
    from ..input.expressions import number_problems
    from ..system import System
    problems: list = []
    unknown = set(table) - KEYS
    if unknown:
        problems.append(f"[system]: unknown key(s) {sorted(unknown)} with bodies (allowed: "
                        f"{', '.join(sorted(KEYS))})")
    params = table.get("parameters", {})
    if not isinstance(params, dict):
        problems.append("[system].parameters must be a table")
        params = {}
    values = {name: number_problems(v, f"parameter {name!r}", problems) for name, v in params.items()}
    names = {name: sp.Symbol(name, real=True) for name in params}
    multibody = read_multibody(table, names, problems)
    if multibody is None or problems:
        raise ModelError(problems, title=f"invalid scene {source}")
    q = [sp.Symbol(c, real=True) for c in multibody.coordinates]
    q_dot = [sp.Symbol(f"{c}_dot", real=True) for c in multibody.coordinates]
    K, V = multibody_energy(multibody)
    M = metric_in_qdot(K, q[2])
    rows, heights = wheel_contacts(multibody, q, values)
    holonomic = [*heights, *table.get("holonomic", [])]
    try:
        return System(coordinates=list(multibody.coordinates), lagrangian=lagrangian(M, V, q_dot),
                      constraints=_independent([in_qdot(r, q[2], q_dot) for r in rows], q, q_dot, names,
                                               values) + list(table.get("constraints", [])),
                      forces=table.get("forces", {}), parameters=params, inputs=table.get("inputs"),
                      name=table.get("name", "system"), fiber=table.get("fiber"),
                      planar_frame=list(multibody.base), holonomic=holonomic,
                      dependent=table.get("dependent"))
    except ModelError as exc:
        raise ModelError(list(exc.problems), title=f"invalid scene {source}") from None


def _independent(rows: list, q: list, q_dot: list, names: dict, values: dict) -> list:
    """The wheels' rows less each that is a combination of the others (the second side-slip
    row of two wheels on one axle: a differential drive), tested at random configurations
    with the parameter values, as for a URDF's wheels (docs/scene-format.md)."""
    from ..urdf.wheels import independent_rows
    known = {names[k]: v for k, v in values.items() if isinstance(v, (int, float))}
    kept = independent_rows([r.xreplace(known) for r in rows], (q[2:], q_dot)) if rows else []
    return [rows[i] for i in kept]


def _width(multibody: Multibody) -> int:
    return len(multibody.coordinates)


def _columns(multibody: Multibody) -> dict:
    return {c: i for i, c in enumerate(multibody.coordinates)}


class MultibodyEnergy(NamedTuple):
    """What :func:`multibody_energy` returns."""

    K: sp.Matrix   #: T = ½ νᵀ K ν
    V: sp.Expr     #: the potential


def multibody_energy(multibody: Multibody) -> MultibodyEnergy:
    """(K(s), V(s)): T = ½ νᵀ K ν and the potential (module docstring)."""
    width, columns = _width(multibody), _columns(multibody)
    placed = frames(multibody, columns)
    K, height = sp.zeros(width, width), sp.Integer(0)
    for body in multibody.bodies:
        frame = placed[body.name]
        if body.mass == 0 and body.inertia == sp.zeros(3, 3):
            continue
        com = frame.place(body.com)
        Jv, Jw = point_jacobian(frame, com, width), frame.angular_jacobian(width)
        K += body.mass * Jv.T * Jv + Jw.T * (frame.R * body.inertia * frame.R.T) * Jw
        height += body.mass * com[2]
    for wheel in multibody.wheels:
        frame = placed[wheel.parent]
        centre, axle = frame.place(wheel.centre), frame.R * wheel.axle
        Jv, Jw = point_jacobian(frame, centre, width), spin_jacobian(frame, axle, columns[wheel.spin], width)
        inertia = wheel.diametral * sp.eye(3) + (wheel.axial - wheel.diametral) * axle * axle.T
        K += wheel.mass * Jv.T * Jv + Jw.T * inertia * Jw
        height += wheel.mass * centre[2]
    return MultibodyEnergy(K, multibody.gravity * height)


def metric_in_qdot(K: sp.Matrix, psi) -> sp.Matrix:
    """M = Bᵀ K B in q̇ = (ẋ, ẏ, ψ̇, ṡ) (u = cos ψ ẋ + sin ψ ẏ, w = −sin ψ ẋ + cos ψ ẏ)."""
    c, s = sp.cos(psi), sp.sin(psi)
    M = sp.Matrix(K)                              # uu, ww: the total mass; uw = 0; the rest as in K
    for j in range(2, K.shape[0]):
        M[0, j] = M[j, 0] = c * K[0, j] - s * K[1, j]
        M[1, j] = M[j, 1] = s * K[0, j] + c * K[1, j]
    return M


def in_qdot(row_nu: sp.Matrix, psi, q_dot) -> sp.Expr:
    """A row in ν as an expression in q̇ (u = cos ψ ẋ + sin ψ ẏ, w = −sin ψ ẋ + cos ψ ẏ)."""
    c, s = sp.cos(psi), sp.sin(psi)
    coefficients = [c * row_nu[0] - s * row_nu[1], s * row_nu[0] + c * row_nu[1], *row_nu[2:]]
    return sp.Add(*[k * v for k, v in zip(coefficients, q_dot, strict=True)])


class WheelContacts(NamedTuple):
    """What :func:`wheel_contacts` returns."""

    rows: list      #: Pfaffian rows in ν, two per rolling wheel
    heights: list   #: contact heights h(q) that do not vanish identically


def wheel_contacts(multibody: Multibody, q, values: dict) -> WheelContacts:
    """(Pfaffian rows in ν — two per rolling wheel —, holonomic contact heights h(q) that do not
    vanish identically)."""
    width, columns = _width(multibody), _columns(multibody)
    placed = frames(multibody, columns)
    rows, heights = [], []
    for wheel in multibody.wheels:
        if not wheel.rolls:
            continue
        frame = placed[wheel.parent]
        centre, axle = frame.place(wheel.centre), frame.R * wheel.axle
        flat = sp.sqrt(1 - axle[2] ** 2)                           # √(1 − a_z²), |a| = 1
        down = (axle * axle[2] - EZ) / flat                        # d: centre → lowest point
        Jv = point_jacobian(frame, centre, width)
        Jw = spin_jacobian(frame, axle, columns[wheel.spin], width)
        contact = Jv - skew(wheel.radius * down) * Jw              # v_P = v_c + ω × ρd
        rows += [contact[0, :], contact[1, :]]
        height = centre[2] - wheel.radius * flat
        if not _vanishes(height, q, values):
            heights.append(height)
    return WheelContacts(rows, heights)


def _vanishes(expr, q, values: dict) -> bool:
    """True when ``expr`` is below IDENTICALLY_ZERO at random configurations (|angles| < 1.2)."""
    symbols = sorted(expr.free_symbols, key=lambda s: s.name)
    f = sp.lambdify(symbols, expr, "numpy")
    rng = np.random.default_rng(11)
    qnames = {s.name for s in q}
    for _ in range(6):
        args = [rng.uniform(-1.2, 1.2) if s.name in qnames else values.get(s.name, np.nan) for s in symbols]
        with np.errstate(all="ignore"):
            value = float(f(*args))
        if not abs(value) < IDENTICALLY_ZERO:
            return False
    return True
