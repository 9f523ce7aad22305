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

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields

import numpy as np
import sympy as sp

from nhgait.dynamics.suggestions import known_names

from ..errors import ModelError
from ..memo import OwnerMemo
from . import parameter_checks
from .input.system_parsing import (
    TIME,
    fiber_problems,
    linear_split,
    parse_field,
    parse_system,
    quadratic_split,
    velocity_name,
)

#: the body axis that points forward → its angle from the frame's heading (``System.forward``)
FORWARD_AXES = {"x": sp.S.Zero, "y": sp.pi / 2, "-x": sp.pi, "-y": -sp.pi / 2}

__all__ = ["System", "TIME", "jump_times", "parse_field", "velocity_name", "FORCE_JUMP_TIMES"]

#: per system (dropped with it): M(q) and V(q), derived once (read off L or differentiated)
METRICS = OwnerMemo("kinetic metric and potential per system")

#: the force jump times of a system per parameter values (sympy walks the forces: ~20 µs a
#: call, and every simulation asks); dropped with the system
FORCE_JUMP_TIMES = OwnerMemo("force jump times per system and parameter values", limit=256)


def jump_times(exprs, subs=None) -> tuple[float, ...]:
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
    forward : "x" (default), "y", "-x" or "-y"
        The body axis of the planar frame that points forward: ``forward_velocity`` is the
        velocity along it and ``lateral_velocity`` along the axis 90° to its left (a car whose
        body y axis points along its length, as opty's gallery cars: ``"y"``).
    holonomic : sequence of str or expression, optional
        Configuration constraints h(q) = 0 (coordinates and parameters only). Each is
        eliminated when it is linear in a coordinate with a constant coefficient (the
        coordinate is substituted everywhere and dropped from ``coordinates``; see
        ``eliminated``), else kept: its velocity row ∇h·q̇ is appended to the constraints and
        ``holonomic`` holds the kept h (:mod:`.holonomic`, docs/holonomic.md).
    dependent : sequence of coordinate names, optional
        The coordinate each holonomic constraint is solved for (eliminated, or the one a
        consistent configuration adjusts); default: the last coordinate it can be solved for,
        else the one with the largest ``|∂h/∂q|`` at q = 0. Normalised to the kept constraints'.
    eliminated : sequence of (name, expression), optional
        Set by the elimination: the coordinates removed and what they equal.
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
    forward: str = "x"
    holonomic: Sequence = ()
    dependent: Sequence | None = None
    eliminated: Sequence = ()
    # derived (read by __post_init__, system_parsing.parse_system)
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
        """Read the statement (:func:`~.system_parsing.parse_system`: names, expressions,
        structure, frames) and check the default parameter values
        (:func:`~.parameter_checks.numeric_checks`); every problem is reported at once in one
        :class:`ModelError`. The fields hold the normalised values afterwards (names as
        tuples, expressions as sympy)."""
        parsed = parse_system(self)
        for item in fields(parsed):
            if item.name not in ("problems", "complete"):
                object.__setattr__(self, item.name, getattr(parsed, item.name))   # frozen: set once, here
        problems = list(parsed.problems)
        if parsed.complete and not problems:   # numbers need every expression and value to be valid
            problems += parameter_checks.numeric_checks(self)
        if problems:
            raise ModelError(problems)

    @classmethod
    def from_mechanics(cls, source, parameters: Mapping, *, inputs=None, origin=None,
                       name: str | None = None, **options) -> System:
        """The System of a sympy.physics.mechanics model: a ``KanesMethod`` (any generalized
        speeds with their kinematic differential equations, dependent speeds with their velocity
        constraints), a ``LagrangesMethod`` (with its nonholonomic constraints) or a
        ``sympy.physics.mechanics.System`` — the same System a scene stating that robot gives.
        T and the generalized forces are read off the positions and orientations (valid at every
        velocity), the constraints off the model's velocity constraints in q̇; the model's own
        velocities are checked against them (:mod:`.from_mechanics`, docs/interop.md).

        Parameters
        ----------
        source : KanesMethod, LagrangesMethod or sympy.physics.mechanics.System
        parameters : mapping name (or Symbol) → float
            A value for every constant of the kinetic energy and the constraints; the loads'
            other symbols (and functions of time that are not coordinates) are inputs.
        inputs : sequence of names, optional
            The inputs in this order (default: those found, sorted by name).
        origin : Point, optional
            A point fixed in the inertial frame (default: the mechanics System's fixed point, else
            a point whose velocity was set to 0, found from the bodies' mass centres).
        name : str, optional
            Default: the kind of the source in lower case.
        options
            Further fields (``fiber``, ``planar_frame``, ``forward``, ``dependent``).
        """
        from .input.from_mechanics import (  # loads sympy.physics.mechanics
            check_stated_velocities,
            read_statement,
        )
        statement = read_statement(source, parameters, inputs=inputs, origin=origin, name=name)
        system = cls(**{**statement.fields, **options})
        check_stated_velocities(statement, system)
        return system

    def with_fiber(self, fiber: Sequence) -> System:
        """This system with another ``fiber`` (the chart of the reduction, thesis §3.1): the same
        statement, so its checks are not repeated (0.3–1 s for a robot of 8–10 coordinates) —
        only the fiber's own (coordinates, each once); equal to ``replace(self, fiber=fiber)``."""
        names = tuple(name.strip() if isinstance(name, str) else str(name) for name in fiber)
        problems = fiber_problems(names, self.coordinates)
        if problems:
            raise ModelError(problems)
        other = copy.copy(self)
        object.__setattr__(other, "fiber", names)      # frozen: a new object, set once, here
        return other

    # ------------------------------------------------------------------ derived objects
    @property
    def forward_angle(self):
        """The angle (sympy: 0, π/2, π or −π/2) from the frame's heading to its forward axis
        (``forward``): forward_velocity = ẋ cos(θ + α) + ẏ sin(θ + α)."""
        return FORWARD_AXES[self.forward]

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return len(self.q)

    @property
    def k(self) -> int:
        """Number of constraints (the velocity rows of kept holonomic constraints included)."""
        return len(self.constraint_exprs)

    @property
    def holonomic_rows(self) -> tuple[int, ...]:
        """Indices of the constraint rows that are velocity forms ∇h·q̇ of kept holonomic
        constraints (the last ``len(holonomic)`` rows)."""
        return tuple(range(self.k - len(self.holonomic), self.k))

    def holonomic_lines(self) -> list:
        """What the holonomic constraints became, one indented line each (empty without)."""
        lines = [f"  holonomic: {c} = {sp.sstr(e)} (eliminated)" for c, e in self.eliminated]
        lines += [f"  holonomic: {sp.sstr(h)} = 0 kept as constraint {row + 1} (its velocity form); "
                  f"{c} follows the other coordinates"
                  for h, c, row in zip(self.holonomic, self.dependent, self.holonomic_rows, strict=True)]
        return lines

    def mass_matrix(self) -> sp.Matrix:
        """Kinetic metric M(q) = ∂²L/∂q̇∂q̇ (eq. 2.5), n×n: read off L when L is written as a
        polynomial in the velocities (:func:`~.velocity_forms.quadratic_split`: sums, products
        and squares of velocity terms), else differentiated; computed once per system, with V
        (:data:`METRICS`)."""
        return METRICS.get(self, "split", self._split)[0]

    def potential(self) -> sp.Expr:
        """V(q) = −L(q, 0)."""
        return METRICS.get(self, "split", self._split)[1]

    def _split(self) -> tuple:
        split = quadratic_split(self.L, self.q_dot)
        if split is not None:
            return split
        return sp.hessian(self.L, self.q_dot), -self.L.xreplace({v: 0 for v in self.q_dot})

    def omega(self) -> sp.Matrix:
        """Pfaffian constraint matrix ω(q), k×n (eq. 2.11): each row read off its constraint
        when written as Σ ω_i q̇_i (:func:`~.velocity_forms.linear_split`), else differentiated;
        computed once per system (:data:`METRICS`)."""
        if not self.constraint_exprs:
            return sp.zeros(0, self.n)
        return sp.Matrix(METRICS.get(self, "omega", self._omega_rows))

    def _omega_rows(self) -> list:
        return [linear_split(c, self.q_dot) or [sp.diff(c, v) for v in self.q_dot]
                for c in self.constraint_exprs]

    def force_jump_times(self, values=None) -> tuple[float, ...]:
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
        return parameter_checks.sample_configurations(self.n, count, seed)

    def numeric_functions(self) -> parameter_checks.NumericFunctions:
        """(M(q, params), ω(q, params) or None, V(q, params)) as numpy callables, lambdified once
        per system (:func:`~.parameter_checks.numeric_functions`)."""
        return parameter_checks.numeric_functions(self)

    def parameter_problems(self, values=None, *, label: str = "the default parameters") -> list:
        """Every problem with a parameter set (``values`` overriding the defaults; a mapping
        name → number or a vector in :attr:`param_symbols` order): non-finite values, a kinetic
        metric that is singular or not positive definite, dependent constraints — checked at
        random configurations (:mod:`.parameter_checks`). Returns a list of sentences (empty
        when the values are valid)."""
        return parameter_checks.parameter_problems(self, values, label)

    # ------------------------------------------------------------------ identity
    def canonical_text(self) -> str:
        """A canonical textual form of everything the derivations depend on (not the parameter
        values): used for the content hash of the cache."""
        parts = [
            "coordinates=" + ",".join(self.coordinates),
            "parameters=" + ",".join(s.name for s in self.param_symbols),
            "inputs=" + ",".join(self.inputs),
            "L=" + sp.srepr(self.L, order="none"),
            "constraints=" + ";".join(sp.srepr(c, order="none") for c in self.constraint_exprs),
            "forces=" + ";".join(sp.srepr(f, order="none") for f in self.tau),
            "fiber=" + (",".join(self.fiber) if self.fiber else "auto"),
            "planar_frame=" + (",".join(self.planar_frame) if self.planar_frame else "none"),
        ] + ([] if self.forward == "x" else [f"forward={self.forward}"])
        if self.holonomic or self.eliminated:
            parts += ["holonomic=" + ";".join(sp.srepr(h, order="none") for h in self.holonomic),
                      "dependent=" + ",".join(self.dependent),
                      "eliminated="
                      + ";".join(f"{c}:{sp.srepr(e, order='none')}" for c, e in self.eliminated)]
        return "\n".join(parts)

    def __repr__(self) -> str:
        return (f"System(name={self.name!r}, coordinates={self.coordinates}, k={self.k}, "
                f"inputs={self.inputs}, parameters={self.parameters})")
