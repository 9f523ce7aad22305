#!/usr/bin/env python3
"""Hand-written CasADi reference implementation of three nonholonomic OCP benchmarks.

This file is the *baseline* against which the automatic ``nhgait`` planner is
compared (same objective values, timing ratio).  It deliberately uses nothing
from ``nhgait``: the models are written out explicitly below.

Models (explicit ODEs)
----------------------
**Unicycle** (rolling disk; m = 0.5, r = 0.1, J_phi = 0.2, J_theta = 0.3)

    state   X = (x, y, theta, phi, thetadot, phidot)      controls U = (tau_theta, tau_phi)

    xdot        = r cos(theta) phidot
    ydot        = r sin(theta) phidot
    thetaddot   = tau_theta / J_theta
    phiddot     = tau_phi / (J_phi + m r^2)

**Snakeboard** (m = 0.5, J = 0.3, J_r = 0.2, J_w = 0.1, r = sqrt((J + J_r + 2 J_w)/m),
i.e. m r^2 = J + J_r + 2 J_w)

    configuration q = (x, y, theta, psi, phi); Lagrangian
        L = 1/2 m (xdot^2 + ydot^2) + 1/2 m r^2 thetadot^2 + J_r psidot thetadot
            + 1/2 J_r psidot^2 + J_w phidot^2
    constraints (back wheel at -r steered by -phi, front wheel at +r steered by +phi)
        -sin(theta - phi) xdot + cos(theta - phi) ydot - r cos(phi) thetadot = 0
        -sin(theta + phi) xdot + cos(theta + phi) ydot + r cos(phi) thetadot = 0
    <=> lateral body velocity = 0 and thetadot = tan(phi) v / r, with the forward
        body velocity v = xdot cos(theta) + ydot sin(theta).

    Reduced (Hamel / Lagrange-d'Alembert) model with the velocity basis
    qdot = X(q) (v, psidot, phidot),  X = [(cos th, sin th, tan phi / r, 0, 0), e_psi, e_phi]:

    state   X = (x, y, theta, psi, phi, v, psidot, phidot)  controls U = (tau_psi, tau_phi)

    xdot      = v cos(theta)
    ydot      = v sin(theta)
    thetadot  = v tan(phi) / r
    D         = m r^2 - J_r sin^2(phi)            ( = J + 2 J_w + J_r cos^2(phi) )
    vdot      = -[ (m r^2 - J_r) tan(phi) phidot v + r sin(phi) cos(phi) tau_psi ] / D
    psiddot   =  m r [ r tau_psi - J_r phidot v ] / (J_r D)
    phiddot   = tau_phi / (2 J_w)

    ``check_models()`` (``--check``) verifies both reduced ODEs against an
    independent index-reduced Lagrange-multiplier DAE integration (scipy, rtol 1e-11).

Transcription
-------------
Direct multiple shooting, N intervals on a fixed horizon T, piecewise-constant
controls, one RK4 integrator Function (built from SX, explicit ODE) doing M = 4
sub-steps per interval (h = T/(N M)), applied to all intervals via
``Function.map(N)``.  Objective  J = sum_k (T/N) u_k . u_k  (the exact integral
of |u|^2 for piecewise-constant u).  Ipopt, exact Hessian, ``expand=True``,
optional JIT (``--jit``: ``jit=True, compiler='shell', jit_options={'flags': ['-O1']}``).

Default formulation: plain ``nlpsol`` with one flat decision vector, stacked
interval-wise  w = (x_0, u_0, x_1, u_1, ..., x_{N-1}, u_{N-1}, x_N)  (banded KKT
for MUMPS), boundary conditions / box constraints expressed as variable bounds
and only the shooting-gap and periodicity conditions as g.  ``formulation='opti'``
builds the same NLP with ``casadi.Opti`` (variables declared in the same order,
``detect_simple_bounds=True``).

Measured on the 2-core dev machine (median of repeated solves, CasADi 3.8.2, MUMPS):
* nlpsol and Opti need the same iterations and give identical objectives; nlpsol is
  equal or a few % faster per solve (e.g. P3/N=200 no-JIT 230 vs 246 ms, JIT 77 vs
  83 ms) and Opti's JIT build is much slower (P3/N=200: ~20 s vs 4.7 s), so nlpsol is
  the default (``--formulation opti`` to compare).
* without JIT, ``expand=True`` (SX VM) beats the un-expanded MX/map graph
  (P2/N=100: 72 ms vs 142 ms serial map, 82 ms thread map).
* with JIT the NLP is *not* expanded: the MX graph keeps F.map(N) as a loop over
  one compiled RK4 kernel (gcc ~1-5 s); JIT-compiling the expanded SX NLP took
  475 s at P2/N=100 and was not faster.  'serial' map beats 'thread' (2 cores).

Problems (J = int_0^T u1^2 + u2^2 dt)
-------------------------------------
P1 unicycle parallel parking: T = 4, X(0) = 0, x(T) = 0, y(T) = 0.5, theta(T) = 0,
   thetadot(T) = phidot(T) = 0, phi(T) free, |tau| <= 5.
P2 snakeboard forward: T = 2 pi, x(0) = y(0) = theta(0) = psi(0) = 0, v(0) = 0;
   x(T) = 1, theta(T) = 0, y(T) free; (psi, phi, v, psidot, phidot) periodic
   (value at T = value at 0); |phi| <= 1 at every shooting node; |tau| <= 10.
P3 snakeboard rotation: as P2 but x(T) = y(T) = 0, theta(T) = pi/2.

This interpretation reproduces the reference objectives (REFERENCE, N = 25..200) to
<= 2e-6 relative: v is the forward *body* velocity (a state), the periodic set
includes v (so v(T) = v(0) = 0), psi(T) = psi(0) = 0, and |phi| <= 1 is imposed on
the N+1 shooting nodes only.  The phi bound is inactive for P2 (max |phi| = 0.76)
and active for P3 (phi(0) = phi(T) = 1); dropping it changes P3 completely, and
leaving v(T) free gives P2/P3 = 0.0588/1.7485 at N = 50 instead.

Usage:  python experiments/reference_casadi_ocp.py [--problems P1,P2,P3]
            [--N 25,50,100,200] [--jit] [--repeats 5] [--check]
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import math
import os
import statistics
import sys
import tempfile
import time

import casadi as ca
import numpy as np

# ----------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------
UNI = dict(m=0.5, r=0.1, J_phi=0.2, J_theta=0.3)
_SB_m, _SB_J, _SB_Jr, _SB_Jw = 0.5, 0.3, 0.2, 0.1
SB = dict(m=_SB_m, J=_SB_J, J_r=_SB_Jr, J_w=_SB_Jw,
          r=math.sqrt((_SB_J + _SB_Jr + 2 * _SB_Jw) / _SB_m))

# Reference objective values of this exact transcription (M = 4).
REFERENCE = {
    "P1": {25: 1.543703, 50: 1.536285, 100: 1.534441, 200: 1.533981},
    "P2": {25: 0.110252, 50: 0.109813, 100: 0.109703, 200: 0.109676},
    "P3": {25: 2.162582, 50: 2.110183, 100: 2.097288, 200: 2.094085},
}


# ----------------------------------------------------------------------------
# Models
# ----------------------------------------------------------------------------
def unicycle_rhs(X, U, p=UNI):
    """Explicit unicycle ODE; X = (x, y, theta, phi, thetadot, phidot)."""
    m, r, J_phi, J_theta = p["m"], p["r"], p["J_phi"], p["J_theta"]
    theta, thetadot, phidot = X[2], X[4], X[5]
    return ca.vertcat(
        r * ca.cos(theta) * phidot,
        r * ca.sin(theta) * phidot,
        thetadot,
        phidot,
        U[0] / J_theta,
        U[1] / (J_phi + m * r**2),
    )


def snakeboard_rhs(X, U, p=SB):
    """Explicit reduced snakeboard ODE; X = (x, y, theta, psi, phi, v, psidot, phidot)."""
    m, J_r, J_w, r = p["m"], p["J_r"], p["J_w"], p["r"]
    theta, phi, v, psidot, phidot = X[2], X[4], X[5], X[6], X[7]
    tau_psi, tau_phi = U[0], U[1]
    mr2 = m * r**2
    s, c = ca.sin(phi), ca.cos(phi)
    tan_phi = s / c
    D = mr2 - J_r * s**2
    vdot = -((mr2 - J_r) * tan_phi * phidot * v + r * s * c * tau_psi) / D
    psiddot = m * r * (r * tau_psi - J_r * phidot * v) / (J_r * D)
    phiddot = tau_phi / (2 * J_w)
    return ca.vertcat(
        v * ca.cos(theta),
        v * ca.sin(theta),
        v * tan_phi / r,
        psidot,
        phidot,
        vdot,
        psiddot,
        phiddot,
    )


MODELS = {  # name -> (rhs, nx, nu)
    "unicycle": (unicycle_rhs, 6, 2),
    "snakeboard": (snakeboard_rhs, 8, 2),
}


@functools.cache
def ode_function(model: str) -> ca.Function:
    rhs, nx, nu = MODELS[model]
    X, U = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    return ca.Function("f_" + model, [X, U], [rhs(X, U)], ["x", "u"], ["xdot"])


@functools.cache
def rk4_function(model: str, dt: float, M: int) -> ca.Function:
    """One shooting interval: M explicit RK4 steps of size dt/M (SX, ODE inlined)."""
    rhs, nx, nu = MODELS[model]
    X0, U = ca.SX.sym("x0", nx), ca.SX.sym("u", nu)
    h = dt / M
    X = X0
    for _ in range(M):
        k1 = rhs(X, U)
        k2 = rhs(X + h / 2 * k1, U)
        k3 = rhs(X + h / 2 * k2, U)
        k4 = rhs(X + h * k3, U)
        X = X + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("F_" + model, [X0, U], [X], ["x0", "u"], ["xf"])


# ----------------------------------------------------------------------------
# Problem definitions
# ----------------------------------------------------------------------------
INF = np.inf


def problem_spec(problem: str) -> dict:
    """Horizon, bounds on x_0 / x_N / path nodes, periodic indices, control bound."""
    if problem == "P1":
        nx = 6
        x0 = np.zeros(nx)
        xN_lb = np.array([0.0, 0.5, 0.0, -INF, 0.0, 0.0])   # phi(T) free
        xN_ub = np.array([0.0, 0.5, 0.0, INF, 0.0, 0.0])
        return dict(model="unicycle", T=4.0, nx=nx, nu=2, umax=5.0,
                    x0_lb=x0, x0_ub=x0, xN_lb=xN_lb, xN_ub=xN_ub,
                    path_lb=np.full(nx, -INF), path_ub=np.full(nx, INF), periodic=[])
    if problem in ("P2", "P3"):
        nx = 8
        # start: x = y = theta = psi = 0, v = 0; phi, psidot, phidot free (tied by periodicity)
        x0_lb = np.array([0, 0, 0, 0, -1.0, 0, -INF, -INF])
        x0_ub = np.array([0, 0, 0, 0, 1.0, 0, INF, INF])
        if problem == "P2":
            end = (1.0, None, 0.0)            # x, y (free), theta
        else:
            end = (0.0, 0.0, math.pi / 2)
        xN_lb = np.array([-INF] * nx)
        xN_ub = np.array([INF] * nx)
        for i, val in enumerate(end):
            if val is not None:
                xN_lb[i] = xN_ub[i] = val
        # periodic psi, phi, v, psidot, phidot  =>  psi(T) = psi(0) = 0, v(T) = v(0) = 0
        xN_lb[3] = xN_ub[3] = 0.0
        xN_lb[5] = xN_ub[5] = 0.0
        xN_lb[4], xN_ub[4] = -1.0, 1.0
        path_lb = np.full(nx, -INF)
        path_ub = np.full(nx, INF)
        path_lb[4], path_ub[4] = -1.0, 1.0    # |phi| <= 1 at every node
        return dict(model="snakeboard", T=2 * math.pi, nx=nx, nu=2, umax=10.0,
                    x0_lb=x0_lb, x0_ub=x0_ub, xN_lb=xN_lb, xN_ub=xN_ub,
                    path_lb=path_lb, path_ub=path_ub,
                    periodic=[4, 6, 7])   # remaining periodic states not fixed by bounds
    raise ValueError(f"unknown problem {problem!r}")


# Shape-guess amplitudes (see initial_guess); found by a small scan, robust for N = 25..200.
GUESS = {
    "P1": dict(theta_amp=0.3),                     # theta = 0.3 sin(2 pi t / T)
    "P2": dict(psi_amp=1.0, phi_amp=0.6, ratio=1),  # drive gait, rotor:wheel = 1:1
    "P3": dict(psi_amp=1.0, phi_amp=0.9, ratio=2),  # rotate gait, rotor:wheel = 2:1
}


def initial_guess(problem: str, N: int) -> tuple[np.ndarray, np.ndarray]:
    """Deterministic shape guesses: X0 of shape (nx, N+1), U0 = 0 of shape (nu, N).

    A zero guess fails for both models (at rest the linearisation cannot move the
    body: Ipopt reports local infeasibility), so:

    * P1: y ramps linearly 0 -> 0.5, theta = 0.3 sin(2 pi t/T), all else 0.
    * P2/P3 (w = 2 pi / T): psi = A sin(k w t), psidot = A k w cos(k w t),
      phi = B sin(w t + pi/2) = B cos(w t), phidot = -B w sin(w t), with
      (A, B, k) = (1, 0.6, 1) for P2 (drive) and (1, 0.9, 2) for P3 (rotate);
      P2 additionally ramps x linearly 0 -> 1.  x, y, theta (P3) and v are 0.
    """
    spec = problem_spec(problem)
    T, nx, nu = spec["T"], spec["nx"], spec["nu"]
    t = np.linspace(0.0, T, N + 1)
    w = 2 * math.pi / T
    X0 = np.zeros((nx, N + 1))
    U0 = np.zeros((nu, N))
    g = GUESS[problem]
    if problem == "P1":
        X0[1] = 0.5 * t / T
        X0[2] = g["theta_amp"] * np.sin(w * t)
        return X0, U0
    A, B, k = g["psi_amp"], g["phi_amp"], g["ratio"]
    X0[3] = A * np.sin(k * w * t)
    X0[6] = A * k * w * np.cos(k * w * t)
    X0[4] = B * np.sin(w * t + math.pi / 2)
    X0[7] = B * w * np.cos(w * t + math.pi / 2)
    if problem == "P2":
        X0[0] = 1.0 * t / T
    return X0, U0


# ----------------------------------------------------------------------------
# NLP construction
# ----------------------------------------------------------------------------
def _ipopt_opts(jit: bool, expand: bool = True) -> dict:
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "record_time": True,
            "ipopt.hessian_approximation": "exact", "expand": expand}
    if jit:
        # CasADi writes jit_tmp*.c / tmp_casadi_compiler_shell*.so into the working directory
        # and may leave them at exit: the solvers are built inside _scratch_cwd().
        opts.update({"jit": True, "compiler": "shell", "jit_cleanup": False,
                     "jit_options": {"flags": ["-O1"], "cleanup": False}})
    return opts


@contextlib.contextmanager
def _scratch_cwd():
    """Run inside a temporary working directory (CasADi's shell compiler writes its jit_tmp*
    files there; the compiled library is loaded before the directory is removed)."""
    old = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="nhgait-reference-jit-") as tmp:
        os.chdir(tmp)
        try:
            yield
        finally:
            os.chdir(old)


def _map(step: ca.Function, N: int, mode: str) -> ca.Function:
    """step.map(N) evaluated 'serial' (loop) or 'thread' (one thread per core)."""
    if mode == "thread":
        return step.map(N, "thread", os.cpu_count() or 1)
    return step.map(N, mode)


def _shooting(problem, N, M, map_mode):
    """The problem's spec and its RK4 step (``M`` sub-steps over T/N) mapped over the N
    intervals."""
    spec = problem_spec(problem)
    return spec, _map(rk4_function(spec["model"], spec["T"] / N, M), N, map_mode)


class _ShootingOCP:
    """Multiple shooting of one problem with N intervals: the sizes and the RK4 step mapped
    over the intervals are set up here; a formulation states the NLP (``_formulate``) and may
    book a warm-up solve's non-Ipopt time as setup time (``_warm_up``)."""

    def __init__(self, problem, N, M, jit, map_mode="serial", expand=True):
        t0 = time.perf_counter()
        spec, step_map = _shooting(problem, N, M, map_mode)
        self.nx, self.nu, self.N = spec["nx"], spec["nu"], N
        self._formulate(spec, step_map, jit, expand)
        build = time.perf_counter() - t0
        self.setup_time = build + self._warm_up(problem)

    def _warm_up(self, problem) -> float:
        return 0.0


class _NlpsolOCP(_ShootingOCP):
    """Flat-vector nlpsol multiple-shooting formulation."""

    def _formulate(self, spec, step_map, jit, expand):
        nx, nu, N, T = self.nx, self.nu, self.N, spec["T"]
        # decision vector, interval-stacked: V[:, k] = (x_k, u_k), plus x_N
        V = ca.MX.sym("V", nx + nu, N)
        XN = ca.MX.sym("XN", nx)
        w = ca.vertcat(ca.vec(V), XN)
        Xs, Us = V[:nx, :], V[nx:, :]
        Xnext = ca.horzcat(Xs[:, 1:], XN)
        gaps = step_map(Xs, Us) - Xnext
        g = [ca.vec(gaps)]
        for i in spec["periodic"]:
            g.append(XN[i] - Xs[i, 0])
        g = ca.vertcat(*g)
        J = (T / N) * ca.sumsqr(Us)
        with _scratch_cwd():
            self.solver = ca.nlpsol("ocp", "ipopt", {"x": w, "f": J, "g": g}, _ipopt_opts(jit, expand))
        self.lbg = np.zeros(g.shape[0])
        self.ubg = np.zeros(g.shape[0])
        # variable bounds
        lbV = np.empty((nx + nu, N))
        ubV = np.empty((nx + nu, N))
        lbV[:nx, :] = spec["path_lb"][:, None]
        ubV[:nx, :] = spec["path_ub"][:, None]
        lbV[:nx, 0], ubV[:nx, 0] = spec["x0_lb"], spec["x0_ub"]
        lbV[nx:, :], ubV[nx:, :] = -spec["umax"], spec["umax"]
        self.lbx = np.concatenate([lbV.ravel(order="F"), np.maximum(spec["xN_lb"], spec["path_lb"])])
        self.ubx = np.concatenate([ubV.ravel(order="F"), np.minimum(spec["xN_ub"], spec["path_ub"])])

    def solve(self, X0, U0):
        nx, nu, N = self.nx, self.nu, self.N
        w0 = np.concatenate([np.vstack([X0[:, :N], U0]).ravel(order="F"), X0[:, N]])
        t0 = time.perf_counter()
        sol = self.solver(x0=w0, lbx=self.lbx, ubx=self.ubx, lbg=self.lbg, ubg=self.ubg)
        wall = time.perf_counter() - t0
        st = self.solver.stats()
        w = np.asarray(sol["x"]).ravel()
        V = w[: (nx + nu) * N].reshape((nx + nu, N), order="F")
        X = np.hstack([V[:nx], w[(nx + nu) * N:, None]])
        return dict(objective=float(sol["f"]), iterations=int(st["iter_count"]),
                    solve_time_s=wall, ipopt_time_s=float(st["t_wall_total"]),
                    success=bool(st["success"]), status=st["return_status"], X=X, U=V[nx:])


class _OptiOCP(_ShootingOCP):
    """Same NLP with casadi.Opti (simple bounds detected and moved to lbx/ubx)."""

    def _formulate(self, spec, step_map, jit, expand):
        nx, nu, N, T = self.nx, self.nu, self.N, spec["T"]
        opti = ca.Opti()
        # declare interval-wise (x_0, u_0, x_1, ...) so the variable order matches _NlpsolOCP
        xs, us = [], []
        for _ in range(N):
            xs.append(opti.variable(nx))
            us.append(opti.variable(nu))
        xs.append(opti.variable(nx))
        Xv, Uv = ca.horzcat(*xs), ca.horzcat(*us)
        opti.minimize((T / N) * ca.sumsqr(Uv))
        opti.subject_to(step_map(Xv[:, :N], Uv) == Xv[:, 1:])
        for i in spec["periodic"]:
            opti.subject_to(Xv[i, N] == Xv[i, 0])

        def box(expr, lb, ub):
            for j in range(len(lb)):
                if lb[j] == ub[j]:
                    opti.subject_to(expr[j] == lb[j])
                elif np.isfinite(lb[j]) or np.isfinite(ub[j]):
                    opti.subject_to(opti.bounded(lb[j], expr[j], ub[j]))

        box(Xv[:, 0], spec["x0_lb"], spec["x0_ub"])
        box(Xv[:, N], np.maximum(spec["xN_lb"], spec["path_lb"]), np.minimum(spec["xN_ub"], spec["path_ub"]))
        for j in range(nx):
            if np.isfinite(spec["path_lb"][j]):
                opti.subject_to(opti.bounded(spec["path_lb"][j], Xv[j, 1:N], spec["path_ub"][j]))
        opti.subject_to(opti.bounded(-spec["umax"], Uv, spec["umax"]))
        opts = _ipopt_opts(jit, expand)
        opts["detect_simple_bounds"] = True
        opti.solver("ipopt", opts)
        self.opti, self.Xv, self.Uv = opti, Xv, Uv

    def _warm_up(self, problem) -> float:
        """Opti constructs nlpsol (expand / JIT) lazily inside the first solve(): one warm-up
        solve, whose non-Ipopt part is setup time."""
        with _scratch_cwd():
            warm = self.solve(*initial_guess(problem, self.N))
        return warm["solve_time_s"] - warm["ipopt_time_s"]

    def solve(self, X0, U0):
        opti = self.opti
        opti.set_initial(self.Xv, X0)
        opti.set_initial(self.Uv, U0)
        t0 = time.perf_counter()
        try:
            sol = opti.solve()
            ok = True
        except RuntimeError:
            sol = opti.debug
            ok = False
        wall = time.perf_counter() - t0
        st = sol.stats()
        return dict(objective=float(sol.value(opti.f)), iterations=int(st["iter_count"]),
                    solve_time_s=wall, ipopt_time_s=float(st["t_wall_total"]),
                    success=ok and bool(st["success"]), status=st["return_status"],
                    X=np.asarray(sol.value(self.Xv)).reshape(self.nx, -1),
                    U=np.asarray(sol.value(self.Uv)).reshape(self.nu, -1))


_FORMULATIONS = {"nlpsol": _NlpsolOCP, "opti": _OptiOCP}


@dataclasses.dataclass(frozen=True)
class _Build:
    """One configuration of the NLP (see :func:`solve`); the key of the built solvers."""

    problem: str
    N: int
    M: int
    jit: bool
    formulation: str
    map_mode: str
    expand: bool


@functools.cache
def _build(build: _Build):
    return _FORMULATIONS[build.formulation](build.problem, build.N, build.M, build.jit, build.map_mode,
                                            build.expand)


def solve(problem: str, N: int, *, jit: bool = False, M: int = 4,
          formulation: str = "nlpsol", map_mode: str = "serial", expand: bool | None = None) -> dict:
    """Solve benchmark ``problem`` ('P1' | 'P2' | 'P3') with N shooting intervals.

    The NLP (and its JIT-compiled code) is built once per configuration and cached;
    ``setup_time_s`` is the construction time of that cached instance.

    ``expand`` defaults to ``not jit``: without JIT the fully expanded SX NLP is the
    fastest to evaluate; with JIT the MX graph (which keeps ``F.map(N)`` as a loop over
    one compiled RK4 kernel) is compiled instead -- JIT-compiling the expanded SX NLP
    takes gcc minutes at N = 100 (measured: 475 s for P2) for no runtime gain.
    """
    if expand is None:
        expand = not jit
    ocp = _build(_Build(problem, N, M, jit, formulation, map_mode, expand))
    X0, U0 = initial_guess(problem, N)
    res = ocp.solve(X0, U0)
    res.update(problem=problem, N=N, setup_time_s=ocp.setup_time)
    return res


# ----------------------------------------------------------------------------
# Model check: reduced ODEs vs. index-reduced Lagrange-multiplier DAE
# ----------------------------------------------------------------------------
def _dae_unicycle(t, z, ctrl):
    """Lagrange DAE, q = (x, y, theta, phi), index-reduced (acceleration-level constraints)."""
    m, r, J_phi, J_theta = UNI["m"], UNI["r"], UNI["J_phi"], UNI["J_theta"]
    q, qd = z[:4], z[4:]
    th, thd = q[2], qd[2]
    Mq = np.diag([m, m, J_theta, J_phi])
    A = np.array([[1.0, 0.0, 0.0, -r * np.cos(th)],
                  [0.0, 1.0, 0.0, -r * np.sin(th)]])
    Adot_qd = np.array([r * np.sin(th) * thd * qd[3], -r * np.cos(th) * thd * qd[3]])
    tau = np.array([0.0, 0.0, *ctrl(t, q, qd)])
    return _kkt_accel(Mq, A, Adot_qd, tau, qd)


def _dae_snakeboard(t, z, ctrl):
    """Lagrange DAE, q = (x, y, theta, psi, phi), index-reduced."""
    m, J_r, J_w, r = SB["m"], SB["J_r"], SB["J_w"], SB["r"]
    q, qd = z[:5], z[5:]
    th, ph = q[2], q[4]
    thd, phd = qd[2], qd[4]
    Mq = np.array([[m, 0, 0, 0, 0],
                   [0, m, 0, 0, 0],
                   [0, 0, m * r**2, J_r, 0],
                   [0, 0, J_r, J_r, 0],
                   [0, 0, 0, 0, 2 * J_w]], dtype=float)
    a, b = th - ph, th + ph
    A = np.array([[-np.sin(a), np.cos(a), -r * np.cos(ph), 0, 0],
                  [-np.sin(b), np.cos(b), r * np.cos(ph), 0, 0]])
    Adot = np.array([[-np.cos(a) * (thd - phd), -np.sin(a) * (thd - phd), r * np.sin(ph) * phd, 0, 0],
                     [-np.cos(b) * (thd + phd), -np.sin(b) * (thd + phd), -r * np.sin(ph) * phd, 0, 0]])
    tau = np.array([0.0, 0.0, 0.0, *ctrl(t, q, qd)])
    return _kkt_accel(Mq, A, Adot @ qd, tau, qd)


def _kkt_accel(Mq, A, Adot_qd, tau, qd):
    """Solve  M qdd = tau + A^T lam,  A qdd = -Adot qd  (dL/dq = 0 for both models)."""
    n, c = Mq.shape[0], A.shape[0]
    K = np.zeros((n + c, n + c))
    K[:n, :n], K[:n, n:], K[n:, :n] = Mq, -A.T, A
    sol = np.linalg.solve(K, np.concatenate([tau, -Adot_qd]))
    return np.concatenate([qd, sol[:n]])


#: the integrator settings of the model check
_CHECK_IVP = dict(method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True)


def _check_unicycle(t_end, tol, verbose) -> bool:
    """The unicycle's reduced ODE against its multiplier DAE (see :func:`check_models`)."""
    from scipy.integrate import solve_ivp

    def pd_uni(t, q, qd):      # q = (x, y, theta, phi)
        return (2.0 * (0.8 * np.sin(1.3 * t) - q[2]) - 0.5 * qd[2],
                1.5 * (2.0 * np.sin(0.7 * t) - q[3]) - 0.3 * qd[3])

    rhs = ode_function("unicycle")
    r = UNI["r"]
    Xi = np.array([0.1, -0.2, 0.3, 0.0, 0.4, 1.5])   # (x, y, theta, phi, thetadot, phidot)

    def uni_qd(X):
        return np.array([r * np.cos(X[2]) * X[5], r * np.sin(X[2]) * X[5], X[4], X[5]])

    ts = np.linspace(0.0, t_end, 61)
    ode = solve_ivp(lambda t, X: np.asarray(rhs(X, pd_uni(t, X[:4], uni_qd(X)))).ravel(),
                    (0, t_end), Xi, **_CHECK_IVP)
    qd0 = uni_qd(Xi)
    dae = solve_ivp(_dae_unicycle, (0, t_end), np.concatenate([Xi[:4], qd0]), args=(pd_uni,), **_CHECK_IVP)
    Zo, Zd = ode.sol(ts), dae.sol(ts)
    err = np.max(np.abs(Zo - Zd[[0, 1, 2, 3, 6, 7]]))
    if verbose:
        print(f"unicycle   ODE vs DAE: max |dX| = {err:.2e}  ({'ok' if err < tol else 'FAIL'})")
    return err < tol


def _check_snakeboard(t_end, tol, verbose) -> bool:
    """The snakeboard's reduced ODE against its multiplier DAE (see :func:`check_models`)."""
    from scipy.integrate import solve_ivp

    def pd_sb(t, q, qd):       # q = (x, y, theta, psi, phi)
        return (2.0 * (0.8 * np.sin(2.0 * t) - q[3]) - 0.5 * qd[3],
                0.5 * (0.6 * np.sin(1.0 * t + 0.3) - q[4]) - 0.2 * qd[4])

    rhs = ode_function("snakeboard")
    Xi = np.array([0.1, -0.2, 0.3, 0.1, 0.2, 0.3, 0.2, -0.1])   # (x, y, th, psi, phi, v, psid, phid)
    rs = SB["r"]

    def sb_rhs(t, X):
        th, ph, v = X[2], X[4], X[5]
        qd = np.array([v * np.cos(th), v * np.sin(th), v * np.tan(ph) / rs, X[6], X[7]])
        return np.asarray(rhs(X, pd_sb(t, X[:5], qd))).ravel()

    ts = np.linspace(0.0, t_end, 61)
    ode = solve_ivp(sb_rhs, (0, t_end), Xi, **_CHECK_IVP)
    th, ph, v = Xi[2], Xi[4], Xi[5]
    qd0 = np.array([v * np.cos(th), v * np.sin(th), v * np.tan(ph) / rs, Xi[6], Xi[7]])
    dae = solve_ivp(_dae_snakeboard, (0, t_end), np.concatenate([Xi[:5], qd0]), args=(pd_sb,), **_CHECK_IVP)
    Zo, Zd = ode.sol(ts), dae.sol(ts)
    v_dae = Zd[5] * np.cos(Zd[2]) + Zd[6] * np.sin(Zd[2])
    lat = -Zd[5] * np.sin(Zd[2]) + Zd[6] * np.cos(Zd[2])
    Zd_red = np.vstack([Zd[:5], v_dae, Zd[8], Zd[9]])
    err = np.max(np.abs(Zo - Zd_red))
    err_kin = np.max(np.abs(Zd[7] - v_dae * np.tan(Zd[4]) / rs)) + np.max(np.abs(lat))
    ok = err < tol and err_kin < tol
    if verbose:
        print(f"snakeboard ODE vs DAE: max |dX| = {err:.2e}, DAE constraint drift = {err_kin:.2e}"
              f"  ({'ok' if ok else 'FAIL'}); |x(T)-x(0)| = {np.hypot(*(Zo[:2, -1] - Zo[:2, 0])):.3f}")
    return ok


def check_models(t_end: float = 3.0, tol: float = 1e-8, verbose: bool = True) -> bool:
    """Integrate each reduced ODE and the independent multiplier DAE under the same
    PD-type state feedback; compare the reduced states along the trajectory."""
    unicycle = _check_unicycle(t_end, tol, verbose)
    snakeboard = _check_snakeboard(t_end, tol, verbose)
    return bool(unicycle and snakeboard)


# ----------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="P1,P2,P3")
    ap.add_argument("--N", default="25,50,100,200")
    ap.add_argument("--jit", action="store_true", help="JIT-compile the NLP functions (gcc -O1)")
    ap.add_argument("--repeats", type=int, default=5, help="solves per case (median reported)")
    ap.add_argument("--M", type=int, default=4, help="RK4 sub-steps per interval")
    ap.add_argument("--formulation", choices=sorted(_FORMULATIONS), default="nlpsol")
    ap.add_argument("--map-mode", choices=["serial", "thread"], default="serial",
                    help="F.map(N) parallelisation (only matters when the NLP is not expanded)")
    ap.add_argument("--check", action="store_true", help="verify the ODEs against the DAE first")
    args = ap.parse_args(argv)

    ok = True
    if args.check:
        ok &= check_models()
    problems = [p.strip() for p in args.problems.split(",") if p.strip()]
    Ns = [int(n) for n in args.N.split(",") if n.strip()]
    print(f"# CasADi {ca.__version__}, Ipopt/MUMPS, {args.formulation}, RK4 M={args.M}, "
          f"jit={args.jit}, map={args.map_mode}, repeats={args.repeats}")
    hdr = (f"{'problem':7s} {'N':>4s} {'objective':>11s} {'ref':>11s} {'rel err':>9s} {'iter':>4s} "
           f"{'solve ms':>9s} {'ipopt ms':>9s} {'setup ms':>9s}  status")
    print(hdr)
    print("-" * len(hdr))
    for prob in problems:
        for N in Ns:
            runs = [solve(prob, N, jit=args.jit, M=args.M, formulation=args.formulation,
                          map_mode=args.map_mode) for _ in range(max(1, args.repeats))]
            r = runs[-1]
            ref = REFERENCE.get(prob, {}).get(N) if args.M == 4 else None
            rel = abs(r["objective"] - ref) / abs(ref) if ref else float("nan")
            t_med = statistics.median(x["solve_time_s"] for x in runs) * 1e3
            t_ip = statistics.median(x["ipopt_time_s"] for x in runs) * 1e3
            ok &= all(x["success"] for x in runs) and (ref is None or rel < 1e-4)
            ref_s = f"{ref:11.6f}" if ref else f"{'-':>11s}"
            print(f"{prob:7s} {N:4d} {r['objective']:11.6f} {ref_s} {rel:9.1e} {r['iterations']:4d} "
                  f"{t_med:9.1f} {t_ip:9.1f} {r['setup_time_s'] * 1e3:9.1f}  {r['status']}", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
