"""Forward simulation of any formulation: :func:`simulate` → :class:`Trajectory`.

What is integrated
------------------
The formulation's own state x (``model.state_names``: reduced z = (q, P, P̃), Lagrangian
(q, q̇), Hamiltonian (q, p = M q̇)), extended by the work W = ∫ τ·q̇ dt as a quadrature state,
so the energy balance E(t) − E(t₀) − W(t) is an accuracy check of the run (see
:mod:`.closed_loop` for the extended state and its order).

* Reduced ODE: ż = f(t, z, u); no multipliers.
* DAE forms, ``dae="index1"``: λ is solved from the differentiated constraint (the
  acceleration-level equation d/dt(ω q̇) = 0, resp. d/dt(ω ∂H/∂p) = 0) and the resulting ODE is
  integrated; λ(t) is reported from the same solve.
* DAE forms, ``dae="idas"``: CasADi IDAS (variable-order BDF) on the semi-explicit index-1 DAE
  ẋ = f(t, x, λ, u), 0 = g₁(t, x, λ, u) with λ an algebraic variable; λ(t) is IDAS's own.

Methods (``method``)
--------------------
* scipy: ``"RK23"``, ``"RK45"``, ``"DOP853"`` (default), ``"Radau"``, ``"BDF"``, ``"LSODA"``;
* ``"CVODES"``: CasADi's CVODES (BDF, Newton with the exact Jacobian) on the same right-hand side;
* ``"compiled"`` / ``"compiled-DOPRI5"``: the closed loop compiled to C and integrated there by
  Dormand–Prince 8(5,3) / 5(4) (:mod:`.compiled`). Needs the controller as CasADi (PD laws,
  :class:`~.controllers.OpenLoop`, scene input laws, any ``casadi(t, q, q̇)``); a plain Python
  controller runs on scipy DOP853 instead, and without a C compiler it warns and does the same
  (``Trajectory.settings["fallback"]`` says why);
* ``"auto"``: ``"compiled"`` with stiffness detection; when the explicit method's step size is
  limited by stability (h|λ| above :data:`~.integrators.STIFF_LIMIT` for 15 steps) the run is redone with
  ``"CVODES"`` (``"Radau"`` for a Python controller) and ``settings["auto"]`` says so.
  The explicit methods always report the detection (``diagnostics["stiff_at"]`` and a
  recommendation) — with ``"auto"`` the switch is automatic.

Both DAE routes integrate the *index-reduced* system: the velocity constraint ω(q)q̇ = 0 itself
is only an invariant and drifts at the level of the integration error. Stabilisation is off by
default and recorded in ``Trajectory.settings`` when on: ``"baumgarte"`` (ġ + 2αg + β²∫g = 0)
and ``"projection"`` (scipy and compiled methods: after every accepted step the velocities are
projected onto {g = 0} in the kinetic-energy metric and the integration restarts from there).
With kept holonomic constraints h(q) = 0 (every formulation, the reduced ODE included)
``"projection"`` first moves the dependent coordinates back onto h = 0 (Newton's method);
the drift h(q(t)) is reported as ``Trajectory.holonomic_residual`` either way.

Failure is data, never a hang
-----------------------------
A non-finite right-hand side, input or state stops the run at once: ``success=False``,
``status=NONFINITE`` and a message naming the time and the quantity (the controller's input,
the force τ_i and its expression, or the state entry). ``max_steps`` caps the accepted steps of
every method (scipy: also 100·max_steps evaluations; SUNDIALS: steps per output interval).
Reaching the singular set (the measure of :mod:`.closed_loop` below ``singular_tol``) stops the
run with ``status=SINGULAR`` at the located crossing time. Bad input raises :class:`ModelError`
listing every problem. Angles are never wrapped.

Model only what a run needs
---------------------------
``outputs=("psi", "phi", "p", …)`` integrates only the dependency closure of those outputs
(:mod:`.closure`); the other entries of x are not modelled and are NaN in ``q``/``qdot``/``state``
columns that need them; ``Trajectory.outputs`` holds the requested columns.
"""
from __future__ import annotations

import dataclasses
import time
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..derivation.states import to_state
from ..errors import ModelError
from ..memo import OwnerMemo
from .closed_loop import closed_loop
from .compiled import CompilerUnavailable
from .failures import diagnose_failure
from .integrators import (
    FAILED,
    FINISHED,
    MAX_STEPS,
    NONFINITE,
    SCIPY_METHODS,
    SINGULAR,
    RunRequest,
    Samples,
    integrate_scipy,
    left_of,
)
from .options import COMPILED_METHODS, METHODS, SINGULAR_EVENT_TOL, SimulationOptions, checked_span
from .route_compiled import integrate_compiled
from .route_sundials import integrate_sundials
from .trajectory import Diagnostics, OnRead, Trajectory, max_condition, min_measure

__all__ = ["simulate", "Trajectory", "Diagnostics", "SimulationOptions", "METHODS", "FINISHED", "FAILED",
           "MAX_STEPS", "NONFINITE", "SINGULAR", "SINGULAR_EVENT_TOL"]

STATUS_NAMES = {FINISHED: "finished", FAILED: "failed", MAX_STEPS: "max_steps",
                NONFINITE: "non-finite", SINGULAR: "singular set"}


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Call:
    """One :func:`simulate` call as the user stated it (unchecked): what is simulated and the
    :class:`~.options.SimulationOptions` of how."""

    model: object
    t_span: object
    q0: object
    qdot0: object
    controller: object
    params: object
    options: SimulationOptions


def _check_request(call: _Call) -> list:
    """Every problem with the request, as a list of sentences."""
    options, model = call.options, call.model
    span = checked_span(call.t_span)
    t0, tf = span.t0, span.tf
    problems = span.problems + options.name_problems()
    if options.stabilisation_type is not None:
        holonomic = bool(getattr(model, "system", None) and model.system.holonomic)
        problems += model.dae_option_problems(options.idas, options.stabilisation_type, holonomic=holonomic)
    problems += options.combination_problems()
    problems += options.value_problems(t0, tf)
    if call.controller is not None:
        problems += _check_controller(call, t0, tf)
    return problems


def _check_controller(call: _Call, t0, tf) -> list:
    system, controller, options = call.model.system, call.controller, call.options
    problems = []
    if not callable(controller):
        problems.append("controller must be callable as controller(t, q, qdot) -> u")
    coords = getattr(controller, "system_coordinates", None)
    if coords is not None and tuple(coords) != tuple(system.coordinates):
        problems.append(f"controller indexes q as {tuple(coords)}, the system's coordinates "
                        f"are {tuple(system.coordinates)}")
    names = getattr(controller, "inputs", None)
    if names is not None and tuple(names) != tuple(system.inputs):
        problems.append(f"controller outputs {tuple(names)}, the system's inputs are "
                        f"{tuple(system.inputs)}")
    domain = getattr(controller, "domain", None)
    if domain is not None and t0 is not None and (t0 < domain[0] or tf > domain[1]):
        problems.append(f"t_span [{t0:g}, {tf:g}] exceeds the controller's domain "
                        f"[{domain[0]:g}, {domain[1]:g}]")
    symbolic = hasattr(controller, "casadi") or hasattr(controller, "casadi_segment")
    if options.sundials and not symbolic:
        asked = f"dae={options.dae!r}" if options.idas else f"method={options.method!r}"
        problems.append(f"{asked} needs a controller with a casadi(t, q, qdot) method (SUNDIALS evaluates "
                        "u as a CasADi expression of the state)")
    return problems


#: the problems of each parameter vector given to simulate, per system (dropped with the system)
CHECKED_PARAMETERS = OwnerMemo("parameter problems per system and parameter vector", limit=256)


def _parameter_problems(model, params) -> list:
    """``System.parameter_problems`` for ``simulate(params=...)`` (remembered per system and
    parameter vector, :data:`CHECKED_PARAMETERS`): non-finite values, a singular or indefinite
    kinetic metric, dependent constraints."""
    system = model.system

    def check():
        return tuple(system.parameter_problems(params, label="the given params"))
    try:
        key = model.numeric.params(params).tobytes()
    except (ModelError, TypeError, ValueError):   # malformed params: parameter_problems names them
        return list(check())
    return list(CHECKED_PARAMETERS.get(system, key, check))


def _segments(t0, tf, controller, system=None, params=None):
    """Integration intervals [(a, b)] split at the controller's breakpoints and at the times a
    force jumps (``System.force_jump_times``) inside (t0, tf)."""
    cuts = set()
    if controller is not None and getattr(controller, "breakpoints", None) is not None:
        cuts.update(float(b) for b in np.asarray(controller.breakpoints, dtype=float).ravel())
    if system is not None and hasattr(system, "force_jump_times"):
        cuts.update(system.force_jump_times(params))
    points = [t0] + sorted(b for b in cuts if t0 < b < tf) + [tf]
    return list(zip(points[:-1], points[1:], strict=True))


# --------------------------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------------------------
def simulate(model, t_span, q0, qdot0, *, controller=None, options: SimulationOptions | None = None,
             **keywords) -> Trajectory:
    """Simulate a derived formulation from a consistent physical state (q0, q̇0).

    Parameters
    ----------
    model : ReducedODE, LagrangianDAE or HamiltonianDAE
        From :func:`~nhgait.dynamics.derivation.formulations.derive`.
    t_span : (t0, tf) with tf > t0.
    q0, qdot0 : (n,) initial coordinates and velocities; q̇0 must satisfy ω(q0)q̇0 = 0 (it is
        mapped to the formulation's state by :func:`~nhgait.dynamics.derivation.states.to_state`, which
        raises for an inconsistent or singular state).
    controller : callable (t, q, q̇) → u (m,), optional
        See :mod:`.controllers`. None applies u = 0.
    options : SimulationOptions, optional
        How to integrate, and the parameter values (every default when None).
    **keywords
        Any field of :class:`~.options.SimulationOptions`, replacing the one of ``options``:
        ``params`` (dict or (n_params,) array: parameter values overriding the system's
        defaults, checked like them — finite, positive-definite kinetic metric), ``method``
        (:data:`METHODS`, see the module docstring), ``rtol``, ``atol``, ``t_eval``, ``dae``
        ("index1", "idas"), ``stabilization`` (None, "baumgarte", "projection"), ``baumgarte``
        (α, β), ``max_step``, ``max_steps``, ``singular_tol``, ``outputs``, ``quantities``.

    Returns
    -------
    Trajectory

    Examples
    --------
    The unicycle rolling straight ahead at 1 rad/s of its wheel (r = 0.1 m) for one second:

    >>> from nhgait.dynamics import derive, simulate
    >>> model = derive("unicycle")
    >>> traj = simulate(model, (0.0, 1.0), [0, 0, 0, 0], [0.1, 0, 0, 1.0], t_eval=[0.0, 0.5, 1.0])
    >>> traj.success, traj.t.tolist()
    (True, [0.0, 0.5, 1.0])
    >>> traj.q[-1].round(6).tolist()        # x = r φ, y = 0, θ = 0, φ = 1
    [0.1, 0.0, 0.0, 1.0]
    >>> float(abs(traj.constraint_residual).max()) < 1e-12
    True
    """
    options = SimulationOptions.from_keywords(options, **keywords)
    call = _Call(model=model, t_span=t_span, q0=q0, qdot0=qdot0, controller=controller, params=options.params,
                 options=options)
    resolved = _checked_outputs(call)
    prepared, request = _prepare(call, resolved)
    route = "IDAS" if call.options.idas and model.dae_options_apply else call.options.method
    return _assemble(call, request, ROUTES[route](request, route, prepared.settings), prepared)


@dataclass(frozen=True, eq=False)
class _Prepared:
    """What :func:`simulate` settled before integrating: the parameter vector ``pv``, the
    resolved ``outputs`` (or None), the ``settings`` reported (the route adds to them), the
    ``start`` of the wall time and whether the initial point is an output (``with_initial``)."""

    pv: np.ndarray
    resolved: object
    settings: dict
    start: float
    with_initial: bool


def _checked_outputs(call: _Call):
    """The resolved ``outputs`` (or None) of a valid request; :class:`ModelError` listing every
    problem otherwise."""
    problems = _check_request(call)
    resolved, outputs = None, call.options.outputs
    if outputs is not None and not problems:
        from .closure import resolve_outputs
        try:
            resolved = resolve_outputs(call.model, tuple(outputs), call.options.quantities)
        except ModelError as err:
            problems += list(err.problems)
    if not problems and call.params is not None:
        problems += _parameter_problems(call.model, call.params)
    if problems:
        raise ModelError(problems, title="invalid simulation request")
    return resolved


def _prepare(call: _Call, resolved) -> tuple[_Prepared, RunRequest]:
    """The initial state, the segments, the closed loop and the settings of a checked request."""
    model, controller, options = call.model, call.controller, call.options
    system, num = model.system, model.numeric
    pv = num.params(call.params)
    t0, tf = float(call.t_span[0]), float(call.t_span[1])
    x0 = to_state(model, call.q0, call.qdot0, call.params)
    named_params = dict(zip(num.param_names, pv.tolist(), strict=True))
    segments = _segments(t0, tf, controller, system, named_params)
    if controller is not None:
        _check_first_input(call, t0)
    start = time.perf_counter()
    settings = _settings(call, (t0, tf), len(segments), named_params)
    seeds = None
    if resolved is not None:
        if options.idas or options.stabilisation.projects:
            settings["outputs_note"] = "the dependency closure needs the ODE route; every state integrated"
        else:
            seeds = resolved.seeds
    loop = closed_loop(_integration_model(model, pv, settings), controller,
                       stabilisation=options.stabilisation, seeds=seeds)
    y0 = np.zeros(loop.n_y)              # (x_S, W = 0, ∫g = 0)
    y0[:len(loop.state_index)] = x0[list(loop.state_index)]
    seg_params = [loop.segment_params(pv, controller, a) for a, _ in segments]
    request = RunRequest(loop=loop, controller=controller, segments=segments, y0=y0, seg_params=seg_params,
                         options=options)
    te = None if options.t_eval is None else np.asarray(options.t_eval, dtype=float)
    with_initial = te is None or abs(te[0] - t0) <= 1e-12 * max(1.0, abs(t0))
    return _Prepared(pv, resolved, settings, start, with_initial), request


def _check_first_input(call: _Call, t0: float) -> None:
    """The controller's input at the initial state has one entry per system input."""
    system = call.model.system
    with np.errstate(all="ignore"):
        u0 = np.asarray(call.controller(t0, np.asarray(call.q0, float), np.asarray(call.qdot0, float)),
                        float).ravel()
    if u0.shape != (len(system.inputs),):
        raise ModelError([f"controller returned {u0.size} inputs, the system has "
                          f"{len(system.inputs)} ({', '.join(system.inputs)})"],
                         title="invalid simulation request")


def _settings(call: _Call, t_span: tuple, n_segments: int, named_params: dict) -> dict:
    """Every option the run uses, as ``Trajectory.settings`` reports them."""
    options = call.options
    return {**options.settings(call.model), "t_span": t_span, "segments": n_segments, "params": named_params,
            "controller": None if call.controller is None else type(call.controller).__name__,
            "singular_tol": options.singular_tol,
            "outputs": None if options.outputs is None else tuple(options.outputs)}


#: per compiled model (model.numeric, dropped with it): parameter values → (the model
#: specialised to them, the route taken)
SPECIALISED = OwnerMemo("reduced models specialised to parameter values, per compiled model")


def _integration_model(model, pv, settings):
    """The model whose functions the run integrates. The reduced ODE is specialised to these
    parameter values (:func:`~nhgait.dynamics.numerics.specialisation.specialise`: the values
    substituted, the trigonometric normal form taken, checked against the general functions,
    cached on disk), which leaves far fewer operations per evaluation (the snakeboard's ż: 108
    instead of 313); the DAE forms are integrated as derived. ``settings["specialised"]`` says
    which route was taken."""
    if not model.specialised_for_integration:
        return model

    def specialised_view():           # one view per model and values: its closed loop is reused
        from ..numerics.specialisation import specialise
        specialised = specialise(model, pv)
        return dataclasses.replace(model, compiled=specialised.numeric), specialised.route
    view, route = SPECIALISED.get(model.numeric, tuple(float(v) for v in pv), specialised_view)
    settings["specialised"] = route
    return view


# --------------------------------------------------------------------------------------------
# routes: one function per integration route, all fed by one RunRequest
# --------------------------------------------------------------------------------------------
class Routed(NamedTuple):
    """What a route returns: the integration ``run``, the name of the method that ran it and
    ``extra`` diagnostics."""

    run: object
    method: str
    extra: dict


def _route_scipy(request: RunRequest, method: str, settings: dict) -> Routed:
    run = integrate_scipy(request, method, projection=request.options.stabilisation.projects)
    return Routed(run, method, {})


def _route_cvodes(request: RunRequest, method: str, settings: dict) -> Routed:
    return Routed(integrate_sundials(request, "cvodes"), "CVODES", {})


def _route_idas(request: RunRequest, method: str, settings: dict) -> Routed:
    t0 = request.segments[0][0]
    lam0 = _outputs(request.loop, request.controller, None, Samples.point(t0, t0, 0, request.y0),
                    request.seg_params)["lam"][0]
    return Routed(integrate_sundials(request, "idas", lam0), "IDAS", {})


def _route_compiled(request: RunRequest, method: str, settings: dict) -> Routed:
    """The compiled explicit Runge–Kutta route ("compiled", "compiled-DOPRI5"); scipy DOP853
    when no library can be built."""
    return _explicit(request, method, settings, stop_on_stiff=False)


def _route_auto(request: RunRequest, method: str, settings: dict) -> Routed:
    """"auto": the compiled DOP853 route stopped on stiffness and redone by an implicit method."""
    return _explicit(request, method, settings, stop_on_stiff=True)


def _explicit(request: RunRequest, method: str, settings: dict, *, stop_on_stiff: bool) -> Routed:
    extra = {}
    scheme = COMPILED_METHODS.get(method, "DOP853")
    projection = request.options.stabilisation.projects
    library, reason = _library(request.loop, request.python_inputs, projection)
    if library is None:
        settings["fallback"] = f"{reason}; integrated with scipy DOP853"
        if "compiler" in reason:
            warnings.warn(f"method={method!r}: {settings['fallback']}", stacklevel=3)
        if not stop_on_stiff:
            return Routed(integrate_scipy(request, "DOP853", projection=projection), "DOP853", extra)
        run = integrate_scipy(request, "DOP853", stop_on_stiff=True)
        if run.message == "stiff":
            return _switch_to_implicit(request, run, settings, extra)
        return Routed(run, "DOP853", extra)
    extra["library"] = library
    extra["compile_time_s"] = library.compile_time_s
    run = integrate_compiled(request, library, scheme, stop_on_stiff=stop_on_stiff)
    if stop_on_stiff and run.message == "stiff":
        extra.pop("library")
        return _switch_to_implicit(request, run, settings, extra)
    return Routed(run, f"compiled {scheme}", extra)


#: route name → route(request, method, settings) → :class:`Routed`
ROUTES = {**{name: _route_scipy for name in SCIPY_METHODS}, "CVODES": _route_cvodes, "IDAS": _route_idas,
          **{name: _route_compiled for name in COMPILED_METHODS}, "auto": _route_auto}


def _switch_to_implicit(request: RunRequest, run, settings: dict, extra: dict) -> Routed:
    implicit = "Radau" if request.python_inputs else "CVODES"
    settings["auto"] = (f"DOP853 detected stiffness at t = {run.t_stiff:.6g} (h|λ| "
                        f"up to {run.h_lambda:.3g} for 15 steps: the step is set by stability) "
                        f"after {run.nfev} evaluations; redone with {implicit}")
    if request.python_inputs:
        new = integrate_scipy(request, "Radau")
    else:
        new = integrate_sundials(request, "cvodes")
    new.nfev += run.nfev
    new.t_stiff, new.h_lambda = run.t_stiff, run.h_lambda
    return Routed(new, implicit, extra)


def _library(loop, explicit_u, projection=False):
    """(CompiledLoop, None) or (None, the reason the compiled route cannot run)."""
    if explicit_u:
        return None, ("the controller has no casadi(t, q, qdot) method, so it cannot be compiled "
                      "into the closed loop")
    try:
        return loop.compiled(projection), None
    except CompilerUnavailable as exc:
        return None, f"no usable C compiler ({exc})"


# --------------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------------
_BLOCKS = ("q", "qdot", "lam", "g", "energy", "u", "measure", "metric", "gram")
#: the blocks whose non-finite values stop a run
_CHECKED_BLOCKS = ("q", "qdot", "lam", "g", "energy", "u")


def _outputs(loop, controller, library, points: Samples, seg_params) -> dict:
    """The output blocks of the closed loop at the N ``points``, each (N, size); the diagnostic
    blocks (measure, metric, gram) under the key ``"diagnostic"`` as :class:`_DiagnosticBlocks`
    (the compiled library evaluates them only when a diagnostic is read); from the compiled
    library also ``"table"``, the checked blocks side by side (N, Σ sizes)."""
    N = len(points)
    Y = points.y.reshape(N, loop.n_y)
    P = np.asarray(seg_params, dtype=float).reshape(len(seg_params), loop.n_p)
    if library is not None:
        table = library.output_table(points.t, points.t_c, Y, P, points.seg)
        out = dict(zip(_CHECKED_BLOCKS, library.blocks(table), strict=True), table=table)
        out["diagnostic"] = _DiagnosticBlocks(library, (points.t, points.t_c, Y, P, points.seg))
        return out
    P = P[points.seg]
    T, Tc = points.t[None, :], points.t_c[None, :]
    if controller is not None and not (loop.symbolic_u or loop.segment_u):
        qdot = np.asarray(loop.qdot.map(N)(Y.T, P.T)).reshape(-1, N)
        with np.errstate(all="ignore"):
            U = np.array([np.asarray(controller(tc, Y[i, :loop.n_q], qdot[:, i]), float).ravel()
                          for i, tc in enumerate(points.t_c)]).T
        res = loop.outputs.map(N)(T, Tc, Y.T, U, P.T)
    else:
        res = loop.outputs.map(N)(T, Tc, Y.T, P.T)
    out = {k: np.asarray(v).T.reshape(N, -1) for k, v in zip(_BLOCKS, res, strict=True)}
    out["diagnostic"] = _DiagnosticBlocks(None, None, {k: out.pop(k) for k in _BLOCKS[6:]})
    return out


def _output_rows(out: dict, start: int, stop: int | None) -> dict:
    """The rows ``start:stop`` of every output block (views)."""
    return {k: v.rows(start, stop) if k == "diagnostic" else v[start:stop] for k, v in out.items()}


@dataclass(frozen=True, eq=False)
class _DiagnosticBlocks:
    """The blocks measure, metric and gram at the output points: ``blocks`` as given, or — with
    a compiled ``library`` — evaluated by it at ``points`` = (t, t_c, Y, the segments'
    parameter vectors, each point's segment) on first use."""

    library: object
    points: tuple | None
    blocks: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        if not self.blocks:
            self.blocks.update(zip(_BLOCKS[6:], self.library.diagnostic_outputs(*self.points), strict=True))
        return self.blocks[name]

    def size(self, name: str) -> int:
        """Entries per point of block ``name`` (without evaluating it)."""
        if self.library is not None:
            return self.library.diag_sizes[_BLOCKS[6:].index(name)]
        return self.blocks[name].shape[1]

    def rows(self, start: int, stop: int | None) -> _DiagnosticBlocks:
        part = slice(start, stop)
        if self.library is not None and not self.blocks:
            t, t_c, Y, P, seg = self.points
            return _DiagnosticBlocks(self.library, (t[part], t_c[part], Y[part], P, seg[part]))
        return _DiagnosticBlocks(None, None, {k: self[k][part] for k in _BLOCKS[6:]})


def _first_nonfinite_row(out: dict) -> int | None:
    """First row after the initial one (counted from 0 after it) with a non-finite value in a
    column that is modelled (finite at the initial point)."""
    whole = out.get("table")                       # NaN and ±inf reach the sum
    if np.isfinite(whole.sum()) if whole is not None else all(np.isfinite(out[k].sum())
                                                              for k in _CHECKED_BLOCKS):
        return None
    rows = []
    for key in _CHECKED_BLOCKS:
        block = out[key][1:]
        if not block.size or np.isfinite(block.sum()):
            continue
        bad = (~np.isfinite(block[:, np.isfinite(out[key][0])])).any(axis=1)
        if bad.any():
            rows.append(int(np.argmax(bad)))
    return min(rows) if rows else None


def _assemble(call: _Call, request: RunRequest, routed: Routed, prepared: _Prepared) -> Trajectory:
    """Outputs, diagnosis of a failure, diagnostics → :class:`Trajectory` (``routed``: what the
    route returned)."""
    run, method_name, extra = routed
    model, loop, segments = call.model, request.loop, request.segments
    library = extra.pop("library", None)
    # outputs at the initial state first: E(t0) and which columns the run models at all
    t0 = segments[0][0]
    initial = Samples.point(t0, min(t0, left_of(segments[0][1])), 0, request.y0)
    samples = run.samples(loop.n_y, model.numeric.n_multipliers if run.with_lam else 0)
    points = Samples.join([initial, samples.with_lam(None)])
    out = _outputs(loop, request.controller, library, points, request.seg_params)
    if run.status == FINISHED:
        row = _first_nonfinite_row(out)
        if row is not None:
            run.fail(NONFINITE, samples.t[row], "")
            run.keep_first(row)
            samples, points = samples.rows(0, row), points.rows(0, row + 1)
            out = _output_rows(out, 0, row + 1)
    if run.status in (FAILED, MAX_STEPS, NONFINITE):
        diagnose_failure(model, request, run)
    if run.status == SINGULAR:
        run.message = (f"reached the singular set at t = {run.t_fail:.9g}: singular-set measure "
                       f"below {request.options.singular_tol:g} ({model.singular_set_text()})"
                       + (f"; {run.message}" if run.message else ""))
    energy0 = float(out["energy"][0, 0])
    if prepared.with_initial:          # the points the outputs were evaluated at
        samples = (points if samples.lam is None
                   else points.with_lam(np.concatenate([out["lam"][:1], samples.lam])))
    else:
        out = _output_rows(out, 1, None)
    wall = time.perf_counter() - prepared.start
    return _trajectory(call, loop, (run, samples, out, energy0), (method_name, extra, wall), prepared)


def _trajectory(call: _Call, loop, results: tuple, route: tuple, prepared: _Prepared) -> Trajectory:
    """The :class:`Trajectory` of ``results`` = (Run, its samples, the output blocks, E(t₀))
    and ``route`` = (method name, extra diagnostics, wall time)."""
    model = call.model
    run, samples, out, energy0 = results
    method_name, extra, wall = route
    N = len(samples)
    Y = samples.y.reshape(N, loop.n_y)
    n_xs = len(loop.state_index)
    work = Y[:, n_xs] if loop.has_work else np.full(N, np.nan)
    energy = out["energy"].ravel()
    lam = None
    if model.has_multipliers:
        lam = samples.lam.reshape(N, -1) if samples.lam is not None else out["lam"]
    traj_outputs = _named_outputs(call, prepared, loop, out, Y)
    arrays = dict(t=samples.t, q=out["q"], qdot=out["qdot"], state=Y[:, :n_xs], u=out["u"], lam=lam,
                  constraint_residual=out["g"], energy=energy, work=work,
                  energy_balance=energy - energy0 - work,
                  holonomic_residual=_holonomic_drift(model.system, out["q"], prepared.pv))
    for a in list(arrays.values()) + list(traj_outputs.values()):
        if a is not None:
            a.setflags(write=False)
    settings = prepared.settings
    settings["method"] = method_name
    names = _names(model, loop)
    return Trajectory(**arrays, nfev=run.nfev, njev=run.njev, n_steps=run.n_steps,
                      wall_time_s=wall, success=run.status == FINISHED, status=run.status,
                      message=run.message, formulation=model.formulation, method=method_name,
                      **names, settings=settings,
                      diagnostics=_diagnostics(model, loop, run, out, extra), outputs=traj_outputs)


def _holonomic_drift(system, q, pv) -> np.ndarray:
    """h(q(t)) of the kept holonomic constraints at the samples (N, c); (N, 0) without them."""
    if not system.holonomic:
        return np.zeros((q.shape[0], 0))
    from ..derivation.holonomic import holonomic_residual
    with np.errstate(all="ignore"):
        return holonomic_residual(system, q, np.asarray(pv, dtype=float))


#: per closed loop (dropped with it): the column names of its trajectories
COLUMN_NAMES = OwnerMemo("trajectory column names per closed loop")


def _names(model, loop) -> dict:
    """``coordinates``, ``state_names`` (the integrated entries of x) and ``input_names``."""
    system = model.system
    return COLUMN_NAMES.get(loop, "names", lambda: dict(
        coordinates=tuple(system.coordinates),
        state_names=tuple(model.state_names[i] for i in loop.state_index), input_names=tuple(system.inputs)))


def _diagnostics(model, loop, run, out, extra) -> Diagnostics:
    d = dict(extra)
    d["integrated_states"] = _names(model, loop)["state_names"]
    d["state_count"] = (len(loop.state_index), loop.n_x)
    blocks = out["diagnostic"]
    if blocks.size("measure"):
        d["min_singular_measure"] = OnRead(min_measure, blocks, "measure")
    d["max_cond_metric"] = OnRead(max_condition, blocks, "metric")
    if model.has_constraint_gram and blocks.size("gram"):
        d["max_cond_gram"] = OnRead(max_condition, blocks, "gram")
    if run.status == SINGULAR:
        d["t_event"] = run.t_fail
    if run.h_lambda:
        d["h_lambda_max"] = run.h_lambda
    if run.t_stiff is not None:
        d["stiff_at"] = run.t_stiff
        d["recommendation"] = (f"stiffness detected at t = {run.t_stiff:.6g} (h|λ| up to "
                               f"{run.h_lambda:.3g}): the explicit method's step is limited by "
                               "stability, not accuracy; use method='CVODES', 'Radau' or 'BDF' "
                               "(or method='auto', which switches by itself)")
    return Diagnostics(d)


def _named_outputs(call: _Call, prepared: _Prepared, loop, out, Y) -> dict:
    resolved, quantities, model = prepared.resolved, call.options.quantities, call.model
    if resolved is None:
        return {}
    from .closure import expand_outputs
    coords = list(model.system.coordinates)
    names_x = list(model.state_names)
    names = expand_outputs(model, resolved.names)
    quantity_values = None
    if quantities and any(name in quantities for name in names):   # every quantity in one evaluation
        from ..derivation.quantities import quantity_function
        N = out["q"].shape[0]
        f = quantity_function(model.system, quantities)
        quantity_values = np.asarray(f.map(N)(out["q"].T, out["qdot"].T,
                                              np.repeat(prepared.pv[:, None], N, 1)))
    result = {}
    for name in names:
        if name in names_x and names_x.index(name) in loop.state_index:
            result[name] = Y[:, loop.state_index.index(names_x.index(name))].copy()
        elif name in coords:
            result[name] = out["q"][:, coords.index(name)].copy()
        elif name.endswith("_dot") and name[:-4] in coords:
            result[name] = out["qdot"][:, coords.index(name[:-4])].copy()
        elif quantity_values is not None and name in quantities:
            result[name] = quantity_values[list(quantities).index(name)].copy()
    return result
