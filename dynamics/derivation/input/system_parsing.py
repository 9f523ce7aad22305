"""Reading a system statement: names, expressions and the structural checks of a
:class:`~.system.System` (thesis §3: q, L(q, q̇), ω(q)q̇ = 0, τ and the parameters).

:func:`parse_system` turns the fields a user wrote (strings, numbers or sympy expressions)
into a frozen :class:`ParsedSystem` — the real symbols q, q̇, the parameters and inputs, L, the
constraint expressions and τ — and lists every problem it finds, in one pass:

1. the names (:func:`_declare`): coordinates, velocities ``<q>_dot``, parameters, inputs and
   ``t`` distinct valid identifiers; the parameter values finite numbers;
2. the expressions (:func:`_expressions`): L, the constraints and the forces parsed by
   :mod:`.expressions` (never evaluated as code); every symbol known; the inputs found in the
   forces when not declared;
3. the structure (:func:`_check_structure`): L = ½q̇ᵀM(q)q̇ − V(q) (eq. 2.6) and smooth, each
   constraint linear in q̇ with no velocity-free term (Pfaffian, eq. 2.11);
4. the holonomic constraints h(q) = 0 (:func:`_holonomic`, :mod:`.holonomic`): parsed, then each
   eliminated (a coordinate solved for and substituted everywhere) where it is linear in a
   coordinate, else kept with its velocity row ∇h·q̇ appended to the constraints;
5. the frames (:func:`_frames`): the fiber coordinates and the planar frame (x, y, heading).

A problem in one field never hides one in another; a check that needs an earlier result runs
on whatever is valid. The numeric checks of the parameter values (a positive-definite M(q),
independent constraints) are :mod:`.parameter_checks`.
"""
from __future__ import annotations

import keyword
import math
from collections.abc import Mapping
from dataclasses import dataclass

import sympy as sp

from nhgait.dynamics.suggestions import known_names

from ...algebra.symbols import TIME
from ..holonomic import Elimination, choose_dependent, eliminate, velocity_row
from ..velocity_forms import linear_split, quadratic_split
from .expressions import CONSTANTS, FUNCTIONS, expression_problems, name_clashes, number_problems

#: (``TIME``, the time symbol t of forces and input laws, is :data:`nhgait.dynamics.algebra.symbols.TIME`)
__all__ = ["TIME", "ParsedSystem", "parse_system", "parse_field", "velocity_name", "name_of", "names_of",
           "from_sympy", "is_time_function", "NON_SMOOTH", "linear_split", "quadratic_split",
           "fiber_problems"]

#: functions that make L or ω non-smooth: their derivatives (DiracDelta) are not functions
NON_SMOOTH = (sp.Heaviside, sp.sign, sp.Min, sp.Max)


def velocity_name(coordinate: str) -> str:
    """Name of the velocity symbol of ``coordinate`` (``x`` → ``x_dot``)."""
    return f"{coordinate}_dot"


def is_time_function(obj) -> bool:
    """``obj`` is an undefined function of time alone, q(t) — sympy.physics.mechanics'
    ``dynamicsymbols("q")`` (whose t carries no assumptions, unlike :data:`TIME`)."""
    return (isinstance(obj, sp.core.function.AppliedUndef) and len(obj.args) == 1
            and isinstance(obj.args[0], sp.Symbol) and obj.args[0].name == TIME.name)


def name_of(obj) -> str:
    """The name a coordinate, parameter or input is given by: a string, a Symbol ``x`` or a
    dynamicsymbol ``x(t)`` (whose velocity ``x(t).diff(t)`` is then ``x_dot`` everywhere)."""
    if isinstance(obj, str):
        return obj.strip()
    if isinstance(obj, sp.Symbol):
        return obj.name
    if is_time_function(obj):
        return obj.func.__name__       # dynamicsymbols('x') -> 'x'
    what = (f"the sympy expression {obj}" if isinstance(obj, sp.Basic)
            else f"{type(obj).__name__} {obj!r:.60}")
    raise TypeError(f"expected a name, a sympy Symbol or a dynamicsymbol such as x(t), got {what}")


def names_of(value, field_name: str, problems: list, *, required: bool = False) -> list:
    """A list of names from a sequence of str/Symbol; a string where a list belongs, or a
    wrong element type, is one problem for the whole field."""
    if value is None:
        return []
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        kind = "a string" if isinstance(value, str) else type(value).__name__
        words = value.replace(",", " ").split() if isinstance(value, str) else []
        hint = f" (write {field_name} = [{', '.join(chr(34) + w + chr(34) for w in words)}])" if words else ""
        problems.append(f"{field_name}: expected a list of names, got {kind}{hint}")
        return []
    out = []
    for item in value:
        try:
            out.append(name_of(item))
        except TypeError as exc:
            problems.append(f"{field_name}: {exc}")
    if required and not out and value is not None:
        problems.append(f"{field_name}: at least one is required")
    return out


def from_sympy(expr, names: dict, where: str, problems: list):
    """A sympy expression given through the API: dynamicsymbols x(t) → x, x(t)' → x_dot and
    every symbol mapped onto the system's real symbol of the same name."""
    reps = {}
    for d in expr.atoms(sp.Derivative):
        if is_time_function(d.expr) and d.variables == d.expr.args:
            nm = velocity_name(d.expr.func.__name__)
            reps[d] = names.get(nm, sp.Symbol(nm, real=True))
    expr = expr.xreplace(reps) if reps else expr
    reps = {f: names[f.func.__name__] for f in expr.atoms(sp.core.function.AppliedUndef)
            if is_time_function(f) and f.func.__name__ in names}
    expr = expr.xreplace(reps) if reps else expr
    reps = {s: names[s.name] for s in expr.free_symbols if s.name in names and s != names[s.name]}
    expr = expr.xreplace(reps) if reps else expr
    if expr.has(sp.I, sp.zoo, sp.nan, sp.oo):
        problems.append(f"{where}: {expr} is not a finite real expression")
        return None
    return expr


def parse_field(value, names: dict, where: str, problems: list):
    """One field's expression: a string (parsed by :mod:`.expressions`, never evaluated), a
    number or a sympy expression. Unknown identifiers become plain symbols, reported by the
    caller with a hint; problems are appended to ``problems``, None is returned."""
    if isinstance(value, bool):
        problems.append(f"{where}: expected an expression, got {value!r}")
        return None
    if isinstance(value, (int, float)):
        if not math.isfinite(value):
            problems.append(f"{where}: {value!r} is not finite")
            return None
        return sp.Integer(value) if isinstance(value, int) else sp.Float(repr(value))
    if isinstance(value, str):
        expr = expression_problems(value, names, where, problems, allow_unknown=True)
        if expr is not None and isinstance(expr, sp.Equality):  # pragma: no cover - ast has no '='
            expr = expr.lhs - expr.rhs
        return expr
    if isinstance(value, sp.Equality):
        value = value.lhs - value.rhs
    if isinstance(value, sp.Expr):
        return from_sympy(value, names, where, problems)
    problems.append(f"{where}: expected an expression string or a sympy expression, got "
                    f"{type(value).__name__}")
    return None


@dataclass(frozen=True)
class ParsedSystem:
    """A system statement read: the normalised fields of :class:`~.system.System` and every
    problem found.

    Attributes
    ----------
    coordinates, parameters, inputs : the names (a tuple, a dict name → value, a tuple).
    q, q_dot : (n,) real symbols of the coordinates and their velocities ``<q>_dot``.
    L : the Lagrangian (None when it could not be read).
    constraint_exprs : (k,) the constraints that could be read, each meaning ``expr = 0``.
    tau : (n,) the generalized forces (0 for a coordinate without one).
    param_symbols, param_values : the parameters' symbols and default values (NaN when invalid).
    input_symbols : the input symbols of the forces.
    fiber : the fiber coordinates given, or None (chosen by the symmetry test).
    planar_frame : (x, y, heading) names or None.
    holonomic : the holonomic constraints h(q) kept (their velocity rows are the last
        entries of ``constraint_exprs``); dependent : the coordinate each is solved for.
    eliminated : (name, expression) of the coordinates eliminated by holonomic constraints.
    lagrangian, constraints, forces : the statement's fields, as expressions in the kept
        coordinates when a coordinate was eliminated (else as given).
    problems : every problem found, as sentences.
    complete : every field read and every structural check passed (the numeric checks of the
        parameters can run).
    """

    coordinates: tuple
    parameters: dict
    inputs: tuple
    q: tuple
    q_dot: tuple
    L: object
    constraint_exprs: tuple
    tau: tuple
    param_symbols: tuple
    param_values: tuple
    input_symbols: tuple
    fiber: tuple | None
    planar_frame: tuple | None
    holonomic: tuple
    dependent: tuple
    eliminated: tuple
    lagrangian: object
    constraints: object
    forces: object
    problems: tuple
    complete: bool


@dataclass(frozen=True)
class _Declared:
    """Step 1's names: coordinates, parameters (with values, NaN when invalid), the declared
    inputs (None: found in the forces) and whether every name is valid."""

    coordinates: list
    parameters: list
    values: list
    inputs: list | None
    names_ok: bool


@dataclass(frozen=True)
class _Symbols:
    """The real symbols of the declared names; ``names`` maps a name (and ``t``) to its
    symbol, ``known`` is the set of q, q̇ and the parameters."""

    q: tuple
    q_dot: tuple
    params: tuple
    names: dict
    known: frozenset


def parse_system(statement) -> ParsedSystem:
    """Read a system statement (any object with the fields of :class:`~.system.System`:
    coordinates, lagrangian, constraints, forces, parameters, inputs, fiber, planar_frame)."""
    problems: list[str] = []
    declared = _declare(statement, problems)
    symbols = _symbols(declared)
    L, cons, tau, inputs = _expressions(statement, declared, symbols, problems)
    holonomic, wanted = _holonomic(statement, declared, symbols, problems)
    complete = declared.names_ok and L is not None and None not in cons and not problems
    if declared.names_ok:
        _check_structure(L, cons, symbols.q_dot, problems)
    stated = _Stated(q=symbols.q, q_dot=symbols.q_dot, L=L, cons=tuple(cons), tau=tuple(tau),
                     holonomic=(), dependent=(),
                     eliminated=tuple(getattr(statement, "eliminated", ()) or ()),
                     lagrangian=statement.lagrangian, constraints=statement.constraints,
                     forces=statement.forces)
    if holonomic and complete and not problems:
        problems += _motion_left(holonomic, declared.coordinates)
    if holonomic and complete and not problems:
        stated = _constrained(stated, holonomic, wanted, declared, problems)
    coordinates = tuple(c.name for c in stated.q)
    fiber, planar_frame = _frames(statement, list(coordinates), problems)
    return ParsedSystem(
        coordinates=coordinates, parameters=dict(zip(declared.parameters, declared.values, strict=True)),
        inputs=tuple(u.name for u in inputs), q=stated.q, q_dot=stated.q_dot, L=stated.L,
        constraint_exprs=tuple(c for c in stated.cons if c is not None), tau=stated.tau,
        param_symbols=symbols.params, param_values=tuple(declared.values), input_symbols=tuple(inputs),
        fiber=fiber, planar_frame=planar_frame, holonomic=stated.holonomic, dependent=stated.dependent,
        eliminated=stated.eliminated, lagrangian=stated.lagrangian, constraints=stated.constraints,
        forces=stated.forces, problems=tuple(problems), complete=complete)


@dataclass(frozen=True, kw_only=True)
class _Stated:
    """The statement in its working coordinates (after any elimination)."""

    q: tuple
    q_dot: tuple
    L: object
    cons: tuple
    tau: tuple
    holonomic: tuple
    dependent: tuple
    eliminated: tuple
    lagrangian: object
    constraints: object
    forces: object


def _motion_left(holonomic, coordinates) -> list:
    """The problem of holonomic constraints that fix every coordinate: each removes one of the
    n coordinates, so h ≥ n leaves no motion (and no coordinate to integrate)."""
    h, n = len(holonomic), len(coordinates)
    if h < n:
        return []
    return [f"holonomic: {h} holonomic constraint(s) on {n} coordinate(s) ({', '.join(coordinates)}) "
            f"fix every coordinate: no motion is left (each removes one coordinate; keep at most {n - 1})"]


def _holonomic(statement, declared: _Declared, symbols: _Symbols, problems: list) -> tuple:
    """Step 4a: the holonomic constraints parsed (each a function of the coordinates and
    parameters only) and the dependent coordinate wanted for each (None: chosen)."""
    raw = getattr(statement, "holonomic", ()) or ()
    if isinstance(raw, (str, sp.Expr)):
        problems.append("holonomic: expected a list of expressions (write holonomic = [\"...\"])")
        return [], []
    exprs = [parse_field(h, symbols.names, f"holonomic constraint {i + 1}", problems)
             for i, h in enumerate(raw)]
    dependent = getattr(statement, "dependent", None)
    wanted = [None] * len(exprs)
    if dependent is not None:
        named = names_of(dependent, "dependent", problems)
        if len(named) != len(exprs):
            problems.append(f"dependent: one coordinate per holonomic constraint ({len(exprs)}), got "
                            f"{len(named)}")
        else:
            wanted = named
    if not declared.names_ok:
        return exprs, wanted
    known = frozenset(symbols.q) | frozenset(symbols.params)
    for i, (h, c) in enumerate(zip(exprs, wanted, strict=True)):
        if h is None:
            continue
        where = f"holonomic constraint {i + 1}"
        _check_symbols(h, where, known, symbols.names, problems)
        if h.has(*NON_SMOOTH):
            problems.append(f"{where} uses a discontinuous function: holonomic constraints must be smooth")
        if not h.free_symbols & set(symbols.q):
            problems.append(f"{where} ({h} = 0) contains no coordinate")
        if c is not None and (c not in declared.coordinates or symbols.names[c] not in h.free_symbols):
            problems.append(f"dependent: {c!r} is not a coordinate of holonomic constraint {i + 1} ({h} = 0)")
    if len(set(c for c in wanted if c)) < len([c for c in wanted if c]):
        problems.append("dependent: a coordinate is named twice")
    return exprs, wanted


def _constrained(stated: _Stated, holonomic, wanted, declared: _Declared, problems: list) -> _Stated:
    """Step 4b: eliminate what can be solved, keep the rest with its velocity rows (:mod:`.holonomic`)."""
    el = eliminate(Elimination(q=stated.q, q_dot=stated.q_dot, L=stated.L, constraints=stated.cons,
                               tau=stated.tau, holonomic=tuple(zip(holonomic, wanted, strict=True))))
    params = dict(zip(declared.parameters, declared.values, strict=True))
    kept = [h for h, _ in el.holonomic]
    names = [c.name for c in el.q]
    dependent = []
    for h, c in el.holonomic:
        if c is not None and c not in names:
            problems.append(f"dependent: {c!r} was eliminated by another holonomic constraint")
            c = None
        dependent.append(c if c is not None else names[choose_dependent(h, el.q, params)])
    rows = tuple(velocity_row(h, el.q, el.q_dot) for h in kept)
    changed = bool(el.eliminated)
    forces = {c: t for c, t in zip(names, el.tau, strict=True) if t != 0} if changed else stated.forces
    return _Stated(q=el.q, q_dot=el.q_dot, L=el.L, cons=el.constraints + rows, tau=el.tau,
                   holonomic=tuple(kept), dependent=tuple(dependent),
                   eliminated=stated.eliminated + el.eliminated,
                   lagrangian=el.L if changed else stated.lagrangian,
                   constraints=list(el.constraints) if changed else stated.constraints, forces=forces)


def _declare(statement, problems: list) -> _Declared:
    """Step 1: names of coordinates, parameters and inputs; parameter values (NaN when
    invalid); whether the names are valid."""
    coord_names = names_of(statement.coordinates, "coordinates", problems)
    if not coord_names and not any(p.startswith("coordinates") for p in problems):
        problems.append("coordinates: at least one coordinate is required")
    params = statement.parameters if statement.parameters is not None else {}
    if not isinstance(params, Mapping):
        problems.append(f"parameters: expected a table of name = value, got {type(params).__name__}")
        params = {}
    param_names = names_of(list(params), "parameters", problems)
    declared = None if statement.inputs is None else names_of(statement.inputs, "inputs", problems)
    all_names = coord_names + [velocity_name(c) for c in coord_names] + param_names + (declared or [])
    seen = set()
    for nm in all_names + ["t"]:
        if not nm.isidentifier() or keyword.iskeyword(nm) or nm.startswith("_"):
            problems.append(f"name {nm!r} is not a valid identifier (letters, digits and _; "
                            "not starting with _ or a digit)")
        elif nm in FUNCTIONS or nm in CONSTANTS:
            problems.append(f"name {nm!r} clashes with the function/constant of that name")
        elif nm in seen:
            problems.append(f"name {nm!r} is used twice (coordinates, velocities, parameters,"
                            " inputs and t must be distinct)")
        seen.add(nm)
    problems += name_clashes(all_names)
    names_ok = not problems
    values = [number_problems(v, f"parameter {nm!r}", problems)
              for nm, v in zip(param_names, params.values(), strict=False)]
    return _Declared(coord_names, param_names, values, declared, names_ok)


def _symbols(declared: _Declared) -> _Symbols:
    """The real symbols of step 1's names. Symbol checks use only valid names (no cascade of
    "unknown symbol" after a bad coordinates field)."""
    q = tuple(sp.Symbol(c, real=True) for c in declared.coordinates)
    q_dot = tuple(sp.Symbol(velocity_name(c), real=True) for c in declared.coordinates)
    params = tuple(sp.Symbol(p, real=True) for p in declared.parameters)
    names = {s.name: s for s in q + q_dot + params}
    names["t"] = TIME
    for u in declared.inputs or ():
        names[u] = sp.Symbol(u, real=True)
    return _Symbols(q, q_dot, params, names, frozenset(q + q_dot + params))


def _expressions(statement, declared: _Declared, symbols: _Symbols, problems: list) -> tuple:
    """Step 2: (L, constraints, τ, inputs) parsed; the symbols checked and the inputs found or
    checked when the names are valid."""
    names = symbols.names
    L = parse_field(statement.lagrangian, names, "lagrangian", problems)
    raw = statement.constraints if statement.constraints is not None else ()
    if isinstance(raw, (str, sp.Expr)):
        problems.append("constraints: expected a list of expressions, got a single "
                        f"{'string' if isinstance(raw, str) else 'expression'} (write constraints "
                        "= [\"...\"])")
        raw = ()
    cons = [parse_field(c, names, f"constraint {i + 1}", problems) for i, c in enumerate(raw)]
    tau = _forces(statement, declared, names, problems)
    if not declared.names_ok:
        return L, cons, tau, ()
    known = symbols.known
    if L is not None:
        _check_symbols(L, "the Lagrangian", known, names, problems)
    for i, c in enumerate(cons):
        if c is not None:
            _check_symbols(c, f"constraint {i + 1}", known, names, problems)
    if declared.inputs is None:
        found = []
        for e in tau:
            for s in sorted(e.free_symbols, key=lambda s: s.name):
                if s not in known and s != TIME and s not in found:
                    found.append(s)
        inputs = tuple(sp.Symbol(s.name, real=True) for s in found)   # API symbols may lack real=True
        return L, cons, [e.xreplace(dict(zip(found, inputs, strict=True))) for e in tau], inputs
    inputs = tuple(names[u] for u in declared.inputs)
    for cname, e in zip(declared.coordinates, tau, strict=True):
        _check_symbols(e, f"the force on {cname}", known | set(inputs) | {TIME}, names, problems)
    return L, cons, tau, inputs


def _forces(statement, declared: _Declared, names: dict, problems: list) -> list:
    """τ_i per coordinate from the ``forces`` table (0 where none is given)."""
    coord_names = declared.coordinates
    tau = [sp.Integer(0)] * len(coord_names)
    forces = statement.forces if statement.forces is not None else {}
    if not isinstance(forces, Mapping):
        problems.append(f"forces: expected a table of coordinate = expression, got {type(forces).__name__}")
        forces = {}
    for key, val in forces.items():
        try:
            kname = name_of(key)
        except TypeError as exc:
            problems.append(f"forces: {exc}")
            continue
        if kname not in coord_names:
            if declared.names_ok:
                problems.append(f"forces: {kname!r} is not a coordinate"
                                f"{known_names(kname, coord_names, label='coordinates')}")
            continue
        e = parse_field(val, names, f"force on {kname}", problems)
        if e is not None:
            tau[coord_names.index(kname)] = e
    return tau


def _check_structure(L, cons, qd, problems: list) -> None:
    """Step 3: a natural mechanical Lagrangian, smooth; constraints linear in the velocities."""
    zero_v = {v: 0 for v in qd}
    for i, c in enumerate(cons):
        if c is None:
            continue
        if c.has(*NON_SMOOTH):
            problems.append(f"constraint {i + 1} uses a discontinuous function (Heaviside, sign, "
                            "Min, Max): constraints must be smooth")
        elif linear_split(c, qd) is not None:
            continue              # read off as Σ ω_i(q) q̇_i (velocity_forms): Pfaffian
        elif any(sp.diff(c, a, b) != 0 for a in qd for b in qd):
            problems.append(f"constraint {i + 1} ({c} = 0) is not linear in the velocities")
        elif sp.expand(c.xreplace(zero_v)) != 0:
            problems.append(f"constraint {i + 1} ({c} = 0) has a term without velocities "
                            "(only Pfaffian constraints ω(q)q̇ = 0 are supported)")
        elif all(sp.diff(c, v) == 0 for v in qd):
            problems.append(f"constraint {i + 1} ({c} = 0) contains no velocity")
    if L is None:
        return
    if L.has(*NON_SMOOTH):
        problems.append("the Lagrangian uses a discontinuous function (Heaviside, sign, Min, Max): "
                        "L must be twice differentiable (use such functions in forces)")
        return
    if quadratic_split(L, qd) is not None:
        return                    # read off as ½q̇ᵀMq̇ − V (velocity_forms): natural
    grad = [sp.diff(L, v) for v in qd]
    if any(sp.diff(g, v) != 0 for g in [sp.diff(gg, w) for gg in grad for w in qd] for v in qd):
        problems.append("the Lagrangian is not quadratic in the velocities (need L = ½q̇ᵀMq̇ − V)")
    elif any(sp.expand(g.xreplace(zero_v)) != 0 for g in grad):
        problems.append("the Lagrangian has terms linear in the velocities (gyroscopic terms "
                        "are not supported; need L = ½q̇ᵀM(q)q̇ − V(q))")


def fiber_problems(fiber: tuple, coord_names) -> list:
    """What is wrong with the fiber's names ``fiber`` for these coordinates (empty: nothing)."""
    problems = []
    bad = [f for f in fiber if f not in coord_names]
    if bad:
        problems.append(f"fiber: {', '.join(bad)} not coordinates")
    if len(set(fiber)) != len(fiber):
        problems.append("fiber: repeated coordinate")
    return problems


def _frames(statement, coord_names: list, problems: list) -> tuple:
    """Step 4: (fiber, planar_frame) checked and normalised (``"auto"``: x, y, theta when the
    system has coordinates of those names)."""
    fiber = statement.fiber
    if fiber is not None:
        fiber = tuple(names_of(fiber, "fiber", problems))
        problems += fiber_problems(fiber, coord_names)
    frame = statement.planar_frame
    if frame == "auto":
        frame = ("x", "y", "theta") if {"x", "y", "theta"} <= set(coord_names) else None
    elif frame is not None:
        frame = tuple(names_of(frame, "planar_frame", problems))
        if len(frame) != 3 or any(c not in coord_names for c in frame):
            problems.append(f"planar_frame: need three coordinate names (x, y, heading), got {frame}")
        elif len(set(frame)) < 3:
            twice = sorted({c for c in frame if frame.count(c) > 1})
            problems.append(f"planar_frame = {list(frame)}: {', '.join(map(repr, twice))} named twice "
                            "(need three different coordinates: x, y, heading)")
    forward = getattr(statement, "forward", "x")
    if forward not in ("x", "y", "-x", "-y"):
        problems.append("forward: the body axis that points forward is \"x\", \"y\", \"-x\" or \"-y\", got "
                        f"{forward!r}")
    elif forward != "x" and frame is None:
        problems.append(f"forward = {forward!r} needs a planar frame (planar_frame = [x, y, heading])")
    return fiber, frame


def _check_symbols(expr, where: str, known, names: dict, problems: list) -> None:
    """Every symbol of ``expr`` known (with the close names as a hint); no time dependence, no
    undefined function."""
    for s in sorted(expr.free_symbols, key=lambda s: s.name):
        if s in known:
            continue
        if s == TIME:
            problems.append(f"{where} depends explicitly on time t (only autonomous "
                            "Lagrangians and constraints are supported)")
            continue
        hint = ""
        if s.name.endswith("_dot"):
            hint = f" (no coordinate named {s.name[:-4]!r})"
        elif velocity_name(s.name) in names:
            hint = ""
        allowed = [n for n, k in names.items() if k in known and k != TIME]
        problems.append(f"unknown symbol {s.name!r} in {where}: not a coordinate, velocity"
                        f" or parameter{hint}{known_names(s.name, allowed, sep='; ')}")
    for f in expr.atoms(sp.Function):
        if isinstance(f, sp.core.function.AppliedUndef):
            problems.append(f"unknown function {f.func.__name__!r} in {where}")
