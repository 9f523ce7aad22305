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

import hashlib
import keyword
import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
import sympy as sp
from sympy.parsing.sympy_parser import (auto_number, auto_symbol, parse_expr,
                                        implicit_multiplication_application,
                                        standard_transformations)

from .errors import ModelError

TIME = sp.Symbol("t", real=True)

#: functions a scene expression may use
_FUNCTIONS = {
    name: getattr(sp, name)
    for name in ("sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "atan2",
                 "sinh", "cosh", "tanh", "exp", "log", "sqrt", "Abs", "sign", "Min", "Max",
                 "Heaviside")
}
_CONSTANTS = {"pi": sp.pi}


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
    raise TypeError(f"expected a name or a sympy Symbol, got {obj!r}")


def _parse(text, names: dict, where: str, problems: list):
    """Parse ``text`` (str or sympy expression) and map every symbol onto the canonical real
    symbol of the same name. Unknown names stay as plain symbols and are reported later."""
    if isinstance(text, (int, float)):
        return sp.sympify(text)
    if isinstance(text, str):
        text = " ".join(text.split())  # multi-line TOML strings
        glob = {"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational,
                "Symbol": sp.Symbol, "Function": sp.Function, **_FUNCTIONS, **_CONSTANTS}
        try:
            expr = parse_expr(text, local_dict=dict(names), global_dict=glob,
                              transformations=standard_transformations, evaluate=True)
        except Exception as exc:  # sympy raises many types; re-raise as ours with the cause
            problems.append(f"{where}: cannot parse {text!r} ({type(exc).__name__}: {exc})")
            return None
    else:
        try:
            expr = sp.sympify(text)
        except (sp.SympifyError, TypeError) as exc:
            problems.append(f"{where}: not an expression: {text!r} ({exc})")
            return None
    if not isinstance(expr, sp.Basic):
        problems.append(f"{where}: not an expression: {text!r}")
        return None
    # dynamicsymbols x(t) -> x ; Derivative(x(t), t) -> x_dot
    reps = {}
    for d in expr.atoms(sp.Derivative):
        if d.expr.is_Function and d.variables == (TIME,) or (
                d.expr.is_Function and len(d.variables) == 1 and d.variables[0].name == "t"):
            reps[d] = names.get(velocity_name(type(d.expr).__name__), sp.Symbol(
                velocity_name(type(d.expr).__name__)))
    if reps:
        expr = expr.xreplace(reps)
    reps = {}
    for f in expr.atoms(sp.Function):
        if len(f.args) == 1 and isinstance(f.args[0], sp.Symbol) and f.args[0].name == "t" \
                and type(f).__name__ in names:
            reps[f] = names[type(f).__name__]
    if reps:
        expr = expr.xreplace(reps)
    reps = {s: names[s.name] for s in expr.free_symbols if s.name in names and s != names[s.name]}
    return expr.xreplace(reps) if reps else expr


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
        problems: list[str] = []
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen dataclass)

        # --- names
        try:
            coord_names = [_name(c) for c in self.coordinates]
        except TypeError as exc:
            raise ModelError([f"coordinates: {exc}"]) from None
        if not coord_names:
            problems.append("coordinates: at least one coordinate is required")
        params = dict(self.parameters or {})
        param_names = [_name(p) for p in params]
        declared_inputs = None if self.inputs is None else [_name(u) for u in self.inputs]
        all_names = coord_names + [velocity_name(c) for c in coord_names] + param_names + (
            declared_inputs or [])
        for nm in all_names:
            if not nm.isidentifier() or keyword.iskeyword(nm):
                problems.append(f"name {nm!r} is not a valid identifier")
        seen = set()
        for nm in all_names + ["t"]:
            if nm in seen:
                problems.append(f"name {nm!r} is used twice (coordinates, velocities, parameters,"
                                " inputs and t must be distinct)")
            seen.add(nm)
        for nm in all_names:
            if nm in _FUNCTIONS or nm in _CONSTANTS:
                problems.append(f"name {nm!r} clashes with the function/constant of that name")
        values = []
        for nm, val in zip(param_names, params.values()):
            try:
                fv = float(val)
            except (TypeError, ValueError):
                problems.append(f"parameter {nm!r}: value {val!r} is not a number")
                fv = float("nan")
            if not math.isfinite(fv):
                problems.append(f"parameter {nm!r}: value {val!r} is not finite")
            values.append(fv)
        if problems:
            raise ModelError(problems)

        q = tuple(sp.Symbol(c, real=True) for c in coord_names)
        qd = tuple(sp.Symbol(velocity_name(c), real=True) for c in coord_names)
        ps = tuple(sp.Symbol(p, real=True) for p in param_names)
        names = {s.name: s for s in q + qd + ps}
        names["t"] = TIME
        if declared_inputs is not None:
            for u in declared_inputs:
                names[u] = sp.Symbol(u, real=True)

        # --- expressions
        L = _parse(self.lagrangian, names, "lagrangian", problems)
        cons = []
        for i, c in enumerate(self.constraints or ()):
            e = _parse(c, names, f"constraint {i + 1}", problems)
            if e is not None:
                if isinstance(e, sp.Equality):
                    e = e.lhs - e.rhs
                cons.append(e)
        forces_in = dict(self.forces or {})
        tau = [sp.Integer(0)] * len(q)
        for key, val in forces_in.items():
            try:
                kname = _name(key)
            except TypeError as exc:
                problems.append(f"forces: {exc}")
                continue
            if kname not in coord_names:
                problems.append(f"forces: {kname!r} is not a coordinate (coordinates: "
                                f"{', '.join(coord_names)})")
                continue
            e = _parse(val, names, f"force on {kname}", problems)
            if e is not None:
                tau[coord_names.index(kname)] = e
        if problems:
            raise ModelError(problems)

        known_lc = set(q) | set(qd) | set(ps)
        self._check_symbols(L, "the Lagrangian", known_lc, names, problems)
        for i, c in enumerate(cons):
            self._check_symbols(c, f"constraint {i + 1}", known_lc, names, problems)
        # inputs
        if declared_inputs is None:
            found = []
            for e in tau:
                for s in sorted(e.free_symbols, key=lambda s: s.name):
                    if s not in known_lc and s != TIME and s not in found:
                        found.append(s)
            inputs = tuple(sp.Symbol(s.name, real=True) for s in found)
            tau = [e.xreplace({s: u for s, u in zip(found, inputs)}) for e in tau]
        else:
            inputs = tuple(names[u] for u in declared_inputs)
            for cname, e in zip(coord_names, tau):
                self._check_symbols(e, f"the force on {cname}", known_lc | set(inputs) | {TIME},
                                    names, problems)
        for cname, e in zip(coord_names, tau):
            bad = [f.func.__name__ for f in e.atoms(sp.Function) if isinstance(f, sp.core.function.AppliedUndef)]
            if bad:
                problems.append(f"the force on {cname}: unknown function(s) {', '.join(sorted(bad))}")
        if problems:
            raise ModelError(problems)

        # --- structure: natural mechanical Lagrangian, constraints linear in velocities
        zero_v = {v: 0 for v in qd}
        for i, c in enumerate(cons):
            if any(sp.diff(c, a, b) != 0 for a in qd for b in qd):
                problems.append(f"constraint {i + 1} ({c} = 0) is not linear in the velocities")
            elif sp.simplify(c.xreplace(zero_v)) != 0:
                problems.append(f"constraint {i + 1} ({c} = 0) has a term without velocities "
                                "(only Pfaffian constraints ω(q)q̇ = 0 are supported)")
            elif all(sp.diff(c, v) == 0 for v in qd):
                problems.append(f"constraint {i + 1} ({c} = 0) contains no velocity")
        grad = [sp.diff(L, v) for v in qd]
        if any(sp.diff(g, v) != 0 for g in [sp.diff(gg, w) for gg in grad for w in qd] for v in qd):
            problems.append("the Lagrangian is not quadratic in the velocities (need L = ½q̇ᵀMq̇ − V)")
        elif any(sp.simplify(g.xreplace(zero_v)) != 0 for g in grad):
            problems.append("the Lagrangian has terms linear in the velocities (gyroscopic terms "
                            "are not supported; need L = ½q̇ᵀM(q)q̇ − V(q))")
        if problems:
            raise ModelError(problems)

        set_("q", q)
        set_("q_dot", qd)
        set_("L", L)
        set_("constraint_exprs", tuple(cons))
        set_("tau", tuple(tau))
        set_("param_symbols", ps)
        set_("param_values", tuple(values))
        set_("input_symbols", inputs)
        set_("coordinates", tuple(coord_names))
        set_("parameters", dict(zip(param_names, values)))
        set_("inputs", tuple(u.name for u in inputs))

        # fiber / planar frame names
        if self.fiber is not None:
            fib = [_name(f) for f in self.fiber]
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
            pf = tuple(_name(c) for c in pf)
            if len(pf) != 3 or any(c not in coord_names for c in pf):
                problems.append(f"planar_frame: need three coordinate names (x, y, heading), got {pf}")
        set_("planar_frame", pf)
        if problems:
            raise ModelError(problems)

        # --- numeric checks: metric positive definite, constraints independent
        self._numeric_checks(problems)
        if problems:
            raise ModelError(problems)

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
                            f" or parameter{hint}")
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

    def force_vector(self) -> sp.Matrix:
        """Generalized forces τ(t, q, q̇, u), n×1."""
        return sp.Matrix(self.tau)

    def param_subs(self, values: Mapping | None = None) -> dict:
        """Map parameter symbols to numbers (defaults overridden by ``values``)."""
        vals = dict(self.parameters)
        if values:
            unknown = [k for k in values if k not in vals]
            if unknown:
                raise ModelError([f"unknown parameter {k!r} (parameters: {', '.join(vals)})"
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
        cache = self.__dict__.get("_nhgait_lambdified")
        if cache is None:
            args = [self.q, self.param_symbols]
            cache = (sp.lambdify(args, self.mass_matrix(), "numpy"),
                     sp.lambdify(args, self.omega(), "numpy") if self.k else None,
                     sp.lambdify(args, self.potential(), "numpy"))
            object.__setattr__(self, "_nhgait_lambdified", cache)
        return cache

    def _numeric_checks(self, problems: list) -> None:
        f_M, f_w, _ = self.numeric_functions()
        pv = self.param_vector()
        worst_eig, where_eig = np.inf, None
        max_rank = 0
        for qs in self.sample_configurations(8, seed=1):
            with np.errstate(all="ignore"):
                Mn = np.array(f_M(qs, pv), dtype=float)
            if not np.all(np.isfinite(Mn)):
                continue
            ev = np.linalg.eigvalsh(0.5 * (Mn + Mn.T))
            if ev[0] < worst_eig:
                worst_eig, where_eig = ev[0], qs
            if f_w is not None:
                with np.errstate(all="ignore"):
                    Wn = np.array(f_w(qs, pv), dtype=float).reshape(self.k, self.n)
                if np.all(np.isfinite(Wn)):
                    max_rank = max(max_rank, np.linalg.matrix_rank(Wn, tol=1e-9 * max(1, np.abs(Wn).max())))
        scale = max(1.0, abs(worst_eig)) if np.isfinite(worst_eig) else 1.0
        if where_eig is not None and worst_eig <= 1e-12 * scale:
            zero_rows = [c for c, v in zip(self.coordinates, self.q_dot)
                         if all(sp.diff(self.L, v, w) == 0 for w in self.q_dot)]
            extra = f" (no kinetic energy in {', '.join(zero_rows)})" if zero_rows else ""
            problems.append("the kinetic metric M(q) = ∂²L/∂q̇² is not positive definite: smallest "
                            f"eigenvalue {worst_eig:.3g} at q = {np.round(where_eig, 3).tolist()} "
                            f"with the default parameters{extra}")
        if self.k and max_rank < self.k:
            problems.append(f"the constraints are dependent: rank ω(q) = {max_rank} < k = {self.k}"
                            " at every sampled configuration (remove redundant constraints)")
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

    def content_hash(self) -> str:
        """SHA-256 of :meth:`canonical_text`."""
        return hashlib.sha256(self.canonical_text().encode()).hexdigest()

    def __repr__(self) -> str:
        return (f"System(name={self.name!r}, coordinates={self.coordinates}, k={self.k}, "
                f"inputs={self.inputs}, parameters={self.parameters})")
