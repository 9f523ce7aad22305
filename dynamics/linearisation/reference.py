"""The motion a linearisation is taken about: an equilibrium, or a straight steady motion.

* **Equilibrium**: a configuration q* at rest (q̇ = 0) with constant inputs u*, where the
  non-cyclic part of the reduced ODE is at rest (checked by :mod:`.linearised`).
* **Straight steady motion at forward speed V** (a system with a planar frame (x, y, heading)):
  the shape held at q*, the planar frame moving along its heading at speed V without turning —
  ẋ = V cos ψ, ẏ = V sin ψ, ψ̇ = 0, every coordinate outside the fiber at rest — and the
  other fiber velocities (wheel spins) from the constraints ω(q*)q̇ = 0. The cyclic
  coordinates drift (x grows, the wheels turn); the rest of the state is constant.

The reduced state z* = (q*, P*) follows from (q*, q̇*) by P = XᵀM(q*)q̇ (Tables 3.2–3.3); as
q̇* is linear in V, so is P*, and ``family`` = ∂z*/∂V is the direction along the family of
steady motions (a neutral direction of the linearisation, see :mod:`.linearised`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..suggestions import known_names

__all__ = ["ReferenceMotion", "reference_motion", "EQUILIBRIUM", "STEADY"]

EQUILIBRIUM = "equilibrium"
STEADY = "straight steady motion"


@dataclass(frozen=True)
class ReferenceMotion:
    """The reference motion of a linearisation.

    Attributes
    ----------
    kind : ``EQUILIBRIUM`` or ``STEADY``.
    speed : forward speed V of the planar frame [m/s]; None for an equilibrium.
    q, qdot : (n,) configuration and velocities, coordinate order.
    z : (2n − k,) reduced state, ``model.state_names`` order.
    u : (m,) constant inputs, ``system.inputs`` order.
    params : parameter vector in ``system.param_symbols`` order.
    family : (2n − k,) ∂z*/∂V along the steady motions (None for an equilibrium).
    """

    kind: str
    speed: float | None
    q: np.ndarray
    qdot: np.ndarray
    z: np.ndarray
    u: np.ndarray
    params: np.ndarray
    family: np.ndarray | None

    def describe(self, coordinates) -> str:
        """One line: which motion, at which configuration."""
        where = ", ".join(f"{c} = {v:.6g}"
                          for c, v in zip(coordinates, self.q, strict=True) if v != 0) or "q = 0"
        if self.kind == STEADY:
            return f"straight steady motion at {self.speed:.6g} m/s ({where})"
        return f"equilibrium at rest ({where})"


def _named_vector(names, values, label: str, problems: list) -> np.ndarray:
    """A vector in ``names`` order from a mapping name → value (missing names: 0)."""
    out = np.zeros(len(names))
    for key, value in dict(values or {}).items():
        if key not in names:
            problems.append(f"{key!r} is not {label}{known_names(key, names, label=label + 's')}")
            continue
        out[list(names).index(key)] = float(value)
    return out


def reference_motion(model, *, speed=None, configuration=None, inputs=None, params=None) -> ReferenceMotion:
    """The reference motion of ``model`` (a reduced ODE).

    Parameters
    ----------
    speed : forward speed V (a straight steady motion) or None (an equilibrium at rest).
    configuration : mapping coordinate → value (the others 0): q*. With kept holonomic
        constraints the dependent coordinates are solved from the others (a value given for
        one is Newton's starting point).
    inputs : mapping input → constant value (the others 0): u*.
    params : mapping parameter → value overriding the defaults.
    """
    from ..derivation.states import consistent_velocities
    system = model.system
    names = tuple(system.coordinates)
    problems: list = []
    q = _named_vector(names, configuration, "a coordinate", problems)
    u = _named_vector(tuple(system.inputs), inputs, "an input", problems)
    if speed is not None and not np.isfinite(speed):
        problems.append(f"the speed must be a finite number, got {speed}")
    if speed is not None and system.planar_frame is None:
        problems.append("a steady motion at a forward speed needs a planar frame (x, y, heading): "
                        "write planar_frame = [...] in [system], or linearise about an equilibrium "
                        "(no --speed)")
    if problems:
        raise ModelError(problems, title="invalid linearisation request")
    if system.holonomic:
        from ..derivation.holonomic import consistent_configuration
        q = consistent_configuration(system, q, params=params)
    pv = model.numeric.params(params)
    if speed is None:
        qdot = np.zeros(len(names))
        z = _state(model, q, qdot, pv)
        return ReferenceMotion(kind=EQUILIBRIUM, speed=None, q=q, qdot=qdot, z=z, u=u, params=pv, family=None)
    qdot = _straight_velocities(system, model.fiber, q, float(speed), params, consistent_velocities)
    unit = _straight_velocities(system, model.fiber, q, 1.0, params, consistent_velocities)
    z = _state(model, q, qdot, pv)
    family = _state(model, q, unit, pv) - _state(model, q, np.zeros(len(names)), pv)
    return ReferenceMotion(kind=STEADY, speed=float(speed), q=q, qdot=qdot, z=z, u=u, params=pv,
                           family=family)


def _straight_velocities(system, fiber, q, speed, params, solve) -> np.ndarray:
    """q̇ of the straight motion at ``speed`` (see the module docstring)."""
    x, y, heading = system.planar_frame
    psi = q[list(system.coordinates).index(heading)]
    given = {x: speed * np.cos(psi), y: speed * np.sin(psi), heading: 0.0}
    given.update({c: 0.0 for c in system.coordinates if c not in fiber and c not in given})
    try:
        return solve(system, q, given, params=params)
    except ModelError as err:
        raise ModelError([f"no straight steady motion at this configuration: with the frame "
                          f"({x}, {y}, {heading}) moving forward and the shape at rest, {p}"
                          for p in err.problems], title="invalid linearisation request") from None


def _state(model, q, qdot, pv) -> np.ndarray:
    """z = (q, P(q, q̇)) by the model's own map."""
    return np.asarray(model.numeric["state"](q, qdot, pv), dtype=float).ravel()
