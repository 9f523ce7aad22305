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

Statements are coordinate-free: they name configuration coordinates and velocity quantities
(``<coordinate>_dot``, ``forward_velocity``), never the momenta, so a task is the same problem
on the momentum model and on a velocity-coordinate model. Each task also names the velocity
quantities the planner uses as states (``velocities``, see :func:`~nhgait.gaits.planner.specialise`):
the snakeboard's (v, ψ̇, φ̇) with v the forward body velocity, the unicycle's (φ̇, θ̇). In those
coordinates every boundary condition and periodicity condition is a bound on a state or a
linear row, as in the hand-written reference, and Ipopt needs its iteration counts.

Periodicity (snakeboard): the benchmark asks for ψ, φ, v, ψ̇, φ̇ periodic with v the forward
body velocity and v(0) = 0, i.e. ψ, φ, ψ̇, φ̇ periodic and v(T) = v(0) = 0. (In momentum
coordinates p̃_ψ, p̃_φ periodic is the same feasible set given φ and v periodic.)
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
    velocities: tuple = ()      # velocity quantities used as states by the planner

    def problem(self, model, *, distance=None, angle=None, period=None, intervals=50) -> OptimalControlProblem:
        opts = dict(self.defaults)
        for key, value in (("distance", distance), ("angle", angle), ("period", period)):
            if value is not None:
                opts[key] = float(value)
        problem = self.factory(model, intervals=intervals, **opts)
        return problem.replace(name=f"{self.system}/{self.name}")


TASKS: dict = {}


def register(system: str, name: str, *, description: str, defaults: dict, guess_family: str,
             velocities: tuple = ()):
    """Decorator: register ``factory(model, *, intervals, distance, angle, period)``."""
    def deco(factory):
        TASKS[(system, name)] = GaitTask(system, name, factory, description, dict(defaults), guess_family,
                                         tuple(velocities))
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
UNICYCLE_VELOCITIES = ("phi_dot", "theta_dot")
SNAKEBOARD_VELOCITIES = ("forward_velocity", "psi_dot", "phi_dot")


@register("unicycle", "parallel-park", guess_family="unicycle-park", velocities=UNICYCLE_VELOCITIES,
          description="P1: shift sideways by `distance` and end at rest with the same heading",
          defaults={"distance": 0.5, "angle": 0.0, "period": 4.0})
def parallel_park(model, *, intervals, distance, angle, period):
    rest = {"phi_dot": 0.0, "theta_dot": 0.0}
    return OptimalControlProblem(
        model, horizon=period, intervals=intervals,
        initial={"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0, **rest},
        final={"x": 0.0, "y": distance, "theta": angle, **rest},
        control_bounds=5.0)


# ----------------------------------------------------------------------------- snakeboard
def _snakeboard(model, *, intervals, period, final):
    return OptimalControlProblem(
        model, horizon=period, intervals=intervals,
        initial={"x": 0.0, "y": 0.0, "theta": 0.0, "psi": 0.0, "forward_velocity": 0.0},
        final={**final, "forward_velocity": 0.0},
        periodic=("psi", "phi", "psi_dot", "phi_dot"),
        state_bounds={"phi": (-1.0, 1.0)}, control_bounds=10.0)


@register("snakeboard", "forward", guess_family="drive", velocities=SNAKEBOARD_VELOCITIES,
          description="P2: move `distance` forward in one period, start and end at rest",
          defaults={"distance": 1.0, "angle": 0.0, "period": 2 * math.pi})
def forward(model, *, intervals, distance, angle, period):
    return _snakeboard(model, intervals=intervals, period=period, final={"x": distance, "theta": angle})


@register("snakeboard", "rotate", guess_family="rotate", velocities=SNAKEBOARD_VELOCITIES,
          description="P3: turn by `angle` on the spot in one period",
          defaults={"distance": 0.0, "angle": math.pi / 2, "period": 2 * math.pi})
def rotate(model, *, intervals, distance, angle, period):
    return _snakeboard(model, intervals=intervals, period=period,
                       final={"x": distance, "y": 0.0, "theta": angle})


@register("snakeboard", "lateral", guess_family="park", velocities=SNAKEBOARD_VELOCITIES,
          description="P4: shift sideways by `distance` (x(T) = 0, θ(T) = 0) in one period",
          defaults={"distance": 0.5, "angle": 0.0, "period": 2 * math.pi})
def lateral(model, *, intervals, distance, angle, period):
    return _snakeboard(model, intervals=intervals, period=period,
                       final={"x": 0.0, "y": distance, "theta": angle})
