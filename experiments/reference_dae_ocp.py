#!/usr/bin/env python3
"""An independent transcription of any generated robot-and-task pair (issue 24, item 3).

Nothing of nhgait is used: the model is built here, in CasADi, from the robot's physical
description (``experiments/robot_generator.py``: frames, points, bodies, wheels, loads), and the
task is read from the pair's ``[task]`` dict. Its verdict decides whether a pair is solvable.

Model: the Lagrange DAE with multipliers in (q, q̇, λ)
-----------------------------------------------------
With J_b = ∂p_b/∂q (2 × n) the Jacobian of body b's mass centre and j_b = ∂h_b/∂q its heading's,

    M(q) = Σ_b m_b J_bᵀ J_b + I_b j_bᵀ j_b,      c(q, q̇) = Σ_b m_b J_bᵀ (J̇_b q̇)

(Kane's / d'Alembert's form of the Euler–Lagrange equations of T = Σ ½ m |ṗ|² + ½ I ḣ²; the
headings are linear in q, so j̇_b = 0), ω(q) (k × n) the rows n(h_w)ᵀ ∂p_w/∂q of the wheels'
contact points (no side slip: n(h_w)·ṗ_w = 0), Q(q, u) the generalized forces of the inputs'
loads (torques τ ∂(h_on − h_against)/∂q, pushes F uᵀ ∂p/∂q, a slider's force F on its slide).
At every evaluation the linear system

    [ M   −ωᵀ ] [ q̈ ]   [ Q − c ]
    [ ω    0  ] [ λ  ] = [ −ω̇ q̇ ]          (ω̇ q̇ = ∂(ω q̇)/∂q · q̇)

is solved for (q̈, λ) (CasADi ``solve`` in the SX graph). State x = (q, q̇), 2n entries,
coordinate order.

Transcription
-------------
Direct multiple shooting on the task's fixed horizon T with its N intervals, piecewise-constant
inputs, 4 RK4 sub-steps per interval (as the planner). Each node satisfies ω(q_k) q̇_k = 0; the
velocity gap is closed up to a projection on that constraint,
q̇_{k+1} = F_q̇(x_k, u_k) + ω(q_{k+1})ᵀ μ_k with μ_k ∈ R^k a variable (the O(h⁵) drift of RK4 off
ω q̇ = 0 — without it the node constraints and the gaps are dependent up to that drift). At an end
where the fixed velocities and ω q̇ = 0 leave no freedom (every velocity zero, e.g. "from rest"),
the velocities are fixed at 0 and that node's ω rows dropped; where they over-determine the free
velocities, only the independent ω rows are kept (rank at random configurations). Objective
Σ_k (T/N) |u_k|² (the task's ``effort``). Ipopt, exact Hessian, MUMPS, ``max_wall_time`` per
solve. The interval is an MX graph of 16 calls of the SX function (q̈, λ) (the KKT solve inlined:
3171 SX operations for a 5-link chain with 4 wheels); the NLP is compiled once per pair with
CasADi's shell compiler at ``-O0`` (``flags``; -O1 took 272 s for that chain's 16.8 MB of C, -O0
45 s) — interpreted, the same chain took 2.2 s per iteration, and ``expand=True`` did not finish
building in 15 minutes.

Starts: the planner's best point (its ``solution.json``: ``trajectory.q``, ``qdot``, ``u``) or a
generic guess of its own — the fibre coordinates ramp from their initial to their final values,
each shape variable oscillates once (half its bound, or 0.5; phases spread), q̇ its time
derivative projected on ω q̇ = 0, u = 0.

Re-simulation: the optimum's inputs applied to the DAE from x_0 with scipy DOP853 (rtol 1e-10,
atol 1e-12), restarted at every control switch from the state it reached; ``resim_error`` is the
largest node error, ``condition_error`` the largest miss of the task's end values, periodic
names and path bounds. ``solved`` = Ipopt converged and both ≤ ``tolerance`` (default 1e-4).

Usage: python experiments/reference_dae_ocp.py SEED INDEX [--guess solution.json]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
import sibling  # experiments/sibling.py: the other scripts, loaded by file path

SUBSTEPS = 4


# --------------------------------------------------------------------------- #
# the DAE
# --------------------------------------------------------------------------- #
def dae(robot):
    """CasADi functions of ``robot`` (module docstring): ``accel``(q, q̇, u) → (q̈, λ),
    ``omega``(q) → ω (k × n), ``mass``(q) → M."""
    import casadi as ca
    gen = sibling.load("robot_generator")
    n, names = robot.n, list(robot.coordinates)
    q, qd, u = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("u", len(robot.inputs))
    qmap = {c: q[i] for i, c in enumerate(names)}
    heads, pos = gen.walk(robot, qmap, ca.sin, ca.cos, lambda p: robot.parameters[p])
    M, c = ca.SX.zeros(n, n), ca.SX.zeros(n, 1)
    for b in robot.bodies:
        if b.mass:
            J = ca.jacobian(ca.vertcat(*pos[b.point]), q)
            Jdot_qd = ca.jacobian(ca.mtimes(J, qd), q) @ qd
            M += robot.parameters[b.mass] * (J.T @ J)
            c += robot.parameters[b.mass] * (J.T @ Jdot_qd)
        if b.inertia:
            j = ca.jacobian(heads[b.frame], q)
            M += robot.parameters[b.inertia] * (j.T @ j)
    Q = _forces(robot, q, u, heads, pos, names)
    rows = []
    for point, frame in robot.wheels:
        h = heads[frame]
        rows.append(ca.horzcat(-ca.sin(h), ca.cos(h)) @ ca.jacobian(ca.vertcat(*pos[point]), q))
    W = ca.vertcat(*rows)
    Wdot_qd = ca.jacobian(W @ qd, q) @ qd
    k = robot.k
    KKT = ca.blockcat([[M, -W.T], [W, ca.SX.zeros(k, k)]])
    sol = ca.solve(KKT, ca.vertcat(Q - c, -Wdot_qd))
    return {"accel": ca.Function("accel", [q, qd, u], [sol[:n], sol[n:]]),
            "omega": ca.Function("omega", [q], [W]), "mass": ca.Function("mass", [q], [M])}


def _forces(robot, q, u, heads, pos, names):
    """Q(q, u): the generalized forces of the inputs' loads (module docstring)."""
    import casadi as ca
    inputs = list(robot.inputs)
    Q = ca.SX.zeros(robot.n, 1)
    for t in robot.torques:
        rel = heads[t.on] - (heads[t.against] if t.against is not None else 0)
        Q += t.gain * u[inputs.index(t.input)] * ca.jacobian(rel, q).T
    slides = {p.name: p.slide for p in robot.points}
    for p in robot.pushes:
        F = u[inputs.index(p.input)]
        if p.reaction:
            Q[names.index(slides[p.point][0])] += F
            continue
        h = heads[p.frame] + p.angle
        Q += F * (ca.horzcat(ca.cos(h), ca.sin(h)) @ ca.jacobian(ca.vertcat(*pos[p.point]), q)).T
    return Q


def rk4_interval(f, n_sub):
    """x⁺ = RK4^n_sub(x, u; h) of ẋ = (q̇, q̈(q, q̇, u)): an MX Function (x, u, h) → x⁺ calling the
    SX function ``f`` 4·n_sub times (compiled, the C holds f and its derivatives once)."""
    import casadi as ca
    n = f.size1_in(0)
    x, u, h = ca.MX.sym("x", 2 * n), ca.MX.sym("u", f.size1_in(2)), ca.MX.sym("h")

    def rhs(z):
        return ca.vertcat(z[n:], f(z[:n], z[n:], u)[0])
    z = x
    for _ in range(n_sub):
        k1 = rhs(z)
        k2 = rhs(z + h / 2 * k1)
        k3 = rhs(z + h / 2 * k2)
        k4 = rhs(z + h * k3)
        z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("interval", [x, u, h], [z])


# --------------------------------------------------------------------------- #
# the task, transcribed
# --------------------------------------------------------------------------- #
def _range(v):
    if isinstance(v, (list, tuple)):
        return float(v[0]), float(v[1])
    return float(v), float(v)


def _control_bounds(task, inputs):
    cb = task.get("control_bounds")
    if cb is None:
        return [-np.inf] * len(inputs), [np.inf] * len(inputs)
    if isinstance(cb, (int, float)):
        return [-float(cb)] * len(inputs), [float(cb)] * len(inputs)
    lo = [float(cb[u][0]) if u in cb else -np.inf for u in inputs]
    hi = [float(cb[u][1]) if u in cb else np.inf for u in inputs]
    return lo, hi


@dataclass(frozen=True)
class Ends:
    """Bounds on x_0 and x_N (2n each), the periodic pairs still rows, and the ω rows kept at
    each end (indices)."""

    lo0: np.ndarray
    hi0: np.ndarray
    loN: np.ndarray
    hiN: np.ndarray
    periodic: tuple
    omega0: tuple
    omegaN: tuple


def _ends(robot, task, omega) -> Ends:
    """The task's end conditions as bounds and rows (module docstring: Transcription)."""
    names = list(robot.coordinates) + [f"{c}_dot" for c in robot.coordinates]
    n = robot.n
    b = [np.full(2 * n, -np.inf), np.full(2 * n, np.inf), np.full(2 * n, -np.inf), np.full(2 * n, np.inf)]
    for end, (lo, hi) in (("initial", (b[0], b[1])), ("final", (b[2], b[3]))):
        for name, v in task.get(end, {}).items():
            lo[names.index(name)], hi[names.index(name)] = _range(v)
    periodic = []
    for name in task.get("periodic", []):
        i = names.index(name)
        fixed0, fixedN = b[0][i] == b[1][i], b[2][i] == b[3][i]
        if fixed0 and not fixedN:
            b[2][i] = b[3][i] = b[0][i]
        elif fixedN and not fixed0:
            b[0][i] = b[1][i] = b[2][i]
        elif not fixed0:
            periodic.append(i)
    rng = np.random.default_rng(0)
    keep = []
    for lo, hi in ((b[0], b[1]), (b[2], b[3])):
        keep.append(_omega_rows(robot, omega, lo, hi, rng, [i for i in periodic if i >= n]))
    return Ends(*b, tuple(periodic), *keep)


def _omega_rows(robot, omega, lo, hi, rng, periodic_vel):
    """Indices of the ω rows kept at one end; fixes every velocity at 0 when the fixed ones
    (all zero) and ω q̇ = 0 leave none free."""
    n, k = robot.n, robot.k
    fixed = [j for j in range(n) if lo[n + j] == hi[n + j] and j + n not in periodic_vel]
    free = [j for j in range(n) if j not in fixed]
    if not free:
        return ()
    qs = rng.uniform(-1.0, 1.0, (5, n))
    blocks = [np.asarray(omega(q_))[:, free] for q_ in qs]
    rank = max(np.linalg.matrix_rank(B, tol=1e-8) for B in blocks)
    zero = all(lo[n + j] == 0.0 for j in fixed)
    if zero and rank == len(free) and not periodic_vel:
        lo[n + np.array(free)] = 0.0
        hi[n + np.array(free)] = 0.0
        return ()
    if rank == k:
        return tuple(range(k))
    import scipy.linalg
    _, _, piv = scipy.linalg.qr(blocks[0].T, pivoting=True)
    return tuple(sorted(int(i) for i in piv[:rank]))


# --------------------------------------------------------------------------- #
# the NLP
# --------------------------------------------------------------------------- #
class ReferenceOCP:
    """The transcribed pair (module docstring); :meth:`solve` from a guess."""

    def __init__(self, p, intervals=None, jit=True, flags=("-O0",)):
        import casadi as ca
        self.pair, robot, task = p, p.robot, p.task
        self.jit, self.flags, self._solvers, self.compile_s, self.c_bytes = jit, list(flags), {}, 0.0, 0
        self.robot, self.task = robot, task
        n, m, k = robot.n, len(robot.inputs), robot.k
        self.N = N = int(intervals or task["intervals"])
        self.T = T = float(sibling.load("scale_tasks").horizon(task))
        t0 = time.perf_counter()
        self.f = dae(robot)
        step = rk4_interval(self.f["accel"], SUBSTEPS)
        ends = _ends(robot, task, self.f["omega"])
        self.ends = ends
        h = T / N / SUBSTEPS
        x, xn = ca.MX.sym("x", 2 * n), ca.MX.sym("xn", 2 * n)
        uu, mu = ca.MX.sym("u", m), ca.MX.sym("mu", k)
        nxt = step(x, uu, h)
        Wn = self.f["omega"](xn[:n])
        link = ca.Function("link", [x, uu, mu, xn], [ca.vertcat(xn[:n] - nxt[:n],
                                                                xn[n:] - nxt[n:] - Wn.T @ mu,
                                                                 Wn @ xn[n:])])
        stride = 2 * n + m + k
        w = ca.MX.sym("w", N * stride + 2 * n)                              # interval-stacked
        Wk = ca.reshape(w[:N * stride], stride, N)
        X = ca.horzcat(Wk[:2 * n, :], w[N * stride:])
        U, MU = Wk[2 * n:2 * n + m, :], Wk[2 * n + m:, :]
        links = link.map(N, "serial")(X[:, :N], U, MU, X[:, 1:])        # (2n + k) × N
        keepN = [2 * n + r for r in ends.omegaN]
        g = [links[:, :N - 1][:], links[list(range(2 * n)) + keepN, N - 1]]
        if ends.omega0:
            g.insert(0, (self.f["omega"](X[:n, 0]) @ X[n:, 0])[list(ends.omega0)])
        g += [X[i, N] - X[i, 0] for i in ends.periodic]
        g = ca.vertcat(*g)
        self.ng = int(g.shape[0])
        J = ca.sumsqr(U) * (T / N)
        self.nlp = {"x": w, "f": J, "g": g}
        self.sizes = (n, m, k)
        self._bounds(ends)
        self.build_s = time.perf_counter() - t0

    def _bounds(self, ends):
        n, m, k = self.sizes
        task = self.task
        names = list(self.robot.coordinates)
        path_lo, path_hi = np.full(2 * n, -np.inf), np.full(2 * n, np.inf)
        for name, v in task.get("bounds", {}).items():
            i = (names + [f"{c}_dot" for c in names]).index(name)
            path_lo[i], path_hi[i] = _range(v)
        ulo, uhi = _control_bounds(task, list(self.robot.inputs))
        lbw, ubw = [], []
        for i in range(self.N + 1):
            lo, hi = path_lo.copy(), path_hi.copy()
            if i == 0:
                lo, hi = np.maximum(lo, ends.lo0), np.minimum(hi, ends.hi0)
            if i == self.N:
                lo, hi = np.maximum(lo, ends.loN), np.minimum(hi, ends.hiN)
            lbw += list(lo)
            ubw += list(hi)
            if i < self.N:
                lbw += ulo + [-np.inf] * k
                ubw += uhi + [np.inf] * k
        self.lbw, self.ubw = np.array(lbw), np.array(ubw)
        self.path = (path_lo, path_hi)

    # -- guesses ----------------------------------------------------------- #
    def own_guess(self) -> tuple:
        """(Q, Qd, U): the generic guess (module docstring)."""
        n, m, k = self.sizes
        robot, task, N, T = self.robot, self.task, self.N, self.T
        t = np.linspace(0.0, T, N + 1)
        Q = np.zeros((N + 1, n))
        ini, fin = task.get("initial", {}), task.get("final", {})
        bounds = task.get("bounds", {})
        shape_i = 0
        for j, c in enumerate(robot.coordinates):
            a = _range(ini[c])[0] if c in ini else 0.0
            b_ = _range(fin[c])[0] if c in fin else a
            Q[:, j] = a + (b_ - a) * t / T
            if c in robot.shape:
                amp = 0.5 * min(abs(v) for v in _range(bounds[c])) if c in bounds else 0.5
                if c in ini and c in task.get("periodic", []) or c not in ini:
                    Q[:, j] += amp * np.sin(2 * np.pi * t / T + shape_i * np.pi / 2)
                else:
                    Q[:, j] += amp * np.sin(np.pi * t / T) * np.sin(2 * np.pi * t / T + shape_i * np.pi / 2)
                shape_i += 1
        Qd = np.gradient(Q, t, axis=0)
        for i in range(N + 1):
            W = np.asarray(self.f["omega"](Q[i]))
            Qd[i] -= W.T @ np.linalg.lstsq(W @ W.T, W @ Qd[i], rcond=None)[0]
        return Q, Qd, np.zeros((N, m))

    def planner_guess(self, solution) -> tuple:
        """(Q, Qd, U) from a planner's ``solution.json`` (dict or path), inputs mapped by name."""
        import json
        from pathlib import Path
        if not isinstance(solution, dict):
            solution = json.loads(Path(solution).read_text())
        tr = solution["trajectory"]
        cols = [list(tr["coordinates"]).index(c) for c in self.robot.coordinates]
        ucols = [list(tr["inputs"]).index(u_) for u_ in self.robot.inputs]
        Q, Qd = np.asarray(tr["q"], float)[:, cols], np.asarray(tr["qdot"], float)[:, cols]
        U = np.asarray(tr["u"], float)
        if Q.shape[0] != self.N + 1:
            raise ValueError(f"the planner's point has {Q.shape[0] - 1} intervals, the reference {self.N}")
        return Q, Qd, U[:, ucols]

    def pack(self, Q, Qd, U) -> np.ndarray:
        n, m, k = self.sizes
        w = []
        for i in range(self.N):
            w += [Q[i], Qd[i], U[i], np.zeros(k)]
        w += [Q[self.N], Qd[self.N]]
        return np.concatenate(w)

    def unpack(self, w) -> tuple:
        n, m, k = self.sizes
        stride = 2 * n + m + k
        X = np.array([w[i * stride: i * stride + 2 * n] for i in range(self.N + 1)])
        U = np.array([w[i * stride + 2 * n: i * stride + 2 * n + m] for i in range(self.N)])
        return X, U

    # -- solve -------------------------------------------------------------- #
    def _solver(self, max_wall_s, max_iter):
        """Ipopt on the NLP (compiled with gcc -O1 once when ``jit``); (solver, seconds to make it)."""
        import casadi as ca
        key = (float(max_wall_s), int(max_iter))
        if key in self._solvers:
            return self._solvers[key], 0.0
        opts = {"print_time": False, "ipopt": {"print_level": 0, "max_iter": max_iter, "tol": 1e-8,
                                               "sb": "yes", "max_wall_time": float(max_wall_s)}}
        t0 = time.perf_counter()
        if self.jit:
            opts.update({"expand": False, "jit": True, "compiler": "shell", "jit_cleanup": False,
                         "jit_options": {"flags": self.flags, "cleanup": False, "verbose": False}})
            with sibling.load("reference_scale_ocp").scratch_cwd() as tmp:
                solver = ca.nlpsol("reference", "ipopt", self.nlp, opts)
                self.c_bytes = sum(f.stat().st_size for f in tmp.glob("*.c"))
        else:
            solver = ca.nlpsol("reference", "ipopt", self.nlp, {**opts, "expand": True})
        self._solvers[key] = solver
        setup = time.perf_counter() - t0
        self.compile_s += setup
        return solver, setup

    def solve(self, guess=None, max_wall_s=300.0, max_iter=1000, tolerance=1e-4) -> ReferenceResult:
        """Ipopt from ``guess`` (a solution.json path/dict, or None: the own guess)."""
        start = "planner" if guess is not None else "own"
        Q, Qd, U = self.planner_guess(guess) if guess is not None else self.own_guess()
        w0 = np.clip(self.pack(Q, Qd, U), self.lbw, self.ubw)
        solver, setup = self._solver(max_wall_s, max_iter)
        t0 = time.perf_counter()
        sol = solver(x0=w0, lbx=self.lbw, ubx=self.ubw, lbg=np.zeros(self.ng), ubg=np.zeros(self.ng))
        solve_s = time.perf_counter() - t0
        stats = solver.stats()
        w = np.asarray(sol["x"]).ravel()
        X, U = self.unpack(w)
        self.last_w = w
        ok = bool(stats["success"]) or stats["return_status"] == "Solved_To_Acceptable_Level"
        resim, cond = self.resimulate(X, U) if ok else (math.nan, math.nan)
        return ReferenceResult(self.pair.name, start, ok, stats["return_status"], float(sol["f"]),
                               int(stats["iter_count"]), setup + self.build_s, solve_s, resim, cond,
                               bool(ok and resim <= tolerance and cond <= tolerance), X, U)

    # -- re-simulation ------------------------------------------------------ #
    def resimulate(self, X, U) -> tuple:
        """(largest node error, largest condition error) of the inputs U re-simulated (DOP853)."""
        from scipy.integrate import solve_ivp
        n = self.robot.n
        accel = self.f["accel"]
        h = self.T / self.N
        x = X[0].copy()
        err = 0.0
        sim = [x.copy()]
        for i in range(self.N):
            def rhs(_t, z, u=U[i]):
                return np.concatenate([z[n:], np.asarray(accel(z[:n], z[n:], u)[0]).ravel()])
            r = solve_ivp(rhs, (0.0, h), x, method="DOP853", rtol=1e-10, atol=1e-12)
            x = r.y[:, -1]
            sim.append(x.copy())
            err = max(err, float(np.max(np.abs(x - X[i + 1]) / np.maximum(1.0, np.abs(X[i + 1])))))
        return err, self._condition_error(np.array(sim))

    def _condition_error(self, S) -> float:
        """Largest miss of the task's end values, periodic names and path bounds by the
        re-simulated states S ((N+1) × 2n), every condition as written."""
        names = list(self.robot.coordinates) + [f"{c}_dot" for c in self.robot.coordinates]
        miss = [0.0]
        for end, row in (("initial", S[0]), ("final", S[-1])):
            for name, v in self.task.get(end, {}).items():
                lo, hi = _range(v)
                x = row[names.index(name)]
                miss.append(max(lo - x, x - hi, 0.0))
        for name in self.task.get("periodic", []):
            i = names.index(name)
            miss.append(abs(S[-1, i] - S[0, i]))
        lo, hi = self.path
        miss.append(float(np.max(np.maximum(lo - S, S - hi).clip(min=0.0))))
        return float(max(miss))


@dataclass(frozen=True)
class ReferenceResult:
    """One reference solve: ``solved`` = converged and re-simulated within the tolerance."""

    pair: str
    start: str
    converged: bool
    status: str
    objective: float
    iterations: int
    setup_s: float
    solve_s: float
    resim_error: float
    condition_error: float
    solved: bool
    X: np.ndarray
    U: np.ndarray

    def summary(self) -> dict:
        return {"start": self.start, "success": self.converged, "solved": self.solved, "status": self.status,
                "objective": self.objective, "iterations": self.iterations, "setup_s": round(self.setup_s, 2),
                "solve_s": round(self.solve_s, 2), "resim_error": self.resim_error,
                "condition_error": self.condition_error}


def solve_pair(p, guess=None, max_wall_s=300.0, tolerance=1e-4) -> ReferenceResult:
    """Build the reference of pair ``p`` and solve it from ``guess`` (solution.json or None)."""
    return ReferenceOCP(p).solve(guess, max_wall_s=max_wall_s, tolerance=tolerance)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("index", type=int)
    ap.add_argument("--intervals", type=int, default=40)
    ap.add_argument("--guess", default=None, help="a planner's solution.json to start from")
    args = ap.parse_args(argv)
    p = sibling.load("robot_generator").pair(args.seed, args.index, intervals=args.intervals)
    r = solve_pair(p, args.guess)
    print({k: v for k, v in r.summary().items()})
    return 0 if r.solved else 1


if __name__ == "__main__":
    sys.exit(main())
