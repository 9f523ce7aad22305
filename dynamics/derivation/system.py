"""Stating a system: coordinates q, Lagrangian L(q, q̇), Pfaffian constraints ω(q)q̇ = 0,
generalized forces τ and parameters — the five ingredients of thesis §3 ("the method requires
simply and only the knowledge of ...").

A :class:`System` is validated when it is built; every problem found is reported in one
:class:`~nhgait.dynamics.errors.ModelError`.

Conventions
-----------
* The velocity of coordinate ``x`` is the symbol ``x_dot``.
* ``lagrangian`` is T − V with T quadratic in the velocities, T = ½ q̇ᵀ M(q) q̇ (eq. 2.6).
* Each constraint is an expression linear in the velocities meaning ``expression = 0``; the
  rows of ω(q) are their velocity coefficients (eq. 2.11).
* ``forces`` maps a coordinate name to its generalized force τ_i, an expression in ``t``, the
  coordinates, the velocities, parameters and *input* symbols (controls). Inputs are declared
  with ``inputs=``; when not declared, every other symbol of the forces is an input.
* All symbols are real. Angles are not wrapped.
"""
from __future__ import annotations

import keyword
import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from nhgait.dynamics.suggestions import known_names

from ..errors import ModelError
from ..memo import OwnerMemo
from .expressions import CONSTANTS, FUNCTIONS, expression_problems, number_problems

TIME = sp.Symbol("t", real=True)

#: the force jump times of a system per parameter values (sympy walks the forces: ~20 µs a
#: call, and every simulation asks); dropped with the system
FORCE_JUMP_TIMES = OwnerMemo("force jump times per system and parameter values", limit=256)

#: functions that make L or ω non-smooth: their derivatives (DiracDelta) are not functions
_NON_SMOOTH = (sp.Heaviside, sp.sign, sp.Min, sp.Max)


def jump_times(exprs, subs=None) -> tuple:
    """Times at which ``exprs`` jump: the roots t = −b/a of the arguments a·t + b (a, b numbers
    after ``subs``) of Heaviside and sign. A simulation restarts its integrator there (a
    breakpoint), so a jump in a force or an input law is never stepped over."""
    out = set()
    for e in exprs:
        e = e.xreplace(subs) if subs else e
        for f in e.atoms(sp.Heaviside, sp.sign):
            arg = sp.expand(f.args[0])
            if arg.free_symbols != {TIME}:
                continue
            a, b = arg.coeff(TIME, 1), arg.coeff(TIME, 0)
            if a.is_number and b.is_number and a != 0 and sp.expand(arg - a * TIME - b) == 0:
                out.add(float(-b / a))
    return tuple(sorted(out))


def velocity_name(coordinate: str) -> str:
    """Name of the velocity symbol of ``coordinate`` (``x`` → ``x_dot``)."""
    return f"{coordinate}_dot"


def _name(obj) -> str:
    if isinstance(obj, str):
        return obj.strip()
    if isinstance(obj, sp.Symbol):
        return obj.name
    if isinstance(obj, sp.Expr) and obj.is_Function and not obj.args[1:] and obj.args == (TIME,):
        return type(obj).__name__  # dynamicsymbols('x') -> 'x'
    raise TypeError(f"expected a name or a sympy Symbol, got {type(obj).__name__} {obj!r:.60}")


def _names(value, field_name: str, problems: list, *, required: bool = False) -> list:
    """A list of names from a sequence of str/Symbol; a string where a list belongs, or a
    wrong element type, is one problem for the whole field."""
    if value is None:
        return []
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        kind = "a string" if isinstance(value, str) else type(value).__name__
        hint = f' (write {field_name} = ["{value.split()[0]}", ...])' if isinstance(value, str) and value.split() else ""
        problems.append(f"{field_name}: expected a list of names, got {kind}{hint}")
        return []
    out = []
    for item in value:
        try:
            out.append(_name(item))
        except TypeError as exc:
            problems.append(f"{field_name}: {exc}")
    if required and not out and value is not None:
        problems.append(f"{field_name}: at least one is required")
    return out


def _from_sympy(expr, names: dict, where: str, problems: list):
    """A sympy expression given through the API: dynamicsymbols x(t) → x, x(t)' → x_dot and
    every symbol mapped onto the system's real symbol of the same name."""
    reps = {}
    for d in expr.atoms(sp.Derivative):
        if d.expr.is_Function and len(d.variables) == 1 and d.variables[0].name == "t":
            nm = velocity_name(type(d.expr).__name__)
            reps[d] = names.get(nm, sp.Symbol(nm, real=True))
    expr = expr.xreplace(reps) if reps else expr
    reps = {f: names[type(f).__name__] for f in expr.atoms(sp.Function)
            if len(f.args) == 1 and isinstance(f.args[0], sp.Symbol) and f.args[0].name == "t"
            and type(f).__name__ in names}
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
        return _from_sympy(value, names, where, problems)
    problems.append(f"{where}: expected an expression string or a sympy expression, got "
                    f"{type(value).__name__}")
    return None


@dataclass(frozen=True, eq=False)
class System:
    """A mechanical system with Pfaffian constraints (thesis Def. 2.23 without assumption 3,
    which the symmetry test of step 3 checks instead).

    Parameters
    ----------
    coordinates : sequence of str or Symbol
        Generalized coordinates q (length n). The state ordering of every formulation follows
        this order.
    lagrangian : str or sympy expression
        L = T − V in the coordinates, velocities ``<q>_dot`` and parameters.
    constraints : sequence of str or expression, optional
        k expressions linear in the velocities, each meaning ``expr = 0``.
    forces : mapping coordinate name → str or expression, optional
        Generalized forces τ_i (missing coordinates get 0).
    parameters : mapping name → float, optional
        Named constants with their default values (SI units).
    inputs : sequence of str, optional
        Control input symbols appearing in the forces. Default: every symbol of the forces that
        is not t, a coordinate, a velocity or a parameter.
    name : str
        A label used in reports and file names.
    fiber : sequence of str, optional
        Fiber (group) coordinates s for the reduction; default: chosen by the full-symmetry test.
    planar_frame : (x, y, heading) names, "auto" or None
        Coordinates of a planar pose used for the SE(2)-type choice of g (version B of the
        reconstruction). "auto" looks for coordinates named x, y and theta.
    """

    coordinates: Sequence
    lagrangian: object
    constraints: Sequence = ()
    forces: Mapping | None = None
    parameters: Mapping | None = None
    inputs: Sequence | None = None
    name: str = "system"
    fiber: Sequence | None = None
    planar_frame: object = "auto"
    # derived (filled by __post_init__)
    q: tuple = field(init=False, repr=False)
    q_dot: tuple = field(init=False, repr=False)
    L: sp.Expr = field(init=False, repr=False)
    constraint_exprs: tuple = field(init=False, repr=False)
    tau: tuple = field(init=False, repr=False)
    param_symbols: tuple = field(init=False, repr=False)
    param_values: tuple = field(init=False, repr=False)
    input_symbols: tuple = field(init=False, repr=False)

    # ------------------------------------------------------------------ construction
    def __post_init__(self):
        """Validate everything and report every problem at once: a problem in one field never
        hides one in another; checks that need an earlier result (linearity needs the parsed
        constraint, the metric test needs every expression) run on whatever is valid."""
        problems: list[str] = []
        coord_names, param_names, values, declared_inputs, declared = self._declare(problems)
        q = tuple(sp.Symbol(c, real=True) for c in coord_names)
        qd = tuple(sp.Symbol(velocity_name(c), real=True) for c in coord_names)
        ps = tuple(sp.Symbol(p, real=True) for p in param_names)
        names = {s.name: s for s in q + qd + ps}
        names["t"] = TIME
        for u in declared_inputs or ():
            names[u] = sp.Symbol(u, real=True)
        known = set(q) | set(qd) | set(ps)  # symbol checks need valid names (no cascade of
                                            # "unknown symbol" after a bad coordinates field)
        L, cons, tau, inputs = self._expressions(coord_names, names, declared_inputs, known,
                                                 problems, check_symbols=declared)
        complete = declared and L is not None and None not in cons and not problems
        if declared:
            self._check_structure(L, cons, qd, problems)

        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen dataclass)
        set_("q", q)
        set_("q_dot", qd)
        set_("L", L)
        set_("constraint_exprs", tuple(c for c in cons if c is not None))
        set_("tau", tuple(tau))
        set_("param_symbols", ps)
        set_("param_values", tuple(values))
        set_("input_symbols", inputs)
        set_("coordinates", tuple(coord_names))
        set_("parameters", dict(zip(param_names, values)))
        set_("inputs", tuple(u.name for u in inputs))
        self._frames(coord_names, problems)
        if complete and not problems:   # numbers need every expression and value to be valid
            self._numeric_checks(problems)
        if problems:
            raise ModelError(problems)

    def _declare(self, problems):
        """Names of coordinates, parameters and inputs; parameter values (nan when invalid);
        whether the names are valid."""
        coord_names = _names(self.coordinates, "coordinates", problems)
        if not coord_names and not any(p.startswith("coordinates") for p in problems):
            problems.append("coordinates: at least one coordinate is required")
        params = self.parameters if self.parameters is not None else {}
        if not isinstance(params, Mapping):
            problems.append(f"parameters: expected a table of name = value, got {type(params).__name__}")
            params = {}
        param_names = _names(list(params), "parameters", problems)
        declared = None if self.inputs is None else _names(self.inputs, "inputs", problems)
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
        names_ok = not problems
        values = [number_problems(v, f"parameter {nm!r}", problems) for nm, v in zip(param_names, params.values())]
        return coord_names, param_names, values, declared, names_ok

    def _expressions(self, coord_names, names, declared_inputs, known, problems, check_symbols=True):
        """Parse L, the constraints and the forces; find or check the inputs."""
        L = parse_field(self.lagrangian, names, "lagrangian", problems)
        raw = self.constraints if self.constraints is not None else ()
        if isinstance(raw, (str, sp.Expr)):
            problems.append("constraints: expected a list of expressions, got a single "
                            f"{'string' if isinstance(raw, str) else 'expression'} (write constraints = [\"...\"])")
            raw = ()
        cons = [parse_field(c, names, f"constraint {i + 1}", problems) for i, c in enumerate(raw)]
        tau = [sp.Integer(0)] * len(coord_names)
        forces = self.forces if self.forces is not None else {}
        if not isinstance(forces, Mapping):
            problems.append(f"forces: expected a table of coordinate = expression, got {type(forces).__name__}")
            forces = {}
        for key, val in forces.items():
            try:
                kname = _name(key)
            except TypeError as exc:
                problems.append(f"forces: {exc}")
                continue
            if kname not in coord_names:
                if check_symbols:
                    problems.append(f"forces: {kname!r} is not a coordinate"
                                    f"{known_names(kname, coord_names, label='coordinates')}")
                continue
            e = parse_field(val, names, f"force on {kname}", problems)
            if e is not None:
                tau[coord_names.index(kname)] = e
        if not check_symbols:
            return L, cons, tau, ()
        if L is not None:
            self._check_symbols(L, "the Lagrangian", known, names, problems)
        for i, c in enumerate(cons):
            if c is not None:
                self._check_symbols(c, f"constraint {i + 1}", known, names, problems)
        if declared_inputs is None:
            found = []
            for e in tau:
                for s in sorted(e.free_symbols, key=lambda s: s.name):
                    if s not in known and s != TIME and s not in found:
                        found.append(s)
            inputs = tuple(sp.Symbol(s.name, real=True) for s in found)   # API symbols may lack real=True
            tau = [e.xreplace(dict(zip(found, inputs))) for e in tau]
        else:
            inputs = tuple(names[u] for u in declared_inputs)
            for cname, e in zip(coord_names, tau):
                self._check_symbols(e, f"the force on {cname}", known | set(inputs) | {TIME},
                                    names, problems)
        return L, cons, tau, inputs

    @staticmethod
    def _check_structure(L, cons, qd, problems):
        """Natural mechanical Lagrangian, smooth; constraints linear in the velocities."""
        zero_v = {v: 0 for v in qd}
        for i, c in enumerate(cons):
            if c is None:
                continue
            if c.has(*_NON_SMOOTH):
                problems.append(f"constraint {i + 1} uses a discontinuous function (Heaviside, sign, "
                                "Min, Max): constraints must be smooth")
            elif any(sp.diff(c, a, b) != 0 for a in qd for b in qd):
                problems.append(f"constraint {i + 1} ({c} = 0) is not linear in the velocities")
            elif sp.expand(c.xreplace(zero_v)) != 0:
                problems.append(f"constraint {i + 1} ({c} = 0) has a term without velocities "
                                "(only Pfaffian constraints ω(q)q̇ = 0 are supported)")
            elif all(sp.diff(c, v) == 0 for v in qd):
                problems.append(f"constraint {i + 1} ({c} = 0) contains no velocity")
        if L is None:
            return
        if L.has(*_NON_SMOOTH):
            problems.append("the Lagrangian uses a discontinuous function (Heaviside, sign, Min, Max): "
                            "L must be twice differentiable (use such functions in forces)")
            return
        grad = [sp.diff(L, v) for v in qd]
        if any(sp.diff(g, v) != 0 for g in [sp.diff(gg, w) for gg in grad for w in qd] for v in qd):
            problems.append("the Lagrangian is not quadratic in the velocities (need L = ½q̇ᵀMq̇ − V)")
        elif any(sp.expand(g.xreplace(zero_v)) != 0 for g in grad):
            problems.append("the Lagrangian has terms linear in the velocities (gyroscopic terms "
                            "are not supported; need L = ½q̇ᵀM(q)q̇ − V(q))")

    def _frames(self, coord_names, problems):
        """Check and normalise ``fiber`` and ``planar_frame``."""
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen dataclass)
        if self.fiber is not None:
            fib = _names(self.fiber, "fiber", problems)
            bad = [f for f in fib if f not in coord_names]
            if bad:
                problems.append(f"fiber: {', '.join(bad)} not coordinates")
            if len(set(fib)) != len(fib):
                problems.append("fiber: repeated coordinate")
            set_("fiber", tuple(fib))
        pf = self.planar_frame
        if pf == "auto":
            pf = ("x", "y", "theta") if {"x", "y", "theta"} <= set(coord_names) else None
        elif pf is not None:
            pf = tuple(_names(pf, "planar_frame", problems))
            if len(pf) != 3 or any(c not in coord_names for c in pf):
                problems.append(f"planar_frame: need three coordinate names (x, y, heading), got {pf}")
        set_("planar_frame", pf)

    @staticmethod
    def _check_symbols(expr, where, known, names, problems):
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
            problems.append(f"unknown symbol {s.name!r} in {where}: not a coordinate, velocity"
                            f" or parameter{hint}{known_names(s.name, [n for n, k in names.items() if k in known and k != TIME], sep='; ')}")
        for f in expr.atoms(sp.Function):
            if isinstance(f, sp.core.function.AppliedUndef):
                problems.append(f"unknown function {f.func.__name__!r} in {where}")

    # ------------------------------------------------------------------ derived objects
    @property
    def n(self) -> int:
        """Number of coordinates."""
        return len(self.q)

    @property
    def k(self) -> int:
        """Number of constraints."""
        return len(self.constraint_exprs)

    def mass_matrix(self) -> sp.Matrix:
        """Kinetic metric M(q) = ∂²L/∂q̇∂q̇ (eq. 2.5), n×n."""
        return sp.hessian(self.L, self.q_dot)

    def potential(self) -> sp.Expr:
        """V(q) = −L(q, 0)."""
        return -self.L.xreplace({v: 0 for v in self.q_dot})

    def omega(self) -> sp.Matrix:
        """Pfaffian constraint matrix ω(q), k×n (eq. 2.11)."""
        if not self.constraint_exprs:
            return sp.zeros(0, self.n)
        return sp.Matrix([[sp.diff(c, v) for v in self.q_dot] for c in self.constraint_exprs])

    def force_jump_times(self, values=None) -> tuple:
        """Times at which a force jumps (Heaviside/sign of a·t + b): integration breakpoints
        (remembered per system and parameter values, :data:`FORCE_JUMP_TIMES`)."""
        key = tuple(sorted((name, float(v)) for name, v in values.items())) if values else ()
        return FORCE_JUMP_TIMES.get(self, key, lambda: jump_times(self.tau, self.param_subs(values)))

    def force_vector(self) -> sp.Matrix:
        """Generalized forces τ(t, q, q̇, u), n×1."""
        return sp.Matrix(self.tau)

    def param_subs(self, values: Mapping | None = None) -> dict:
        """Map parameter symbols to numbers (defaults overridden by ``values``)."""
        vals = dict(self.parameters)
        if values:
            unknown = [k for k in values if k not in vals]
            if unknown:
                raise ModelError([f"unknown parameter {k!r}{known_names(k, vals, label='parameters')}"
                                  for k in unknown])
            vals.update({k: float(v) for k, v in values.items()})
        return {s: vals[s.name] for s in self.param_symbols}

    def param_vector(self, values: Mapping | None = None) -> np.ndarray:
        """Parameter values as a vector in the order of :attr:`param_symbols`."""
        subs = self.param_subs(values)
        return np.array([subs[s] for s in self.param_symbols], dtype=float)

    def sample_configurations(self, count: int, seed: int = 0) -> np.ndarray:
        """Random configurations (count×n) used by numeric checks, uniform in [−1.2, 1.2]."""
        rng = np.random.default_rng(seed)
        return rng.uniform(-1.2, 1.2, size=(count, self.n))

    def numeric_functions(self):
        """(M(q, params), ω(q, params) or None, V(q, params)) as numpy callables, lambdified once
        per system and shared by the input checks and the symmetry test (not pickled)."""
        return self._nhgait_lambdified

    @cached_property
    def _nhgait_lambdified(self) -> tuple:
        args = [self.q, self.param_symbols]
        return (sp.lambdify(args, self.mass_matrix(), "numpy"),
                sp.lambdify(args, self.omega(), "numpy") if self.k else None,
                sp.lambdify(args, self.potential(), "numpy"))

    def parameter_problems(self, values=None, *, label: str = "the default parameters") -> list:
        """Every problem with a parameter set (``values`` overriding the defaults; a mapping
        name → number or a vector in :attr:`param_symbols` order): non-finite values, a kinetic
        metric that is singular or not positive definite, dependent constraints — checked at
        random configurations. Returns a list of sentences (empty when the values are valid)."""
        problems: list = []
        if values is None:
            pv = self.param_vector()
        elif isinstance(values, Mapping):
            unknown = [k for k in values if k not in self.parameters]
            problems += [f"unknown parameter {k!r}{known_names(k, self.parameters, label='parameters')}"
                         for k in unknown]
            merged = dict(self.parameters)
            merged.update({k: number_problems(v, f"parameter {k!r}", problems) for k, v in values.items()
                           if k in self.parameters})
            pv = np.array([merged[s.name] for s in self.param_symbols], dtype=float)
        else:
            pv = np.asarray(values, dtype=float).ravel()
            if pv.size != len(self.param_symbols):
                return [f"expected {len(self.param_symbols)} parameter values "
                        f"({', '.join(self.parameters)}), got {pv.size}"]
            problems += [f"parameter {s.name!r}: {v!r} is not finite" for s, v in zip(self.param_symbols, pv)
                         if not np.isfinite(v)]
        if problems:
            return problems
        self._numeric_checks(problems, pv, label)
        return problems

    def _numeric_checks(self, problems: list, pv=None, label: str = "the default parameters") -> None:
        f_M, f_w, _ = self.numeric_functions()
        pv = self.param_vector() if pv is None else pv
        worst_eig, where_eig, largest = np.inf, None, 0.0
        max_rank = 0
        for qs in self.sample_configurations(8, seed=1):
            with np.errstate(all="ignore"):
                Mn = np.array(f_M(qs, pv), dtype=float)
            if not np.all(np.isfinite(Mn)):
                continue
            ev = np.linalg.eigvalsh(0.5 * (Mn + Mn.T))
            largest = max(largest, abs(ev[-1]), abs(ev[0]))
            if ev[0] < worst_eig:
                worst_eig, where_eig = ev[0], qs
            if f_w is not None:
                with np.errstate(all="ignore"):
                    Wn = np.array(f_w(qs, pv), dtype=float).reshape(self.k, self.n)
                if np.all(np.isfinite(Wn)):
                    max_rank = max(max_rank, np.linalg.matrix_rank(Wn, tol=1e-9 * max(1, np.abs(Wn).max())))
        tiny = 1e-12 * max(1.0, largest)
        if where_eig is not None and worst_eig <= tiny:
            zero_rows = [c for c, v in zip(self.coordinates, self.q_dot)
                         if all(sp.diff(self.L, v, w) == 0 for w in self.q_dot)]
            extra = f" (no kinetic energy in {', '.join(zero_rows)})" if zero_rows else ""
            at = f"at q = {np.round(where_eig, 3).tolist()} with {label}"
            if abs(worst_eig) <= tiny:
                problems.append(f"the kinetic metric M(q) = ∂²L/∂q̇² is singular {at}{extra}: a "
                                "velocity direction carries no kinetic energy (a zero mass or inertia?)")
            else:
                problems.append("the kinetic metric M(q) = ∂²L/∂q̇² is not positive definite: smallest "
                                f"eigenvalue {worst_eig:.3g} {at}{extra} (a negative mass or inertia?)")
        if self.k and max_rank < self.k:
            problems.append(f"the constraints are dependent: rank ω(q) = {max_rank} < k = {self.k}"
                            f" at every sampled configuration with {label} (remove redundant constraints)")
        if self.k >= self.n:
            problems.append(f"{self.k} constraints on {self.n} coordinates leave no motion")

    # ------------------------------------------------------------------ pickling
    def __getstate__(self):
        """Drop private caches (lambdified functions are not picklable)."""
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_nhgait")}

    def __setstate__(self, state):
        self.__dict__.update(state)

    # ------------------------------------------------------------------ identity
    def canonical_text(self) -> str:
        """A canonical textual form of everything the derivations depend on (not the parameter
        values): used for the content hash of the cache."""
        parts = [
            "coordinates=" + ",".join(self.coordinates),
            "parameters=" + ",".join(s.name for s in self.param_symbols),
            "inputs=" + ",".join(self.inputs),
            "L=" + sp.srepr(self.L),
            "constraints=" + ";".join(sp.srepr(c) for c in self.constraint_exprs),
            "forces=" + ";".join(sp.srepr(f) for f in self.tau),
            "fiber=" + (",".join(self.fiber) if self.fiber else "auto"),
            "planar_frame=" + (",".join(self.planar_frame) if self.planar_frame else "none"),
        ]
        return "\n".join(parts)

    def __repr__(self) -> str:
        return (f"System(name={self.name!r}, coordinates={self.coordinates}, k={self.k}, "
                f"inputs={self.inputs}, parameters={self.parameters})")
