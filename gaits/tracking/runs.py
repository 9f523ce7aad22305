"""One sample of a tracking study: the plan re-simulated on the general model with the
parameters changed, open loop and with the plan's feedback (the worker side of :mod:`.study`).

A worker gets a :class:`TrackingCase` — the scene as data (:class:`~nhgait.gaits.sweeps.point.SceneData`),
the task table, the nominal and the robot's parameter values, the feedback as
``Feedback.to_dict()``, the noise and the seed — and sample indices; it derives and specialises
the model itself (both from the disk cache after the first time), builds the
:class:`~nhgait.dynamics.simulation.gain_schedule.GainSchedule` and answers with plain dicts
(:func:`run_samples`). Nothing live crosses a process boundary.

Sample i (``numpy.random.default_rng((seed, i))``):

* initial state z(0) = z_0 + δz, δz_i ~ N(0, (σ_z s_i)²) in the plan's own (velocity)
  coordinates (consistent with the model's nonholonomic constraints by construction), s_i the
  feedback's state scales; q(0) = z(0)[:n], q̇(0) = q̇(z(0)) of the plan's model, then made the
  robot's (:func:`robot_start`: on its kept holonomic constraints, in its constraint
  distribution);
* input noise u_k + δu_k, δu_{k,j} ~ N(0, (σ_u ū_j)²), constant on each plan interval, ū_j the
  feedback's input scales; the actuators clip the sum to the task's input bounds;
* the same noise for the open loop (gains zero) and the closed loop (the plan's gains), both
  ``simulate(general model, params=robot, method="compiled", rtol 1e-8, atol 1e-10)``.

Measured on the output grid (each plan interval cut in :data:`REFINE`): the state in the plan's
coordinates z(t) = σ(q, q̇) (the map with the *nominal* parameters: what the controller
computes) against the reference z_ref(t); the final position error ‖p(T) − p_ref(T)‖ of the
planar frame's point (without a planar frame: of the configuration); the time any input sits
at a bound.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from nhgait.dynamics.memo import LruMemo

__all__ = ["Noise", "TrackingCase", "run_samples", "schedule_of", "robot_start", "REFINE", "LOOPS"]

#: output points per plan interval
REFINE = 4
#: the two loops of every sample, in report order
LOOPS = ("open_loop", "closed_loop")


@dataclass(frozen=True)
class Noise:
    """Standard deviations of the sample noise, as fractions of the feedback's scales:
    ``state`` of each initial state (s_i, default 1 %), ``input`` of each input per plan
    interval (ū_j: the plan's peak input, default 5 %)."""

    state: float = 0.01
    input: float = 0.05

    def to_dict(self) -> dict:
        return {"state": self.state, "input": self.input,
                "meaning": "standard deviations as fractions of each state's scale s_i (initial state, "
                           "plan coordinates) and of each input's scale (the plan's peak |u_j|), the input "
                           "noise constant on each plan interval"}


@dataclass(kw_only=True, frozen=True, eq=False)
class TrackingCase:
    """What every sample shares, as picklable data (module docstring): ``robot`` the parameter
    values of the simulated robot, ``params`` the nominal ones the plan and its feedback use."""

    scene: object
    task: dict
    params: dict
    robot: dict
    feedback: dict
    noise: Noise = field(default_factory=Noise)
    seed: int = 0
    key: str = ""


@dataclass(frozen=True, eq=False)
class _Context:
    """What a worker builds once per case: the general model, the plan's model and the schedule."""

    model: object
    specialised: object
    schedule: object
    scales: tuple
    frame: tuple


#: this process's built contexts by case key (a cache, never a source of results)
CONTEXTS = LruMemo("tracking contexts of this worker by case", size=4)


def schedule_of(feedback, specialised, system):
    """The :class:`~nhgait.dynamics.simulation.gain_schedule.GainSchedule` of a
    :class:`~nhgait.ocp.feedback.Feedback` on the plan's (specialised) model: its state map
    (q, q̇) ↦ z with the nominal parameters bound."""
    import casadi as ca

    from nhgait.dynamics.simulation.gain_schedule import GainSchedule
    n = system.n
    q, qd = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    state = specialised.numeric["state"]
    state_map = ca.Function("state_map", [q, qd], [state(q, qd, np.zeros(state.size1_in(2)))])
    return GainSchedule(times=feedback.t, controls=feedback.controls.T, gains=feedback.gains,
                        reference=feedback.states.T, rates=feedback.rates, state_map=state_map,
                        lower=feedback.lower, upper=feedback.upper, inputs=tuple(system.inputs),
                        system_coordinates=tuple(system.coordinates))


def _context(case: TrackingCase) -> _Context:
    def build():
        from nhgait.ocp.feedback import Feedback

        from ..planner import prepare
        from ..sweeps.point import scene_of
        from ..tasks.sources import resolve
        prepared = prepare(resolve(scene_of(case.scene), case.task), params=case.params)
        feedback = Feedback.from_dict(case.feedback)
        system = prepared.model.system
        frame = tuple(system.planar_frame or ())[:2] or tuple(system.coordinates)
        return _Context(prepared.model, prepared.specialised,
                        schedule_of(feedback, prepared.specialised, system),
                        (feedback.weights.state_scale, feedback.weights.control_scale), frame)
    return CONTEXTS.get(case.key, build)


def run_samples(case: TrackingCase, indices) -> list:
    """The answers (:func:`run_sample`) of samples ``indices`` (in a worker process)."""
    ctx = _context(case)
    return [run_sample(ctx, case, int(i)) for i in indices]


def _noise(case: TrackingCase, ctx: _Context, index: int) -> tuple:
    """(δz (nz,), δu (N, m)) of sample ``index``; index −1 is the noise-free run."""
    sched = ctx.schedule
    nz, (N, m) = sched.n_states, sched.controls.shape
    if index < 0:
        return np.zeros(nz), np.zeros((N, m))
    rng = np.random.default_rng((int(case.seed), int(index)))
    s, ubar = ctx.scales
    return rng.normal(size=nz) * case.noise.state * s, rng.normal(size=(N, m)) * case.noise.input * ubar


def run_sample(ctx: _Context, case: TrackingCase, index: int) -> dict:
    """{"index", "open_loop": {...}, "closed_loop": {...}} of one sample (:func:`_measure`).
    A stop received while an earlier sample ran is raised here again, in case its exception was
    lost inside CasADi (:func:`~nhgait.dynamics.errors.raise_if_stopped`)."""
    from nhgait.dynamics import simulate
    from nhgait.dynamics.errors import raise_if_stopped
    raise_if_stopped()
    sched = ctx.schedule
    dz, du = _noise(case, ctx, index)
    z0 = sched.reference[0] + dz
    n = ctx.model.system.n
    qdot0 = np.asarray(ctx.specialised.numeric["qdot"](z0, []), dtype=float).ravel()
    q0, qdot0 = robot_start(ctx.model.system, z0[:n], qdot0, case.robot)
    grid = _grid(sched.times)
    robot = np.array([case.robot[name] for name in ctx.model.numeric.param_names], dtype=float)
    out = {"index": index}
    if index < 0:                          # the noise-free run also carries the reference's path
        pos = [list(ctx.model.system.coordinates).index(c) for c in ctx.frame]
        out["reference_position"] = [sched.reference_state(tt)[pos].tolist() for tt in grid]
        out["position_names"] = list(ctx.frame)
    for loop, law in zip(LOOPS, (sched.open_loop(), sched), strict=True):
        traj = simulate(ctx.model, (sched.times[0], sched.times[-1]), q0, qdot0,
                        controller=law.with_controls(sched.controls + du), params=robot, method="compiled",
                        t_eval=grid, rtol=1e-8, atol=1e-10)
        out[loop] = _measure(ctx, traj)
    return out


class RobotStart(NamedTuple):
    """What :func:`robot_start` returns."""

    q: np.ndarray      #: configuration on the robot's holonomic constraints
    qdot: np.ndarray   #: velocity on its constraints


def robot_start(system, q, qdot, robot: dict) -> RobotStart:
    """(q, q̇) a robot with the parameter values ``robot`` can start in, nearest the sample's:
    the dependent coordinates solved onto its kept holonomic constraints h(q) = 0
    (:func:`~nhgait.dynamics.derivation.holonomic.consistent_configuration`; noise in the plan's
    coordinates moves every coordinate), then q̇ moved by the least change (Euclidean) onto
    {ω(q) q̇ = 0} of the robot, q̇ − W⁺W q̇ with W = ω(q) (the velocity rows of the holonomic
    constraints included) — which changes nothing unless a mismatched parameter enters the
    constraints (a wheel's radius) or the configuration moved."""
    from nhgait.dynamics.derivation.holonomic import consistent_configuration
    if system.holonomic:
        q = consistent_configuration(system, q, params=robot)
    if system.k:
        omega = system.numeric_functions().omega
        W = np.array(omega(q, system.param_vector(robot)), dtype=float).reshape(system.k, system.n)
        qdot = qdot - np.linalg.pinv(W) @ (W @ qdot)
    return RobotStart(q, qdot)


def _grid(times) -> np.ndarray:
    s = np.linspace(0.0, 1.0, REFINE + 1)[:-1]
    inner = (times[:-1, None] + np.diff(times)[:, None] * s[None, :]).ravel()
    return np.r_[inner, times[-1]]


def _measure(ctx: _Context, traj) -> dict:
    """The errors of one run against the reference (module docstring)."""
    sched = ctx.schedule
    t = traj.t
    names = list(ctx.model.system.coordinates)
    pos = [names.index(c) for c in ctx.frame]
    z = np.array([np.asarray(sched.state_map(q, qd), dtype=float).ravel()
                  for q, qd in zip(traj.q, traj.qdot, strict=True)])
    ref = np.array([sched.reference_state(tt) for tt in t])
    err = z - ref if len(t) else np.zeros((0, sched.n_states))
    complete = (bool(traj.success) and len(t)
                and abs(t[-1] - sched.times[-1]) <= 1e-9 * max(1.0, sched.times[-1]))
    final = float(np.linalg.norm(traj.q[-1, pos] - sched.reference[-1, pos])) if complete else float("nan")
    return {"success": bool(traj.success), "status": int(traj.status), "message": str(traj.message),
            "final_position_error": final,
            "state_rms": _rms(t, err).tolist(), "state_max": np.abs(err).max(axis=0, initial=0.0).tolist(),
            "saturation_time_s": _saturation_time(t, traj.u, sched.lower, sched.upper),
            "t": t.tolist(), "position": traj.q[:, pos].tolist(),
            "position_error": np.linalg.norm(traj.q[:, pos] - ref[:, pos] if len(t) else np.zeros((0, 2)),
                                             axis=1).tolist(),
            "coordinate_errors": err[:, :len(names)].tolist()}


def _rms(t, err) -> np.ndarray:
    """√(1/T ∫ e² dt) per state (trapezoid rule)."""
    if len(t) < 2:
        return np.full(err.shape[1], np.nan)
    squares = err ** 2
    integral = np.sum(np.diff(t)[:, None] * (squares[1:] + squares[:-1]) / 2, axis=0)
    return np.sqrt(integral / (t[-1] - t[0]))


def _saturation_time(t, u, lower, upper) -> float:
    """Seconds during which some input sits at a bound (left-point rule on the output grid); an
    input the task fixes (lower = upper: the bicycle's lean torque) is never counted."""
    if len(t) < 2:
        return 0.0
    tol = 1e-9 * np.maximum(1.0, np.abs(np.where(np.isfinite(upper), upper, 0.0)))
    at = np.zeros(u.shape[0], dtype=bool)
    for j in range(u.shape[1]):
        if lower[j] == upper[j]:
            continue
        for bound in (lower[j], upper[j]):
            if np.isfinite(bound):
                at |= np.abs(u[:, j] - bound) <= tol[j]
    return float(np.sum(np.diff(t) * at[:-1]))
