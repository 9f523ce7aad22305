"""The statement of an optimal control problem, kept apart from its transcription and solver.

Problem (fixed horizon T unless ``free_horizon`` is given)::

    minimise    Σ_k h Σ_j w_j u_{j,k}²  +  Σ_k h Σ_i c_i z_i(t_k)²  +  c_T T
    subject to  ż = f(t, z, u, params)                        (the model's reduced ODE)
                u(t) = u_k on [t_k, t_k + h),  h = T / N       (piecewise-constant controls)
                lo ≤ y(0) ≤ hi,  lo ≤ y(T) ≤ hi                (``initial`` / ``final``)
                y(T) = y(0)                                    (``periodic``)
                lo ≤ y(t_k) ≤ hi,  k = 0 … N                   (``state_bounds``: at the nodes)
                lo ≤ u_k ≤ hi                                  (``control_bounds``)

with y any *quantity*: a state by name (``state_names`` of the model, e.g. ``x``, ``phi``,
``p``, ``pt_psi``), a generalised velocity ``<coordinate>_dot`` (through the model's
``qdot(z, params)``), the planar body velocities ``forward_velocity`` / ``lateral_velocity``
(for models with coordinates ``x, y, theta``: ẋ cos θ + ẏ sin θ and −ẋ sin θ + ẏ cos θ), or a
user :class:`Quantity`. The control term Σ h |u_k|² is the exact integral ∫|u|² dt for
piecewise-constant controls; the state term is the left-rectangle rule on the nodes.

A statement is validated when it is made: every problem found (unknown names, lo > hi,
T ≤ 0, N < 1, a fixed value outside its bounds …) is listed in one :class:`ProblemError`.

This module imports only casadi and numpy; the model is anything with ``numeric`` (CasADi
Functions ``rhs(t, z, u, params)`` and ``qdot(z, params)``, ``params()``), ``state_names`` and
``system.inputs`` / ``system.coordinates`` — a :class:`~nhgait.dynamics.derivation.reduction.ReducedODE`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Callable, Mapping

import casadi as ca
import numpy as np

from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.suggestions import known_names

__all__ = ["OptimalControlProblem", "Quantity", "ProblemError"]


class ProblemError(ModelError):
    """An optimal control problem that cannot be transcribed (all problems listed)."""

    def __init__(self, problems, *, title: str = "invalid optimal control problem"):
        super().__init__(problems, title=title)


@dataclass(frozen=True)
class Quantity:
    """A scalar derived quantity y = function(z, params) of the state.

    ``function`` takes CasADi SX ``z`` (nz×1) and ``params`` (numeric vector) and returns a
    scalar SX expression.
    """

    name: str
    function: Callable[[Any, Any], Any]
    description: str = ""


def _coordinates(model) -> tuple:
    system = getattr(model, "system", None)
    coords = getattr(system, "coordinates", None)
    if coords is None:  # fall back to the q-part of the state names
        n = getattr(getattr(model, "numeric", None), "n_coordinates", 0)
        coords = tuple(model.state_names[:n])
    return tuple(coords)


def builtin_quantities(model) -> dict:
    """Derived quantities every model offers: ``<q>_dot`` and, for a planar frame (x, y, θ)
    (``system.planar_frame``), the body velocities of
    :func:`nhgait.dynamics.numerics.specialisation.body_velocity` (the one definition)."""
    from nhgait.dynamics.numerics.specialisation import BODY_VELOCITIES, body_velocity
    coords = _coordinates(model)
    qdot = model.numeric["qdot"]
    out = {}
    for i, c in enumerate(coords):
        out[f"{c}_dot"] = Quantity(f"{c}_dot", lambda z, params, i=i: qdot(z, params)[i],
                                   f"generalised velocity d{c}/dt (through qdot(z))")
    frame = getattr(getattr(model, "system", None), "planar_frame", None)
    if frame is None and {"x", "y", "theta"} <= set(coords):
        frame = ("x", "y", "theta")
    if frame and all(c in coords for c in frame):
        ix, iy, ih = (coords.index(c) for c in frame)
        for name in BODY_VELOCITIES:
            def body(z, params, name=name):
                v = qdot(z, params)
                return body_velocity(name, v[ix], v[iy], z[ih], ca.cos, ca.sin)
            out[name] = Quantity(name, body, f"planar body velocity {name} of the frame {tuple(frame)}")
    return out


def _interval(value, where: str, problems: list) -> tuple[float, float]:
    """A bound given as a number (equality) or (lo, hi) with None for unbounded."""
    try:
        if isinstance(value, (tuple, list)):
            if len(value) != 2:
                raise TypeError
            lo = -math.inf if value[0] is None else float(value[0])
            hi = math.inf if value[1] is None else float(value[1])
        else:
            lo = hi = float(value)
    except (TypeError, ValueError):
        problems.append(f"{where}: expected a number or a (lo, hi) pair, got {value!r}")
        return -math.inf, math.inf
    if math.isnan(lo) or math.isnan(hi):
        problems.append(f"{where}: NaN bound {value!r}")
    elif lo > hi:
        problems.append(f"{where}: contradictory bounds lo = {lo:g} > hi = {hi:g}")
    return lo, hi


def _frozen(mapping) -> Mapping:
    return MappingProxyType(dict(mapping or {}))


@dataclass(frozen=True, eq=False)
class OptimalControlProblem:
    """One optimal control problem on a reduced ODE (see the module docstring for the maths).

    Parameters
    ----------
    model : ReducedODE or alike
    horizon : float
        T > 0 (the initial value of T when ``free_horizon`` is given).
    intervals : int
        N ≥ 1 control intervals of length h = T / N.
    initial, final : mapping name → value or (lo, hi)
        Boundary conditions on quantities at t = 0 and t = T.
    periodic : sequence of names
        Quantities with y(T) = y(0).
    state_bounds : mapping name → (lo, hi)
        Bounds on quantities at every node t_0 … t_N.
    control_bounds : mapping name → (lo, hi), or a number b meaning |u_j| ≤ b for every input
    control_weights : mapping input name → w ≥ 0 (default 1)
    state_weights : mapping name → c ≥ 0, adds Σ_k h c z_i(t_k)²
    time_weight : float, adds c_T T (free horizon only)
    free_horizon : (T_min, T_max) or None
    quantities : mapping name → Quantity, extra derived quantities
    params : parameter vector or mapping (default: the model's defaults)
    name : a label for reports
    """

    model: Any
    horizon: float
    intervals: int = 50
    initial: Mapping = field(default_factory=dict)
    final: Mapping = field(default_factory=dict)
    periodic: tuple = ()
    state_bounds: Mapping = field(default_factory=dict)
    control_bounds: Any = field(default_factory=dict)
    control_weights: Mapping = field(default_factory=dict)
    state_weights: Mapping = field(default_factory=dict)
    time_weight: float = 0.0
    free_horizon: tuple | None = None
    quantities: Mapping = field(default_factory=dict)
    params: Any = None
    name: str = ""

    def __post_init__(self):
        problems: list[str] = []
        model = self.model
        for attr in ("numeric", "state_names"):
            if not hasattr(model, attr):
                problems.append(f"model has no attribute {attr!r} (expected a derived ReducedODE)")
        if problems:
            raise ProblemError(problems)
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731  (frozen dataclass)
        set_("initial", _frozen(self.initial))
        set_("final", _frozen(self.final))
        set_("state_bounds", _frozen(self.state_bounds))
        set_("control_weights", _frozen(self.control_weights))
        set_("state_weights", _frozen(self.state_weights))
        set_("quantities", _frozen(self.quantities))
        set_("periodic", tuple(self.periodic))
        if not isinstance(self.control_bounds, Mapping):
            try:
                b = abs(float(self.control_bounds))
                set_("control_bounds", _frozen({u: (-b, b) for u in self.control_names}))
            except (TypeError, ValueError):
                problems.append(f"control_bounds: expected a mapping or a number, got {self.control_bounds!r}")
                set_("control_bounds", _frozen({}))
        else:
            set_("control_bounds", _frozen(self.control_bounds))
        try:
            set_("params", np.asarray(model.numeric.params(self.params), dtype=float))
        except ValueError as exc:
            problems.append(f"params: {exc}")

        # horizon and grid
        try:
            T = float(self.horizon)
            if not (T > 0 and math.isfinite(T)):
                problems.append(f"horizon T = {self.horizon!r} must be positive and finite")
        except (TypeError, ValueError):
            problems.append(f"horizon T = {self.horizon!r} is not a number")
        if isinstance(self.intervals, bool) or not isinstance(self.intervals, (int, np.integer)) or self.intervals < 1:
            problems.append(f"intervals N = {self.intervals!r} must be an integer ≥ 1")
        if self.free_horizon is not None:
            lo, hi = _interval(self.free_horizon, "free_horizon", problems)
            if lo <= 0:
                problems.append(f"free_horizon: lower bound {lo:g} must be positive")
        elif self.time_weight:
            problems.append("time_weight is only meaningful with free_horizon")

        # names
        known = self.quantity_names
        for where, mapping in (("initial", self.initial), ("final", self.final),
                               ("state_bounds", self.state_bounds)):
            for name, value in mapping.items():
                if name not in known:
                    problems.append(f"{where}: unknown quantity {name!r}{known_names(name, known)}")
                _interval(value, f"{where}[{name!r}]", problems)
        for name in self.periodic:
            if name not in known:
                problems.append(f"periodic: unknown quantity {name!r}{known_names(name, known)}")
        if len(set(self.periodic)) != len(self.periodic):
            problems.append(f"periodic: repeated names in {self.periodic}")
        for name, value in self.control_bounds.items():
            if name not in self.control_names:
                problems.append(f"control_bounds: unknown input {name!r}"
                                f"{known_names(name, self.control_names, label='inputs')}")
            _interval(value, f"control_bounds[{name!r}]", problems)
        for where, mapping, names in (("control_weights", self.control_weights, self.control_names),
                                      ("state_weights", self.state_weights, self.state_names)):
            for name, w in mapping.items():
                if name not in names:
                    problems.append(f"{where}: unknown name {name!r}{known_names(name, names)}")
                elif not (float(w) >= 0):
                    problems.append(f"{where}[{name!r}] = {w!r} must be ≥ 0")
        for name, q in self.quantities.items():
            if not isinstance(q, Quantity) or not callable(q.function):
                problems.append(f"quantities[{name!r}]: expected a Quantity with a callable function")

        # consistency of fixed values with path bounds and periodicity
        for where, mapping in (("initial", self.initial), ("final", self.final)):
            for name, value in mapping.items():
                if name in self.state_bounds and name in known:
                    lo, hi = _interval(value, "", [])
                    plo, phi = _interval(self.state_bounds[name], "", [])
                    if hi < plo or lo > phi:
                        problems.append(f"{where}[{name!r}] = {value!r} lies outside state_bounds "
                                        f"[{plo:g}, {phi:g}]")
        for name in self.periodic:
            if name in self.initial and name in self.final:
                a = _interval(self.initial[name], "", [])
                b = _interval(self.final[name], "", [])
                if max(a[0], b[0]) > min(a[1], b[1]):
                    problems.append(f"periodic {name!r}: initial {self.initial[name]!r} and final "
                                    f"{self.final[name]!r} cannot be equal")
        if problems:
            raise ProblemError(problems)

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple:
        return tuple(self.model.state_names)

    @property
    def control_names(self) -> tuple:
        system = getattr(self.model, "system", None)
        if system is not None and hasattr(system, "inputs"):
            return tuple(system.inputs)
        return tuple(self.model.numeric.input_names)

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def n_controls(self) -> int:
        return len(self.control_names)

    @property
    def derived_quantities(self) -> Mapping:
        """Derived (non-state) quantities: the built-in ones and the user's."""
        out = builtin_quantities(self.model)
        out.update(self.quantities)
        return MappingProxyType(out)

    @property
    def quantity_names(self) -> tuple:
        return self.state_names + tuple(n for n in self.derived_quantities if n not in self.state_names)

    def is_state(self, name: str) -> bool:
        return name in self.state_names

    def quantity(self, name: str, z, params=None):
        """The SX/MX expression of quantity ``name`` at state ``z``."""
        params = self.params if params is None else params
        if name in self.state_names:
            return z[self.state_names.index(name)]
        return self.derived_quantities[name].function(z, params)

    def bounds(self, mapping: Mapping, name: str) -> tuple[float, float]:
        return _interval(mapping[name], name, [])

    def fixed_value(self, mapping: Mapping, name: str) -> float | None:
        """The value of ``name`` in the conditions ``mapping`` when it is fixed (lo = hi), else None."""
        if name in mapping:
            lo, hi = self.bounds(mapping, name)
            if lo == hi:
                return lo
        return None

    def control_bound_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        lo = np.full(self.n_controls, -np.inf)
        hi = np.full(self.n_controls, np.inf)
        for name, value in self.control_bounds.items():
            i = self.control_names.index(name)
            lo[i], hi[i] = _interval(value, name, [])
        return lo, hi

    def grid(self, horizon: float | None = None) -> np.ndarray:
        """The N + 1 node times t_k = k T / N."""
        T = float(self.horizon if horizon is None else horizon)
        return np.linspace(0.0, T, self.intervals + 1)

    def replace(self, **changes) -> "OptimalControlProblem":
        """A copy with some fields changed (validated again)."""
        from dataclasses import replace
        return replace(self, **changes)

    def describe(self) -> dict:
        """A JSON-friendly statement (for solution files)."""
        fmt = lambda m: {k: (list(v) if isinstance(v, (tuple, list)) else v) for k, v in m.items()}  # noqa: E731
        return {
            "name": self.name, "horizon": float(self.horizon), "intervals": int(self.intervals),
            "states": list(self.state_names), "controls": list(self.control_names),
            "initial": fmt(self.initial), "final": fmt(self.final), "periodic": list(self.periodic),
            "state_bounds": fmt(self.state_bounds), "control_bounds": fmt(self.control_bounds),
            "control_weights": dict(self.control_weights), "state_weights": dict(self.state_weights),
            "time_weight": self.time_weight,
            "free_horizon": list(self.free_horizon) if self.free_horizon is not None else None,
            "params": dict(zip(getattr(self.model.numeric, "param_names", ()), map(float, self.params))),
        }
