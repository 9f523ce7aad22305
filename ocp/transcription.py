"""Transcriptions of an :class:`~nhgait.ocp.problem.OptimalControlProblem` into an NLP.

Every transcription produces a :class:`TranscribedNLP`: CasADi MX expressions of one flat
decision vector w, objective f(w) and constraints g(w), with numeric bounds. The decision
vector is stacked interval by interval so the KKT matrix is banded for MUMPS::

    multiple shooting  w = (z_0, u_0, z_1, u_1, …, z_{N-1}, u_{N-1}, z_N [, T_1 … T_P])
    collocation        w = (z_0, Z_0, u_0, z_1, Z_1, u_1, …, z_N [, T_1 … T_P])   Z_k: nz × d

with z the problem's states (the model's, then its integral states) and T_p the phase horizons
when any is free (:mod:`.schedule`: a problem without phases is one phase). Simple conditions
on states (fixed values, ranges, path bounds at the nodes, conditions at waypoints and phase
ends) become bounds on w, and a periodic state fixed at one end is fixed at the other end by a
bound too; only the dynamics (gaps or collocation equations), conditions on derived quantities,
path bounds on derived quantities and the remaining periodicity conditions are rows of g.

* :class:`MultipleShooting` — ``steps`` explicit RK4 sub-steps per interval (default 4) in
  one stage function ``F(z_k, u_k, T_p, κ_k, (ν_k, t0_p)) -> z_{k+1}`` with its exact
  derivatives (:mod:`.stage`), applied to all intervals by ``F.map(N)``. Path bounds on
  derived quantities are two more mapped functions with their own exact derivatives — c(z) at
  the nodes 0 … N and, for quantities of the inputs and accelerations, c(z, u, T_p, κ, (ν, t0))
  at the nodes 0 … N−1 with the input of the interval each starts. The NLP records where
  these *mapped terms* sit (:class:`StageLayout`) so that the solver assembles the constraint
  Jacobian and the Lagrangian Hessian from their derivatives (:mod:`.derivatives`) instead of
  differentiating the whole graph: the NLP's code does not grow with N.
* :class:`StageShooting` — the same in stage order, for FATROP.
* :class:`Collocation` — Legendre (or Radau) collocation of degree d (default 3) on each
  interval, the collocation equations of one interval one Function mapped over N.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from .problem import OptimalControlProblem, ProblemError
from .schedule import check_time, schedule
from .stage import StageFunctions, stage_functions

__all__ = ["MultipleShooting", "Collocation", "StageShooting", "TranscribedNLP", "Decisions", "Assembly",
           "StageLayout",
           "MappedTerm", "PathFunctions", "TRANSCRIPTIONS", "get_transcription", "ode_function",
           "path_functions"]


from .nlp import (  # noqa: F401
    Assembly,
    Decisions,
    MappedTerm,
    PathFunctions,
    StageLayout,
    TranscribedNLP,
    ode_function,
    path_functions,
)


def _stage_layout(w, g_of, specs) -> tuple:
    """Build g with a placeholder for each term's outputs and read the placement off it.

    ``specs``: (functions, arguments, number of leading variable arguments) per term;
    ``g_of(*placeholders)`` builds g from the outputs (n_outputs × K each). The placeholders'
    Jacobians give the rows and signs, the Jacobian of the variable arguments the columns
    (both constant).
    """
    P = [ca.MX.sym(f"F{i}", fn.n_outputs, int(args[0].shape[1])) for i, (fn, args, _) in enumerate(specs)]
    g_p = g_of(*P)
    terms, mapped = [], []
    for (fn, args, n_var), Pi in zip(specs, P, strict=True):
        m, K = Pi.shape
        x_in = ca.vertcat(*args[:n_var])
        sel = ca.Function("placement", [w, Pi], [ca.jacobian(g_p, ca.vec(Pi)), ca.jacobian(ca.vec(x_in), w)])
        gp, xin = sel(np.zeros(w.shape[0]), np.zeros((m, K)))
        rows, signs = _single_entries(gp, by="column")
        columns, _ = _single_entries(xin, by="row")
        if not np.all(signs == signs[0]):   # pragma: no cover - guards the transcriptions below
            raise ProblemError(["internal: a mapped term enters g with mixed signs"])
        terms.append(MappedTerm(fn, tuple(args), rows.reshape((K, m)).T,
                                columns.reshape((K, fn.n_variables)).T, float(signs[0])))
        mapped.append(fn.value.map(K, "serial")(*args))
    g_linear = ca.substitute([g_p], P, [ca.MX.zeros(*Pi.shape) for Pi in P])[0]
    g = ca.substitute([g_p], P, mapped)[0]
    return g, StageLayout(tuple(terms), g_linear)


def _single_entries(M: ca.DM, by: str):
    """For a constant selection matrix: the index of the single nonzero of each column (or
    row) and its value."""
    r, c = M.sparsity().get_triplet()
    r, c, v = np.array(r, dtype=int), np.array(c, dtype=int), np.array(M.nonzeros())
    key, other = (c, r) if by == "column" else (r, c)
    n = M.shape[1] if by == "column" else M.shape[0]
    if len(key) != n or len(set(key.tolist())) != n:   # pragma: no cover - internal invariant
        raise ProblemError(["internal: the stage placement is not a selection"])
    order = np.argsort(key)
    return other[order], v[order]


# ----------------------------------------------------------------------------- bookkeeping
class PathRanges(NamedTuple):
    """The path bounds of a transcription: state quantities by node, input quantities by interval."""

    state_lo: np.ndarray   #: m_s × (N+1)
    state_hi: np.ndarray
    input_lo: np.ndarray   #: m_u × N
    input_hi: np.ndarray


class _Builder:
    """Shared bookkeeping: bounds on w, rows of g, objective terms, the path quantities."""

    def __init__(self, problem: OptimalControlProblem):
        self.problem = problem
        self.schedule = schedule(problem)
        self.g, self.lbg, self.ubg, self.labels = [], [], [], []
        derived = [n for n in self.schedule.path_names(problem) if not problem.is_state(n)]
        self.state_paths = [n for n in derived if not problem.uses_inputs(n)]
        self.input_paths = [n for n in derived if problem.uses_inputs(n)]

    def reset(self):
        self.g, self.lbg, self.ubg, self.labels = [], [], [], []

    def add_g(self, expr, lo, hi, label):
        """Rows ``lo ≤ expr ≤ hi`` of g; ``label`` (one string, or one per row) names the
        condition they state: "dynamics", "initial.<name>", "final.<name>", "<waypoint>.<name>",
        "<phase>.final.<name>", "periodic.<name>", "bounds.<name>" (reports say which conditions
        a point violates)."""
        n = int(expr.shape[0])
        self.g.append(expr)
        self.lbg.append(np.broadcast_to(np.asarray(lo, float), (n,)))
        self.ubg.append(np.broadcast_to(np.asarray(hi, float), (n,)))
        self.labels.extend([label] * n if isinstance(label, str) else list(label))

    def node_bounds(self) -> tuple[np.ndarray, np.ndarray, list]:
        """Bounds (nz × (N+1)) on the node states and the periodic states left for g."""
        p, sched = self.problem, self.schedule
        N = p.intervals
        lo, hi = sched.node_ranges(p, p.state_names)
        for event in sched.events:
            for name in event.conditions:
                if p.is_state(name):
                    i = p.state_names.index(name)
                    a, b = p.bounds(event.conditions, name)
                    lo[i, event.node], hi[i, event.node] = (max(lo[i, event.node], a),
                                                            min(hi[i, event.node], b))
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

    def event_rows(self, node: int, z) -> list:
        """(expression, lo, hi, label) of the conditions on derived quantities at ``node``."""
        p = self.problem
        out = []
        for event in self.schedule.events:
            if event.node == node:
                out += [(p.quantity(n, z), *p.bounds(event.conditions, n), f"{event.label}.{n}")
                        for n in event.conditions if not p.is_state(n)]
        return out

    def add_events_and_periodic(self, Z, periodic_g) -> None:
        """Rows of the conditions on derived quantities at single nodes (``Z``: every node)
        and of the periodic quantities left for g."""
        for node in self.event_nodes():
            for expr, a, c, label in self.event_rows(node, Z[:, node]):
                self.add_g(expr, a, c, label)
        for name in periodic_g:
            f = self.qfun(name)
            self.add_g(f(Z[:, -1]) - f(Z[:, 0]), 0.0, 0.0, f"periodic.{name}")

    def event_nodes(self) -> list:
        """The nodes with rows of their own (conditions on derived quantities)."""
        p = self.problem
        return sorted({e.node for e in self.schedule.events if any(not p.is_state(n) for n in e.conditions)})

    def qfun(self, name):
        zs = ca.SX.sym("z", self.problem.n_states)
        return ca.Function(f"q_{name}", [zs], [self.problem.quantity(name, zs)])

    def mapped_terms(self, stage, Z, args, free: bool) -> list:
        """(functions, arguments, number of leading variable arguments) of the mapped terms of
        a shooting NLP: the stage, then the path bounds on derived quantities of the state
        (at the nodes Z) and of the inputs (with the stage's arguments)."""
        n_var = 3 if free else 2
        specs = [(stage, args, n_var)]
        if self.state_paths:
            specs.append((path_functions(self.problem, self.state_paths, inputs=False,
                                         free_horizon=free), (Z,), 1))
        if self.input_paths:
            specs.append((path_functions(self.problem, self.input_paths, inputs=True, free_horizon=free),
                          args, n_var))
        return specs

    def path_ranges(self) -> PathRanges:
        """(lo, hi) of the state path quantities (m_s × (N+1)) and of the input ones (m_u × N)."""
        p, sched = self.problem, self.schedule
        (slo, shi), (ulo, uhi) = (sched.node_ranges(p, self.state_paths),
                                  sched.node_ranges(p, self.input_paths))
        return PathRanges(slo, shi, ulo[:, :-1], uhi[:, :-1])

    def horizons(self):
        """(the phase horizons as MX (a vector of P, variables or constants), their variable
        symbol or None, their bounds)."""
        sched = self.schedule
        if not sched.variable_horizons:
            return ca.MX(ca.DM(sched.initial_horizons())), None, None
        T = ca.MX.sym("T", sched.n_phases)
        return T, T, sched.horizon_bounds()

    def interval_arguments(self, Trow):
        """The constant rows of the stage arguments: κ (1 × N) and (ν, t0) (2 × N)."""
        sched = self.schedule
        return ca.DM(sched.local_index().astype(float)).T, ca.DM(sched.phase_rows())

    def objective(self, Z, U, h, Tphases):
        """Σ_k h_k Σ_j w_j u_{jk}² + Σ_k h_k Σ_i c_i z_i(t_k)² + c_T Σ_p T_p + Σ_e w_e y_e(t_N);
        ``h`` the interval lengths (1 × N)."""
        p = self.problem
        wu = np.array([float(p.control_weights.get(n, 1.0)) for n in p.control_names])
        f = ca.sum2(h * ca.mtimes(ca.DM(wu).T, U ** 2))
        if p.state_weights:
            wz = np.array([float(p.state_weights.get(n, 0.0)) for n in p.state_names])
            f = f + ca.sum2(h * ca.mtimes(ca.DM(wz).T, Z[:, :-1] ** 2))
        if p.time_weight:
            f = f + float(p.time_weight) * ca.sum1(Tphases)
        for name, weight in p.end_weights.items():
            f = f + float(weight) * self.qfun(name)(Z[:, -1])
        return f

    def finish(self, transcription, decisions: Decisions, f, assembly: Assembly) -> TranscribedNLP:
        """The NLP: ``decisions``, objective ``f``, the rows added (or ``assembly.g``)."""
        g = assembly.g
        if g is None:
            g = ca.vertcat(*self.g) if self.g else ca.MX(0, 1)
        lbg = np.concatenate(self.lbg) if self.lbg else np.zeros(0)
        ubg = np.concatenate(self.ubg) if self.ubg else np.zeros(0)
        d = decisions
        scale = objective_scale(self.problem)
        return TranscribedNLP(problem=self.problem, transcription=transcription, w=d.w, f=scale * f, g=g,
                              lbx=d.lbx, ubx=d.ubx, lbg=lbg, ubg=ubg, node_index=d.node_index,
                              control_index=d.control_index,
                              horizon_indices=tuple(int(i) for i in d.horizon_indices),
                              kernel=assembly.kernel, guess_filler=assembly.guess_filler,
                              structure=assembly.structure, layout=assembly.layout,
                              row_labels=tuple(self.labels), objective_scale=scale)


#: the size of objective both solvers handle well (their barrier starts at μ = 0.1)
OBJECTIVE_REFERENCE = 1e4


def objective_scale(problem) -> float:
    """The factor s of the NLP's objective f = s J: min(1, OBJECTIVE_REFERENCE / J_ref), with
    J_ref = T_max Σ_j w_j max(lo_j², hi_j²) over the bounded inputs (the effort at the bounds
    for the longest horizon) + c_T T_max.

    Ipopt's gradient-based scaling looks at the gradient at the start, which is zero for an
    effort objective from zero inputs; an objective whose optimum is 10⁵–10⁶ (opty's parallel
    park: forces up to 300 N for 30 s) then crawls at μ = 0.1 with tiny steps (288 Ipopt and 278
    FATROP iterations; 37–41 with the objective scaled by any factor from 3.6e-3 to 3.6e-7).
    Objectives that stay below the reference (every built-in gait, opty's garage) are left as
    they are. Reported objectives are J (the solver divides by s)."""
    T = float(problem.free_horizon[1]) if problem.free_horizon is not None else float(problem.horizon)
    lo, hi = problem.control_bound_vectors()
    reach = np.maximum(np.abs(lo), np.abs(hi))
    weights = np.array([float(problem.control_weights.get(n, 1.0)) for n in problem.control_names])
    finite = np.isfinite(reach)
    J_ref = T * float(np.sum(weights[finite] * reach[finite] ** 2)) + float(problem.time_weight) * T
    return 1.0 if not (J_ref > OBJECTIVE_REFERENCE and math.isfinite(J_ref)) else OBJECTIVE_REFERENCE / J_ref


def _bounds_on(n_w: int, *blocks) -> tuple[np.ndarray, np.ndarray]:
    """lbx, ubx of a decision vector of ``n_w`` entries, each block ``(index, lo, hi)`` placed: the
    node bounds, the control bounds, each horizon's (:func:`_horizon_blocks`); ±inf elsewhere."""
    lbx, ubx = np.full(n_w, -np.inf), np.full(n_w, np.inf)
    for index, lo, hi in blocks:
        lbx[index], ubx[index] = lo, hi
    return lbx, ubx


def _horizon_blocks(horizon_indices, Tbounds) -> list:
    """The ``(index, lo, hi)`` block of each phase horizon for :func:`_bounds_on`."""
    return [(i, lo, hi) for i, (lo, hi) in zip(horizon_indices, Tbounds or (), strict=False)]


# ----------------------------------------------------------------------------- multiple shooting
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
        ode = ode_function(problem)
        check_time(problem, ode)
        return stage_functions(ode, steps=self.steps, free_horizon=schedule(problem).variable_horizons,
                               mode=self.stage)

    def settings(self) -> dict:
        return {"transcription": self.name, "rk4_steps": self.steps, "map_mode": self.map_mode}

    def build(self, problem: OptimalControlProblem) -> TranscribedNLP:
        nz, nu, N = problem.n_states, problem.n_controls, problem.intervals
        b = _Builder(problem)
        Tvec, Tsym, Tbounds = b.horizons()
        V = ca.MX.sym("V", nz + nu, N)
        ZN = ca.MX.sym("zN", nz)
        w = ca.vertcat(*([ca.vec(V), ZN] + ([Tsym] if Tsym is not None else [])))
        Z = ca.horzcat(V[:nz, :], ZN)
        U = V[nz:, :]
        stage = self.stage_functions(problem)
        free = b.schedule.variable_horizons
        Trow = b.schedule.horizon_row(Tvec)
        K, PH = b.interval_arguments(Trow)
        args = (Z[:, :N], U, Trow, K, PH)
        specs = b.mapped_terms(stage, Z, args, free)
        slo, shi, ulo_p, uhi_p = b.path_ranges()
        lo, hi, periodic_g = b.node_bounds()

        def g_of(Zend, *paths):
            b.reset()
            b.add_g(ca.vec(Zend - Z[:, 1:]), 0.0, 0.0, "dynamics")
            b.add_events_and_periodic(Z, periodic_g)
            for names, C, a, c in _path_blocks(b, paths, slo, shi, ulo_p, uhi_p):
                b.add_g(ca.vec(C), a.T.ravel(), c.T.ravel(), [f"bounds.{n}" for n in names] * C.shape[1])
            return ca.vertcat(*b.g)

        g, layout = _stage_layout(w, g_of, specs)
        f = b.objective(Z, U, PH[0, :] * Trow, Tvec)
        idx = np.arange((nz + nu) * N).reshape((N, nz + nu)).T        # column k = (z_k, u_k)
        node_index = np.hstack([idx[:nz, :], (nz + nu) * N + np.arange(nz)[:, None]])
        control_index = idx[nz:, :]
        h_index = (tuple(range(int(w.shape[0]) - b.schedule.n_phases, int(w.shape[0])))
                   if Tsym is not None else ())
        lbx, ubx = _bounds_on(int(w.shape[0]), (node_index, lo, hi),
                              (control_index, *b.schedule.control_ranges(problem)),
                              *_horizon_blocks(h_index, Tbounds))
        return b.finish(self, Decisions(w, lbx, ubx, node_index, control_index, h_index), f,
                        Assembly(stage.step, g=g, layout=layout))


def _path_blocks(b: _Builder, paths, slo, shi, ulo, uhi) -> list:
    """(names, values (m × K), lo, hi) of the path terms whose placeholders are ``paths``."""
    blocks, paths = [], list(paths)
    if b.state_paths:
        blocks.append((b.state_paths, paths.pop(0), slo, shi))
    if b.input_paths:
        blocks.append((b.input_paths, paths.pop(0), ulo, uhi))
    return blocks


# ----------------------------------------------------------------------------- collocation
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
        check_time(problem, ode)
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
        Tvec, Tsym, Tbounds = b.horizons()
        blk = nz + nz * d + nu
        V = ca.MX.sym("V", blk, N)
        ZN = ca.MX.sym("zN", nz)
        w = ca.vertcat(*([ca.vec(V), ZN] + ([Tsym] if Tsym is not None else [])))
        Z = ca.horzcat(V[:nz, :], ZN)
        Zc = V[nz:nz + nz * d, :]                   # column k: vec(Z_k), nz*d
        U = V[nz + nz * d:, :]
        Trow = b.schedule.horizon_row(Tvec)
        K, PH = b.interval_arguments(Trow)
        h = PH[0, :] * Trow
        tk = PH[1, :] + K * h
        W = self.interval_function(problem)
        R, Zend = W.map(N, self.map_mode)(Z[:, :N], Zc, U, h, tk)
        # interleave residuals and continuity per interval (banded Jacobian)
        b.add_g(ca.vec(ca.vertcat(R, Zend - Z[:, 1:])), 0.0, 0.0, "dynamics")
        lo, hi, periodic_g = b.node_bounds()
        b.add_events_and_periodic(Z, periodic_g)
        slo, shi, ulo_p, uhi_p = b.path_ranges()
        free = b.schedule.variable_horizons
        paths = []
        if b.state_paths:
            paths.append(path_functions(problem, b.state_paths, inputs=False, free_horizon=free).value
                         .map(N + 1)(Z))
        if b.input_paths:
            paths.append(path_functions(problem, b.input_paths, inputs=True, free_horizon=free).value
                         .map(N)(Z[:, :N], U, Trow, K, PH))
        for names, C, a, c in _path_blocks(b, paths, slo, shi, ulo_p, uhi_p):
            b.add_g(ca.vec(C), a.T.ravel(), c.T.ravel(), [f"bounds.{n}" for n in names] * C.shape[1])
        f = b.objective(Z, U, h, Tvec)
        idx = np.arange(blk * N).reshape((N, blk)).T
        node_index = np.hstack([idx[:nz, :], blk * N + np.arange(nz)[:, None]])
        coll_index = idx[nz:nz + nz * d, :]
        control_index = idx[nz + nz * d:, :]
        h_index = (tuple(range(int(w.shape[0]) - b.schedule.n_phases, int(w.shape[0])))
                   if Tsym is not None else ())
        lbx, ubx = _bounds_on(int(w.shape[0]), (node_index, lo, hi),
                              (control_index, *b.schedule.control_ranges(problem)),
                              *_horizon_blocks(h_index, Tbounds))
        # path bounds on states also hold at the collocation points (those of the interval's phase)
        state_lo, state_hi = b.schedule.interval_ranges(problem, problem.state_names)
        lbx[coll_index] = np.tile(state_lo, (d, 1))
        ubx[coll_index] = np.tile(state_hi, (d, 1))
        tau = self.coefficients()[0]

        def fill(w0, states, controls):
            # collocation states: linear interpolation between the node guesses
            for j in range(d):
                s = tau[j + 1]
                w0[coll_index[j * nz:(j + 1) * nz, :]] = (1 - s) * states[:, :-1] + s * states[:, 1:]

        return b.finish(self, Decisions(w, lbx, ubx, node_index, control_index, h_index), f,
                        Assembly(W, guess_filler=fill))


# ----------------------------------------------------------------------------- stage order (FATROP)
@dataclass(frozen=True)
class StageShooting(MultipleShooting):
    """Multiple shooting in stage order, for structure-exploiting solvers (FATROP).

    FATROP needs an optimal control structure: the decision vector stage by stage,
    w = (x̃_0, u_0, x̃_1, u_1, …, x̃_N), and the constraints stage by stage, each stage's
    dynamics gap x̃_{k+1} − F̃(x̃_k, u_k) followed by the conditions on (x̃_k, u_k) alone
    (path bounds, the conditions of an event at that node). Conditions linking the two ends
    (periodicity) or using global variables (free phase horizons T_p) are made stage-local by
    *carrying* the values along the horizon:

        x̃_k = (z_k, c_k [, T_1,k … T_P,k]),   c_{k+1} = c_k,  T_{p,k+1} = T_{p,k},
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
        sched = b.schedule
        lo, hi, periodic_g = b.node_bounds()
        zs = ca.SX.sym("z", nz)
        yper = ca.Function("y_per", [zs], [ca.vertcat(*[problem.quantity(n, zs) for n in periodic_g])]
                           if periodic_g else [ca.SX(0, 1)])
        nc, free, P = len(periodic_g), sched.variable_horizons, sched.n_phases
        nT = P if free else 0
        nx = nz + nc + nT
        V, XN = ca.MX.sym("V", nx + nu, N), ca.MX.sym("xN", nx)
        w = ca.vertcat(ca.vec(V), XN)                  # (x̃_0, u_0, …, x̃_{N-1}, u_{N-1}, x̃_N)
        X, U = ca.horzcat(V[:nx, :], XN), V[nx:, :]
        Z = X[:nz, :]
        stage = self.stage_functions(problem)
        if free:   # each interval's own phase horizon, read from its stage's carried copy
            Trow = ca.horzcat(*[X[nz + nc + p, int(sched.starts[p]):int(sched.starts[p + 1])]
                                for p in range(P)])
        else:
            Trow = sched.horizon_row(ca.DM(sched.initial_horizons()))
        K, PH = b.interval_arguments(Trow)
        args = (Z[:, :N], U, Trow, K, PH)
        specs = b.mapped_terms(stage, Z, args, free)
        slo, shi, ulo_p, uhi_p = b.path_ranges()
        ends = {0: [], N: []}
        if nc:
            labels = [f"periodic.{n}" for n in periodic_g]
            ends[0].append((X[nz:nz + nc, 0] - yper(Z[:, 0]), 0.0, 0.0, labels))
            ends[N].append((yper(Z[:, N]) - X[nz:nz + nc, N], 0.0, 0.0, labels))
        events = {k: b.event_rows(k, Z[:, k]) for k in b.event_nodes()}
        special = sorted(set(events) | {0, N})
        counts = {}

        def g_of(Zend, *paths):
            b.reset()
            blocks = _path_blocks(b, paths, slo, shi, ulo_p, uhi_p)
            gaps = X[:, 1:] - ca.vertcat(Zend, X[nz:, :N])            # column k: gap of stage k
            for k in range(N + 1):
                counts[k] = 0
            start = 0
            for k in special:
                if start < k:            # the stages start … k−1: no rows of their own, one vectorised block
                    self._run(b, gaps, blocks, start, k, counts)
                self._stage(b, gaps, blocks, k, events.get(k, []) + ends.get(k, []), counts)
                start = k + 1
            return ca.vertcat(*b.g)

        g, layout = _stage_layout(w, g_of, specs)
        wu = np.array([float(problem.control_weights.get(n, 1.0)) for n in problem.control_names])
        hk = PH[0, :] * Trow                           # the step of each interval
        f = ca.sum2(hk * ca.mtimes(ca.DM(wu).T, U ** 2))
        if problem.state_weights:
            wz = np.array([float(problem.state_weights.get(n, 0.0)) for n in problem.state_names])
            f = f + ca.sum2(hk * ca.mtimes(ca.DM(wz).T, Z[:, :N] ** 2))
        if problem.time_weight:
            f = f + float(problem.time_weight) * (ca.sum1(X[nz + nc:, 0]) if free
                                                  else float(np.sum(sched.initial_horizons())))
        for name, weight in problem.end_weights.items():
            f = f + float(weight) * b.qfun(name)(Z[:, N])
        vector = _StageVector(w=w, lo=lo, hi=hi, nx=nx, nc=nc, yper=yper, counts=counts)
        return self._layout(b, vector, f, g, layout)

    @staticmethod
    def _run(b, gaps, blocks, a, c, counts):
        """The stages a … c−1 (none an event's): gap then path rows, one vectorised block."""
        body = ca.vertcat(gaps[:, a:c], *[C[:, a:c] for _, C, _, _ in blocks])
        nx = int(gaps.shape[0])
        lo = np.vstack([np.zeros((nx, c - a))] + [blo[:, a:c] for *_, blo, _ in blocks])
        hi = np.vstack([np.zeros((nx, c - a))] + [bhi[:, a:c] for *_, _, bhi in blocks])
        labels = ["dynamics"] * nx + [f"bounds.{n}" for names, *_ in blocks for n in names]
        b.add_g(ca.vec(body), lo.T.ravel(), hi.T.ravel(), labels * (c - a))
        for k in range(a, c):
            counts[k] = sum(len(names) for names, *_ in blocks)

    @staticmethod
    def _stage(b, gaps, blocks, k, rows, counts):
        """Stage k alone: its gap (k < N, the columns of ``gaps``), its path rows, its events' and
        ends' rows."""
        if k < int(gaps.shape[1]):
            b.add_g(gaps[:, k], 0.0, 0.0, "dynamics")
        n = 0
        for names, C, blo, bhi in blocks:
            if k < C.shape[1]:
                b.add_g(C[:, k], blo[:, k], bhi[:, k], [f"bounds.{m}" for m in names])
                n += len(names)
        for expr, a, c, label in rows:
            b.add_g(expr, a, c, label)
            n += int(expr.shape[0])
        counts[k] = n

    def _layout(self, b, vector: _StageVector, f, g, layout):
        """The NLP in stage order: bounds on w, the FATROP structure and the guess filler."""
        problem, sched = b.problem, b.schedule
        w, lo, hi, nx, nc, yper, counts = (vector.w, vector.lo, vector.hi, vector.nx, vector.nc, vector.yper,
                                           vector.counts)
        nz, nu, N = problem.n_states, problem.n_controls, problem.intervals
        blk = nx + nu
        starts = np.arange(N + 1) * blk
        node_index = starts[None, :] + np.arange(nz)[:, None]
        control_index = starts[None, :N] + nx + np.arange(nu)[:, None]
        ulo, uhi = sched.control_ranges(problem)
        lbx, ubx = _bounds_on(int(w.shape[0]), (node_index, lo, hi), (control_index, ulo, uhi))
        h_index = ()
        if sched.variable_horizons:
            for p, (a, c) in enumerate(sched.horizon_bounds()):
                T_index = starts + nz + nc + p
                lbx[T_index], ubx[T_index] = a, c
            h_index = tuple(int(nz + nc + p) for p in range(sched.n_phases))
        ng = [counts.get(k, 0) for k in range(N + 1)]
        structure = {"N": N, "nx": [nx] * (N + 1), "nu": [nu] * N + [0], "ng": ng}

        def fill(w0, states, controls):
            # the carried copies: y_per(z_0) and the horizons T_p on every stage
            extra = []
            if nc:
                extra.append(np.asarray(yper(states[:, 0])).ravel())
            if h_index:
                extra.append(w0[list(h_index)])
            if extra:
                extra = np.concatenate(extra)
                for k in range(N + 1):
                    w0[starts[k] + nz:starts[k] + nx] = extra

        return b.finish(self, Decisions(w, lbx, ubx, node_index, control_index, h_index), f,
                        Assembly(layout.stage.step, g=g, layout=layout, guess_filler=fill,
                                 structure=structure))


@dataclass(frozen=True, eq=False, kw_only=True)
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
            raise ProblemError([f"unknown transcription {spec!r} (known: "
                                f"{', '.join(TRANSCRIPTIONS)})"]) from None
    return spec
