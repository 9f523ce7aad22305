"""What a ``[task]`` says between its ends: waypoints, phases and integral states.

Format (docs/gait-planning.md)::

    [task]
    integrals = {near1 = "hump1"}        # I(t) = ∫₀ᵗ hump1 dt, a state: I(0) = 0 unless initial gives it
    final = {near1 = [0.2, "inf"]}       # … usable in every condition, bound and objective weight

    [[task.waypoints]]                   # conditions at a node between the ends
    time = 3.0                           # s from the start (from the phase's start in a phase);
    name = "corner"                      #   t N / T must be an integer (a node)
    conditions = {x = 1.0, y = [0.4, 0.6]}

    [[task.phases]]                      # phases, joined continuously, solved as one NLP; the task
    name = "to the pylon"                #   then has no horizon of its own (intervals = N shares N
                                         #   among the phases in proportion to theirs: a refinement)
    horizon = [1.0, 10.0]                # fixed, or free [min, max] (or {initial, min, max})
    intervals = 40
    final = {x = 10.0}                   # at the phase's end (a waypoint at a free time)
    bounds = {phi = [-0.5, 0.5]}         # path bounds on its nodes (added to the task's)
    control_bounds = {F = [0.0, 5.0]}    # on its inputs (intersected with the task's)
    waypoints = [{time = 1.0, conditions = {y = 0.0}}]

The task's ``final``, ``bounds`` and ``control_bounds`` hold in every phase (``final`` at the
end of the last). Each parser appends its problems in the table's words.
"""
from __future__ import annotations

from collections.abc import Mapping

from nhgait.dynamics.suggestions import known_names
from nhgait.ocp.statement import Phase, Waypoint

from .values import control_bounds, horizon, number, table

__all__ = ["WAYPOINT_KEYS", "PHASE_KEYS", "parse_waypoints", "parse_phases", "parse_integrals",
           "waypoint_table", "phase_table"]

WAYPOINT_KEYS = ("time", "name", "conditions")
PHASE_KEYS = ("name", "horizon", "intervals", "final", "bounds", "control_bounds", "waypoints")


def _tables(data, key, where, problems) -> list:
    """``data[key]``: a list of tables (TOML ``[[task.key]]``)."""
    items = data.get(key, [])
    if not isinstance(items, (list, tuple)) or not all(isinstance(i, Mapping) for i in items):
        problems.append(f"{where}.{key} must be a list of tables ([[task.{key}]]), got {items!r}")
        return []
    return list(items)


def _unknown_keys(item, allowed, at, problems) -> None:
    unknown = sorted(set(item) - set(allowed))
    if unknown:
        problems.append(f"{at}: unknown key(s) {unknown}{known_names(unknown[0], allowed, label='allowed')}")


def _name(item, at, problems) -> str:
    name = item.get("name", "")
    if not isinstance(name, str) or "." in name:
        problems.append(f"{at}.name must be a string without '.', got {name!r}")
        return ""
    return name


def parse_waypoints(data, problems, where: str = "[task]") -> tuple[Waypoint, ...]:
    """The :class:`~nhgait.ocp.statement.Waypoint` s of ``data["waypoints"]`` (their times
    are checked against the horizon by the statement)."""
    out = []
    for j, item in enumerate(_tables(data, "waypoints", where, problems)):
        at = f"{where}.waypoints[{j}]"
        _unknown_keys(item, WAYPOINT_KEYS, at, problems)
        if "time" not in item:
            problems.append(f"{at}: missing key 'time' (seconds from the start)")
        if not isinstance(item.get("conditions", {}), Mapping) or not item.get("conditions"):
            problems.append(f"{at}: 'conditions' must be a table of name = value, such as {{x = 1.0}}")
            conditions = {}
        else:
            conditions = table(item, "conditions", problems, at)
        time = number(item["time"], f"{at}.time", problems) if "time" in item else None   # missing: said
        out.append(Waypoint(time, conditions, _name(item, at, problems)))
    return tuple(out)


def parse_phases(data, problems, where: str = "[task]") -> tuple[Phase, ...]:
    """The :class:`~nhgait.ocp.statement.Phase` s of ``data["phases"]``."""
    out = []
    for i, item in enumerate(_tables(data, "phases", where, problems)):
        at = f"{where}.phases[{i}]"
        _unknown_keys(item, PHASE_KEYS, at, problems)
        T, free = horizon(item, problems, at)
        N = item.get("intervals", 20)
        if isinstance(N, bool) or not isinstance(N, int):
            problems.append(f"{at}.intervals = {N!r} must be an integer")
            N = 1
        out.append(Phase(T if T is not None else 1.0, N, free, final=table(item, "final", problems, at),
                         state_bounds=table(item, "bounds", problems, at),
                         control_bounds=_phase_controls(item, problems, at),
                         waypoints=parse_waypoints(item, problems, at), name=_name(item, at, problems)))
    if out and "horizon" in data:
        problems.append(f"{where}: with phases, each phase states its own horizon (remove horizon "
                        f"from {where})")
    if out and "intervals" in data:
        out = _spread(out, data["intervals"], where, problems)
    if out and data.get("waypoints"):
        problems.append(f"{where}.waypoints: with phases, each phase states its own waypoints (times "
                        "from its start)")
    return tuple(out)


def _spread(phases: list, total, where, problems) -> list:
    """The phases with ``total`` intervals shared in proportion to their own (``--intervals``
    or ``--set intervals=N`` on a task of phases: a refinement), each at least 1."""
    from dataclasses import replace
    if isinstance(total, bool) or not isinstance(total, int) or total < len(phases):
        problems.append(f"{where}.intervals = {total!r}: with phases, an integer of at least one "
                        f"interval per phase ({len(phases)}), shared in proportion to theirs")
        return phases
    own = [max(1, int(p.intervals)) if isinstance(p.intervals, int) else 1 for p in phases]
    shares = [max(1, round(total * n / sum(own))) for n in own]
    shares[-1] = max(1, total - sum(shares[:-1]))
    return [replace(p, intervals=n) for p, n in zip(phases, shares, strict=True)]


def _phase_controls(item, problems, at) -> dict:
    bounds = control_bounds(item, problems, at)
    if not isinstance(bounds, Mapping):
        problems.append(f"{at}.control_bounds: a phase bounds inputs by name "
                        "(a table such as {F = [0, 5]})")
        return {}
    return bounds


def parse_integrals(data, problems, where: str = "[task]") -> dict:
    """``integrals``: a table of new state name = the name of the quantity it integrates."""
    item = data.get("integrals", {})
    if not isinstance(item, Mapping):
        problems.append(f"{where}.integrals must be a table of name = \"quantity\", got {item!r}")
        return {}
    out = {}
    for name, integrand in item.items():
        if not isinstance(integrand, str):
            problems.append(f"{where}.integrals.{name}: the integrand is the name of a quantity (a string), "
                            f"got {integrand!r}")
            continue
        out[str(name)] = integrand
    return out


# ----------------------------------------------------------------------------- back to tables
def _conditions(mapping) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in mapping.items()}


def waypoint_table(point: Waypoint) -> dict:
    """A waypoint as its ``[[task.waypoints]]`` table."""
    out = {"time": point.time, "conditions": _conditions(point.conditions)}
    return {**out, "name": point.name} if point.name else out


def phase_table(phase: Phase) -> dict:
    """A phase as its ``[[task.phases]]`` table."""
    bounds = phase.free_horizon
    out = {"horizon": ({"initial": phase.horizon, "min": bounds[0], "max": bounds[1]} if bounds
                       else phase.horizon), "intervals": phase.intervals}
    for key, mapping in (("final", phase.final), ("bounds", phase.state_bounds),
                         ("control_bounds", phase.control_bounds)):
        if mapping:
            out[key] = _conditions(mapping)
    if phase.waypoints:
        out["waypoints"] = [waypoint_table(w) for w in phase.waypoints]
    return {**out, "name": phase.name} if phase.name else out
