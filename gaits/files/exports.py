"""What a plan gives out beside ``solution.json``: ``trajectory.csv`` (the gait as one time-first
table, :meth:`nhgait.ocp.solution.Solution.table`) and the sentence of the plan's summary that
says which states the gait was solved in and which the files hold.

The planner transcribes a task in the velocity states it names (``forward_velocity``,
``psi_dot`` …: bounds and "at rest" are then bounds on states) and verifies and stores the gait
in the momenta of a regular chart (``p``, ``pt_psi`` …); ``trajectory.csv`` holds both worlds a
user knows: q, q̇ = ``<q>_dot``, the stored momenta and the inputs, each column with its unit.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["write_trajectory_csv", "states_text", "TRAJECTORY_CSV"]

TRAJECTORY_CSV = "trajectory.csv"


def write_trajectory_csv(solution, out: Path, units=None) -> Path:
    """``out/trajectory.csv``: t, q, q̇, the solution's other states and the inputs, one row per
    node, header ``name [unit]`` (the figures' units, :func:`nhgait.dynamics.units.unit_of`)."""
    return solution.to_csv(Path(out) / TRAJECTORY_CSV, units=units)


def states_text(solution) -> str:
    """``states (x, …, forward_velocity, psi_dot, phi_dot) in the solve; (x, …, p, pt_psi,
    pt_phi) in solution.json, with q̇ in trajectory.csv`` — or one list when they agree."""
    stored = list(solution.state_names)
    solved = list(solution.settings.get("transcribed_in", stored))
    if solved == stored:
        return f"states ({', '.join(stored)}); trajectory.csv adds q̇"
    return (f"solved in the states ({', '.join(solved)}); solution.json holds ({', '.join(stored)}) "
            "and trajectory.csv adds q̇")
