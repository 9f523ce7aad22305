"""The values a transcription builds and hands on: the decision vector's layout
(:class:`Decisions`), the assembled terms (:class:`Assembly`), the NLP itself
(:class:`TranscribedNLP`), the ODE and path-bound functions of a problem
(:func:`ode_function`, :func:`path_functions`) and where the mapped terms sit
(:class:`MappedTerm`, :class:`StageLayout`). The transcriptions that build them are in
:mod:`.transcription`, which re-exports these names."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from .problem import OptimalControlProblem
from .schedule import schedule

__all__ = ["TranscribedNLP", "Decisions", "Assembly", "StageLayout", "MappedTerm", "PathFunctions",
           "ode_function", "path_functions"]


@dataclass(frozen=True, eq=False)
class Decisions:
    """The decision vector w, its bounds and where z_k (``node_index``, nz × (N+1)), u_k
    (``control_index``, nu × N) and the phase horizons (``horizon_indices``, empty for fixed
    horizons) sit in it."""

    w: ca.MX
    lbx: np.ndarray
    ubx: np.ndarray
    node_index: np.ndarray
    control_index: np.ndarray
    horizon_indices: tuple = ()


@dataclass(frozen=True, eq=False)
class Assembly:
    """What a transcription adds to its decisions and objective: ``kernel`` (the function
    applied on every interval), ``g`` (its own constraint expression; None: the builder's
    rows), the stage ``layout``, a ``guess_filler`` and the FATROP ``structure``."""

    kernel: ca.Function
    g: Any = None
    layout: StageLayout | None = None
    guess_filler: Any = None
    structure: dict | None = None


@dataclass(frozen=True, eq=False)
class TranscribedNLP:
    """An NLP ``min f(w) s.t. lbg ≤ g(w) ≤ ubg, lbx ≤ w ≤ ubx`` and its layout.

    ``node_index`` (nz × (N+1)) and ``control_index`` (nu × N) give the positions of z_k and
    u_k in w; ``horizon_indices`` the positions of the phase horizons T_p (empty for fixed
    horizons; ``horizon_index`` the first of them, or None).
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
    horizon_indices: tuple
    kernel: ca.Function
    guess_filler: Any = field(default=None, repr=False)
    structure: dict | None = None        # stage structure (N, nx, nu, ng) for FATROP
    layout: StageLayout | None = None  # where the mapped terms sit (shooting only)
    row_labels: tuple = ()               # the condition each row of g states (see _Builder.add_g)
    objective_scale: float = 1.0         # f = objective_scale · J (:func:`objective_scale`)

    @property
    def horizon_index(self) -> int | None:
        return int(self.horizon_indices[0]) if len(self.horizon_indices) else None

    @property
    def schedule(self):
        return schedule(self.problem)

    def violations(self, g: np.ndarray, w: np.ndarray, tol: float = 1e-6) -> dict:
        """Label → largest violation (> ``tol``) of the rows of g and of the bounds on w at a
        point ("dynamics", "initial.x", "final.y", "periodic.psi", "bounds.phi",
        "control_bounds.tau", "horizon"). A solver that fails may return a point outside the
        bounds (FATROP relaxes fixed ones), so both are checked."""
        out = {}
        for labels, lo, hi, value in ((self.row_labels, self.lbg, self.ubg, g),
                                      (self.w_labels(), self.lbx, self.ubx, w)):
            viol = np.maximum(np.maximum(lo - value, value - hi), 0.0)
            for label, v in zip(labels, viol, strict=True):
                if v > tol:
                    out[label] = max(out.get(label, 0.0), float(v))
        return out

    def w_labels(self) -> list:
        """The condition each bound on w states: "<event>.<state>" at a node where an event
        (initial, a waypoint, a phase's end, final) fixes that state, "periodic.<state>" at an end
        node fixed by periodicity (the state fixed at the other end), "bounds.<state>" on the
        other nodes, "control_bounds.<input>", "horizon" (every carried copy of T in the stage
        order); "" for entries that are never bounded (the carried periodic values)."""
        p = self.problem
        labels = [""] * self.n_w
        N = p.intervals
        at = {}
        for event in self.schedule.events:
            for name in event.conditions:
                at[(event.node, name)] = f"{event.label}.{name}"
        for i, name in enumerate(p.state_names):
            for k in range(N + 1):
                j = int(self.node_index[i, k])
                if (k, name) in at:
                    labels[j] = at[(k, name)]
                # see _Builder.node_bounds
                elif k in (0, N) and name in p.periodic and self.lbx[j] == self.ubx[j]:
                    labels[j] = f"periodic.{name}"
                else:
                    labels[j] = f"bounds.{name}"
        for j, name in enumerate(p.control_names):
            for k in range(N):
                labels[int(self.control_index[j, k])] = f"control_bounds.{name}"
        for index in self.horizon_indices:
            labels[int(index)] = "horizon"
        if self.structure is not None and len(self.horizon_indices):   # stage order: T copies on every stage
            block = self.structure["nx"][0] + self.structure["nu"][0]
            for index in self.horizon_indices:
                for k in range(N + 1):
                    labels[int(index) + k * block] = "horizon"
        return labels

    @property
    def n_w(self) -> int:
        return int(self.w.shape[0])

    def pack(self, states: np.ndarray, controls: np.ndarray, horizon: float | None = None) -> np.ndarray:
        """A decision vector from node states (nz × (N+1); the model's states alone are
        completed by the integral states, :meth:`complete`) and controls (nu × N); the phase
        horizons are the problem's initial ones scaled to total ``horizon`` when given."""
        states = self.complete(np.asarray(states, float), np.asarray(controls, float), horizon)
        w0 = np.zeros(self.n_w)
        w0[self.node_index] = states
        w0[self.control_index] = controls
        if len(self.horizon_indices):
            w0[list(self.horizon_indices)] = self.schedule.initial_horizons(horizon)
        if self.guess_filler is not None:
            self.guess_filler(w0, states, np.asarray(controls, float))
        return w0

    def complete(self, states: np.ndarray, controls: np.ndarray, horizon: float | None = None) -> np.ndarray:
        """Node states of the model alone with the integral states appended: I(t_{k+1}) = I(t_k)
        + h_k y(z_k, u_k) (left rectangles from the initial value), a guess of their values."""
        p = self.problem
        n_model = len(p.model_state_names)
        if states.shape[0] != n_model or not p.integrals:
            return states
        t = p.grid(horizon)
        ode = p.ode()
        I = np.zeros((len(p.integrals), states.shape[1]))
        I[:, 0] = [float(np.clip(p.bounds(p.initial, n)[0], -1e300, 1e300)) if n in p.initial else 0.0
                   for n in p.integrals]
        for k in range(states.shape[1] - 1):
            z = np.concatenate([states[:, k], I[:, k]])
            rate = np.asarray(ode(t[k], z, controls[:, k])).ravel()[n_model:]
            I[:, k + 1] = I[:, k] + (t[k + 1] - t[k]) * np.where(np.isfinite(rate), rate, 0.0)
        return np.vstack([states, I])

    def unpack(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(states (nz × (N+1)), controls (nu × N), T) from a decision vector (T: the total
        horizon)."""
        w = np.asarray(w, dtype=float).ravel()
        return w[self.node_index], w[self.control_index], float(np.sum(self.horizons(w)))

    def horizons(self, w: np.ndarray) -> np.ndarray:
        """The phase horizons T_p at a decision vector."""
        if len(self.horizon_indices):
            return np.asarray(w, float).ravel()[list(self.horizon_indices)]
        return self.schedule.initial_horizons()

    def times(self, w: np.ndarray) -> np.ndarray:
        """The node times t_0 … t_N at a decision vector."""
        return self.schedule.grid(horizons=self.horizons(w))


def ode_function(problem: OptimalControlProblem) -> ca.Function:
    """f(t, z, u) of the problem's states with the parameter values substituted (constants
    folded), one SX Function (:meth:`~nhgait.ocp.problem.OptimalControlProblem.ode`)."""
    return problem.ode()


# ----------------------------------------------------------------------------- mapped terms
@dataclass(frozen=True, eq=False)
class PathFunctions:
    """c, ∂c/∂x and ∇²_x(λᵀc) of the path bounds on derived quantities at one node, with the
    argument layout of the stage functions: ``(z)`` for quantities of the state, ``(z, u, T,
    k, phase)`` for quantities of the inputs and accelerations (x = (z, u[, T])); ``hessian``
    takes ``lam`` (one per output) last."""

    step: ca.Function
    jacobian: ca.Function
    hessian: ca.Function
    names: tuple
    n_variables: int
    inputs: bool

    @property
    def value(self) -> ca.Function:
        return self.step

    @property
    def n_outputs(self) -> int:
        return len(self.names)


def path_functions(problem: OptimalControlProblem, names, *, inputs: bool,
                   free_horizon: bool) -> PathFunctions:
    """The :class:`PathFunctions` of the quantities ``names`` (the node time of an input term
    t = t0 + κ ν T enters the forces)."""
    nz, nu, m = problem.n_states, problem.n_controls, len(names)
    z, u, T, k, ph, lam = (ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("T"), ca.SX.sym("k"),
                           ca.SX.sym("phase", 2), ca.SX.sym("lam", m))
    if inputs:
        t = ph[1] + k * ph[0] * T
        c = ca.vertcat(*[problem.quantity(n, z, u=u, t=t) for n in names])
        x, ins, arg_names = (ca.vertcat(z, u, T) if free_horizon else ca.vertcat(z, u)), [z, u, T, k, ph], \
            ["z", "u", "T", "k", "phase"]
    else:
        c = ca.vertcat(*[problem.quantity(n, z) for n in names])
        x, ins, arg_names = z, [z], ["z"]
    value = ca.Function("path", ins, [c], arg_names, ["c"])
    jac = ca.Function("path_jac", ins, [c, ca.jacobian(c, x)], arg_names, ["c", "J"])
    hess = ca.Function("path_hess", ins + [lam], [ca.hessian(ca.dot(lam, c), x)[0]],
                       arg_names + ["lam"], ["H"])
    return PathFunctions(value, jac, hess, tuple(names), int(x.shape[0]), inputs)


@dataclass(frozen=True, eq=False)
class MappedTerm:
    """One function applied at K points and placed in g::

        g(w) ⊃ sign · E F(x_k),   x_k = w[columns[:, k]],

    ``functions`` (``value``, ``jacobian`` → (F, J), ``hessian`` (…, λ) → H), ``arguments``
    (their inputs, expressions of w with K columns; the leading ones make x_k), ``rows``
    (n_outputs × K) the rows of g of each output, ``sign`` ±1."""

    functions: Any
    arguments: tuple
    rows: np.ndarray
    columns: np.ndarray
    sign: float

    @property
    def count(self) -> int:
        return int(self.rows.shape[1])


@dataclass(frozen=True, eq=False)
class StageLayout:
    """Where the mapped terms sit in an NLP::

        g(w) = g_linear(w) + Σ_terms sign · E F(x_k)

    The first term is the shooting stage (``stage``, ``rows``, ``columns``, ``arguments``,
    ``sign`` read it), the others the path bounds on derived quantities."""

    terms: tuple
    g_linear: ca.MX

    stage = property(lambda self: self.terms[0].functions)
    rows = property(lambda self: self.terms[0].rows)
    columns = property(lambda self: self.terms[0].columns)
    arguments = property(lambda self: self.terms[0].arguments)
    sign = property(lambda self: self.terms[0].sign)
