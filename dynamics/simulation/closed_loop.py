"""The closed-loop system of one simulation as CasADi functions: :func:`closed_loop`.

Extended state (documented order)
---------------------------------
y = (x_S, W, ∫g), where

* x_S are the integrated entries of the formulation's state x (``model.state_names``): all of
  them, or — when a run names its outputs — the dependency closure S of the outputs
  (:mod:`.closure`), in the order of x;
* W = ∫ τ·q̇ dt, the work of the forces (a quadrature, present when its integrand depends on
  x_S only);
* ∫g, the integrals of the constraint residual g = ω(q)q̇ (Baumgarte stabilisation with β ≠ 0).

Entries of x outside S are not modelled: they are NaN in every output that needs them.

Functions (SX unless the model's functions are MX)
--------------------------------------------------
``rhs(t, t_c, y, p[, u]) → ẏ``; ``outputs(t, t_c, y, p[, u]) → (q, q̇, λ, g, E, u, s, W_v, S)``
with s the singular-set measure (1 away from it, 0 on it), W_v the kinetic metric of the
velocity part of x (∂²E/∂v², column-major) and S = ω M⁻¹ ωᵀ (DAE forms; column-major);
``event(y, ẏ, p) → (s, ṡ)`` (the rate ṡ = ∇s·ẏ tells the integrators when a step may hide a
crossing); ``qdot(y, p) → q̇``. ``t_c`` is t clamped to the current interval
[a, b) (see :func:`~.simulation.simulate`): the controller *and* the model's time-dependent
forces are evaluated at t_c, so a jump at a breakpoint b is seen from the left up to b and from
the right after it, however the integrator places its stages. ``p = (params, d)`` for a
controller integrated by segments — one that states its law as ``casadi_segment(t, q, q̇, d)``
with ``d = segment_data(a)`` the numbers of the segment starting at a (an open-loop input:
d = (u₀, u₁, t_a), u = u₀ + u₁(t_c − t_a); a gain schedule: its gains and reference) —, else
``params``: one compiled loop serves every value of d. ``u`` is an explicit input only for a
controller without a CasADi form.

ẋ, λ, g, s and S come from the model's formulation
(:meth:`~nhgait.dynamics.derivation.formulation_base.Formulation.loop_dynamics`).
The singular-set measure s: the reduced ODE's ``numeric["singular"]`` (the engine's measure,
0 where any matrix the reduction inverts loses rank); for the DAE forms the Hadamard ratio
det S / Π Sᵢᵢ of the matrix ω M⁻¹ ωᵀ that the multipliers are solved with.
"""
from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from ..derivation.formulation_base import LoopPoint, Stabilisation
from ..errors import ModelError
from ..memo import OwnerMemo
from ..numerics.compiler import compiler_command
from .closure import closure
from .compiled import build

__all__ = ["ClosedLoop", "closed_loop", "controller_key", "OUTPUT_NAMES"]

#: the blocks of ``ClosedLoop.outputs``, in order
OUTPUT_NAMES = ("q", "qdot", "lam", "g", "energy", "u_applied", "measure", "metric", "gram")

#: per compiled model (model.numeric, dropped with it): (controller key, options) → ClosedLoop
CLOSED_LOOPS = OwnerMemo("closed loops per compiled model, controller and options")
#: content keys of frozen (immutable) controller objects, dropped with the controller
CONTROLLER_KEYS = OwnerMemo("content keys of frozen controllers")


def _by_segments(controller) -> bool:
    """The controller states its law per segment (``casadi_segment``, ``segment_data``)."""
    return hasattr(controller, "casadi_segment") and hasattr(controller, "segment_data")


def controller_key(controller) -> str:
    """A content key of the controller's law as it enters the closed loop (remembered for
    frozen dataclass controllers, which cannot change)."""
    frozen = dataclasses.is_dataclass(controller) and controller.__dataclass_params__.frozen
    if not frozen:
        return _controller_key(controller)
    return CONTROLLER_KEYS.get(controller, "law", lambda: _controller_key(controller))


def _controller_key(controller) -> str:
    if controller is None:
        return "none"
    segmented = _by_segments(controller)
    if not (segmented or hasattr(controller, "casadi")):
        return "python"
    n = len(getattr(controller, "system_coordinates", ()) or ()) or None
    t, q, qd = ca.SX.sym("t"), ca.SX.sym("q", n or 64), ca.SX.sym("qdot", n or 64)
    data = ca.SX.sym("segment_data", int(controller.segment_size) if segmented else 0)
    method = "casadi_segment" if segmented else "casadi"
    try:
        u = ca.vertcat(controller.casadi_segment(t, q, qd, data) if segmented
                       else controller.casadi(t, q, qd))
    except Exception as exc:  # the law could not be traced symbolically: refuse, with the cause
        raise ModelError([f"controller.{method} failed on symbolic arguments "
                          f"({type(exc).__name__}: {exc})"], title="invalid controller") from exc
    text = ca.Function("u", [t, q, qd, data], [u]).serialize()
    return ("segments/" if segmented else "casadi/") + hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True, eq=False)
class ClosedLoop:
    """CasADi functions of one closed loop (see the module docstring)."""

    formulation: str
    dae_form: bool              # the model is a DAE form (λ solved; velocities projected onto g = 0)
    n_q: int
    n_x: int
    n_y: int
    n_params: int
    n_u: int
    state_index: tuple          # entries of x integrated, in the order of x
    has_work: bool
    n_int: int                  # number of ∫g states
    symbolic_u: bool
    segment_u: bool
    rhs: ca.Function
    outputs: ca.Function
    event: ca.Function | None
    qdot: ca.Function
    _pieces: dict
    _compiled: dict = dataclasses.field(default_factory=dict)
    n_segment: int = 0          # length of a segment's data d in p (controllers by segments)

    def compiled(self, projection: bool = False):
        """The loop as a compiled library (:func:`.compiled.build`; with ``projection`` every
        step is projected onto the constraints), built once per compiler command; raises
        :class:`~.compiled.CompilerUnavailable`."""
        key = (tuple(compiler_command() or ()), projection)
        if key not in self._compiled:
            self._compiled[key] = build(self.rhs, self.outputs, self.event,
                                        self.project if projection else None)
        return self._compiled[key]

    @property
    def n_p(self) -> int:
        """Length of the parameter vector p of the functions."""
        return self.n_params + self.n_segment

    @property
    def complete(self) -> bool:
        """True when every entry of x is integrated."""
        return len(self.state_index) == self.n_x

    @cached_property
    def jac(self) -> ca.Function:
        """∂ẏ/∂y with the arguments of ``rhs`` (implicit scipy methods)."""
        pc = self._pieces
        return ca.Function("closed_loop_jac", pc["args"], [ca.densify(ca.jacobian(pc["ydot"], pc["y"]))],
                           pc["names"], ["dydot_dy"])

    @cached_property
    def project(self) -> ca.Function | None:
        """y ↦ y with q moved back onto the kept holonomic constraints h(q) = 0 (Newton's
        method on the dependent coordinates, :data:`HOLONOMIC_NEWTON` steps) and, in the DAE
        forms, the velocity part projected onto {g = 0} in the kinetic metric."""
        pc = self._pieces
        holonomic = pc.get("holonomic")
        if not self.complete or not (self.dae_form or holonomic):
            return None
        y = pc["y"]
        x, g, energy, n = pc["x"], pc["g"], pc["energy"], self.n_q
        q = x[:n]
        if holonomic:
            h, cols = holonomic
            J = ca.jacobian(h, q)[:, cols]
            for _ in range(HOLONOMIC_NEWTON):
                step = ca.solve(ca.substitute(J, x[:n], q), ca.substitute(h, x[:n], q))
                q = q - ca.mtimes(_scatter(cols, n), step)
        v = x[n:]
        if self.dae_form:
            moved = ca.vertcat(q, v)
            g_q, energy_q = ca.substitute(g, x, moved), ca.substitute(energy, x, moved)
            Jv = ca.jacobian(g_q, v)                       # g is linear in v (q̇ or p)
            W = ca.hessian(energy_q, v)[0]                 # kinetic metric in v (M or M⁻¹)
            WinvJt = ca.solve(W, Jv.T)
            v = v - ca.mtimes(WinvJt, ca.solve(ca.mtimes(Jv, WinvJt), g_q))
        return ca.Function("project", [y, pc["params"]],
                           [ca.densify(ca.vertcat(q, v, y[self.n_x:]))], ["y", "params"],
                           ["y_projected"])

    def dae(self) -> dict:
        """The semi-explicit index-1 DAE for IDAS: ``{"t", "x", "z", "p", "ode", "alg"}`` with
        p = (p of ``rhs``, t_hi) and λ the algebraic variable (its law with the loop's
        stabilisation's feedback)."""
        pc = self._pieces
        num, t, y, x = pc["num"], pc["t"], pc["y"], pc["x"]
        k = num.n_multipliers
        t_hi = ca.SX.sym("t_hi")
        z = ca.SX.sym("lam", k)
        u_d = (ca.substitute(pc["u"], pc["t_c"], ca.fmin(t, t_hi)) if (self.symbolic_u or self.segment_u)
               else pc["u"])
        xp = pc["params"]
        t_d = ca.fmin(t, t_hi)
        res = pc["stabilisation"].feedback(num["dae_g"](t_d, x, z, u_d, xp), pc["g"], pc["g_int"])
        ode = ca.vertcat(num["dae_f"](t_d, x, z, u_d, xp), num["power"](t_d, x, u_d, xp),
                         pc["g"] if self.n_int else ca.SX(0, 1))
        return {"t": t, "x": y, "z": z, "p": ca.vertcat(pc["p"], t_hi), "ode": ode, "alg": res}

    def segment_params(self, params: np.ndarray, controller, a: float) -> np.ndarray:
        """p on the interval starting at ``a``: params, and for a controller by segments the
        numbers ``controller.segment_data(a)`` its law reads on that interval."""
        if not self.segment_u:
            return params
        data = np.asarray(controller.segment_data(a), dtype=float).ravel()
        if data.size != self.n_segment:
            raise ModelError([f"controller.segment_data({a:g}) has {data.size} numbers, its segment_size is "
                              f"{self.n_segment}"], title="invalid controller")
        return np.r_[params, data]


def closed_loop(model, controller, *, stabilisation: Stabilisation = Stabilisation(),
                seeds=None) -> ClosedLoop:
    """The closed loop of ``model`` under ``controller`` (memoised per model and content).

    ``stabilisation``: the DAE forms' constraint stabilisation
    (:class:`~nhgait.dynamics.derivation.formulation_base.Stabilisation`, none by default);
    ``seeds``: indices of x that the run must report (None: all); the loop integrates their
    dependency closure.
    """
    seeds = None if seeds is None else tuple(sorted(set(int(s) for s in seeds)))
    key = (controller_key(controller), stabilisation, seeds)
    return CLOSED_LOOPS.get(model.numeric, key, lambda: _build(model, controller, stabilisation, seeds))


#: Newton steps of the holonomic projection (each squares the drift: 1e-8 → 1e-16 → below)
HOLONOMIC_NEWTON = 2


def _scatter(cols, n) -> ca.DM:
    """The n×len(cols) matrix that puts a vector into the rows ``cols``."""
    E = np.zeros((n, len(cols)))
    for j, i in enumerate(cols):
        E[i, j] = 1.0
    return ca.DM(E)


def _holonomic_pieces(model, q, params):
    """(h(q) as SX, dependent columns) of the kept holonomic constraints, or None."""
    system = model.system
    if not system.holonomic:
        return None
    h = model.numeric["holonomic"](q, params)
    return h, [list(system.coordinates).index(c) for c in system.dependent]


def _invariant_entries(expr, x, params, candidates, param_values, samples=6) -> list:
    """Entries of x that ``expr`` reads only structurally: ∂expr/∂x_i vanishes (to 1e-12
    relative) at ``samples`` random states. The singular-set measure of a reduced model is
    invariant under the symmetry group, yet its expression contains the fiber coordinates."""
    if not candidates:
        return []
    grad = ca.Function("grad", [x, params], [ca.jacobian(expr, x[candidates]), expr])
    rng = np.random.default_rng(7)
    pv = np.asarray(param_values, dtype=float)
    free = np.ones(len(candidates), dtype=bool)
    for _ in range(samples):
        with np.errstate(all="ignore"):
            d, value = grad(rng.uniform(-1.2, 1.2, x.shape[0]), pv)
        d = np.abs(np.asarray(d, dtype=float)).ravel()
        free &= np.isfinite(d) & (d <= 1e-12 * (1.0 + abs(float(value))))
    return [i for i, f in zip(candidates, free, strict=True) if f]


def _event_function(measure, y, p) -> ca.Function:
    """``event(y, ẏ, p) → (s, ṡ)``: the singular-set measure and its rate along ẏ."""
    ydot = ca.SX.sym("ydot", y.shape[0])
    return ca.Function("event", [y, ydot, p], [measure, ca.jtimes(measure, y, ydot)],
                       ["y", "ydot", "p"], ["measure", "rate"])


def _velocity_metric(energy, v):
    return ca.hessian(energy, v)[0]


def _input(controller, m, t_c, q, qdot, params):
    """(u, explicit u arguments, p, symbolic, by segments): the input as the closed loop sees it."""
    if controller is None:
        return ca.SX.zeros(m), [], params, False, False
    if _by_segments(controller):                  # u(t_c, q, q̇, d), d the segment's numbers in p
        data = ca.SX.sym("segment_data", int(controller.segment_size))
        u = _checked_shape(ca.vertcat(controller.casadi_segment(t_c, q, qdot, data)), m, "casadi_segment")
        return u, [], ca.vertcat(params, data), False, True
    if hasattr(controller, "casadi"):
        u = _checked_shape(ca.vertcat(controller.casadi(t_c, q, qdot)), m, "casadi")
        return u, [], params, True, False
    u = ca.SX.sym("u", m)
    return u, [u], params, False, False


def _checked_shape(u, m, method):
    if u.shape != (m, 1):
        raise ModelError([f"controller.{method} returned shape {u.shape}, expected ({m}, 1)"],
                         title="invalid controller")
    return u


@dataclass(frozen=True, kw_only=True)
class _LoopExpressions:
    """The CasADi expressions of the closed loop that decide what must be integrated: the state
    ``x``, ``params``, ẋ, the singular-set ``measure``, q̇, the residual ``g``, the ``power``
    τ·q̇, the number ``n_int`` of integrated residuals and whether the input law is opaque
    (a Python controller, which may read any q and q̇)."""

    x: object
    params: object
    xdot: object
    measure: object
    qdot: object
    g: object
    power: object
    n_int: int
    opaque_u: bool


def _integrated(model, seeds, loop: _LoopExpressions):
    """(indices of x to integrate, measure, whether W is integrated): the closure of the seeds
    plus what the event, ∫g and an opaque controller read (see :mod:`.closure`)."""
    x, params, xdot, measure, qdot, g, power, n_int, opaque_u = (
        loop.x, loop.params, loop.xdot, loop.measure, loop.qdot, loop.g, loop.power, loop.n_int,
        loop.opaque_u)
    nx, n = x.shape[0], model.system.n
    if seeds is None:
        return tuple(range(nx)), measure, True

    def reads(expr):
        return [i for i in range(nx) if ca.depends_on(expr, x[i])]
    dep = np.array(ca.DM(ca.jacobian_sparsity(xdot, x), 1)).astype(bool)
    free = _invariant_entries(measure, x, params, reads(measure), model.numeric.param_defaults)
    measure = ca.substitute(measure, x[free], ca.SX.zeros(len(free))) if free else measure
    opaque = list(range(n)) + reads(qdot) if opaque_u else []   # a Python law may read anything
    index = closure(dep, list(seeds) + reads(measure) + (reads(g) if n_int else []) + opaque)
    return index, measure, set(reads(power)) <= set(index)


def _build(model, controller, stabilisation: Stabilisation, seeds) -> ClosedLoop:
    num, system = model.numeric, model.system
    n, nx, m = system.n, len(model.state_names), len(system.inputs)
    n_int = stabilisation.integral_states(model.multiplier_count())
    t, t_c = ca.SX.sym("t"), ca.SX.sym("t_c")
    params = ca.SX.sym("params", len(num.param_names))
    x, work, g_int = ca.SX.sym("x", nx), ca.SX.sym("work"), ca.SX.sym("g_int", n_int)
    q, qdot = x[:n], num["qdot"](x, params)
    u, u_args, p, symbolic_u, segment_u = _input(controller, m, t_c, q, qdot, params)
    n_segment = int(p.shape[0]) - len(num.param_names)
    dynamics = model.loop_dynamics(LoopPoint(t_c=t_c, x=x, u=u, params=params, g_int=g_int), stabilisation)
    xdot, lam, g, measure, gram = dynamics.xdot, dynamics.lam, dynamics.g, dynamics.measure, dynamics.gram
    power = num["power"](t_c, x, u, params)
    energy = num["energy"](x, params)
    metric = ca.vec(_velocity_metric(energy, x[n:]))
    loop = _LoopExpressions(x=x, params=params, xdot=xdot, measure=measure, qdot=qdot, g=g, power=power,
                            n_int=n_int, opaque_u=bool(u_args))
    index, measure, has_work = _integrated(model, seeds, loop)
    if len(index) == nx:
        x_s = x

        def restrict(expr):
            return expr
    else:                                         # entries not integrated are NaN constants
        x_s = ca.SX.sym("x_s", len(index))
        entries = [ca.SX(np.nan)] * nx
        for j, i in enumerate(index):
            entries[i] = x_s[j]
        x_full = ca.vertcat(*entries)

        def restrict(expr):
            return ca.substitute(expr, x, x_full)
    y = ca.vertcat(x_s, work if has_work else ca.SX(0, 1), g_int)
    ydot = restrict(ca.vertcat(xdot[list(index)], power if has_work else ca.SX(0, 1),
                               g if n_int else ca.SX(0, 1)))
    ydot = ca.cse(ca.densify(ydot))               # the model's functions share subexpressions
    args, names = [t, t_c, y] + u_args + [p], ["t", "t_c", "y"] + ["u"] * bool(u_args) + ["p"]
    outs = [ca.densify(restrict(o)) for o in (q, qdot, lam, g, energy, u, measure, metric, gram)]
    return ClosedLoop(
        formulation=model.formulation, dae_form=model.dae_options_apply, n_q=n, n_x=nx,
        n_y=int(y.shape[0]),
        n_params=len(num.param_names), n_u=m, state_index=tuple(index), has_work=has_work,
        n_int=n_int, symbolic_u=symbolic_u, segment_u=segment_u,
        rhs=ca.Function("closed_loop", args, [ydot], names, ["ydot"]),
        outputs=ca.Function("outputs", args, outs, names, list(OUTPUT_NAMES)),
        event=_event_function(restrict(measure), y, p) if system.k else None,
        qdot=ca.Function("qdot", [y, p], [ca.densify(restrict(qdot))], ["y", "p"], ["qdot"]),
        _pieces=dict(args=args, names=names, ydot=ydot, y=y, x=x, g=g, energy=energy, num=num, t=t,
                     t_c=t_c, u=u, p=p, params=params, g_int=g_int, stabilisation=stabilisation,
                     holonomic=_holonomic_pieces(model, q, params)),
        n_segment=n_segment)
