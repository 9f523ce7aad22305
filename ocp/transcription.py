"""Transcriptions of an :class:`~nhgait.ocp.problem.OptimalControlProblem` into an NLP.

Both transcriptions produce a :class:`TranscribedNLP`: CasADi MX expressions of one flat
decision vector w, objective f(w) and constraints g(w), with numeric bounds. The decision
vector is stacked interval by interval so the KKT matrix is banded for MUMPS::

    multiple shooting  w = (z_0, u_0, z_1, u_1, …, z_{N-1}, u_{N-1}, z_N [, T])
    collocation        w = (z_0, Z_0, u_0, z_1, Z_1, u_1, …, z_N [, T])   Z_k: nz × d

Simple conditions on states (fixed values, ranges, path bounds at the nodes) become bounds
on w, and a periodic state fixed at one end is fixed at the other end by a bound too; only
the dynamics (gaps or collocation equations), conditions on derived quantities and the
remaining periodicity conditions are rows of g.

* :class:`MultipleShooting` — ``steps`` explicit RK4 sub-steps per interval (default 4) in
  one stage function ``F(z_k, u_k, T, k) -> z_{k+1}`` with its exact derivatives
  (:mod:`.stage`), applied to all intervals by ``F.map(N)``: the NLP's code does not grow
  with N. The NLP records where F sits (:class:`StageLayout`) so that the solver assembles
  the constraint Jacobian and the Lagrangian Hessian from the stage derivatives
  (:mod:`.derivatives`) instead of differentiating the whole graph.
* :class:`Collocation` — Legendre (or Radau) collocation of degree d (default 3) on each
  interval, the collocation equations of one interval one Function mapped over N.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from .problem import OptimalControlProblem, ProblemError
from .stage import StageFunctions, stage_functions

__all__ = ["MultipleShooting", "Collocation", "StageShooting", "TranscribedNLP", "Decisions", "Assembly", "StageLayout",
           "TRANSCRIPTIONS",
           "get_transcription", "ode_function"]


@dataclass(frozen=True, eq=False)
class Decisions:
    """The decision vector w, its bounds and where z_k (``node_index``, nz × (N+1)), u_k
    (``control_index``, nu × N) and T (``horizon_index``, None for a fixed horizon) sit in it."""

    w: ca.MX
    lbx: np.ndarray
    ubx: np.ndarray
    node_index: np.ndarray
    control_index: np.ndarray
    horizon_index: int | None = None


@dataclass(frozen=True, eq=False)
class Assembly:
    """What a transcription adds to its decisions and objective: ``kernel`` (the function
    applied on every interval), ``g`` (its own constraint expression; None: the builder's
    rows), the stage ``layout``, a ``guess_filler`` and the FATROP ``structure``."""

    kernel: ca.Function
    g: Any = None
    layout: "StageLayout | None" = None
    guess_filler: Any = None
    structure: dict | None = None


@dataclass(frozen=True, eq=False)
class TranscribedNLP:
    """An NLP ``min f(w) s.t. lbg ≤ g(w) ≤ ubg, lbx ≤ w ≤ ubx`` and its layout.

    ``node_index`` (nz × (N+1)) and ``control_index`` (nu × N) give the positions of z_k and
    u_k in w; ``horizon_index`` the position of T (free horizon) or None.
    """

    problem: OptimalControlProblem
    transcription: Any
    w: ca.MX
    f: ca.MX
    g: ca.MX
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    node_index: np.ndarray
    control_index: np.ndarray
    horizon_index: int | None
    kernel: ca.Function
    guess_filler: Any = field(default=None, repr=False)
    structure: dict | None = None        # stage structure (N, nx, nu, ng) for FATROP
    layout: "StageLayout | None" = None  # where the stage function sits (shooting only)
    row_labels: tuple = ()               # the condition each row of g states (see _Builder.add_g)

    def violations(self, g: np.ndarray, w: np.ndarray, tol: float = 1e-6) -> dict:
        """Label → largest violation (> ``tol``) of the rows of g and of the bounds on w at a
        point ("dynamics", "initial.x", "final.y", "periodic.psi", "bounds.phi",
        "control_bounds.tau", "horizon"). A solver that fails may return a point outside the
        bounds (FATROP relaxes fixed ones), so both are checked."""
        out = {}
        for labels, lo, hi, value in ((self.row_labels, self.lbg, self.ubg, g), (self.w_labels(), self.lbx, self.ubx, w)):
            viol = np.maximum(np.maximum(lo - value, value - hi), 0.0)
            for label, v in zip(labels, viol):
                if v > tol:
                    out[label] = max(out.get(label, 0.0), float(v))
        return out

    def w_labels(self) -> list:
        """The condition each bound on w states: "initial.<state>" / "final.<state>" at the end
        nodes where the problem fixes that state, "periodic.<state>" at an end node fixed by
        periodicity (the state fixed at the other end), "bounds.<state>" on the other nodes,
        "control_bounds.<input>", "horizon" (every carried copy of T in the stage order);
        "" for entries that are never bounded (the carried periodic values)."""
        p = self.problem
        labels = [""] * self.n_w
        N = p.intervals
        for i, name in enumerate(p.state_names):
            for k in range(N + 1):
                end = "initial" if k == 0 else "final" if k == N else None
                mapping = p.initial if end == "initial" else p.final if end == "final" else {}
                j = int(self.node_index[i, k])
                if name in mapping:
                    labels[j] = f"{end}.{name}"
                elif end and name in p.periodic and self.lbx[j] == self.ubx[j]:   # see _Builder.node_bounds
                    labels[j] = f"periodic.{name}"
                else:
                    labels[j] = f"bounds.{name}"
        for j, name in enumerate(p.control_names):
            for k in range(N):
                labels[int(self.control_index[j, k])] = f"control_bounds.{name}"
        if self.horizon_index is not None:
            labels[self.horizon_index] = "horizon"
            if self.structure is not None:   # stage order: x̃_k = (z_k, c_k, T_k) on every stage
                block = self.structure["nx"][0] + self.structure["nu"][0]
                for k in range(N + 1):
                    labels[self.horizon_index + k * block] = "horizon"
        return labels

    @property
    def n_w(self) -> int:
        return int(self.w.shape[0])

    def pack(self, states: np.ndarray, controls: np.ndarray, horizon: float | None = None) -> np.ndarray:
        """A decision vector from node states (nz × (N+1)) and controls (nu × N)."""
        w0 = np.zeros(self.n_w)
        w0[self.node_index] = states
        w0[self.control_index] = controls
        if self.horizon_index is not None:
            w0[self.horizon_index] = self.problem.horizon if horizon is None else horizon
        if self.guess_filler is not None:
            self.guess_filler(w0, np.asarray(states, float), np.asarray(controls, float))
        return w0

    def unpack(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(states (nz × (N+1)), controls (nu × N), T) from a decision vector."""
        w = np.asarray(w, dtype=float).ravel()
        T = float(w[self.horizon_index]) if self.horizon_index is not None else float(self.problem.horizon)
        return w[self.node_index], w[self.control_index], T


def ode_function(problem: OptimalControlProblem) -> ca.Function:
    """f(t, z, u) with the parameter values substituted (constants folded), one SX Function."""
    nz, nu = problem.n_states, problem.n_controls
    z, u, t = ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("t")
    rhs = problem.model.numeric["rhs"](t, z, u, problem.params)
    return ca.Function("ode", [t, z, u], [rhs], ["t", "z", "u"], ["zdot"])


@dataclass(frozen=True, eq=False)
class StageLayout:
    """Where the stage function sits in an NLP::

        g(w) = g_linear(w) + sign · Σ_k E_k F(x_k),   x_k = (z_k, u_k[, T]) = w[columns[:, k]],

    with E_k placing F's nz outputs at the rows ``rows[:, k]`` of g. ``arguments`` are the
    stage functions' inputs (Z, U, T row, k row), expressions of w, to call them mapped.
    """

    stage: StageFunctions
    arguments: tuple
    g_linear: ca.MX
    rows: np.ndarray
    columns: np.ndarray
    sign: float


def _stage_layout(stage, w, g_of, arguments) -> StageLayout:
    """Build g with a placeholder for the stage outputs and read the placement off it.

    ``g_of(Zend)`` builds g from the stage outputs (nz × N); the placeholder's Jacobian gives
    the rows and the sign, the Jacobian of the stage inputs the columns (both constant).
    """
    nz, N = stage.n_states, int(arguments[0].shape[1])
    P = ca.MX.sym("F", nz, N)
    g_p = g_of(P)
    x_in = ca.vertcat(*arguments[:2], arguments[2]) if stage.free_horizon else ca.vertcat(*arguments[:2])
    sel = ca.Function("placement", [w, P], [ca.jacobian(g_p, ca.vec(P)), ca.jacobian(ca.vec(x_in), w)])
    gp, xin = sel(np.zeros(w.shape[0]), np.zeros((nz, N)))
    rows, signs = _single_entries(gp, by="column")
    columns, _ = _single_entries(xin, by="row")
    if not np.all(signs == signs[0]):   # pragma: no cover - guards the transcriptions below
        raise ProblemError(["internal: the stage outputs enter g with mixed signs"])
    g_linear = ca.substitute([g_p], [P], [ca.MX.zeros(nz, N)])[0]
    g = ca.substitute([g_p], [P], [stage.step.map(N, "serial")(*arguments)])[0]
    layout = StageLayout(stage, tuple(arguments), g_linear, rows.reshape((N, nz)).T,
                         columns.reshape((N, stage.n_variables)).T, float(signs[0]))
    return g, layout


def _single_entries(M: ca.DM, by: str):
    """For a constant selection matrix: the index of the single nonzero of each column (or
    row) and its value."""
    r, c = M.sparsity().get_triplet()
    r, c, v = np.array(r), np.array(c), np.array(M.nonzeros())
    key, other = (c, r) if by == "column" else (r, c)
    n = M.shape[1] if by == "column" else M.shape[0]
    if len(key) != n or len(set(key.tolist())) != n:   # pragma: no cover - internal invariant
        raise ProblemError(["internal: the stage placement is not a selection"])
    order = np.argsort(key)
    return other[order], v[order]


class _Builder:
    """Shared bookkeeping: bounds on w, rows of g, objective terms."""

    def __init__(self, problem: OptimalControlProblem):
        self.problem = problem
        self.g, self.lbg, self.ubg, self.labels = [], [], [], []

    def reset(self):
        self.g, self.lbg, self.ubg, self.labels = [], [], [], []

    def add_g(self, expr, lo, hi, label):
        """Rows ``lo ≤ expr ≤ hi`` of g; ``label`` (one string, or one per row) names the
        condition they state: "dynamics", "initial.<name>", "final.<name>",
        "periodic.<name>", "bounds.<name>" (reports say which conditions a point violates)."""
        n = int(expr.shape[0])
        self.g.append(expr)
        self.lbg.append(np.broadcast_to(np.asarray(lo, float), (n,)))
        self.ubg.append(np.broadcast_to(np.asarray(hi, float), (n,)))
        self.labels.extend([label] * n if isinstance(label, str) else list(label))

    def node_bounds(self) -> tuple[np.ndarray, np.ndarray, list]:
        """Bounds (nz × (N+1)) on the node states and the periodic states left for g."""
        p = self.problem
        nz, N = p.n_states, p.intervals
        lo = np.full((nz, N + 1), -np.inf)
        hi = np.full((nz, N + 1), np.inf)
        for name, value in p.state_bounds.items():
            if p.is_state(name):
                i = p.state_names.index(name)
                lo[i, :], hi[i, :] = p.bounds(p.state_bounds, name)
        for col, mapping in ((0, p.initial), (N, p.final)):
            for name in mapping:
                if p.is_state(name):
                    i = p.state_names.index(name)
                    a, b = p.bounds(mapping, name)
                    lo[i, col], hi[i, col] = max(lo[i, col], a), min(hi[i, col], b)
        periodic_g = []
        for name in p.periodic:
            if not p.is_state(name):
                periodic_g.append(name)
                continue
            i = p.state_names.index(name)
            # a periodic state fixed at one end is fixed at the other end (a bound, not a row of g)
            if lo[i, 0] == hi[i, 0] or lo[i, N] == hi[i, N]:
                value = lo[i, 0] if lo[i, 0] == hi[i, 0] else lo[i, N]
                lo[i, 0] = hi[i, 0] = lo[i, N] = hi[i, N] = value
            else:
                periodic_g.append(name)
        return lo, hi, periodic_g

    def derived_rows(self, Z, Zfirst, Zlast, periodic_g):
        """Rows of g for derived-quantity conditions and periodic states not fixed by bounds."""
        p = self.problem
        N = p.intervals
        zs = ca.SX.sym("z", p.n_states)
        cache = {}

        def qfun(name):
            if name not in cache:
                cache[name] = ca.Function(f"q_{name}", [zs], [p.quantity(name, zs)])
            return cache[name]

        for col, mapping, zc in ((0, p.initial, Zfirst), (N, p.final, Zlast)):
            for name in mapping:
                if not p.is_state(name):
                    a, b = p.bounds(mapping, name)
                    self.add_g(qfun(name)(zc), a, b, f"{'initial' if col == 0 else 'final'}.{name}")
        for name in periodic_g:
            f = qfun(name)
            self.add_g(f(Zlast) - f(Zfirst), 0.0, 0.0, f"periodic.{name}")
        for name in p.state_bounds:
            if not p.is_state(name):
                a, b = p.bounds(p.state_bounds, name)
                self.add_g(ca.vec(qfun(name).map(N + 1)(Z)), a, b, f"bounds.{name}")

    def objective(self, Z, U, h, T):
        p = self.problem
        wu = np.array([float(p.control_weights.get(n, 1.0)) for n in p.control_names])
        if np.all(wu == 1.0):
            f = h * ca.sumsqr(U)
        else:
            f = h * ca.sumsqr(ca.mtimes(ca.diag(ca.DM(np.sqrt(wu))), U))
        if p.state_weights:
            wz = np.array([float(p.state_weights.get(n, 0.0)) for n in p.state_names])
            f = f + h * ca.sum2(ca.mtimes(ca.DM(wz).T, Z[:, :-1] ** 2))
        if p.time_weight:
            f = f + float(p.time_weight) * T
        return f

    def finish(self, transcription, decisions: Decisions, f, assembly: Assembly) -> TranscribedNLP:
        """The NLP: ``decisions``, objective ``f``, the rows added (or ``assembly.g``)."""
        g = assembly.g
        if g is None:
            g = ca.vertcat(*self.g) if self.g else ca.MX(0, 1)
        lbg = np.concatenate(self.lbg) if self.lbg else np.zeros(0)
        ubg = np.concatenate(self.ubg) if self.ubg else np.zeros(0)
        d = decisions
        return TranscribedNLP(problem=self.problem, transcription=transcription, w=d.w, f=f, g=g,
                              lbx=d.lbx, ubx=d.ubx, lbg=lbg, ubg=ubg, node_index=d.node_index,
                              control_index=d.control_index, horizon_index=d.horizon_index,
                              kernel=assembly.kernel, guess_filler=assembly.guess_filler,
                              structure=assembly.structure, layout=assembly.layout,
                              row_labels=tuple(self.labels))

    def horizon_variable(self):
        p = self.problem
        if p.free_horizon is None:
            return None, float(p.horizon), None
        T = ca.MX.sym("T")
        lo, hi = p.bounds({"T": p.free_horizon}, "T")
        return T, T, (lo, hi)


@dataclass(frozen=True)
class MultipleShooting:
    """Direct multiple shooting with ``steps`` explicit RK4 sub-steps per interval.

    ``stage``: "auto", "inline" or "structured" (:func:`~nhgait.ocp.stage.stage_functions`).
    """

    steps: int = 4
    map_mode: str = "serial"
    stage: str = "auto"
    name = "multiple-shooting"

    def stage_functions(self, problem: OptimalControlProblem) -> StageFunctions:
        """The stage function of ``problem`` and its derivatives (:mod:`.stage`)."""
        if not (isinstance(self.steps, int) and self.steps >= 1):
            raise ProblemError([f"multiple shooting: steps = {self.steps!r} must be an integer ≥ 1"])
        if self.stage not in ("auto", "inline", "structured"):
            raise ProblemError([f"multiple shooting: stage = {self.stage!r} (auto, inline or structured)"])
        return stage_functions(ode_function(problem), problem.intervals, steps=self.steps,
                               free_horizon=problem.free_horizon is not None, mode=self.stage)

    def settings(self) -> dict:
        return {"transcription": self.name, "rk4_steps": self.steps, "map_mode": self.map_mode}

    def build(self, problem: OptimalControlProblem) -> TranscribedNLP:
        nz, nu, N = problem.n_states, problem.n_controls, problem.intervals
        b = _Builder(problem)
        Tsym, T, Tbounds = b.horizon_variable()
        V = ca.MX.sym("V", nz + nu, N)
        ZN = ca.MX.sym("zN", nz)
        parts = [ca.vec(V), ZN] + ([Tsym] if Tsym is not None else [])
        w = ca.vertcat(*parts)
        Z = ca.horzcat(V[:nz, :], ZN)
        U = V[nz:, :]
        h = T / N
        stage = self.stage_functions(problem)
        args = (Z[:, :N], U, ca.repmat(T, 1, N), ca.DM(np.arange(N, dtype=float)).T)

        def g_of(Zend):
            b.reset()
            b.add_g(ca.vec(Zend - Z[:, 1:]), 0.0, 0.0, "dynamics")
            b.derived_rows(Z, Z[:, 0], Z[:, N], periodic_g)
            return ca.vertcat(*b.g)

        lo, hi, periodic_g = b.node_bounds()
        g, layout = _stage_layout(stage, w, g_of, args)
        f = b.objective(Z, U, h, T)
        ulo, uhi = problem.control_bound_vectors()
        # layout
        idx = np.arange((nz + nu) * N).reshape((N, nz + nu)).T        # column k = (z_k, u_k)
        node_index = np.hstack([idx[:nz, :], (nz + nu) * N + np.arange(nz)[:, None]])
        control_index = idx[nz:, :]
        n_w = int(w.shape[0])
        lbx, ubx = np.full(n_w, -np.inf), np.full(n_w, np.inf)
        lbx[node_index], ubx[node_index] = lo, hi
        lbx[control_index], ubx[control_index] = ulo[:, None], uhi[:, None]
        horizon_index = None
        if Tsym is not None:
            horizon_index = n_w - 1
            lbx[horizon_index], ubx[horizon_index] = Tbounds
        return b.finish(self, Decisions(w, lbx, ubx, node_index, control_index, horizon_index), f,
                        Assembly(stage.step, g=g, layout=layout))


@dataclass(frozen=True)
class Collocation:
    """Direct collocation: degree-d polynomials on Legendre (or Radau) points per interval."""

    degree: int = 3
    scheme: str = "legendre"
    map_mode: str = "serial"
    name = "collocation"

    def settings(self) -> dict:
        return {"transcription": self.name, "degree": self.degree, "scheme": self.scheme,
                "map_mode": self.map_mode}

    def coefficients(self):
        """Collocation points τ (0 prepended), derivative matrix C, continuity D, quadrature B."""
        d = self.degree
        tau = np.append(0.0, ca.collocation_points(d, self.scheme))
        C = np.zeros((d + 1, d + 1))
        D = np.zeros(d + 1)
        for j in range(d + 1):
            coeff = np.poly1d([1.0])
            for r in range(d + 1):
                if r != j:
                    coeff *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
            D[j] = coeff(1.0)
            dcoeff = np.polyder(coeff)
            for r in range(d + 1):
                C[j, r] = dcoeff(tau[r])
        return tau, C, D

    def interval_function(self, problem: OptimalControlProblem) -> ca.Function:
        """Residuals of one interval: (z_k, vec Z_k, u_k, h, t_k) -> (collocation residuals, z_end);
        the collocation point j is at t_k + τ_j h."""
        if not (isinstance(self.degree, int) and self.degree >= 1):
            raise ProblemError([f"collocation: degree = {self.degree!r} must be an integer ≥ 1"])
        if self.scheme not in ("legendre", "radau"):
            raise ProblemError([f"collocation: unknown scheme {self.scheme!r} (legendre, radau)"])
        ode = ode_function(problem)
        nz, nu, d = problem.n_states, problem.n_controls, self.degree
        tau, C, D = self.coefficients()
        zk, zc, u = ca.SX.sym("zk", nz), ca.SX.sym("zc", nz * d), ca.SX.sym("u", nu)
        hs, tk = ca.SX.sym("h"), ca.SX.sym("tk")
        pts = ca.horzcat(zk, ca.reshape(zc, nz, d))
        res = []
        for j in range(1, d + 1):
            zp = ca.mtimes(pts, ca.DM(C[:, j]))
            res.append(hs * ode(tk + tau[j] * hs, pts[:, j], u) - zp)
        zend = ca.mtimes(pts, ca.DM(D))
        return ca.Function("collocation_interval", [zk, zc, u, hs, tk], [ca.vertcat(*res), zend],
                           ["zk", "zc", "u", "h", "tk"], ["residual", "zend"])

    def build(self, problem: OptimalControlProblem) -> TranscribedNLP:
        nz, nu, N, d = problem.n_states, problem.n_controls, problem.intervals, self.degree
        b = _Builder(problem)
        Tsym, T, Tbounds = b.horizon_variable()
        blk = nz + nz * d + nu
        V = ca.MX.sym("V", blk, N)
        ZN = ca.MX.sym("zN", nz)
        w = ca.vertcat(*([ca.vec(V), ZN] + ([Tsym] if Tsym is not None else [])))
        Z = ca.horzcat(V[:nz, :], ZN)
        Zc = V[nz:nz + nz * d, :]                   # column k: vec(Z_k), nz*d
        U = V[nz + nz * d:, :]
        h = T / N
        W = self.interval_function(problem)
        R, Zend = W.map(N, self.map_mode)(Z[:, :N], Zc, U, ca.repmat(h, 1, N),
                                          h * ca.DM(np.arange(N, dtype=float)).T)
        # interleave residuals and continuity per interval (banded Jacobian)
        b.add_g(ca.vec(ca.vertcat(R, Zend - Z[:, 1:])), 0.0, 0.0, "dynamics")
        lo, hi, periodic_g = b.node_bounds()
        b.derived_rows(Z, Z[:, 0], Z[:, N], periodic_g)
        f = b.objective(Z, U, h, T)
        ulo, uhi = problem.control_bound_vectors()
        idx = np.arange(blk * N).reshape((N, blk)).T
        node_index = np.hstack([idx[:nz, :], blk * N + np.arange(nz)[:, None]])
        coll_index = idx[nz:nz + nz * d, :]
        control_index = idx[nz + nz * d:, :]
        n_w = int(w.shape[0])
        lbx, ubx = np.full(n_w, -np.inf), np.full(n_w, np.inf)
        lbx[node_index], ubx[node_index] = lo, hi
        lbx[control_index], ubx[control_index] = ulo[:, None], uhi[:, None]
        # path bounds on states also hold at the collocation points
        path_lo, path_hi = np.full(nz, -np.inf), np.full(nz, np.inf)
        for name in problem.state_bounds:
            if problem.is_state(name):
                i = problem.state_names.index(name)
                path_lo[i], path_hi[i] = problem.bounds(problem.state_bounds, name)
        lbx[coll_index] = np.tile(path_lo, d)[:, None]
        ubx[coll_index] = np.tile(path_hi, d)[:, None]
        horizon_index = None
        if Tsym is not None:
            horizon_index = n_w - 1
            lbx[horizon_index], ubx[horizon_index] = Tbounds
        tau = self.coefficients()[0]

        def fill(w0, states, controls):
            # collocation states: linear interpolation between the node guesses
            for j in range(d):
                s = tau[j + 1]
                w0[coll_index[j * nz:(j + 1) * nz, :]] = (1 - s) * states[:, :-1] + s * states[:, 1:]

        return b.finish(self, Decisions(w, lbx, ubx, node_index, control_index, horizon_index), f,
                        Assembly(W, guess_filler=fill))


@dataclass(frozen=True)
class StageShooting(MultipleShooting):
    """Multiple shooting in stage order, for structure-exploiting solvers (FATROP).

    FATROP needs an optimal control structure: the decision vector stage by stage,
    w = (x̃_0, u_0, x̃_1, u_1, …, x̃_N), and the constraints stage by stage, each stage's
    dynamics gap x̃_{k+1} − F̃(x̃_k, u_k) followed by the conditions on (x̃_k, u_k) alone.
    Conditions linking the two ends (periodicity) or using a global variable (a free
    horizon T) are made stage-local by *carrying* the values along the horizon:

        x̃_k = (z_k, c_k [, T_k]),   c_{k+1} = c_k,  T_{k+1} = T_k,
        c_0 = y_per(z_0)  (stage 0),     y_per(z_N) − c_N = 0  (stage N),

    with y_per the periodic quantities not already fixed at both ends by bounds. The problem
    is the one :class:`MultipleShooting` transcribes (same optimum, checked in the tests).
    """

    name = "multiple-shooting-stages"

    def settings(self) -> dict:
        return {**super().settings(), "transcription": self.name}

    def build(self, problem: OptimalControlProblem) -> TranscribedNLP:
        nz, nu, N = problem.n_states, problem.n_controls, problem.intervals
        b = _Builder(problem)
        lo, hi, periodic_g = b.node_bounds()
        zs = ca.SX.sym("z", nz)
        yper = ca.Function("y_per", [zs], [ca.vertcat(*[problem.quantity(n, zs) for n in periodic_g])]
                           if periodic_g else [ca.SX(0, 1)])
        nc, free = len(periodic_g), problem.free_horizon is not None
        nx = nz + nc + (1 if free else 0)
        V, XN = ca.MX.sym("V", nx + nu, N), ca.MX.sym("xN", nx)
        w = ca.vertcat(ca.vec(V), XN)                  # (x̃_0, u_0, …, x̃_{N-1}, u_{N-1}, x̃_N)
        X, U = ca.horzcat(V[:nx, :], XN), V[nx:, :]
        Z = X[:nz, :]
        stage = self.stage_functions(problem)
        Trow = X[nx - 1, :N] if free else ca.DM.ones(1, N) * float(problem.horizon)
        h = Trow / N if free else float(problem.horizon) / N
        args = (Z[:, :N], U, Trow, ca.DM(np.arange(N, dtype=float)).T)
        path = _StagePaths(problem, Z)                            # rows on every node
        first, last = _end_rows(problem, Z[:, 0], "initial"), _end_rows(problem, Z[:, N], "final")
        if nc:
            labels = [f"periodic.{n}" for n in periodic_g]
            first.append((X[nz:nz + nc, 0] - yper(Z[:, 0]), 0.0, 0.0, labels))
            last.append((yper(Z[:, N]) - X[nz:nz + nc, N], 0.0, 0.0, labels))

        def g_of(Zend):
            # stage 0: gap, path rows, start rows; stages 1..N-1: (gap, path rows) column by column
            b.reset()
            gaps = X[:, 1:] - ca.vertcat(Zend, X[nz:, :N])            # column k: gap of stage k
            b.add_g(gaps[:, 0], 0.0, 0.0, "dynamics")
            path.add(b, 0)
            for expr, a, c, label in first:
                b.add_g(expr, a, c, label)
            if N > 1:
                body = ca.vertcat(gaps[:, 1:], path.matrix[:, 1:N]) if path.n else gaps[:, 1:]
                b.add_g(ca.vec(body), np.tile(np.concatenate([np.zeros(nx), path.lo]), N - 1),
                        np.tile(np.concatenate([np.zeros(nx), path.hi]), N - 1),
                        (["dynamics"] * nx + path.labels) * (N - 1))
            path.add(b, N)
            for expr, a, c, label in last:
                b.add_g(expr, a, c, label)
            return ca.vertcat(*b.g)

        g, layout = _stage_layout(stage, w, g_of, args)
        counts = {k: path.n for k in range(N + 1)}
        counts[0] += sum(int(e.shape[0]) for e, *_ in first)
        counts[N] += sum(int(e.shape[0]) for e, *_ in last)
        wu = np.array([float(problem.control_weights.get(n, 1.0)) for n in problem.control_names])
        hk = h                                         # the step of each interval
        f = ca.sum2(hk * ca.mtimes(ca.DM(wu).T, U ** 2))
        if problem.state_weights:
            wz = np.array([float(problem.state_weights.get(n, 0.0)) for n in problem.state_names])
            f = f + ca.sum2(hk * ca.mtimes(ca.DM(wz).T, Z[:, :N] ** 2))
        if problem.time_weight:
            f = f + float(problem.time_weight) * X[nx - 1, 0]
        return self._layout(b, _StageVector(w, lo, hi, nx, nc, yper, counts), f, g, layout)

    def _layout(self, b, vector: "_StageVector", f, g, layout):
        """The NLP in stage order: bounds on w, the FATROP structure and the guess filler."""
        problem = b.problem
        w, lo, hi, nx, nc, yper, counts = (vector.w, vector.lo, vector.hi, vector.nx, vector.nc, vector.yper,
                                           vector.counts)
        nz, nu, N = problem.n_states, problem.n_controls, problem.intervals
        blk = nx + nu
        starts = np.arange(N + 1) * blk
        node_index = starts[None, :] + np.arange(nz)[:, None]
        control_index = starts[None, :N] + nx + np.arange(nu)[:, None]
        n_w = int(w.shape[0])
        lbx, ubx = np.full(n_w, -np.inf), np.full(n_w, np.inf)
        lbx[node_index], ubx[node_index] = lo, hi
        ulo, uhi = problem.control_bound_vectors()
        lbx[control_index], ubx[control_index] = ulo[:, None], uhi[:, None]
        horizon_index = None
        if problem.free_horizon is not None:
            T_index = starts + nx - 1
            lbx[T_index], ubx[T_index] = problem.bounds({"T": problem.free_horizon}, "T")
            horizon_index = int(T_index[0])
        ng = [counts.get(k, 0) for k in range(N + 1)]
        structure = {"N": N, "nx": [nx] * (N + 1), "nu": [nu] * N + [0], "ng": ng}

        def fill(w0, states, controls):
            # the carried copies: y_per(z_0) and T on every stage
            extra = []
            if nc:
                extra.append(np.asarray(yper(states[:, 0])).ravel())
            if horizon_index is not None:
                extra.append(np.array([w0[horizon_index]]))
            if extra:
                extra = np.concatenate(extra)
                for k in range(N + 1):
                    w0[starts[k] + nz:starts[k] + nx] = extra

        return b.finish(self, Decisions(w, lbx, ubx, node_index, control_index, horizon_index), f,
                        Assembly(layout.stage.step, g=g, layout=layout, guess_filler=fill, structure=structure))


@dataclass(frozen=True, eq=False)
class _StageVector:
    """The stage-ordered decision vector of :class:`StageShooting`: ``w``, the node bounds
    ``lo``/``hi`` (nz × (N+1)), ``nx`` (a stage's state with its carried copies), ``nc`` (the
    carried periodic values, ``yper`` their function of z_0) and ``counts`` (rows per stage)."""

    w: Any
    lo: np.ndarray
    hi: np.ndarray
    nx: int
    nc: int
    yper: Any
    counts: dict


def _end_rows(problem, z, where) -> list:
    """(expression, lo, hi) of the conditions on derived quantities at one end."""
    mapping = problem.initial if where == "initial" else problem.final
    return [(problem.quantity(n, z), *problem.bounds(mapping, n), f"{where}.{n}")
            for n in mapping if not problem.is_state(n)]


class _StagePaths:
    """Path bounds on derived quantities at every node, as a matrix (rows × (N+1))."""

    def __init__(self, problem, Z):
        names = [n for n in problem.state_bounds if not problem.is_state(n)]
        zs = ca.SX.sym("z", problem.n_states)
        self.n = len(names)
        self.labels = [f"bounds.{n}" for n in names]
        bounds = [problem.bounds(problem.state_bounds, n) for n in names]
        self.lo = np.array([a for a, _ in bounds])
        self.hi = np.array([c for _, c in bounds])
        if self.n:
            fn = ca.Function("path", [zs], [ca.vertcat(*[problem.quantity(n, zs) for n in names])])
            self.matrix = fn.map(Z.shape[1])(Z)
        else:
            self.matrix = None

    def add(self, b, k):
        if self.n:
            b.add_g(self.matrix[:, k], self.lo, self.hi, self.labels)


TRANSCRIPTIONS = {"multiple-shooting": MultipleShooting, "collocation": Collocation,
                  "multiple-shooting-stages": StageShooting}


def get_transcription(spec=None):
    """A transcription from a name (``multiple-shooting``, ``collocation``) or an instance."""
    if spec is None:
        return MultipleShooting()
    if isinstance(spec, str):
        try:
            return TRANSCRIPTIONS[spec]()
        except KeyError:
            raise ProblemError([f"unknown transcription {spec!r} (known: {', '.join(TRANSCRIPTIONS)})"]) from None
    return spec
