"""Benchmark tasks of issue 19 for the scaling families of ``experiments/scaling_systems.py``.

Each member gets one forward task, written as an nhgait ``[task]`` table (a dict in the format of
``docs/gait-planning.md``) the way a user would write it — redundant for the reduced state where
that is natural ("at rest" as every ``<q>_dot = 0``, "fibre at rest" as
``x_dot = y_dot = theta_dot = 0``, "joints periodic" as every joint angle *and* joint rate
periodic). ``scene_with_task(member)`` is the member's scene text with that table appended, so
``nhgait plan <file>`` reads it; ``experiments/reference_scale_ocp.py`` solves the same tasks with
an independent hand-written NLP.

Tasks (the brief's numbers, two of them changed where the reference showed the task degenerate
— see "Changes" below):

* ``snake_<N>``, N = 3 … 8 links (q = x, y, θ, α₁ … α_{N−1}): T = 6 s, 50 intervals; the head
  link's centre and heading start at x = y = θ = 0 and end at x = 0.3, y = 0, θ = 0; every αⱼ
  and αⱼ_dot periodic; α₁ ∈ [0.2, 1.5], α₂ ∈ [−1.5, −0.2] (a zig-zag band on the two head
  joints: the joint rates (α̇₁, α̇₂) fix the snake's velocity except where the first three
  axles' lines meet in one point, α₁ = α₂ for equal links — nhgait's singular set of the
  4-link snake is that 3 × 3 determinant too —, which the band excludes for every N) and
  |αⱼ| ≤ 1.5 for j ≥ 3 (joint limits); |τ| ≤ 5 N·m; effort ∫Σ τ² dt.
* ``cart_trailers_<k>``, k = 1 … 6 (q = x, y, θ, φ, β₁ … β_k): T = 8 s, 50 intervals; start with
  every coordinate 0 and at rest (every ``<q>_dot = 0``); end at x = 2 + k m, y = 0.3, θ = 0,
  every βᵢ = 0, at rest, the wheel angle φ free; βᵢ ∈ [−1, 1]; |τ| ≤ 5; effort.
* ``snakeboard_two_steering`` (q = x, y, θ, ψ, φ_f, φ_b): T = 2π, 60 intervals; start at
  x = y = θ = ψ = 0 with the fibre at rest (ẋ = ẏ = θ̇ = 0), end at x = 0.5, θ = 0, fibre at
  rest; ψ, φ_f, φ_b and their rates periodic; φ_f, φ_b ∈ [−1, 1]; |τ| ≤ 10; effort.

Changes from the brief (measured with ``experiments/reference_scale_ocp.py``, jit, N = 50)
-------------------------------------------------------------------------------------------
* **Snake bounds.** The brief's band αⱼ ∈ [0.2, 1.0] (odd j), [−1.0, −0.2] (even j) on *every*
  joint is fine for N = 3 (J = 0.1089, one shape loop) but degenerate for N ≥ 4: the snake has
  two velocity degrees of freedom for every N, so the trailing joints α₃ … are driven by
  (α̇₁, α̇₂) through the no-slip constraints and swing by ~1.3 rad over one head loop; held in a
  0.8 rad band and periodic, the optimum becomes a train of small loops (snake_4: J = 18.7,
  x reverses 12 times, 251 Ipopt iterations; snake_5: no convergence in 500 iterations).
  Relaxing only the trailing joints to |α| ≤ 1.2 still needs two loops (snake_4: J = 0.338,
  249 iterations). With the head band widened to 1.5 and |αⱼ| ≤ 1.5 for the trailing joints
  (not needed to avoid the singular set) the optimum is one loop for every N (J = 0.0550,
  0.0445, 0.0448, 0.0441, 0.0417, 0.0443 for N = 3 … 8; α₃ runs into its limit 1.5 for
  N ≥ 4) and all 48 guesses tried per member for N = 3 … 6 (phase, offset, trailing-joint
  values) reach the same optimum.
* **Cart distance.** With x(T) = 1 m the lane change is a parking manoeuvre, not a forward
  task: the optimum reverses (min φ̇ = −2.1 rad/s for k = 1, −22 rad/s for k = 6) and, for
  k = 2, 3, 5, 6, runs the hitch angles into their bounds (J = 0.18, 0.83, 2.2, 5.4, 8.6, 13.7 for
  k = 1 … 6; k = 5 hit 500 iterations, k = 6 took 406). The tail of a forward-moving train
  must shift 0.3 m sideways and end aligned, which needs a run of a few train lengths: with
  x(T) = 2 + k m the optimum drives forward only (φ̇ ≥ 0) with |β| ≤ 0.2 for every k
  (k = 1 … 6: J = 0.061, 0.155, 0.325, 0.606, 1.04, 1.67 in 6–8 iterations).
"""
from __future__ import annotations

import copy
import math
import sys

import sibling  # experiments/sibling.py: the other scripts, loaded by file path

SNAKE_LINKS = tuple(range(3, 9))
CART_TRAILERS = tuple(range(1, 7))
MEMBERS = ([f"snake_{N}" for N in SNAKE_LINKS] + [f"cart_trailers_{k}" for k in CART_TRAILERS]
           + ["snakeboard_two_steering"])
"""Every benchmark member, smallest first within each family."""


def _scaling_systems():
    """``experiments/scaling_systems.py`` (loaded by file path; it only produces scene text)."""
    return sibling.load("scaling_systems")


def _snake_task(N: int) -> dict:
    joints = [f"alpha{j}" for j in range(1, N)]
    bounds = {"alpha1": [0.2, 1.5], "alpha2": [-1.5, -0.2]}
    bounds.update({a: [-1.5, 1.5] for a in joints[2:]})
    return {
        "name": f"snake-{N}-forward",
        "description": f"{N}-link snake: the head 0.3 m forward, heading and lane kept, joints periodic",
        "horizon": 6.0,
        "intervals": 50,
        "initial": {"x": 0.0, "y": 0.0, "theta": 0.0},
        "final": {"x": 0.3, "y": 0.0, "theta": 0.0},
        "periodic": joints + [f"{a}_dot" for a in joints],
        "bounds": bounds,
        "control_bounds": 5.0,
        "objective": "effort",
    }


def _cart_task(k: int) -> dict:
    coords = ["x", "y", "theta", "phi"] + [f"beta{i}" for i in range(1, k + 1)]
    rest = {f"{c}_dot": 0.0 for c in coords}
    betas = {f"beta{i}": 0.0 for i in range(1, k + 1)}
    return {
        "name": f"cart-{k}-trailers-lane-change",
        "description": f"cart with {k} trailer(s): {2 + k} m forward and 0.3 m to the left, "
                       "aligned, from rest to rest",
        "horizon": 8.0,
        "intervals": 50,
        "initial": {**{c: 0.0 for c in coords}, **rest},
        "final": {"x": float(2 + k), "y": 0.3, "theta": 0.0, **betas, **rest},
        "bounds": {b: [-1.0, 1.0] for b in betas},
        "control_bounds": 5.0,
        "objective": "effort",
    }


def _snakeboard_task() -> dict:
    fibre_rest = {"x_dot": 0.0, "y_dot": 0.0, "theta_dot": 0.0}
    return {
        "name": "snakeboard-two-steering-forward",
        "description": "two-steering snakeboard: 0.5 m forward, heading kept, from rest to rest, "
                       "rotor and wheels periodic",
        "horizon": "2*pi",
        "intervals": 60,
        "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "psi": 0.0, **fibre_rest},
        "final": {"x": 0.5, "theta": 0.0, **fibre_rest},
        "periodic": ["psi", "phi_f", "phi_b", "psi_dot", "phi_f_dot", "phi_b_dot"],
        "bounds": {"phi_f": [-1.0, 1.0], "phi_b": [-1.0, 1.0]},
        "control_bounds": 10.0,
        "objective": "effort",
    }


def task(member: str) -> dict:
    """The ``[task]`` table (a fresh dict) of benchmark ``member`` (see ``MEMBERS``)."""
    if member.startswith("snake_") and member[6:].isdigit():
        return _snake_task(int(member[6:]))
    if member.startswith("cart_trailers_") and member[14:].isdigit():
        return _cart_task(int(member[14:]))
    if member == "snakeboard_two_steering":
        return _snakeboard_task()
    raise KeyError(f"unknown member {member!r}; choose from {', '.join(MEMBERS)}")


TASKS = {m: task(m) for m in MEMBERS}
"""The task of every member (read-only by convention: ``task(member)`` returns a copy to edit)."""


def horizon(task_table: dict) -> float:
    """The task's (fixed) horizon in s: a number or one of the constant strings used here."""
    value = task_table["horizon"]
    if isinstance(value, str):
        allowed = {"2*pi": 2 * math.pi, "pi": math.pi}
        if value.replace(" ", "") not in allowed:
            raise ValueError(f"horizon {value!r}: only {sorted(allowed)} are known here")
        return allowed[value.replace(" ", "")]
    return float(value)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def task_toml(task_table: dict) -> str:
    """A ``[task]`` TOML table of a task dict (keys in the dict's order)."""
    return "[task]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in task_table.items())


def scene_with_task(member: str) -> str:
    """The member's scene text (``scaling_systems.scene_text``) followed by its ``[task]``."""
    return (_scaling_systems().scene_text(member).rstrip("\n") + "\n\n"
            + task_toml(copy.deepcopy(TASKS[member])))


if __name__ == "__main__":  # pragma: no cover - prints one scene file
    print(scene_with_task(sys.argv[1] if len(sys.argv) > 1 else "snake_3"))
