"""``--set KEY=VALUE``: one parser for every command that changes a scene without editing it.

:func:`parse_assignment` splits ``final.x=2.0`` into its key path and value text (``nhgait plan``
and ``nhgait sweep`` apply it to a ``[task]``: :func:`nhgait.gaits.tasks.statement.apply_overrides`);
:func:`apply_simulation_overrides` applies assignments to a scene document's ``[simulation]``
table before the scene is parsed, so a changed value is checked exactly like one written in
the file (``nhgait simulate --set``). Values stay data: numbers, constant expressions
(``10*pi``) and input laws are read by the scene's safe expression parser, never evaluated.

Simulation keys::

    t_final=20  t0=0  samples=401  rtol=1e-10  atol=1e-12  method=compiled  formulation=lagrange
    q0.<coordinate>=0.3        qdot0.<coordinate>=1.0  (or qdot0.<coordinate>_dot=1.0)
    inputs.<input>=0.2*sin(t)  params.<parameter>=2.0  (or parameters.<parameter>=2.0)
"""
from __future__ import annotations

from dataclasses import dataclass

from nhgait.dynamics.suggestions import known_names

from ...errors import ModelError

__all__ = ["Assignment", "parse_assignment", "apply_simulation_overrides", "SIMULATION_SET_KEYS"]

#: the --set keys of ``nhgait simulate`` (tables take ``.<name>``)
SIMULATION_SET_KEYS = ("t_final", "t0", "samples", "rtol", "atol", "method", "formulation",
                       "q0", "qdot0", "inputs", "params", "parameters")
_TABLES = ("q0", "qdot0", "inputs", "params", "parameters")
_WORDS = ("method", "formulation")


@dataclass(frozen=True)
class Assignment:
    """``key.sub=value`` split: ``parts`` = ("key", "sub"), ``value`` the text after ``=``."""

    text: str
    key: str
    parts: tuple
    value: str


def parse_assignment(text, problems: list, *, example: str = "final.x=2.0") -> Assignment | None:
    """``text`` split at its first ``=`` (None after recording a problem when it is not
    ``key=value`` with both sides non-empty)."""
    key, sep, value = str(text).partition("=")
    key, value = key.strip(), value.strip()
    if not sep or not key or not value:
        problems.append(f"--set {text!r}: expected key=value, e.g. {example}")
        return None
    return Assignment(str(text), key, tuple(key.split(".")), value)


def _scalar(value: str):
    """A TOML-like value from text: int, float, or the text itself (a constant expression or a
    word, checked by the scene parser)."""
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            continue        # not this kind of number: the next kind, else the text itself
    return value


def apply_simulation_overrides(document: dict, assignments) -> dict:
    """A copy of a parsed scene ``document`` with ``assignments`` applied to its
    ``[simulation]`` table (see the module docstring); one ModelError lists every malformed or
    unknown key, with the close matches and the known names."""
    if not assignments:
        return document
    problems: list = []
    system = document.get("system") if isinstance(document.get("system"), dict) else {}
    coordinates = [str(c) for c in system.get("coordinates", []) or []]
    sim = dict(document.get("simulation") or {})
    for text in assignments:
        assignment = parse_assignment(text, problems, example="t_final=20 or q0.x=0.5")
        if assignment is None:
            continue
        head, depth = assignment.parts[0], len(assignment.parts)
        if head in SIMULATION_SET_KEYS and depth <= 2 and (head in _TABLES) != (depth == 2):
            form = (f"{head} needs a name: {head}.<name>=value, e.g. {head}.x=0.5" if head in _TABLES
                    else f"{head} takes no .<name>: {head}=value")
            problems.append(f"--set {assignment.text!r}: {form}")
            continue
        if head not in SIMULATION_SET_KEYS or len(assignment.parts) > 2:
            problems.append(f"--set {assignment.text!r}: unknown key {assignment.key!r}"
                            f"{known_names(head, SIMULATION_SET_KEYS, label='allowed')[:-1]}; "
                            "q0, qdot0, inputs and params take .<name>, e.g. q0.x=0.5)")
            continue
        if len(assignment.parts) == 1:
            sim[head] = assignment.value if head in _WORDS else _scalar(assignment.value)
        elif head in ("q0", "qdot0"):
            _set_initial(sim, assignment, coordinates, problems)
        else:
            table = "parameters" if head == "params" else head
            known = ((system.get("parameters") or {}) if table == "parameters"
                     else (system.get("inputs") or []))
            if known and assignment.parts[1] not in known:
                problems.append(f"--set {assignment.text!r}: unknown "
                                f"{'parameter' if table == 'parameters' else 'input'} "
                                f"{assignment.parts[1]!r}{known_names(assignment.parts[1], list(known))}")
                continue
            value = assignment.value if table == "inputs" else _scalar(assignment.value)
            sim[table] = {**dict(sim.get(table) or {}), assignment.parts[1]: value}
    if problems:
        raise ModelError(problems, title="invalid --set")
    return {**document, "simulation": sim}


def _set_initial(sim: dict, assignment: Assignment, coordinates: list, problems: list) -> None:
    """``q0.<c>`` / ``qdot0.<c>``: one entry of the list (coordinate order) or of the table."""
    head, name = assignment.parts
    coordinate = name[:-4] if head == "qdot0" and name.endswith("_dot") else name
    if coordinate not in coordinates:
        problems.append(f"--set {assignment.text!r}: {coordinate!r} is not a coordinate"
                        f"{known_names(coordinate, coordinates, label='coordinates')}")
        return
    current = sim.get(head)
    value = _scalar(assignment.value)
    if isinstance(current, list) and len(current) == len(coordinates):
        current = list(current)
        current[coordinates.index(coordinate)] = value
        sim[head] = current
    elif isinstance(current, dict) or current is None:
        table = {k: v for k, v in dict(current or {}).items() if k not in (coordinate, f"{coordinate}_dot")}
        key = f"{coordinate}_dot" if head == "qdot0" else coordinate
        if head == "q0":
            problems.append(f"--set {assignment.text!r}: [simulation].q0 must be a full list to "
                            "change one entry")
            return
        sim[head] = {**table, key: value}
    else:
        problems.append(f"--set {assignment.text!r}: [simulation].{head} is not a list of "
                        f"{len(coordinates)} values")
