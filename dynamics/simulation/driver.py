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
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..derivation.formulation_protocol import protocol_of
from ..derivation.states import to_state
from ..errors import ModelError
from ..memo import OwnerMemo
from .closed_loop import closed_loop
from .compiled import CompilerUnavailable
from .failures import diagnose_failure
from .integrators import (FAILED, FINISHED, MAX_STEPS, NONFINITE, SCIPY_METHODS, SINGULAR, RunRequest,
                          Samples, integrate_scipy, left_of)
from .route_compiled import integrate_compiled
from .route_sundials import integrate_sundials
from .trajectory import Diagnostics, OnRead, Trajectory, max_condition, min_measure

__all__ = ["simulate", "Trajectory", "Diagnostics", "METHODS", "FINISHED", "FAILED", "MAX_STEPS", "NONFINITE",
           "SINGULAR", "SINGULAR_EVENT_TOL"]

COMPILED_METHODS = {"compiled": "DOP853", "compiled-DOPRI5": "DOPRI5"}
METHODS = tuple(SCIPY_METHODS) + ("CVODES",) + tuple(COMPILED_METHODS) + ("auto",)
DAE_FORMS = ("index1", "idas")
STABILIZATIONS = (None, "baumgarte", "projection")
#: default threshold of the singular-set event (the measure is 1 far from the set, 0 on it)
SINGULAR_EVENT_TOL = 1e-6
STATUS_NAMES = {FINISHED: "finished", FAILED: "failed", MAX_STEPS: "max_steps",
                NONFINITE: "non-finite", SINGULAR: "singular set"}


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Call:
    """One :func:`simulate` call as the user stated it (every argument, unchecked)."""

    model: object
    t_span: object
    q0: object
    qdot0: object
    controller: object
    params: object
    method: str
    rtol: float
    atol: float
    t_eval: object
    dae: str
    stabilization: str | None
    baumgarte: object
    max_step: float
    max_steps: int
    singular_tol: float | None
    outputs: object
    quantities: dict | None


def _check_request(call: _Call) -> list:
    """Every problem with the request, as a list of sentences."""
    problems = []
    try:
        t0, tf = (float(v) for v in call.t_span)
        if not (math.isfinite(t0) and math.isfinite(tf) and tf > t0):
            problems.append(f"t_span must be increasing and finite, got ({t0:g}, {tf:g})")
    except (TypeError, ValueError):
        problems.append(f"t_span must be a pair (t0, tf), got {call.t_span!r}")
        t0 = tf = None
    problems += _option_problems(call)
    if not (isinstance(call.max_steps, (int, np.integer)) and call.max_steps > 0):
        problems.append(f"max_steps must be a positive integer, got {call.max_steps!r}")
    if not (0 < call.rtol < 1 and 0 < call.atol < np.inf):   # rtol = inf allowed steps of any size: a hang
        problems.append(f"rtol must lie in (0, 1) and atol be positive and finite, got rtol={call.rtol!r}, "
                        f"atol={call.atol!r}")
    if call.singular_tol is not None and not (0 <= call.singular_tol < 1):
        problems.append(f"singular_tol must be in [0, 1) or None, got {call.singular_tol!r}")
    if call.t_eval is not None and t0 is not None:
        problems += _t_eval_problems(call.t_eval, t0, tf)
    if call.controller is not None:
        problems += _check_controller(call, t0, tf)
    return problems


def _option_problems(call: _Call) -> list:
    """The method, DAE form and stabilisation problems of the request."""
    method, dae, stabilization = call.method, call.dae, call.stabilization
    problems = []
    if method not in METHODS:
        problems.append(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    if dae not in DAE_FORMS:
        problems.append(f"unknown dae form {dae!r} (choose from {', '.join(DAE_FORMS)})")
    if stabilization not in STABILIZATIONS:
        problems.append(f"unknown stabilization {stabilization!r} (None, 'baumgarte' or 'projection')")
    problems += protocol_of(call.model).dae_option_problems(
        dae, stabilization, holonomic=bool(getattr(call.model, "system", None) and call.model.system.holonomic))
    if stabilization == "projection" and (dae == "idas" or method in ("CVODES", "auto")):
        problems.append("stabilization='projection' needs dae='index1' and a scipy or compiled "
                        "method (the state is projected after every step)")
    if stabilization == "baumgarte":
        try:
            alpha, beta = (float(v) for v in call.baumgarte)
            if not (alpha >= 0 and beta >= 0 and np.isfinite(alpha + beta)):
                problems.append(f"baumgarte = (alpha, beta) must be finite and ≥ 0, got {call.baumgarte!r}")
        except (TypeError, ValueError):
            problems.append(f"baumgarte must be a pair (alpha, beta), got {call.baumgarte!r}")
    return problems


def _t_eval_problems(t_eval, t0: float, tf: float) -> list:
    te = np.asarray(t_eval, dtype=float)
    span = max(abs(t0), abs(tf), 1.0) * 1e-12
    if te.ndim != 1 or te.size == 0:
        return ["t_eval must be a non-empty 1-D array"]
    if not np.all(np.isfinite(te)) or np.any(np.diff(te) <= 0):
        return ["t_eval must be finite and strictly increasing"]
    if te[0] < t0 - span or te[-1] > tf + span:
        return [f"t_eval must lie in t_span [{t0:g}, {tf:g}], got [{te[0]:g}, {te[-1]:g}]"]
    return []


def _check_controller(call: _Call, t0, tf) -> list:
    system, controller, dae, method = call.model.system, call.controller, call.dae, call.method
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
    if (dae == "idas" or method == "CVODES") and not symbolic:
        problems.append(f"{'dae=' + repr(dae) if dae == 'idas' else 'method=' + repr(method)} needs "
                        "a controller with a casadi(t, q, qdot) method (SUNDIALS evaluates u as a "
                        "CasADi expression of the state)")
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
    return list(zip(points[:-1], points[1:]))


# --------------------------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------------------------
def simulate(model, t_span, q0, qdot0, *, controller=None, params=None, method: str = "DOP853",
             rtol: float = 1e-8, atol: float = 1e-10, t_eval=None, dae: str = "index1",
             stabilization: str | None = None, baumgarte=(1.0, 0.0),
             max_step: float = np.inf, max_steps: int = 1_000_000,
             singular_tol: float | None = SINGULAR_EVENT_TOL, outputs=None,
             quantities: dict | None = None) -> Trajectory:
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
    params : dict or (n_params,) array, optional
        Parameter values overriding the system's defaults; checked like the defaults (finite,
        positive-definite kinetic metric).
    method : one of :data:`METHODS` (see the module docstring); ignored with ``dae="idas"``.
    rtol, atol : integrator tolerances (SUNDIALS: reltol, abstol).
    t_eval : (N,) output times in t_span, optional; None reports every accepted step (SUNDIALS:
        the interval ends).
    dae : {"index1", "idas"} — how a DAE form is integrated (see the module docstring).
    stabilization : {None, "baumgarte", "projection"} — constraint stabilisation of the DAE forms.
    baumgarte : (alpha, beta) — ġ + 2αg + β²∫g = 0 when ``stabilization="baumgarte"``.
    max_step : largest step of the scipy and compiled solvers.
    max_steps : cap on accepted steps (SUNDIALS: per output interval); reaching it ends the run
        with status −2.
    singular_tol : the run stops (status −4) where the singular-set measure falls below this;
        None disables the event.
    outputs : sequence of names, optional — integrate only what they depend on (:mod:`.closure`).
    quantities : mapping name → sympy expression of (q, q̇, parameters), optional — named
        quantities that ``outputs`` may refer to (a scene's ``[quantities]``).

    Returns
    -------
    Trajectory
    """
    call = _Call(model, t_span, q0, qdot0, controller, params, method, rtol, atol, t_eval, dae,
                 stabilization, baumgarte, max_step, max_steps, singular_tol, outputs, quantities)
    resolved = _checked_outputs(call)
    prepared, request = _prepare(call, resolved)
    route = "IDAS" if dae == "idas" and protocol_of(model).dae_options_apply else method
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
    resolved = None
    if call.outputs is not None and not problems:
        from .closure import resolve_outputs
        try:
            resolved = resolve_outputs(call.model, tuple(call.outputs), call.quantities)
        except ModelError as err:
            problems += list(err.problems)
    if not problems and call.params is not None:
        problems += _parameter_problems(call.model, call.params)
    if problems:
        raise ModelError(problems, title="invalid simulation request")
    return resolved


def _prepare(call: _Call, resolved) -> tuple:
    """(:class:`_Prepared`, :class:`RunRequest`): the initial state, the segments, the closed
    loop and the settings of a checked request."""
    model, controller = call.model, call.controller
    system, num = model.system, model.numeric
    pv = num.params(call.params)
    t0, tf = float(call.t_span[0]), float(call.t_span[1])
    x0 = to_state(model, call.q0, call.qdot0, call.params)
    named_params = dict(zip(num.param_names, pv.tolist()))
    segments = _segments(t0, tf, controller, system, named_params)
    if controller is not None:
        _check_first_input(call, t0)
    start = time.perf_counter()
    settings = _settings(call, (t0, tf), len(segments), named_params)
    seeds = None
    if resolved is not None:
        if call.dae == "idas" or call.stabilization == "projection":
            settings["outputs_note"] = "the dependency closure needs the ODE route; every state integrated"
        else:
            seeds = resolved.seeds
    loop = closed_loop(_integration_model(model, pv, settings), controller, stabilization=call.stabilization,
                       baumgarte=call.baumgarte, seeds=seeds)
    y0 = np.zeros(loop.n_y)              # (x_S, W = 0, ∫g = 0)
    y0[:len(loop.state_index)] = x0[list(loop.state_index)]
    seg_params = [loop.segment_params(pv, controller, a) for a, _ in segments]
    request = RunRequest(loop, controller, segments, y0, seg_params, call.t_eval, call.rtol, call.atol,
                         call.max_step, call.max_steps, call.singular_tol, call.stabilization, call.baumgarte)
    te = None if call.t_eval is None else np.asarray(call.t_eval, dtype=float)
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
    stabilization = call.stabilization
    return {"method": call.method, "dae": call.dae if protocol_of(call.model).dae_options_apply else None,
            "rtol": call.rtol, "atol": call.atol, "stabilization": stabilization,
            "baumgarte": tuple(float(v) for v in call.baumgarte) if stabilization == "baumgarte" else None,
            "max_step": call.max_step, "max_steps": call.max_steps, "t_span": t_span,
            "segments": n_segments, "params": named_params,
            "controller": None if call.controller is None else type(call.controller).__name__,
            "singular_tol": call.singular_tol, "outputs": None if call.outputs is None else tuple(call.outputs)}


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
    if not protocol_of(model).specialised_for_integration:
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
def _route_scipy(request: RunRequest, method: str, settings: dict) -> tuple:
    run = integrate_scipy(request, method, projection=request.stabilization == "projection")
    return run, method, {}


def _route_cvodes(request: RunRequest, method: str, settings: dict) -> tuple:
    return integrate_sundials(request, "cvodes"), "CVODES", {}


def _route_idas(request: RunRequest, method: str, settings: dict) -> tuple:
    t0 = request.segments[0][0]
    lam0 = _outputs(request.loop, request.controller, None, Samples.point(t0, t0, 0, request.y0),
                    request.seg_params)["lam"][0]
    return integrate_sundials(request, "idas", lam0), "IDAS", {}


def _route_compiled(request: RunRequest, method: str, settings: dict) -> tuple:
    """The compiled explicit Runge–Kutta route ("compiled", "compiled-DOPRI5"; "auto" stops on
    stiffness and switches to an implicit method); scipy DOP853 when no library can be built."""
    extra = {}
    scheme = COMPILED_METHODS.get(method, "DOP853")
    library, reason = _library(request.loop, request.python_inputs, request.stabilization == "projection")
    auto = method == "auto"
    if library is None:
        settings["fallback"] = f"{reason}; integrated with scipy DOP853"
        if "compiler" in reason:
            warnings.warn(f"method={method!r}: {settings['fallback']}", stacklevel=3)
        if not auto:
            return integrate_scipy(request, "DOP853", projection=request.stabilization == "projection"), "DOP853", extra
        run = integrate_scipy(request, "DOP853", stop_on_stiff=True)
        if run.message == "stiff":
            return _switch_to_implicit(request, run, settings, extra)
        return run, "DOP853", extra
    extra["library"] = library
    extra["compile_time_s"] = library.compile_time_s
    run = integrate_compiled(request, library, scheme, stop_on_stiff=auto)
    if auto and run.message == "stiff":
        extra.pop("library")
        return _switch_to_implicit(request, run, settings, extra)
    return run, f"compiled {scheme}", extra


#: route name → route(request, method, settings) → (Run, method name, extra diagnostics)
ROUTES = {**{name: _route_scipy for name in SCIPY_METHODS}, "CVODES": _route_cvodes, "IDAS": _route_idas,
          **{name: _route_compiled for name in COMPILED_METHODS}, "auto": _route_compiled}


def _switch_to_implicit(request: RunRequest, run, settings: dict, extra: dict) -> tuple:
    implicit = "Radau" if request.python_inputs else "CVODES"
    settings["auto"] = (f"DOP853 detected stiffness at t = {run.t_stiff:.6g} (h|λ| "
                        f"up to {run.h_lambda:.3g} for 15 steps: the step is set by stability) "
                        f"after {run.nfev} evaluations; redone with {implicit}")
    if implicit == "CVODES":
        new = integrate_sundials(request, "cvodes")
    else:
        new = integrate_scipy(request, "Radau")
    new.nfev += run.nfev
    new.t_stiff, new.h_lambda = run.t_stiff, run.h_lambda
    return new, implicit, extra


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
        out = dict(zip(_CHECKED_BLOCKS, library.blocks(table)), table=table)
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
    out = {k: np.asarray(v).T.reshape(N, -1) for k, v in zip(_BLOCKS, res)}
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
            self.blocks.update(zip(_BLOCKS[6:], self.library.diagnostic_outputs(*self.points)))
        return self.blocks[name]

    def size(self, name: str) -> int:
        """Entries per point of block ``name`` (without evaluating it)."""
        if self.library is not None:
            return self.library.diag_sizes[_BLOCKS[6:].index(name)]
        return self.blocks[name].shape[1]

    def rows(self, start: int, stop: int | None) -> "_DiagnosticBlocks":
        part = slice(start, stop)
        if self.library is not None and not self.blocks:
            t, t_c, Y, P, seg = self.points
            return _DiagnosticBlocks(self.library, (t[part], t_c[part], Y[part], P, seg[part]))
        return _DiagnosticBlocks(None, None, {k: self[k][part] for k in _BLOCKS[6:]})


def _first_nonfinite_row(out: dict) -> int | None:
    """First row after the initial one (counted from 0 after it) with a non-finite value in a
    column that is modelled (finite at the initial point)."""
    whole = out.get("table")                       # NaN and ±inf reach the sum
    if np.isfinite(whole.sum()) if whole is not None else all(np.isfinite(out[k].sum()) for k in _CHECKED_BLOCKS):
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


def _assemble(call: _Call, request: RunRequest, routed: tuple, prepared: _Prepared) -> Trajectory:
    """Outputs, diagnosis of a failure, diagnostics → :class:`Trajectory` (``routed``: what the
    route returned, (Run, method name, extra diagnostics))."""
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
                       f"below {request.event_tol:g} ({_singular_text(model)})"
                       + (f"; {run.message}" if run.message else ""))
    energy0 = float(out["energy"][0, 0])
    if prepared.with_initial:          # the points the outputs were evaluated at
        samples = points if samples.lam is None else points.with_lam(np.concatenate([out["lam"][:1], samples.lam]))
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
    if protocol_of(model).has_multipliers:
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
        coordinates=tuple(system.coordinates), state_names=tuple(model.state_names[i] for i in loop.state_index),
        input_names=tuple(system.inputs)))


def _singular_text(model) -> str:
    return protocol_of(model).singular_set_text(model)


def _diagnostics(model, loop, run, out, extra) -> Diagnostics:
    d = dict(extra)
    d["integrated_states"] = _names(model, loop)["state_names"]
    d["state_count"] = (len(loop.state_index), loop.n_x)
    blocks = out["diagnostic"]
    if blocks.size("measure"):
        d["min_singular_measure"] = OnRead(min_measure, blocks, "measure")
    d["max_cond_metric"] = OnRead(max_condition, blocks, "metric")
    if protocol_of(model).has_constraint_gram and blocks.size("gram"):
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
    resolved, quantities, model = prepared.resolved, call.quantities, call.model
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
        quantity_values = np.asarray(f.map(N)(out["q"].T, out["qdot"].T, np.repeat(prepared.pv[:, None], N, 1)))
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
