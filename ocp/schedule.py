"""Where each condition and bound of a problem acts: its phases, nodes and intervals.

A problem's time line is one chain of N intervals and N + 1 nodes. Without ``phases`` it is one
phase of N intervals of length h = T / N. With phases p = 1 … P (:class:`~.statement.Phase`)
it is their intervals in order, N = Σ N_p, phase p covering the nodes ``starts[p] …
starts[p+1]`` with intervals of length h_p = T_p / N_p; consecutive phases share their boundary
node, so the state is continuous. Interval k of phase p has

    local index  κ_k = k − starts[p],   ν_k = 1 / N_p,   t_k = t0_p + κ_k ν_k T_p,
    t0_p = Σ_{q<p} T_q,

and the stage functions take (T_p, κ_k, (ν_k, t0_p)) (:mod:`.stage`). When any phase has a free
horizon every phase horizon is a decision variable (the fixed ones bounded lo = hi), so the
horizon of each interval is a selection of the decision vector; a phase's start time t0_p is
then a variable too, which is why a time-dependent model is refused with free multi-phase
horizons (:func:`time_problems`).

**Events** are the conditions at single nodes: ``initial`` (node 0), each waypoint (node
t_w N / T, or t_w N_p / T_p from its phase's start), each phase's ``final`` (its last node) and
the problem's ``final`` (node N). **Path bounds** on a node are the problem's ``state_bounds``
intersected with those of the phases the node belongs to (a boundary node: both); **control
bounds** of an interval are the problem's intersected with its phase's.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np

from .statement import Phase, ProblemError, interval, waypoint_node

__all__ = ["Schedule", "Event", "schedule", "time_problems"]


@dataclass(frozen=True)
class Event:
    """Conditions at one node: ``node`` index, ``label`` ("initial", "final", "waypoint1",
    "phase1.final", …: the prefix of each condition's row label) and ``conditions``."""

    node: int
    label: str
    conditions: dict


class Ranges(NamedTuple):
    """Path bounds (lo, hi) by name and node or interval: :meth:`Schedule.node_ranges` and the others."""

    lo: np.ndarray   #: lower bounds, one row per name
    hi: np.ndarray   #: upper bounds


@dataclass(frozen=True, eq=False)
class Schedule:
    """The phases of a problem laid on its chain of intervals (module docstring).

    Attributes
    ----------
    phases : the phases (one built from the problem's own fields when it has none)
    starts : (P + 1,) the first node of each phase, then N
    interval_phase : (N,) the phase of each interval
    variable_horizons : whether the phase horizons are decision variables (any free)
    events : the :class:`Event` s, in node order (initial first, final last)
    """

    phases: tuple
    starts: np.ndarray
    interval_phase: np.ndarray
    variable_horizons: bool
    events: tuple

    @property
    def intervals(self) -> int:
        return int(self.starts[-1])

    @property
    def n_phases(self) -> int:
        return len(self.phases)

    def horizon_bounds(self) -> list:
        """(lo, hi) of each phase horizon (lo = hi = T_p for a fixed one)."""
        return [interval(p.free_horizon) if p.free_horizon is not None else (float(p.horizon),) * 2
                for p in self.phases]

    def initial_horizons(self, total: float | None = None) -> np.ndarray:
        """T_p of each phase (the initial values of free ones), scaled to sum to ``total``."""
        T = np.array([float(p.horizon) for p in self.phases])
        return T if total is None else T * (float(total) / T.sum())

    def grid(self, total: float | None = None, horizons=None) -> np.ndarray:
        """The node times for the phase horizons ``horizons`` (default :meth:`initial_horizons`
        of ``total``)."""
        T = self.initial_horizons(total) if horizons is None else np.asarray(horizons, float).ravel()
        pieces, t0 = [np.zeros(1)], 0.0
        for p, phase in enumerate(self.phases):
            N = int(phase.intervals)
            pieces.append(t0 + T[p] * np.arange(1, N + 1) / N)
            t0 += T[p]
        return np.concatenate(pieces)

    def local_index(self) -> np.ndarray:
        """κ_k: the index of each interval within its phase."""
        return np.arange(self.intervals) - self.starts[self.interval_phase]

    def phase_rows(self, horizons=None) -> np.ndarray:
        """(2 × N) the constants (ν_k, t0_p) of each interval (t0 from ``horizons``, default the
        initial ones; only meaningful when the start times are constant)."""
        T = self.initial_horizons() if horizons is None else np.asarray(horizons, float)
        t0 = np.concatenate([[0.0], np.cumsum(T)[:-1]])
        nu = np.array([1.0 / int(p.intervals) for p in self.phases])
        return np.vstack([nu[self.interval_phase], t0[self.interval_phase]])

    def horizon_row(self, horizons) -> ca.MX:
        """The horizon T_{p(k)} of each interval (1 × N) from the phase horizons ``horizons``
        (an MX vector of P entries, or numbers), one slice per phase."""
        pieces = [ca.repmat(horizons[p], 1, int(self.starts[p + 1] - self.starts[p]))
                  for p in range(self.n_phases)]
        return ca.horzcat(*pieces)

    def nodes_of_phase(self, p: int) -> range:
        return range(int(self.starts[p]), int(self.starts[p + 1]) + 1)

    # ------------------------------------------------------------------ bounds by node and interval
    def node_ranges(self, problem, names) -> Ranges:
        """(lo, hi), each len(names) × (N + 1): the path bound of each name at each node (±inf
        where none) — the problem's ``state_bounds`` intersected with its phases'."""
        N = self.intervals
        lo, hi = np.full((len(names), N + 1), -np.inf), np.full((len(names), N + 1), np.inf)
        tables = [(problem.state_bounds, range(N + 1))]
        tables += [(phase.state_bounds, self.nodes_of_phase(p)) for p, phase in enumerate(self.phases)]
        for mapping, nodes in tables:
            for i, name in enumerate(names):
                if name in mapping:
                    a, b = interval(mapping[name])
                    nodes = list(nodes)
                    lo[i, nodes] = np.maximum(lo[i, nodes], a)
                    hi[i, nodes] = np.minimum(hi[i, nodes], b)
        return Ranges(lo, hi)

    def interval_ranges(self, problem, names) -> Ranges:
        """(lo, hi), each len(names) × N: the path bound of each name inside each interval (the
        problem's and its phase's; collocation points)."""
        lo, hi = np.full((len(names), self.intervals), -np.inf), np.full((len(names), self.intervals), np.inf)
        tables = [(problem.state_bounds, np.ones(self.intervals, bool))]
        tables += [(phase.state_bounds, self.interval_phase == p) for p, phase in enumerate(self.phases)]
        for mapping, cols in tables:
            for i, name in enumerate(names):
                if name in mapping:
                    a, b = interval(mapping[name])
                    lo[i, cols], hi[i, cols] = np.maximum(lo[i, cols], a), np.minimum(hi[i, cols], b)
        return Ranges(lo, hi)

    def control_ranges(self, problem) -> Ranges:
        """(lo, hi), each nu × N: the bounds of each input on each interval."""
        lo0, hi0 = problem.control_bound_vectors()
        lo, hi = np.repeat(lo0[:, None], self.intervals, 1), np.repeat(hi0[:, None], self.intervals, 1)
        for p, phase in enumerate(self.phases):
            cols = self.interval_phase == p
            for name, value in phase.control_bounds.items():
                i = problem.control_names.index(name)
                a, b = interval(value)
                lo[i, cols], hi[i, cols] = np.maximum(lo[i, cols], a), np.minimum(hi[i, cols], b)
        return Ranges(lo, hi)

    def path_names(self, problem) -> list:
        """Every name bounded on the path somewhere (the problem's and the phases' bounds)."""
        names = dict.fromkeys(problem.state_bounds)
        for phase in self.phases:
            names.update(dict.fromkeys(phase.state_bounds))
        return list(names)


def schedule(problem) -> Schedule:
    """The :class:`Schedule` of ``problem`` (a ProblemStatement or OptimalControlProblem)."""
    if problem.phases:
        phases = tuple(problem.phases)
    else:
        phases = (_own_phase(problem),)
    counts = [int(p.intervals) for p in phases]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    interval_phase = np.repeat(np.arange(len(phases)), counts)
    variable = any(p.free_horizon is not None for p in phases)
    events = [Event(0, "initial", dict(problem.initial))]
    for p, phase in enumerate(phases):
        base = int(starts[p])
        for point in phase.waypoints:
            label = point.name or f"waypoint{len(events)}"
            events.append(Event(base + waypoint_node(point, phase.horizon, phase.intervals), label,
                                dict(point.conditions)))
        if p < len(phases) - 1:
            events.append(Event(int(starts[p + 1]), f"{phase.name or f'phase{p + 1}'}.final",
                                dict(phase.final)))
    events.append(Event(int(starts[-1]), "final", {**dict(phases[-1].final), **dict(problem.final)}))
    return Schedule(phases, starts, interval_phase, variable, tuple(events))


def _own_phase(problem) -> Phase:
    """The single phase of a problem without phases: its horizon, intervals and waypoints (its
    bounds and conditions stay the problem's own)."""
    return Phase(problem.horizon, problem.intervals, problem.free_horizon, waypoints=problem.waypoints)


def time_problems(problem, ode: ca.Function) -> list:
    """A model with time-dependent forces cannot follow a phase of free horizon by another: that
    phase's start time would be a variable of its forces (not supported)."""
    phases = schedule(problem).phases
    if not any(p.free_horizon is not None for p in phases[:-1]):
        return []
    t = ca.SX.sym("t")
    z, u = ca.SX.sym("z", ode.size1_in(1)), ca.SX.sym("u", ode.size1_in(2))
    if ca.depends_on(ode(t, z, u), t):
        return ["phases: the model's forces depend on time t, and a free phase horizon makes the "
                "later phases' start times unknown: fix the horizons of the phases (or of all but the last)"]
    return []


def check_time(problem, ode: ca.Function) -> None:
    problems = time_problems(problem, ode)
    if problems:
        raise ProblemError(problems)
