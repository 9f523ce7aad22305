"""Initial guesses from sinusoidal shape families, with fall-back candidates.

A zero guess does not work for these systems: at rest the linearisation cannot move the body
and Ipopt reports local infeasibility. The classical snakeboard gaits use rotor:wheel
frequency ratios 1:1 (drive), 2:1 (rotate) and 3:2 (parallel park); each family below is a
list of candidates (amplitude/phase variations) that :func:`candidates` yields in order and
the planner tries until Ipopt succeeds. With ω = 2π/T:

* ``drive``  ψ = A sin(ωt),  φ = B cos(ωt), x ramps 0 → x(T)      (A, B) = (1, 0.6), …
* ``rotate`` ψ = A sin(2ωt), φ = B cos(ωt)                          (A, B) = (1, 0.9), …
* ``park``   ψ = A sin(3ωt), φ = B cos(2ωt), y ramps 0 → y(T)      (A, B) = (1, 0.6), …
* ``unicycle-park``  θ = A sin(ωt), y ramps 0 → y(T)                 A = 0.3, …

The guessed configuration q(t) and shape velocities ṙ(t) (fiber velocities 0, i.e. the
body at rest) are mapped to the reduced state with the model's ``state(q, q̇)``; controls
are 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from nhgait.ocp import InitialGuess

__all__ = ["ShapeGuess", "FAMILIES", "candidates", "guess_from_shape"]


@dataclass(frozen=True)
class ShapeGuess:
    """Sinusoids c(t) = amplitude · sin(k ω t + phase) per coordinate, plus final-value ramps."""

    label: str
    waves: tuple            # ((coordinate, amplitude, k, phase), ...)
    ramps: tuple = ()       # coordinates ramped linearly 0 -> final value


def _drive(A, B, label):
    return ShapeGuess(label, (("psi", A, 1, 0.0), ("phi", B, 1, math.pi / 2)), ("x",))


def _rotate(A, B, label):
    return ShapeGuess(label, (("psi", A, 2, 0.0), ("phi", B, 1, math.pi / 2)), ("x", "y"))


def _park(A, B, label):
    return ShapeGuess(label, (("psi", A, 3, 0.0), ("phi", B, 2, math.pi / 2)), ("x", "y"))


FAMILIES = {
    "drive": [_drive(1.0, 0.6, "drive 1:1 A=1 B=0.6"), _drive(1.0, -0.6, "drive 1:1 A=1 B=-0.6"),
              _drive(0.8, 0.4, "drive 1:1 A=0.8 B=0.4"), _drive(1.2, 0.8, "drive 1:1 A=1.2 B=0.8")],
    "rotate": [_rotate(1.0, 0.9, "rotate 2:1 A=1 B=0.9"), _rotate(1.0, 0.6, "rotate 2:1 A=1 B=0.6"),
               _rotate(-1.0, 0.9, "rotate 2:1 A=-1 B=0.9"), _rotate(0.8, 0.8, "rotate 2:1 A=0.8 B=0.8")],
    "park": [_park(1.0, 0.6, "park 3:2 A=1 B=0.6"), _park(1.0, 0.9, "park 3:2 A=1 B=0.9"),
             _park(-1.0, 0.6, "park 3:2 A=-1 B=0.6"), _rotate(1.0, 0.9, "rotate 2:1 A=1 B=0.9"),
             _drive(1.0, 0.6, "drive 1:1 A=1 B=0.6")],
    "unicycle-park": [ShapeGuess(f"theta A={a}", (("theta", a, 1, 0.0),), ("x", "y"))
                      for a in (0.3, 0.6, -0.3, 1.0)],
}


def _final_value(problem, name):
    if name in problem.final:
        lo, hi = problem.bounds(problem.final, name)
        if lo == hi:
            return lo
    return 0.0


def guess_from_shape(problem, shape: ShapeGuess) -> InitialGuess:
    """The reduced-state guess (nz × (N+1)) of one shape family member; zero controls."""
    model = problem.model
    coords = tuple(model.system.coordinates)
    t = problem.grid()
    T = float(problem.horizon)
    w = 2 * math.pi / T
    n = len(coords)
    q = np.zeros((n, t.size))
    qdot = np.zeros((n, t.size))
    for name, amp, k, phase in shape.waves:
        i = coords.index(name)
        q[i] = amp * np.sin(k * w * t + phase)
        qdot[i] = amp * k * w * np.cos(k * w * t + phase)
    for name in shape.ramps:
        if name in coords:
            q[coords.index(name)] = _final_value(problem, name) * t / T
    state = model.numeric["state"]
    Z = np.column_stack([np.asarray(state(q[:, j], qdot[:, j], problem.params)).ravel() for j in range(t.size)])
    return InitialGuess(Z, np.zeros((problem.n_controls, problem.intervals)), label=shape.label)


def candidates(problem, family: str) -> Iterator[InitialGuess]:
    """Guesses of ``family`` in order of preference."""
    for shape in FAMILIES[family]:
        yield guess_from_shape(problem, shape)
