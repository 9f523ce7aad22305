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

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from nhgait.dynamics.suggestions import known_names

from .statement import OCP_WORDS, FrozenMap, ProblemError, ProblemStatement, instant_problems, interval

__all__ = ["OptimalControlProblem", "Quantity", "ProblemError", "model_coordinates"]


@dataclass(frozen=True)
class Quantity:
    """A scalar derived quantity y = function(z, params) of the state, or — with ``inputs`` —
    y = function(z, u, ż, params) of the state, the inputs and the state's derivative
    ż = f(t, z, u) (accelerations q̈ are ∂q̇/∂z · ż).

    ``function`` takes CasADi ``z`` (the model's states, nz×1), [``u`` (nu×1), ``zdot`` (nz×1),]
    and ``params`` (numeric vector) and returns a scalar expression. A quantity of the inputs is
    a path constraint (``state_bounds``: at the nodes t_0 … t_{N−1}, each with the input of the
    interval it starts) or an integrand (``integrals``), never a condition at one instant.
    """

    name: str
    function: Callable[..., Any]
    description: str = ""
    inputs: bool = False


def _require_model(model) -> None:
    missing = [attr for attr in ("numeric", "state_names") if not hasattr(model, attr)]
    if missing:
        raise ProblemError([f"model has no attribute {attr!r} (expected a derived ReducedODE)"
                            for attr in missing])


def model_coordinates(model) -> tuple[str, ...]:
    """The coordinate names of ``model``: its system's, else the first ``numeric.n_coordinates`` states."""
    system = getattr(model, "system", None)
    coords = getattr(system, "coordinates", None)
    if coords is None:  # fall back to the q-part of the state names
        n = getattr(getattr(model, "numeric", None), "n_coordinates", 0)
        coords = tuple(model.state_names[:n])
    return tuple(coords)


def qddot_of(model, z, zdot, params):
    """q̈ = ∂q̇(z)/∂z · ż: the accelerations along the state derivative ``zdot``."""
    n = len(model_coordinates(model))
    zs = ca.SX.sym("z", len(model.state_names))
    J = ca.Function("dqdot_dz", [zs], [ca.jacobian(model.numeric["qdot"](zs, params), zs)])
    return ca.mtimes(J(z), zdot)[:n]


def builtin_quantities(model) -> dict:
    """Derived quantities every model offers: ``<q>_dot`` and, for a planar frame (x, y, θ)
    (``system.planar_frame``), the body velocities of
    :func:`nhgait.dynamics.numerics.specialisation.body_velocity` (the one definition)."""
    from nhgait.dynamics.numerics.specialisation import BODY_VELOCITIES, body_velocity
    coords = model_coordinates(model)
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
        offset = float(getattr(getattr(model, "system", None), "forward_angle", 0.0))   # System.forward
        for name in BODY_VELOCITIES:
            def body(z, params, name=name):
                v = qdot(z, params)
                return body_velocity(name, v[ix], v[iy], z[ih] + offset, ca.cos, ca.sin)
            out[name] = Quantity(name, body, f"planar body velocity {name} of the frame {tuple(frame)}")
    out.update(holonomic_quantities(model))
    return out


def holonomic_quantities(model) -> dict:
    """``holonomic1``, ``holonomic2`` …: h_i(q) of a model whose system keeps holonomic
    constraints (its ``numeric["holonomic"]``); a plan starts on h = 0 (the velocity form keeps
    it there), see :func:`nhgait.gaits.tasks.statement.to_problem`."""
    numeric = model.numeric
    if "holonomic" not in getattr(numeric, "functions", {}):
        return {}
    h, n = numeric["holonomic"], len(model_coordinates(model))
    return {f"holonomic{i + 1}": Quantity(f"holonomic{i + 1}", lambda z, params, i=i: h(z[:n], params)[i],
                                          f"holonomic constraint {i + 1}: h(q), zero on the "
                                          "constraint surface")
            for i in range(h.size1_out(0))}


@dataclass(frozen=True, eq=False)
class OptimalControlProblem(ProblemStatement):
    """One optimal control problem on a reduced ODE (see the module docstring for the maths):
    a :class:`~nhgait.ocp.statement.ProblemStatement` (``horizon``, ``intervals``, ``initial``,
    ``final``, ``periodic``, ``state_bounds``, ``control_bounds``, ``control_weights``,
    ``state_weights``, ``time_weight``, ``free_horizon``: the parameters are documented there)
    bound to a model.

    Parameters
    ----------
    model : ReducedODE or alike
    quantities : mapping name → Quantity, extra derived quantities
    params : parameter vector or mapping (default: the model's defaults)
    name : a label for reports

    Problems are compared by identity (a model is not a value).
    """

    quantities: Mapping = field(default_factory=dict)
    params: Any = None
    name: str = ""

    __eq__ = object.__eq__
    __hash__ = object.__hash__

    def __post_init__(self):
        _require_model(self.model)
        super().__post_init__()
        object.__setattr__(self, "quantities", FrozenMap(self.quantities))
        problems = self._bind_control_bounds() + self._bind_params()
        model_names = [n for n in self.quantity_names if n not in self.integrals
                       or n in self.model_state_names]
        problems += self.problems(OCP_WORDS, known=model_names, inputs=self.control_names)
        problems += self._weight_problems() + self._quantity_problems() + self._input_quantity_problems()
        if problems:
            raise ProblemError(problems)
        missing = {name: 0.0 for name in self.integrals if name not in self.initial}
        # an integral starts at 0 unless the statement says otherwise
        if missing:
            object.__setattr__(self, "initial", FrozenMap({**self.initial, **missing}))

    def _bind_control_bounds(self) -> list:
        """A number b is |u_j| ≤ b for every input."""
        if isinstance(self.control_bounds, Mapping):
            return []
        try:
            b = abs(float(self.control_bounds))
        except (TypeError, ValueError):
            problem = f"control_bounds: expected a mapping or a number, got {self.control_bounds!r}"
            object.__setattr__(self, "control_bounds", FrozenMap())
            return [problem]
        object.__setattr__(self, "control_bounds", FrozenMap({u: (-b, b) for u in self.control_names}))
        return []

    def _bind_params(self) -> list:
        try:
            object.__setattr__(self, "params",
                               np.asarray(self.model.numeric.params(self.params), dtype=float))
        except ValueError as exc:
            return [f"params: {exc}"]
        return []

    def _weight_problems(self) -> list:
        problems = []
        for where, mapping, names in (("control_weights", self.control_weights, self.control_names),
                                      ("state_weights", self.state_weights, self.state_names)):
            for name, w in mapping.items():
                if name not in names:
                    problems.append(f"{where}: unknown name {name!r}{known_names(name, names)}")
                elif not (float(w) >= 0):
                    problems.append(f"{where}[{name!r}] = {w!r} must be ≥ 0")
        return problems

    def _quantity_problems(self) -> list:
        return [f"quantities[{name!r}]: expected a Quantity with a callable function"
                for name, q in self.quantities.items() if not isinstance(q, Quantity)
                or not callable(q.function)]

    def _input_quantity_problems(self) -> list:
        """A quantity of the inputs or accelerations is a path bound or an integrand only."""
        motion = [n for n, q in self.derived_quantities.items() if q.inputs and n not in self.state_names]
        return instant_problems(self, motion)

    # ------------------------------------------------------------------ names
    @property
    def state_names(self) -> tuple[str, ...]:
        """The model's states, then the integral states (``integrals``), in that order."""
        return tuple(self.model.state_names) + tuple(self.integrals)

    @property
    def model_state_names(self) -> tuple[str, ...]:
        """The model's own states z (the first entries of :attr:`state_names`)."""
        return tuple(self.model.state_names)

    @property
    def control_names(self) -> tuple[str, ...]:
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
        return FrozenMap(out)

    @property
    def quantity_names(self) -> tuple[str, ...]:
        return self.state_names + tuple(n for n in self.derived_quantities if n not in self.state_names)

    def is_state(self, name: str) -> bool:
        return name in self.state_names

    def uses_inputs(self, name: str) -> bool:
        """Whether quantity ``name`` depends on the inputs (or on accelerations)."""
        q = self.derived_quantities.get(name) if name not in self.state_names else None
        return bool(q is not None and q.inputs)

    def quantity(self, name: str, z, params=None, *, u=None, t=0.0):
        """The SX/MX expression of quantity ``name`` at state ``z`` (the problem's states, or the
        model's alone); a quantity of the inputs needs ``u`` and, for time-dependent forces, the
        time ``t``."""
        params = self.params if params is None else params
        if name in self.state_names:
            return z[self.state_names.index(name)]
        zm = z[:len(self.model.state_names)]
        q = self.derived_quantities[name]
        if not q.inputs:
            return q.function(zm, params)
        if u is None:
            raise ProblemError([f"{name!r} depends on the inputs: it is a path constraint (bounds) or "
                                "an integrand, not a condition at one instant"])
        zdot = self.model.numeric["rhs"](t, zm, u, params)
        return q.function(zm, u, zdot, params)

    def ode(self) -> ca.Function:
        """ż = f(t, z, u) of the problem's states (the model's, then the integrands of the
        integral states), parameter values substituted: one SX Function ``(t, z, u) → ż``."""
        nz, nu = self.n_states, self.n_controls
        z, u, t = ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("t")
        zm = z[:len(self.model.state_names)]
        rhs = [self.model.numeric["rhs"](t, zm, u, self.params)]
        rhs += [self.quantity(y, zm, u=u, t=t) for y in self.integrals.values()]
        return ca.Function("ode", [t, z, u], [ca.vertcat(*rhs)], ["t", "z", "u"], ["zdot"])

    def bounds(self, mapping: Mapping, name: str) -> tuple[float, float]:
        return interval(mapping[name])

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
            lo[i], hi[i] = interval(value)
        return lo, hi

    def grid(self, horizon: float | None = None) -> np.ndarray:
        """The N + 1 node times: t_k = k T / N, or for phases each phase's own grid, the phase
        horizons scaled by ``horizon`` / T when it is given."""
        from .schedule import schedule
        return schedule(self).grid(horizon)

    def replace(self, **changes) -> OptimalControlProblem:
        """A copy with some fields changed (validated again)."""
        from dataclasses import replace
        return replace(self, **changes)

    @classmethod
    def from_statement(cls, statement: ProblemStatement, model, **changes) -> OptimalControlProblem:
        """``statement`` bound to ``model`` (``changes``: other fields, e.g. ``quantities``)."""
        return cls(model, **{**statement.statement_fields(), **changes})

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
            "waypoints": [{"time": w.time, "name": w.name, "conditions": fmt(w.conditions)}
                          for w in self.waypoints],
            "integrals": dict(self.integrals), "end_weights": dict(self.end_weights),
            "phases": [{"name": p.name, "horizon": p.horizon, "intervals": p.intervals,
                        "free_horizon": list(p.free_horizon) if p.free_horizon is not None else None,
                        "final": fmt(p.final), "state_bounds": fmt(p.state_bounds),
                        "control_bounds": fmt(p.control_bounds),
                        "waypoints": [{"time": w.time, "name": w.name, "conditions": fmt(w.conditions)}
                                      for w in p.waypoints]} for p in self.phases],
            "params": dict(zip(getattr(self.model.numeric, "param_names", ()), map(float, self.params),
                               strict=False)),
        }
