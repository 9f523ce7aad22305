"""A gait-planning task as data: the ``[task]`` table of a scene file, a dict or a :class:`Task`.

Format (docs/gait-planning.md)::

    [task]
    name = "forward"                     # optional label
    horizon = 6.283185307179586          # s; or free: horizon = [2.0, 8.0] (or a table
                                         #   {initial = 4.0, min = 2.0, max = 8.0})
    intervals = 50                       # N control intervals (piecewise-constant inputs)
    initial = {x = 0.0, theta = 0.0, forward_velocity = 0.0}   # t = 0
    final = {x = 1.0, theta = 0.0}                              # t = T
    rest = ["final"]                     # at rest (every velocity zero) at these ends
    periodic = ["psi", "phi", "psi_dot", "phi_dot"]             # y(T) = y(0)
    bounds = {phi = [-1.0, 1.0]}                                # at every node
    control_bounds = {tau_psi = [-10.0, 10.0]}                  # or one number b: |u| ≤ b
    objective = "effort"                 # ∫|u|² dt; "time" (free horizon); or weights
                                         #   {effort = 1.0, time = 0.1, tau_psi = 2.0}
    velocities = ["forward_velocity", "psi_dot", "phi_dot"]     # optional: velocity states
    verify_tolerance = 1e-6              # re-simulation must meet every condition to this
    time_limit = 300                     # s the whole plan may take (default: from the robot's size)
    robust = {parameters = {m = [0.9, 1.1]}}   # optional: scenario planning (:mod:`.task_robust`)

Names are the system's coordinates, ``<coordinate>_dot``, the scene's named quantities
(``[quantities]``) and, for a planar frame (x, y, θ), ``forward_velocity`` and
``lateral_velocity``. A value is a number, a constant expression such as ``"pi/2"`` (parsed
by :func:`nhgait.dynamics.derivation.input.expressions.number_problems`, never evaluated as code), or
``[lo, hi]`` for a range (``"inf"``/``"-inf"`` for one-sided). Conditions may be redundant
(a full consistent state, "fibre at rest" as ẋ = ẏ = θ̇ = 0): the planner drops the dependent
ones and refuses an inconsistent set (:func:`nhgait.ocp.conditions.normalise`). Every problem
found — unknown keys and names, wrong types, contradictory values — is listed in one
:class:`~nhgait.ocp.ProblemError`.

:func:`parse_task` parses the table into the problem's own field types — a
:class:`~nhgait.ocp.statement.ProblemStatement` with no model yet, checked by the statement's
own validators in the words of the table (:data:`TASK_WORDS`) — and keeps what only a task
says (the objective in words, ends at rest, velocity states, the verification tolerance).
:func:`check_names` checks the names against a model, :func:`to_problem` binds the statement
to it: the :class:`~nhgait.ocp.OptimalControlProblem`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from nhgait.dynamics.derivation.input.assignments import parse_assignment
from nhgait.dynamics.suggestions import known_names
from nhgait.ocp import OptimalControlProblem, ProblemError, Quantity
from nhgait.ocp.statement import FrozenMap, ProblemStatement, Wording, instant_problems

from .phases import parse_integrals, parse_phases, parse_waypoints, phase_table, waypoint_table
from .robust import RobustTask, parse_robust, robust_name_problems, robust_table
from .values import control_bounds, horizon, names_list, number, table

__all__ = ["Task", "FrozenMap", "parse_task", "apply_overrides", "check_names", "task_names", "to_problem",
           "at_rest", "TASK_KEYS", "TASK_WORDS", "task_words", "quantity_objects"]

TASK_KEYS = ("name", "description", "horizon", "intervals", "initial", "final", "rest", "periodic", "bounds",
             "control_bounds", "objective", "velocities", "verify_tolerance", "time_limit", "waypoints",
             "integrals", "phases", "robust")
ENDS = ("initial", "final")
OBJECTIVES = ("effort", "time")
#: a task's name of a statement field (the others are the same)
TASK_FIELD_NAMES = {"state_bounds": "bounds", "free_horizon": "horizon_bounds"}


_NEED_MIN_MAX = "[task].horizon: need 0 < min ≤ max, got [{lo:g}, {hi:g}]"
#: the statement's checks (:class:`~nhgait.ocp.statement.Wording`) as a ``[task]`` table says
#: them; ``{where}`` is where the table was found; None: said by the parser already
_TASK_TEMPLATES = {
    "place": "[task].{field}.{name}",
    "field_names": {"state_bounds": "bounds", "free_horizon": "horizon"},
    "horizon": "[task].horizon = {value!r} must be positive",
    "horizon_not_number": None,
    "free_horizon_guess": None,
    "intervals": "{where}.intervals = {value!r} must be an integer from 1 to {max} (N = 5000 already takes "
                 "minutes to build and to solve)",
    "free_horizon_lower": _NEED_MIN_MAX,
    "free_horizon_any": _NEED_MIN_MAX,
    "time_without_free_horizon": "{where}.objective: a time objective needs a free horizon (horizon "
                                 "= [min, max])",
    "not_a_bound": None,
    "nan_bound": None,
    "contradictory": "{place}: contradictory range, lower bound {lo:g} > upper bound {hi:g}",
    "outside_bounds": "{place} = {value} lies outside bounds.{name} = [{lo:g}, {hi:g}]",
    "periodic_unequal": "[task]: {name} is periodic but initial {initial} and final {final} cannot be equal",
    "repeated": "[task].{field}: repeated names in {names_list}",
    "unknown_quantity": "[task].{field}: unknown name {name!r}{hint}",
    "unknown_input": "[task].{field}: unknown input {name!r}{hint}",
}


def task_words(where: str = "[task]") -> Wording:
    """The statement's validators in the words of a ``[task]`` table found at ``where``."""
    return Wording(**{key: (text.replace("{where}", where) if isinstance(text, str) else text)
                      for key, text in _TASK_TEMPLATES.items()})


TASK_WORDS = task_words()


@dataclass(frozen=True)
class Task:
    """A gait task (see the module docstring): the problem ``statement`` it parses into (no
    model yet) and what only a task says. Values are floats, ranges (lo, hi) tuples.

    The statement's fields read in the task's words: ``horizon``, ``intervals``, ``initial``,
    ``final``, ``periodic``, ``bounds`` (the statement's ``state_bounds``), ``control_bounds``
    and ``horizon_bounds`` (``free_horizon``: None for a fixed horizon; otherwise the horizon
    is free in [lo, hi] and ``horizon`` is its initial guess). ``objective`` maps "effort"
    (weight of ∫|u|²), "time" (weight of T) and input names (weights of each u_j², default 1)
    to weights.
    """

    statement: ProblemStatement
    objective: Mapping = field(default_factory=lambda: {"effort": 1.0})
    velocities: tuple = ()
    name: str = "task"
    description: str = ""
    rest: tuple = ()
    verify_tolerance: float = 1e-6
    time_limit: float | None = None
    robust: RobustTask | None = None     # [task.robust]: scenario planning (:mod:`.task_robust`)

    def __post_init__(self):
        object.__setattr__(self, "objective", FrozenMap(self.objective))
        for key in ("velocities", "rest"):
            object.__setattr__(self, key, tuple(getattr(self, key)))

    horizon = property(lambda self: self.statement.horizon)
    intervals = property(lambda self: self.statement.intervals)
    initial = property(lambda self: self.statement.initial)
    final = property(lambda self: self.statement.final)
    periodic = property(lambda self: self.statement.periodic)
    bounds = property(lambda self: self.statement.state_bounds)
    control_bounds = property(lambda self: self.statement.control_bounds)
    horizon_bounds = property(lambda self: self.statement.free_horizon)
    waypoints = property(lambda self: self.statement.waypoints)
    integrals = property(lambda self: self.statement.integrals)
    phases = property(lambda self: self.statement.phases)

    @property
    def names(self) -> tuple:
        """Every quantity name the task uses, in order of appearance (integrands, not the
        integral states)."""
        st = self.statement
        points = [*st.waypoints, *(w for p in st.phases for w in p.waypoints)]
        used = (*self.initial, *self.final, *self.periodic, *self.bounds,
                *(n for w in points for n in w.conditions),
                *(n for p in st.phases for n in (*p.final, *p.state_bounds)), *self.integrals.values())
        return tuple(n for n in dict.fromkeys(used) if n not in self.integrals)

    def replace(self, **changes) -> Task:
        """A copy with some fields changed, named as the task names them (``intervals=60``)."""
        statement_fields = set(self.statement.statement_fields()) | set(TASK_FIELD_NAMES.values())
        own = {k: v for k, v in changes.items() if k not in statement_fields}
        stated = {_STATEMENT_NAMES.get(k, k): v for k, v in changes.items() if k in statement_fields}
        return replace(self, statement=replace(self.statement, **stated), **own)

    def to_dict(self) -> dict:
        """The task as a ``[task]`` table (JSON/TOML-friendly)."""
        bounds = self.horizon_bounds
        out = {"name": self.name, "description": self.description}
        if self.phases:
            out["phases"] = [phase_table(p) for p in self.phases]
        else:
            out["intervals"] = self.intervals
            out["horizon"] = ({"initial": self.horizon, "min": bounds[0], "max": bounds[1]} if bounds
                              else self.horizon)
        if self.waypoints:
            out["waypoints"] = [waypoint_table(w) for w in self.waypoints]
        if self.integrals:
            out["integrals"] = dict(self.integrals)
        for key in ("initial", "final", "bounds"):
            out[key] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in getattr(self, key).items()}
        out["periodic"] = list(self.periodic)
        cb = self.control_bounds
        out["control_bounds"] = ({k: list(v) for k, v in cb.items()} if isinstance(cb, Mapping) else cb)
        out["objective"] = dict(self.objective)
        out["velocities"] = list(self.velocities)
        out["rest"] = list(self.rest)
        out["verify_tolerance"] = self.verify_tolerance
        if self.time_limit is not None:
            out["time_limit"] = self.time_limit
        if self.robust is not None:
            out["robust"] = robust_table(self)
        return out


#: a task's name → the statement's (``bounds`` → ``state_bounds``, ``horizon_bounds`` → ``free_horizon``)
_STATEMENT_NAMES = {task: stated for stated, task in TASK_FIELD_NAMES.items()}


# ----------------------------------------------------------------------------- parsing
def _objective(value, problems) -> dict:
    if isinstance(value, str):
        if value not in OBJECTIVES:
            problems.append(f"[task].objective = {value!r}: use \"effort\" (∫|u|² dt), \"time\" or a "
                            "table of weights")
            return {"effort": 1.0}
        return {value: 1.0}
    if not isinstance(value, Mapping) or not value:
        problems.append(f"[task].objective must be \"effort\", \"time\" or a table of weights, got {value!r}")
        return {"effort": 1.0}
    out = {}
    for name, w in value.items():
        out[str(name)] = number(w, f"[task].objective.{name}", problems)
        if out[str(name)] < 0:
            problems.append(f"[task].objective.{name} = {w!r} must be ≥ 0")
    if all(w == 0 for w in out.values()) and ("effort" in out or "time" in out):   # else unnamed inputs: 1
        problems.append(f"[task].objective = {_inline(value)}: {_NOTHING_TO_MINIMISE}")
    return out


#: the sentence for an objective whose every weight is 0 (the NLP's objective would be empty)
_NOTHING_TO_MINIMISE = ("every weight is 0, so there is nothing to minimise (give one a positive "
                        "weight, e.g. objective = \"effort\")")


def _inline(value: Mapping) -> str:
    """A table of weights as TOML writes it inline: {effort = 0.0, time = 0}."""
    return "{" + ", ".join(f"{k} = {v!r}" for k, v in value.items()) + "}"


def objective_problems(task: Task, inputs: tuple) -> list:
    """The objective's problem on a model with ``inputs``: weights that are each 0 on this
    model (``{effort = 0, u = 1}`` weighs every u_j² by 0) with no time or end term."""
    weights = control_weights(task.objective, inputs)
    if any(w > 0 for w in weights.values()) or task.objective.get("time", 0) > 0 or any(
            w > 0 for w in task.statement.end_weights.values()):
        return []
    return [f"[task].objective = {_inline(task.objective)}: every term weighs 0 (effort = 0 "
            "multiplies each input's weight), so there is nothing to minimise (give effort a "
            "positive weight, e.g. objective = \"effort\")"]


def _statement(data, problems) -> tuple:
    """(The ``[task]`` table's problem statement (no model), its objective), the problems of
    what it parses appended; the statement's own validators run after."""
    phases = parse_phases(data, problems)
    T, free_horizon = horizon(data, problems) if not phases else (None, None)   # with phases: their sums
    objective = _objective(data.get("objective", "effort"), problems)
    integrals, waypoints = parse_integrals(data, problems), parse_waypoints(data, problems)
    return ProblemStatement(
        None, horizon=T, intervals=data.get("intervals", 50), initial=table(data, "initial", problems),
        final=table(data, "final", problems), periodic=names_list(data, "periodic", problems, repeats=False),
        state_bounds=table(data, "bounds", problems), control_bounds=control_bounds(data, problems),
        time_weight=max(0.0, objective.get("time", 0.0)),     # a negative weight: the objective's own check
        free_horizon=free_horizon,
        waypoints=waypoints if not phases else (),   # with phases: said by parse_phases
        integrals=integrals, phases=phases,
        end_weights={n: w for n, w in objective.items() if n in integrals}), objective


def _task_fields(data, where, problems) -> dict:
    """What only a task says (not the statement's): velocities, rest, tolerance, name, description."""
    rest = names_list(data, "rest", problems)
    for end in rest:
        if end not in ENDS:
            problems.append(f"{where}.rest: {end!r} is not an end (use [\"initial\"], [\"final\"] or both)")
    tolerance = number(data.get("verify_tolerance", 1e-6), f"{where}.verify_tolerance", problems)
    if not tolerance > 0:
        problems.append(f"{where}.verify_tolerance = {data.get('verify_tolerance')!r} must be positive")
    for key in ("name", "description"):
        if key in data and not isinstance(data[key], str):
            problems.append(f"{where}.{key} must be a string")
    return {"velocities": names_list(data, "velocities", problems), "rest": rest,
            "verify_tolerance": tolerance,
            "name": str(data.get("name", "task")), "description": str(data.get("description", "")),
            "time_limit": _time_limit(data, where, problems), "robust": parse_robust(data, where, problems)}


def _time_limit(data, where, problems) -> float | None:
    """``time_limit``: seconds the plan may take, > 0 (``"inf"``: unlimited); None when not given."""
    if "time_limit" not in data:
        return None
    seconds = number(data["time_limit"], f"{where}.time_limit", problems, allow_inf=True)
    if math.isnan(seconds):                   # said already
        return None
    if not seconds > 0:
        problems.append(f"{where}.time_limit = {data['time_limit']!r} must be a positive number of seconds "
                        "(\"inf\": unlimited)")
        return None
    return seconds


def parse_task(data, *, where: str = "[task]", system=None, quantities=(), motion=()) -> Task:
    """A :class:`Task` from a ``[task]`` table (dict); every problem in one ProblemError.

    With ``system`` (and the scene's ``quantities``, of which ``motion`` are those of the
    inputs or accelerations) the names and counts are checked too, in the same error (no
    derivation needed: names come from the system's statement).
    """
    if isinstance(data, Task):
        return data
    if not isinstance(data, Mapping):
        raise ProblemError([f"{where} must be a table, got {type(data).__name__}"], title="invalid task")
    problems: list = []
    unknown = sorted(set(data) - set(TASK_KEYS))
    if unknown:
        problems.append(f"{where}: unknown key(s) "
                        f"{unknown}{known_names(unknown[0], TASK_KEYS, label='allowed')}")
    statement, objective = _statement(data, problems)
    task = Task(statement, objective, **_task_fields(data, where, problems))
    if system is None:
        problems += statement.problems(task_words(where))
    else:
        n, k = system.n, len(system.constraint_exprs)
        problems += _name_problems(task, task_names(system, quantities), tuple(system.inputs), n - k,
                                   where, motion)
        problems += robust_name_problems(task.robust, system, task_names(system, quantities), where)
    if problems:
        raise ProblemError(problems, title="invalid task")
    return task


# ----------------------------------------------------------------------------- overrides
def apply_overrides(data, assignments) -> dict:
    """``data`` (a ``[task]`` table) with ``key.sub=value`` assignments applied (``--set``).

    Values are data: numbers or constant expressions (checked by :func:`parse_task`), ranges
    written ``lo,hi`` or ``[lo, hi]``, name lists ``a,b`` for ``periodic``/``velocities``;
    ``objective`` and ``name`` take words. A malformed assignment is a ProblemError; a single
    string is one assignment (not one per character).
    """
    out = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in dict(data or {}).items()}
    problems, changed = [], []
    for text in [assignments] if isinstance(assignments, str) else assignments or ():
        assignment = parse_assignment(text, problems, example="final.x=2.0")
        if assignment is None:
            continue
        key, value, parts = assignment.key, assignment.value, list(assignment.parts)
        if parts[0] not in TASK_KEYS or len(parts) > 2:
            problems.append(f"--set {text!r}: unknown key {key!r}"
                            f"{known_names(parts[0], TASK_KEYS, label='allowed')[:-1]}, or table.name "
                            "such as final.x)")
            continue
        if value.startswith("[") and value.endswith("]"):
            value = value[1:-1]
        items = [v.strip() for v in value.split(",")]
        if parts[0] in ("periodic", "velocities", "rest"):
            parsed = [v for v in items if v]
        elif parts[0] in ("name", "description") or (parts[0] == "objective" and len(parts) == 1):
            parsed = value
        elif len(items) == 2:
            parsed = items
        elif parts[0] == "intervals":
            parsed = int(value) if value.isdigit() else value
        else:
            parsed = value
        changed.append((parts[0], text))
        if len(parts) == 1:
            out[parts[0]] = parsed
        else:
            table = out.get(parts[0], {})
            if not isinstance(table, Mapping):
                problems.append(f"--set {text!r}: [task].{parts[0]} is not a table")
                continue
            out[parts[0]] = {**table, parts[1]: parsed}
    if problems:
        raise ProblemError(problems, title="invalid --set")
    return renamed(out, changed)


#: keys whose change makes another task (the others change how it is solved or checked)
MEANING_KEYS = ("horizon", "initial", "final", "rest", "periodic", "bounds", "control_bounds", "objective",
                "waypoints", "integrals", "phases", "robust")


def renamed(table: dict, changed) -> dict:
    """``table`` named for what ``--set`` changed, unless the assignments name it themselves:
    ``parallel-park`` with ``final.y=0.8`` becomes ``parallel-park (final.y=0.8)`` — a task that
    means something else is not reported under its old name. ``changed``: (key, assignment text)."""
    if any(key == "name" for key, _ in changed):
        return table
    meaning = [text.strip() for key, text in changed if key in MEANING_KEYS]
    if not meaning:
        return table
    return {**table, "name": f"{table.get('name', 'task')} ({', '.join(meaning)})"}


# ----------------------------------------------------------------------------- names and problem
def task_names(system, quantities=()) -> tuple:
    """The names a task may use on ``system``: coordinates, ``<coordinate>_dot``, the planar
    body velocities (with a planar frame) and the scene's quantities."""
    from nhgait.dynamics.numerics.specialisation import BODY_VELOCITIES
    coords = tuple(system.coordinates)
    frame = getattr(system, "planar_frame", None)
    return (coords + tuple(f"{c}_dot" for c in coords) + (BODY_VELOCITIES if frame else ())
            + tuple(n for n in quantities if n not in coords))


def _name_problems(task: Task, known, inputs, n_velocities, where: str = "[task]", motion=()) -> list:
    """The statement's problems with its names checked against ``known`` and ``inputs``, then
    the task's own: quantities of the inputs (``motion``) at one instant, unknown objective
    weights, the count of velocity states, no inputs."""
    problems = task.statement.problems(task_words(where), known, inputs)
    problems += instant_problems(task.statement, motion, prefix="[task].")
    weights = (*OBJECTIVES, *inputs, *task.integrals)
    for name in task.objective:
        if name not in weights:
            problems.append(f"[task].objective: unknown weight {name!r}"
                            f"{known_names(name, weights, label='effort, time, an input or an integral')}")
    if task.velocities and len(task.velocities) != n_velocities:
        problems.append(f"[task].velocities: the system needs {n_velocities} velocity states, got "
                        f"{len(task.velocities)} ({', '.join(task.velocities)})")
    if not inputs:
        problems.append("the system has no inputs: there is nothing to plan")
    return problems


def check_names(task: Task, known: tuple, inputs: tuple, *, n_velocities: int, motion=()):
    """Unknown names and impossible counts of ``task`` on a model (one ProblemError)."""
    problems = _name_problems(task, known, inputs, n_velocities, motion=motion)
    if problems:
        raise ProblemError(problems, title="invalid task")


def scene_quantities(model, quantity_function, motion_function=None) -> dict:
    """The scene's named quantities as OCP :class:`Quantity` objects of the state z.

    ``quantity_function`` is the CasADi Function (q, q̇, params) → y of
    :func:`nhgait.dynamics.derivation.quantities.quantity_function`; q is the first n entries of z and q̇
    the model's ``qdot(z)``. ``motion_function`` (q, q̇, q̈, u, params) → y, of
    :func:`~nhgait.dynamics.derivation.quantities.motion_quantity_function`, gives the quantities
    of the inputs and accelerations, q̈ = ∂q̇/∂z · ż (:func:`~nhgait.ocp.problem.qddot_of`).
    """
    from nhgait.ocp.problem import qddot_of
    n = len(model.system.coordinates)
    qdot = model.numeric["qdot"]
    out = {}
    for name, i in _outputs(quantity_function, model):
        out[name] = Quantity(name,
                             lambda z, params, i=i: quantity_function(z[:n], qdot(z, params), params)[i],
                             f"scene quantity {name}")
    for name, i in _outputs(motion_function, model):
        out[name] = Quantity(name, lambda z, u, zdot, params, i=i: motion_function(
            z[:n], qdot(z, params), qddot_of(model, z, zdot, params), u, params)[i],
            f"scene quantity {name} (of the inputs and accelerations)", inputs=True)
    return out


def _outputs(function, model) -> list:
    """(name, index) of each output of a quantity function, the model's own states left out."""
    if function is None:
        return []
    names = function.name_out(0).split(",")
    return [(name, i) for i, name in enumerate(names) if name and name not in model.state_names]


def control_weights(objective: Mapping, inputs: tuple) -> dict:
    """Weights w_j of Σ_j w_j ∫u_j² dt: ``effort`` × the input's own weight (default 1).

    ``effort`` defaults to 1, except for a pure time objective (``{"time": c}``: 0).
    """
    has_inputs = any(k in inputs for k in objective)
    default = 0.0 if ("time" in objective and not has_inputs) else 1.0
    effort = float(objective.get("effort", default))
    return {u: effort * float(objective.get(u, 1.0)) for u in inputs}


def at_rest(task: Task, model) -> dict:
    """``initial`` and ``final`` with ``rest`` applied: every velocity state of ``model`` (the
    states after the coordinates: velocity quantities or momenta, zero exactly when q̇ = 0) is 0
    at a resting end. A value the task gives that excludes 0 is a ProblemError."""
    n = len(model.system.coordinates)
    ends, problems = {"initial": dict(task.initial), "final": dict(task.final)}, []
    for where in task.rest:
        for name in model.state_names[n:]:
            value = ends[where].get(name, 0.0)
            lo, hi = value if isinstance(value, tuple) else (value, value)
            if not lo <= 0.0 <= hi:
                problems.append(f"[task].{where}.{name} = {value} contradicts rest = [\"{where}\"] "
                                "(every velocity 0)")
            ends[where][name] = 0.0
    if problems:
        raise ProblemError(problems, title="invalid task")
    return ends


def to_problem(task: Task, model, *, quantities=None, params=None, name: str = "") -> OptimalControlProblem:
    """The :class:`OptimalControlProblem` of ``task`` on ``model`` (states, quantities, inputs).
    A model with kept holonomic constraints starts on them: ``holonomic<i> = 0`` at t = 0 (the
    velocity form keeps h(q) = 0 after; without it the dependent coordinate — the bicycle's
    pitch — would be free at t = 0)."""
    from nhgait.ocp.problem import holonomic_quantities
    problems = objective_problems(task, tuple(model.system.inputs))
    if problems:
        raise ProblemError(problems, title="invalid task")
    ends = at_rest(task, model)
    for holonomic in holonomic_quantities(model):
        ends["initial"].setdefault(holonomic, 0.0)
    return OptimalControlProblem.from_statement(
        task.statement, model, initial=ends["initial"], final=ends["final"],
        control_weights=control_weights(task.objective, tuple(model.system.inputs)),
        quantities=dict(quantities or {}), params=params, name=name or task.name)


def quantity_objects(model, scene):
    """The scene's named quantities as :class:`~nhgait.ocp.Quantity` objects on ``model``."""
    from nhgait.dynamics.derivation.quantities import motion_quantity_function, quantity_function
    motion = scene.motion_quantities
    return scene_quantities(model, quantity_function(model.system, scene.quantities) if scene.quantities
                            else None, motion_quantity_function(model.system, motion) if motion else None)
