"""A ``solution.json`` read as data, for a warm start (``nhgait plan --guess``) or a tracking
study (``nhgait track --plan``): :func:`read_solution` reads the file, :func:`previous_trajectory`
checks its trajectory (``t``, ``q``, ``qdot``, ``u`` and the names ``coordinates`` and
``inputs``), :func:`robot_problems` says whether it belongs to the robot at hand.

A file's text is data: nothing in it is evaluated, and every problem found is one sentence of
one :class:`~nhgait.ocp.ProblemError` (``invalid guess``), never an exception from numpy or
CasADi further on. The robot is recognised by what a warm start needs of it — the coordinates
(the columns of ``q`` and ``qdot``) and the inputs (the columns of ``u``), by name and in order
— and named in messages by the file's ``system`` label (``"unicycle/parallel-park"``).
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_SOLUTION_BYTES", "PreviousTrajectory", "read_solution", "previous_trajectory",
           "robot_problems", "file_robot_problems", "GUESS_TITLE"]

#: the largest solution.json read (bytes; the largest plans, with their feedback gains, write a
#: few MB)
MAX_SOLUTION_BYTES = 64 * 1024 * 1024

#: the title of the error for a previous solution that cannot start a plan
GUESS_TITLE = "invalid guess"

#: the longest piece of a file's own text quoted in a message (characters)
QUOTED = 60


def read_solution(path) -> dict:
    """The content of a ``solution.json`` written by :func:`~nhgait.gaits.planner.plan` (a
    dict), read as data (:func:`~nhgait.dynamics.derivation.input.textfiles.read_text_file`); a file
    that is not one is a :class:`~nhgait.dynamics.errors.ModelError` naming it."""
    from nhgait.dynamics.derivation.input.textfiles import read_text_file
    from nhgait.dynamics.errors import ModelError
    title = "cannot read the solution"
    text = read_text_file(path, "solution file", limit=MAX_SOLUTION_BYTES, title=title)
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise ModelError([f"solution file {path} is not JSON ({exc})"], title=title) from None
    if not isinstance(data, dict):
        raise ModelError([f"solution file {path} holds a JSON {type(data).__name__}, not the object "
                          "nhgait plan writes"], title=title)
    return data


@dataclass(kw_only=True, frozen=True, eq=False)
class PreviousTrajectory:
    """A previous answer, checked: ``t`` (K+1,) strictly increasing, ``q`` and ``qdot``
    (n × K+1), ``u`` (m × K), all finite; ``coordinates`` (n names) and ``inputs`` (m names),
    or None where the source did not name them (a sweep's coordinate-free warm data);
    ``system``: the label of the robot and task it came from ("" when unknown)."""

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    u: np.ndarray
    coordinates: tuple | None = None
    inputs: tuple | None = None
    system: str = ""


def quoted(value) -> str:
    """A file's own text in a message: ``repr``, cut to :data:`QUOTED` characters."""
    text = repr(value)
    return text if len(text) <= QUOTED else text[:QUOTED - 1] + "…"


def previous_trajectory(data: dict, source: str) -> PreviousTrajectory:
    """The trajectory of ``data`` (the content of a solution.json, or a sweep's warm data);
    ``source`` names it in messages. One :class:`~nhgait.ocp.ProblemError` lists every
    problem of its form: a part missing or not numbers, shapes that disagree with ``t`` and
    the names, values that are not finite, times that do not increase."""
    from nhgait.ocp import ProblemError
    tr = data.get("trajectory")
    if not isinstance(tr, dict):
        what = "no 'trajectory'" if tr is None else f"a 'trajectory' that is a JSON {_json_type(tr)}"
        raise ProblemError([f"{source} has {what}, not the object with t, q, qdot and u that "
                            "nhgait plan writes in solution.json"], title=GUESS_TITLE)
    problems: list = []
    names = {key: _names(tr, key, source, problems) for key in ("coordinates", "inputs")}
    arrays = {key: _numbers(tr, key, depth, source, problems)
              for key, depth in (("t", 1), ("q", 2), ("qdot", 2), ("u", 2))}
    problems += _shape_problems(arrays, names, source)
    if problems:
        raise ProblemError(problems, title=GUESS_TITLE)
    system = data.get("system")
    return PreviousTrajectory(t=arrays["t"], q=arrays["q"].T, qdot=arrays["qdot"].T, u=arrays["u"].T,
                              coordinates=names["coordinates"], inputs=names["inputs"],
                              system=system if isinstance(system, str) else "")


def _json_type(value) -> str:
    """The JSON name of a parsed value's type (string, number, list, …)."""
    kinds = ((bool, "boolean"), (str, "string"), ((int, float), "number"), (list, "list"),
             (dict, "object"), (type(None), "null"))
    return next((name for kind, name in kinds if isinstance(value, kind)), type(value).__name__)


def _names(tr: dict, key: str, source: str, problems: list) -> tuple | None:
    """``trajectory[key]`` as a tuple of names, None when absent; a problem when it is not a
    list of distinct non-empty strings."""
    value = tr.get(key)
    if value is None:
        return None
    if not (isinstance(value, list) and all(isinstance(v, str) and v for v in value)
            and len(set(value)) == len(value)):
        problems.append(f"{source}: trajectory.{key} must be a list of distinct names, got {quoted(value)}")
        return None
    return tuple(value)


def _is_numbers(value, depth: int) -> bool:
    """Is ``value`` a number (depth 0), a list of numbers (1), a list of lists of numbers (2)?"""
    if depth == 0:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, list) and all(_is_numbers(v, depth - 1) for v in value)


def _numbers(tr: dict, key: str, depth: int, source: str, problems: list):
    """``trajectory[key]`` as a float array of ``depth`` dimensions (rows of equal length), or
    None with the problem noted."""
    form = "a list of numbers" if depth == 1 else "a list of rows of numbers, one row per time"
    if key not in tr:
        problems.append(f"{source}: trajectory.{key} is missing ({form})")
        return None
    value = tr[key]
    if not _is_numbers(value, depth):
        problems.append(f"{source}: trajectory.{key} must be {form}, got {quoted(value)}")
        return None
    lengths = {len(row) for row in value} if depth == 2 else set()
    if len(lengths) > 1:
        problems.append(f"{source}: trajectory.{key} has rows of different lengths "
                        f"({', '.join(map(str, sorted(lengths)))})")
        return None
    array = np.array(value, dtype=float)
    return array.reshape(0, 0) if depth == 2 and array.ndim == 1 else array      # [] has no rows


def _shape_problems(arrays: dict, names: dict, source: str) -> list:
    """The shapes of t (K+1,), q and qdot (K+1 × n), u (K × m) against each other and the
    names; finite values; strictly increasing times."""
    t, problems = arrays["t"], []
    rows = {"q": None if t is None else t.size, "qdot": None if t is None else t.size,
            "u": None if t is None else t.size - 1}
    columns = {"q": names["coordinates"], "qdot": names["coordinates"], "u": names["inputs"]}
    if t is not None and t.size < 2:
        problems.append(f"{source}: trajectory.t has {t.size} time(s); a trajectory needs at least 2")
    for key, a in arrays.items():
        if a is not None and not np.all(np.isfinite(a)):
            problems.append(f"{source}: trajectory.{key} holds values that are not finite numbers (NaN or "
                            "infinite)")
    if t is not None and t.size >= 2 and np.all(np.isfinite(t)) and not np.all(np.diff(t) > 0):
        k = int(np.argmax(np.diff(t) <= 0))
        problems.append(f"{source}: trajectory.t must increase strictly; t[{k + 1}] = {t[k + 1]:g} follows "
                        f"t[{k}] = {t[k]:g}")
    for key in ("q", "qdot", "u"):
        problems += _one_shape(key, arrays[key], rows[key], columns[key], source)
    if arrays["q"] is not None and arrays["qdot"] is not None and names["coordinates"] is None \
            and arrays["q"].shape[1:] != arrays["qdot"].shape[1:]:
        problems.append(f"{source}: trajectory.q and trajectory.qdot have different numbers of columns "
                        f"({arrays['q'].shape[1]} and {arrays['qdot'].shape[1]})")
    return problems


def _one_shape(key: str, a, rows: int | None, names: tuple | None, source: str) -> list:
    """The problems of the shape of ``trajectory[key]``: ``rows`` rows (one per time of t, one
    per interval for u) of ``len(names)`` columns."""
    if a is None:
        return []
    problems = []
    if rows is not None and a.shape[0] != rows:
        per = "interval" if key == "u" else "time"
        problems.append(f"{source}: trajectory.{key} has {a.shape[0]} rows, trajectory.t needs {rows} "
                        f"(one per {per})")
    label = "trajectory.coordinates" if key != "u" else "trajectory.inputs"
    if names is not None and a.shape[0] and a.shape[1] != len(names):
        problems.append(f"{source}: trajectory.{key} has {a.shape[1]} columns, {label} names {len(names)}")
    return problems


def robot_problems(previous: PreviousTrajectory, coordinates, inputs, label: str, source: str) -> list:
    """What makes ``previous`` an answer for another robot than the one with ``coordinates``
    and ``inputs`` (named ``label``): the names (or, where ``previous`` has none, the counts)
    of its coordinates and inputs, in order. [] when it is this robot's; else one sentence
    naming both robots and what differs."""
    theirs = {"coordinates": previous.coordinates, "inputs": previous.inputs}
    counts = {"coordinates": previous.q.shape[0], "inputs": previous.u.shape[0]}
    theirs = {what: counts[what] if names is None else names for what, names in theirs.items()}
    mine = {"coordinates": tuple(coordinates), "inputs": tuple(inputs)}
    return _differences(theirs, previous.system, mine, label, source)


def file_robot_problems(data: dict, coordinates, inputs, label: str, source: str) -> list:
    """:func:`robot_problems` for a solution.json whose trajectory is not used (``nhgait track
    --plan``): its ``trajectory.coordinates`` and ``inputs`` against ``coordinates`` and
    ``inputs``, each where the file names them."""
    tr = data.get("trajectory") if isinstance(data.get("trajectory"), dict) else {}
    theirs = {key: _names(tr, key, source, []) for key in ("coordinates", "inputs")}
    system = data.get("system") if isinstance(data.get("system"), str) else ""
    return _differences({k: v for k, v in theirs.items() if v is not None}, system,
                        {"coordinates": tuple(coordinates), "inputs": tuple(inputs)}, label, source)


def _differences(theirs: dict, system: str, mine: dict, label: str, source: str) -> list:
    """One sentence naming both robots (``system``, ``label``) when ``theirs`` (what → names,
    or a count where the source has no names) differs from ``mine`` (what → names); else []."""
    differences = []
    for what, value in theirs.items():
        if isinstance(value, int) and value != len(mine[what]):
            differences.append(f"it has {value} {what}, this robot {len(mine[what])}")
        elif not isinstance(value, int) and value != mine[what]:
            differences.append(f"its {what} ({', '.join(value) or 'none'}) are not this robot's "
                               f"({', '.join(mine[what]) or 'none'})")
    if not differences:
        return []
    whose = f"of {quoted(system)}" if system else "of another robot"
    return [f"{source} is a plan {whose}, not of {label!r}: " + "; ".join(differences)]
