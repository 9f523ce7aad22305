"""A catalogue of gait tasks: small plug-ins, registry name → factory.

A task factory takes the (specialised) model and the user's options and returns an
:class:`~nhgait.ocp.OptimalControlProblem`. Add one with :func:`register`; the planner and
``nhgait plan --gait NAME`` find it by (system, name).

Benchmark defaults (controls piecewise constant, J = ∫ |u|² dt, RK4 with 4 sub-steps):

* unicycle ``parallel-park`` (P1): T = 4, z(0) = 0 (x, y, θ, φ at 0 and at rest), end
  x = 0, y = ``distance`` (0.5), θ = 0, θ̇ = φ̇ = 0 (momenta p = p̃_θ = 0), φ free; |τ| ≤ 5.
* snakeboard ``forward`` (P2): T = ``period`` (2π); start x = y = θ = ψ = 0 and the board at
  rest (forward body velocity ``forward_velocity`` = ẋ cos θ + ẏ sin θ = 0, through q̇(z));
  end x = ``distance`` (1.0), θ = 0, y free; |φ| ≤ 1 at the nodes, |τ| ≤ 10.
* snakeboard ``rotate`` (P3): as forward, end x = y = 0, θ = ``angle`` (π/2).
* snakeboard ``lateral`` (P4): as forward, end x = 0, θ = 0, y = ``distance`` (0.5; a
  sideways shift of half a board length r ≈ 1.18 — large enough to need a real gait, small
  enough for one period).

Periodicity (snakeboard): the benchmark asks for ψ, φ, v, ψ̇, φ̇ periodic with v the forward
body velocity. In the reduced state (p, p̃_ψ, p̃_φ) this is stated as: ψ, φ, p̃_ψ, p̃_φ periodic
and v(T) = v(0) = 0. Given φ(T) = φ(0) and v(T) = v(0), the momenta p̃_ψ (a function of
v, ψ̇, φ) and p̃_φ = 2 J_w φ̇ are periodic exactly when ψ̇ and φ̇ are, and then p (a function of
v, ψ̇, φ) is periodic too — the same feasible set. (Stating p periodic instead of v(T) = 0
is equivalent but took Ipopt 12–14 instead of 10–11 iterations.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

from nhgait.ocp import OptimalControlProblem, ProblemError

__all__ = ["GaitTask", "register", "get_task", "TASKS", "build_problem"]


@dataclass(frozen=True)
class GaitTask:
    """One gait task: its system, name, defaults and problem factory."""

    system: str
    name: str
    factory: Callable
    description: str
    defaults: dict
    guess_family: str

    def problem(self, model, *, distance=None, angle=None, period=None, intervals=50) -> OptimalControlProblem:
        opts = dict(self.defaults)
        for key, value in (("distance", distance), ("angle", angle), ("period", period)):
            if value is not None:
                opts[key] = float(value)
        problem = self.factory(model, intervals=intervals, **opts)
        return problem.replace(name=f"{self.system}/{self.name}")


TASKS: dict = {}


def register(system: str, name: str, *, description: str, defaults: dict, guess_family: str):
    """Decorator: register ``factory(model, *, intervals, distance, angle, period)``."""
    def deco(factory):
        TASKS[(system, name)] = GaitTask(system, name, factory, description, dict(defaults), guess_family)
        return factory
    return deco


def get_task(system: str, name: str) -> GaitTask:
    try:
        return TASKS[(system, name)]
    except KeyError:
        known = ", ".join(f"{s} {n}" for s, n in sorted(TASKS))
        raise ProblemError([f"unknown gait {name!r} for system {system!r} (known: {known})"],
                           title="invalid gait task") from None


def build_problem(model, system: str, gait: str, **options) -> OptimalControlProblem:
    return get_task(system, gait).problem(model, **options)


# ----------------------------------------------------------------------------- unicycle
@register("unicycle", "parallel-park", guess_family="unicycle-park",
          description="P1: shift sideways by `distance` and end at rest with the same heading",
          defaults={"distance": 0.5, "angle": 0.0, "period": 4.0})
def parallel_park(model, *, intervals, distance, angle, period):
    start = {name: 0.0 for name in model.state_names}
    return OptimalControlProblem(
        model, horizon=period, intervals=intervals, initial=start,
        final={"x": 0.0, "y": distance, "theta": angle, "p": 0.0, "pt_theta": 0.0},
        control_bounds=5.0)


# ----------------------------------------------------------------------------- snakeboard
def _snakeboard(model, *, intervals, period, final):
    return OptimalControlProblem(
        model, horizon=period, intervals=intervals,
        initial={"x": 0.0, "y": 0.0, "theta": 0.0, "psi": 0.0, "forward_velocity": 0.0},
        final={**final, "forward_velocity": 0.0},
        periodic=("psi", "phi", "pt_psi", "pt_phi"),
        state_bounds={"phi": (-1.0, 1.0)}, control_bounds=10.0)


@register("snakeboard", "forward", guess_family="drive",
          description="P2: move `distance` forward in one period, start and end at rest",
          defaults={"distance": 1.0, "angle": 0.0, "period": 2 * math.pi})
def forward(model, *, intervals, distance, angle, period):
    return _snakeboard(model, intervals=intervals, period=period, final={"x": distance, "theta": angle})


@register("snakeboard", "rotate", guess_family="rotate",
          description="P3: turn by `angle` on the spot in one period",
          defaults={"distance": 0.0, "angle": math.pi / 2, "period": 2 * math.pi})
def rotate(model, *, intervals, distance, angle, period):
    return _snakeboard(model, intervals=intervals, period=period,
                       final={"x": distance, "y": 0.0, "theta": angle})


@register("snakeboard", "lateral", guess_family="park",
          description="P4: shift sideways by `distance` (x(T) = 0, θ(T) = 0) in one period",
          defaults={"distance": 0.5, "angle": 0.0, "period": 2 * math.pi})
def lateral(model, *, intervals, distance, angle, period):
    return _snakeboard(model, intervals=intervals, period=period,
                       final={"x": 0.0, "y": distance, "theta": angle})
