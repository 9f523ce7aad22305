"""Scenario (robust) planning: one input sequence for several parameter samples at once.

A plan is an open-loop input sequence for a model whose parameters θ are never exactly the
robot's. The scenario problem plans the inputs against S parameter samples θ_1 … θ_S besides
the nominal θ_0: S *copies* of the model's state c^s_k, each integrated by the same RK4 stage
as the plan with its own θ_s, all driven by the *same* inputs u_k and starting from the plan's
own initial state::

    minimise    J(z, u)  +  W · A_s [ Σ_i ((y_i(c^s_N) − y_i(z_N)) / σ_i)² ]
    subject to  the task on the nominal copy z (every condition, bound and phase, hard)
                c^s_0 = z_0,   c^s_{k+1} = F(c^s_k, u_k; θ_s),   s = 1 … S, k = 0 … N−1

with J the task's objective, y_i the ``terminal`` states compared at the end (each copy's
deviation from where the nominal copy ends), σ_i their scales, W the weight and A_s the mean
over the copies (``aggregate = "mean"``) or their largest (``"worst"``: an epigraph variable
τ ≥ e_s, W τ minimised). The copies carry the model's states only (no integral states) and no
bounds: their only role is the objective's terminal deviation. S = 0 is the nominal problem.

**One stage function for every copy.** The copies' ODE takes θ as an argument,
ż = f(t, z, u, θ) (:func:`nhgait.dynamics.numerics.parametric.parametric_rhs`), which the
stage reads from its constant argument ``phase`` = (ν, t0, θ) (:func:`~.stage.phase_size`);
one stage function F is mapped over the S × N columns (copy s, interval k), so the generated
code grows with neither N nor S — only the decision vector does (S · N · nz more entries).

:class:`ScenarioShooting` composes the nominal NLP of :class:`~.transcription.MultipleShooting`
with the copies: w = (w_nominal, vec C[, τ]) with column k of C the copies' states at node k+1,
g = (g_nominal, vec(F(C_k) − C_{k+1})[, e_s − τ]), and the copies' stage is one more mapped
term of the stage layout (:class:`~.nlp.MappedTerm`), so the constraint Jacobian and the
Lagrangian Hessian are assembled from its exact derivatives like the nominal stage's
(:mod:`.derivatives`). The decision vector's ``node_index`` and ``control_index`` are the
nominal copy's: a solution of the scenario NLP is a plan of the nominal problem (its objective
the scenario objective), verified, fed back and tracked as any plan.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import casadi as ca
import numpy as np

from .nlp import MappedTerm, StageLayout, TranscribedNLP
from .problem import OptimalControlProblem, ProblemError
from .schedule import schedule
from .stage import stage_functions
from .transcription import MultipleShooting

__all__ = ["Scenarios", "ScenarioShooting", "AGGREGATES", "terminal_deviations", "rollout", "copy_states",
           "IntervalArguments"]

AGGREGATES = ("mean", "worst")


@dataclass(kw_only=True, frozen=True, eq=False)
class Scenarios:
    """The copies of a scenario problem (module docstring).

    Attributes
    ----------
    ode : ż = f(t, z, u, θ) of the model's states (CasADi Function, θ the whole parameter vector)
    params : (S, n_θ) each copy's parameter vector θ_s
    terminal : the names y_i compared at t_N (states of the model)
    scales : (len(terminal),) σ_i > 0
    weight : W ≥ 0 (of the objective J's units)
    aggregate : "mean" or "worst"
    labels : a label per copy (reports)
    """

    ode: ca.Function
    params: np.ndarray
    terminal: tuple
    scales: np.ndarray
    weight: float
    aggregate: str = "mean"
    labels: tuple = field(default=())

    def __post_init__(self):
        object.__setattr__(self, "params", np.atleast_2d(np.asarray(self.params, dtype=float)))
        object.__setattr__(self, "scales", np.asarray(self.scales, dtype=float).ravel())
        object.__setattr__(self, "terminal", tuple(self.terminal))
        if not self.labels:
            object.__setattr__(self, "labels", tuple(f"copy{s + 1}" for s in range(self.count)))

    @property
    def count(self) -> int:
        return int(self.params.shape[0])

    def problems(self, problem: OptimalControlProblem) -> list:
        """Everything wrong with these copies for ``problem`` (one list)."""
        out, nzm = [], len(problem.model_state_names)
        if self.aggregate not in AGGREGATES:
            out.append(f"robust.aggregate = {self.aggregate!r}: use {' or '.join(map(repr, AGGREGATES))}")
        if not (np.isfinite(self.weight) and self.weight >= 0):
            out.append(f"robust.weight = {self.weight!r} must be a finite number ≥ 0")
        if (self.ode.n_in() != 4 or int(self.ode.size1_in(1)) != nzm
            or int(self.ode.size1_in(3)) != self.params.shape[1]):
            out.append(f"robust: the copies' ODE must be (t, z[{nzm}], u, θ[{self.params.shape[1]}]) -> ż")
        if not np.all(np.isfinite(self.params)):
            out.append("robust: every copy's parameter values must be finite")
        unknown = [n for n in self.terminal if n not in problem.model_state_names]
        if unknown:
            out.append(f"robust.terminal: {', '.join(map(repr, unknown))} not a state of the plan "
                       f"({', '.join(problem.model_state_names)})")
        if len(self.scales) != len(self.terminal) or not np.all(self.scales > 0):
            out.append("robust: one positive scale per terminal state")
        if not self.terminal and self.count:
            out.append("robust.terminal: no state to compare at the end")
        return out

    def indices(self, problem: OptimalControlProblem) -> list:
        return [problem.model_state_names.index(n) for n in self.terminal]

    def describe(self) -> dict:
        return {"copies": self.count, "labels": list(self.labels), "params": self.params.tolist(),
                "terminal": list(self.terminal), "scales": self.scales.tolist(),
                "objective_weight": float(self.weight), "aggregate": self.aggregate}


def terminal_deviations(scenarios: Scenarios, problem, final_states, copy_finals) -> np.ndarray:
    """e_s = Σ_i ((y_i(c^s_N) − y_i(z_N)) / σ_i)² of each copy (S,), numbers or CasADi
    expressions; ``final_states`` z_N (nz), ``copy_finals`` the copies' c^s_N (nz_model × S)."""
    idx = scenarios.indices(problem)
    if isinstance(copy_finals, np.ndarray):
        d = ((copy_finals[idx, :] - np.asarray(final_states, dtype=float)[idx, None])
             / scenarios.scales[:, None])
        return np.sum(d ** 2, axis=0)
    scales = ca.DM(scenarios.scales)
    return [ca.sumsqr((copy_finals[idx, s] - final_states[idx]) / scales) for s in range(scenarios.count)]


class IntervalArguments(NamedTuple):
    """The stage's arguments besides z and u on each of the N intervals: the ``horizons`` T of
    the interval's phase (N,), ``kappa`` (N,) and ``phases`` (2 × N: ν, t0)."""

    horizons: object
    kappa: object
    phases: object


def rollout(scenarios: Scenarios, stage, z0, controls, arguments: IntervalArguments) -> np.ndarray:
    """The copies' node states (S, nz_model, N+1) under ``controls`` (nu × N) from ``z0``, by the
    stage F of the scenario NLP; ``arguments``: the stage's other arguments on each interval."""
    horizons, kappa, phases = arguments
    N = controls.shape[1]
    out = np.zeros((scenarios.count, len(z0), N + 1))
    for s in range(scenarios.count):
        out[s, :, 0] = z0
        ph = np.vstack([phases, np.repeat(scenarios.params[s][:, None], N, axis=1)])
        z = np.asarray(z0, dtype=float)
        for k in range(N):
            z = np.asarray(stage.step(z, controls[:, k], horizons[k], kappa[k], ph[:, k])).ravel()
            out[s, :, k + 1] = z
    return out


def copy_states(nlp: TranscribedNLP, scenarios: Scenarios, w) -> np.ndarray:
    """The copies' node states (S, nz_model, N+1) held in a decision vector ``w`` of the
    scenario NLP ``nlp`` (node 0: the nominal z_0). A vector packed from a plan
    (``nlp.pack(states, controls)``) holds the roll-out of its inputs."""
    w = np.asarray(w, dtype=float).ravel()
    problem, S = nlp.problem, scenarios.count
    nzm, N = len(problem.model_state_names), problem.intervals
    n0 = nlp.n_w - nzm * S * N - (scenarios.aggregate == "worst")
    inner = np.transpose(w[n0:n0 + nzm * S * N].reshape(N, S, nzm), (1, 2, 0))
    start = np.repeat(w[nlp.node_index[:nzm, 0]][None, :, None], S, axis=0)
    return np.concatenate([start, inner], axis=2)


@dataclass(frozen=True)
class ScenarioShooting(MultipleShooting):
    """Multiple shooting of the nominal problem plus the copies of :class:`Scenarios` (module
    docstring). Ipopt only (the decision vector is not in stage order)."""

    scenarios: Scenarios | None = None
    name = "multiple-shooting-scenarios"

    def settings(self) -> dict:
        out = {**super().settings(), "transcription": self.name}
        if self.scenarios is not None:
            out["scenarios"] = self.scenarios.count
        return out

    def build(self, problem: OptimalControlProblem) -> TranscribedNLP:
        nlp0 = MultipleShooting(self.steps, self.map_mode, self.stage).build(problem)
        sc = self.scenarios
        if sc is None or sc.count == 0:
            return replace(nlp0, transcription=self)
        problems = sc.problems(problem)
        if problems:
            raise ProblemError(problems, title="invalid robust planning")
        return _with_copies(self, problem, nlp0, sc)


def _with_copies(method: ScenarioShooting, problem, nlp0: TranscribedNLP, sc: Scenarios) -> TranscribedNLP:
    """The nominal NLP ``nlp0`` with the copies' variables, gaps and objective (module docstring)."""
    nzm, N, S = len(problem.model_state_names), problem.intervals, sc.count
    sched = schedule(problem)
    free = sched.variable_horizons
    _, U, Trow, K, PH = nlp0.layout.terms[0].arguments
    C = ca.MX.sym("C", nzm * S, N)                      # column k: every copy's state at node k + 1
    worst = ca.MX.sym("tau") if sc.aggregate == "worst" else None
    n0, w = nlp0.n_w, ca.vertcat(nlp0.w, ca.vec(C), *([worst] if worst is not None else []))
    z = lambda k: nlp0.w[nlp0.node_index[:nzm, k].tolist()]        # noqa: E731  nominal node k
    copy = lambda s: C[s * nzm:(s + 1) * nzm, :]                  # noqa: E731  copy s, nodes 1 … N
    starts = ca.horzcat(*[ca.horzcat(z(0), copy(s)[:, :N - 1]) for s in range(S)])
    theta = ca.DM(np.repeat(sc.params.T, N, axis=1))
    args = (starts, ca.repmat(U, 1, S), ca.repmat(Trow, 1, S), ca.repmat(K, 1, S),
            ca.vertcat(ca.repmat(PH, 1, S), theta))
    stage = stage_functions(sc.ode, steps=method.steps, free_horizon=free, mode=method.stage)
    ends = ca.horzcat(*[copy(s) for s in range(S)])
    n_g0 = int(nlp0.g.shape[0])
    term = MappedTerm(stage, args, n_g0 + np.arange(nzm * S * N).reshape(S * N, nzm).T,
                      _columns(nlp0, sc, nzm, n0, free, sched), 1.0)
    devs = terminal_deviations(sc, problem, z(N), ca.horzcat(*[copy(s)[:, N - 1] for s in range(S)]))
    rows, lbg, ubg, labels = [-ca.vec(ends)], [np.zeros(nzm * S * N)], [np.zeros(nzm * S * N)], \
        ["scenario.dynamics"] * (nzm * S * N)
    if worst is not None:
        rows.append(ca.vertcat(*devs) - worst)
        lbg.append(np.full(S, -np.inf))
        ubg.append(np.zeros(S))
        labels += ["scenario.worst"] * S
        robust = worst
    else:
        robust = sum(devs) / S
    g_linear = ca.vertcat(nlp0.layout.g_linear, *rows)
    g = ca.vertcat(nlp0.g, ca.vec(stage.step.map(S * N, "serial")(*args)) + rows[0], *rows[1:])
    f = nlp0.f + nlp0.objective_scale * float(sc.weight) * robust
    lbx = np.concatenate([nlp0.lbx, np.full(nzm * S * N, -np.inf)]
                         + ([np.zeros(1)] if worst is not None else []))
    ubx = np.concatenate([nlp0.ubx, np.full(nzm * S * N + (worst is not None), np.inf)])
    fill = _guess_filler(nlp0, sc, stage, IntervalArguments(Trow, K, PH))
    return replace(nlp0, transcription=method, w=w, f=f, g=g, lbx=lbx, ubx=ubx,
                   lbg=np.concatenate([nlp0.lbg, *lbg]), ubg=np.concatenate([nlp0.ubg, *ubg]),
                   layout=StageLayout(nlp0.layout.terms + (term,), g_linear), guess_filler=fill,
                   row_labels=tuple(nlp0.row_labels) + tuple(labels))


def _columns(nlp0, sc, nzm, n0, free, sched) -> np.ndarray:
    """The positions in w of x = (z, u[, T]) of each column (copy s, interval k) of the copies'
    stage: z the nominal z_0 at k = 0, else the copy's own node; u_k shared; T of k's phase."""
    N, S = nlp0.control_index.shape[1], sc.count
    cols = []
    for s in range(S):
        for k in range(N):
            zc = nlp0.node_index[:nzm, 0] if k == 0 else n0 + (k - 1) * nzm * S + s * nzm + np.arange(nzm)
            x = [zc, nlp0.control_index[:, k]]
            if free:
                x.append([nlp0.horizon_indices[int(sched.interval_phase[k])]])
            cols.append(np.concatenate(x))
    return np.array(cols, dtype=int).T


def _guess_filler(nlp0: TranscribedNLP, sc: Scenarios, stage, symbols: IntervalArguments):
    """The copies' states of a guess: the guess's inputs applied to each copy from its z_0
    (:func:`rollout`, so every copy's gaps start at zero); τ: the largest deviation.
    ``symbols``: the nominal stage's horizon row (an expression of the nominal w) and its
    constant κ and phase rows."""
    problem, n0, has_worst = nlp0.problem, nlp0.n_w, sc.aggregate == "worst"
    horizon_row = ca.Function("horizon_row", [nlp0.w], [symbols.horizons])
    nzm, S = len(problem.model_state_names), sc.count
    kappa, phases = np.asarray(symbols.kappa, dtype=float).ravel(), np.asarray(symbols.phases, dtype=float)

    def fill(w0, states, controls):
        if nlp0.guess_filler is not None:
            nlp0.guess_filler(w0, states, controls)
        z0 = w0[nlp0.node_index[:nzm, 0]]
        T = np.asarray(horizon_row(w0[:n0])).ravel()
        copies = rollout(sc, stage, z0, np.asarray(controls, float),
                         IntervalArguments(T, kappa, phases))                     # (S, nzm, N+1)
        N = copies.shape[2] - 1
        w0[n0:n0 + nzm * S * N] = np.transpose(copies[:, :, 1:], (2, 0, 1)).ravel()
        if has_worst:
            zN = w0[nlp0.node_index[:, N]]
            w0[-1] = float(np.max(terminal_deviations(sc, problem, zN, copies[:, :, N].T)))

    return fill
