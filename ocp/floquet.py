"""Stability of a periodic plan: monodromy matrices and Floquet multipliers, open and closed loop.

Along the plan (t_k, z_k, u_k) of a problem with ODE ż = f(t, z, u), and with a feedback
(:mod:`.feedback`) the closed loop on [t_k, t_{k+1})::

    ż = f(t, z, u_k − K_k (z − z_ref(t)))          (K_k = 0: the open loop),

the monodromy matrix is the derivative of the flow over one period, Φ = ∂z(T)/∂z(0), from the
variational equation integrated with the trajectory (CasADi's CVODES, rtol 1e-10, atol 1e-12,
restarted at each t_k)::

    Φ̇ = (f_z − f_u K_k) Φ,   Φ(0) = I.

Its eigenvalues are the Floquet multipliers μ: a deviation along an eigenvector is multiplied by
μ each time the gait is repeated (a periodic feedback repeats its gains). The closed loop's
multipliers are those of the whole state (the feedback sees every state, the fibre coordinates
included); the open loop's are those of the *periodic states' map* — the block of Φ on the
states outside the fibre (the shape and the velocities, whose dynamics do not depend on the
fibre by the symmetry; the fibre directions themselves are neutral, μ = 1). Verdict:
``stable`` when max |μ| < 1 − :data:`MARGIN`, ``unstable`` when > 1 + :data:`MARGIN`, else
``marginal`` (a multiplier on the unit circle, e.g. a chain of integrators: a fully actuated
shape without restoring forces). The saturation of the inputs is not part of the linearisation.

:func:`finite_difference_monodromy` is the independent check: central differences of the flow
map computed by another integrator (scipy's DOP853, rtol 1e-13), no derivative of f.

The closed loop here is exactly the law of :class:`~nhgait.dynamics.simulation.gain_schedule.GainSchedule`
in the problem's own state (σ = identity); for a periodic gait whose net displacement is a pure
translation the reference of the next period is this one translated, and the error dynamics are
periodic; with a turn (θ(T) ≠ θ(0)) the multipliers describe the first period.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import casadi as ca
import numpy as np

from nhgait.dynamics.simulation.gain_schedule import hermite

__all__ = ["Loop", "Stability", "Verdict", "monodromy", "finite_difference_monodromy", "flow", "stability",
           "MARGIN", "verdict"]

#: |max |μ| − 1| within this is "marginal"
MARGIN = 1e-4


@dataclass(frozen=True)
class Loop:
    """A loop along a plan (module docstring): ``ode`` f(t, z, u) (SX Function); ``t`` (N+1,);
    ``reference`` nz × (N+1); ``controls`` nu × N; ``rates`` (N, 2, nz) the reference's ż at
    both ends of each interval; ``gains`` (N, nu, nz) the feedback K_k, None for the open loop."""

    ode: ca.Function
    t: np.ndarray
    reference: np.ndarray
    controls: np.ndarray
    rates: np.ndarray
    gains: np.ndarray | None = None

    @property
    def nz(self) -> int:
        return self.reference.shape[0]

    def opened(self) -> Loop:
        """The same loop without feedback."""
        return replace(self, gains=None)

    def pieces(self) -> list:
        """Per interval k: (t_k, t_{k+1}, d) with d the numbers read by :func:`_loop_function`."""
        gains = (np.zeros((self.controls.shape[1], self.controls.shape[0], self.nz)) if self.gains is None
                 else np.asarray(self.gains, float))
        return _interval_data(np.asarray(self.t, float), self.controls, gains, self.reference, self.rates)


def _loop_function(ode: ca.Function, nz: int, nu: int, variational: bool) -> ca.Function:
    """(t, X, d) → Ẋ with X = z or (z, vec Φ) and d = (t_k, h, u_k, vec K_k, z_k, z_{k+1}, h ż_k⁺,
    h ż_{k+1}⁻) the numbers of interval k (:func:`_interval_data`)."""
    t, z = ca.SX.sym("t"), ca.SX.sym("z", nz)
    d = ca.SX.sym("d", 2 + nu + nu * nz + 4 * nz)
    t_k, h, u_k = d[0], d[1], d[2:2 + nu]
    K = ca.reshape(d[2 + nu:2 + nu + nu * nz], nu, nz)
    z0, z1, d0, d1 = (d[2 + nu + nu * nz + i * nz:2 + nu + nu * nz + (i + 1) * nz] for i in range(4))
    zdot = ode(t, z, u_k - ca.mtimes(K, z - hermite((t - t_k) / h, z0, z1, d0, d1)))
    if not variational:
        return ca.Function("closed_loop", [t, z, d], [zdot])
    Phi = ca.SX.sym("Phi", nz, nz)
    dPhi = ca.mtimes(ca.jacobian(zdot, z), Phi)          # ∂f/∂z − ∂f/∂u K: u depends on z through −K z
    return ca.Function("variational", [t, ca.vertcat(z, ca.vec(Phi)), d], [ca.vertcat(zdot, ca.vec(dPhi))])


def _interval_data(t, controls, gains, reference, rates) -> list:
    """Per interval k: (t_k, t_{k+1}, d) with d the numbers read by :func:`_loop_function`."""
    out = []
    for k in range(controls.shape[1]):
        h = t[k + 1] - t[k]
        d = np.r_[t[k], h, controls[:, k], gains[k].ravel(order="F"), reference[:, k], reference[:, k + 1],
                  h * rates[k, 0], h * rates[k, 1]]
        out.append((t[k], t[k + 1], d))
    return out


class Monodromy(NamedTuple):
    """What :func:`monodromy` returns."""

    Phi: np.ndarray      #: Φ = ∂z(T)/∂z(0), nz × nz
    final: np.ndarray    #: z(T)


def monodromy(loop: Loop, *, z0=None, rtol: float = 1e-10, atol: float = 1e-12) -> Monodromy:
    """(Φ (nz × nz), z(T)): the variational equation of the module docstring along ``loop``
    from ``z0`` (default: the reference's first node), by CVODES in scaled time per interval."""
    nz, reference = loop.nz, loop.reference
    fn = _loop_function(loop.ode, nz, loop.controls.shape[0], variational=True)
    X, s = ca.SX.sym("X", nz * (nz + 1)), ca.SX.sym("s")
    d = ca.SX.sym("d", fn.size1_in(2))
    scaled = d[1] * fn(d[0] + s * d[1], X, d)             # dX/ds on s ∈ [0, 1], t = t_k + s h
    step = ca.integrator("variational", "cvodes", {"x": X, "p": d, "t": s, "ode": scaled}, 0.0, 1.0,
                         {"abstol": atol, "reltol": rtol, "nonlinear_solver_iteration": "functional"})
    state = np.r_[reference[:, 0] if z0 is None else np.asarray(z0, float), np.eye(nz).ravel(order="F")]
    for _, _, data in loop.pieces():
        state = np.asarray(step(x0=state, p=data)["xf"]).ravel()
    return Monodromy(state[nz:].reshape(nz, nz, order="F"), state[:nz])


def _integrate(fn, X0, pieces, method: str, rtol: float, atol: float) -> np.ndarray:
    from scipy.integrate import solve_ivp
    X = np.asarray(X0, dtype=float)
    for a, b, data in pieces:
        sol = solve_ivp(lambda tt, xx, data=data: np.asarray(fn(tt, xx, data)).ravel(), (a, b), X,
                        method=method, rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(f"the {method} integration of the closed loop failed on [{a:g}, {b:g}]: "
                               f"{sol.message}")
        X = sol.y[:, -1]
    return X


def flow(loop: Loop, z0, *, method: str = "DOP853", rtol: float = 1e-12, atol: float = 1e-14) -> np.ndarray:
    """z(T) of ``loop`` from ``z0`` by scipy's ``method`` (another integrator than :func:`monodromy`'s)."""
    fn = _loop_function(loop.ode, loop.nz, loop.controls.shape[0], variational=False)
    return _integrate(fn, z0, loop.pieces(), method, rtol, atol)


def finite_difference_monodromy(loop: Loop, *, step=None, method: str = "DOP853", rtol: float = 1e-13,
                                atol: float = 1e-15) -> np.ndarray:
    """Φ by central differences of :func:`flow`, column i from z0 ± ε_i e_i with
    ε_i = ``step`` or √rtol · max(1, |z0_i|) (the O(ε²) truncation is then at the level of rtol
    times the flow's third derivative; the integration errors, smooth in z0, largely cancel in
    the difference: on the snakeboard's forward gait the two monodromies agree to 3e-9)."""
    z0 = loop.reference[:, 0]
    nz = z0.size
    Phi = np.empty((nz, nz))
    for i in range(nz):
        eps = step if step is not None else np.sqrt(rtol) * max(1.0, abs(z0[i]))
        e = np.zeros(nz)
        e[i] = eps
        plus = flow(loop, z0 + e, method=method, rtol=rtol, atol=atol)
        minus = flow(loop, z0 - e, method=method, rtol=rtol, atol=atol)
        Phi[:, i] = (plus - minus) / (2 * eps)
    return Phi


class Verdict(NamedTuple):
    """What :func:`verdict` returns."""

    word: str        #: "stable", "marginal" or "unstable"
    radius: float    #: max |μ|


def verdict(multipliers) -> Verdict:
    """("stable" | "marginal" | "unstable", max |μ|)."""
    radius = float(np.max(np.abs(multipliers))) if len(multipliers) else 0.0
    if radius < 1 - MARGIN:
        return Verdict("stable", radius)
    return Verdict("unstable" if radius > 1 + MARGIN else "marginal", radius)


def _complex(values) -> list:
    return [[float(np.real(v)), float(np.imag(v))] for v in values]


@dataclass(kw_only=True, frozen=True)
class Stability:
    """Monodromy matrices and Floquet multipliers of a periodic plan (module docstring).

    ``open_loop``, ``closed_loop``: Φ (nz × nz) in ``state_names`` order; ``periodic_states``:
    the states of the open loop's periodic map; ``open_multipliers``, ``closed_multipliers``:
    eigenvalues sorted by decreasing modulus."""

    period: float
    state_names: tuple
    periodic_states: tuple
    open_loop: np.ndarray
    closed_loop: np.ndarray
    open_multipliers: np.ndarray
    closed_multipliers: np.ndarray

    def verdicts(self) -> dict:
        return {"open_loop": verdict(self.open_multipliers), "closed_loop": verdict(self.closed_multipliers)}

    def summary(self) -> list:
        """One line per loop: the verdict and by how much."""
        lines = []
        for name, (word, radius) in self.verdicts().items():
            loop = name.replace("_", " ")
            if word == "stable":
                how = f"a deviation shrinks to {radius:.3g} of itself each period"
            elif word == "unstable":
                how = f"a deviation grows by {radius:.3g}× each period"
            else:
                how = "a multiplier on the unit circle: deviations neither grow nor shrink geometrically"
            lines.append(f"{loop}: {word}, max |μ| = {radius:.6g} ({how})")
        return lines

    def to_dict(self) -> dict:
        v = self.verdicts()
        return {"period": self.period, "state_names": list(self.state_names),
                "periodic_states": list(self.periodic_states),
                "open_loop": {"verdict": v["open_loop"][0], "max_abs_multiplier": v["open_loop"][1],
                              "multipliers": _complex(self.open_multipliers),
                              "monodromy": self.open_loop.tolist()},
                "closed_loop": {"verdict": v["closed_loop"][0], "max_abs_multiplier": v["closed_loop"][1],
                                "multipliers": _complex(self.closed_multipliers),
                                "monodromy": self.closed_loop.tolist()},
                "summary": self.summary()}


#: up to this many states the monodromies are integrated in this process: the variational
#: system (nz(nz + 1) states) takes tens of milliseconds (the snakeboard's, nz = 8: 35–45 ms a
#: loop), less than forking a child for it; a stop is handled between two intervals' CVODES calls
INLINE_STATES = 10


def _monodromies(loops, workers: int) -> list:
    """Φ of each of ``loops``: in this process for a small state (:data:`INLINE_STATES`), else
    in supervised children."""
    from functools import partial

    from .supervision import Job, supervise
    if all(loop.nz <= INLINE_STATES for loop in loops):
        return [_phi(loop) for loop in loops]
    jobs = [Job(partial(_phi, loop), None, _died) for loop in loops]
    return supervise(jobs, workers=workers)


def _phi(loop: Loop) -> np.ndarray:
    return monodromy(loop).Phi


def _died(status: str, message: str, seconds: float):
    raise RuntimeError(f"the variational equations' process ended without an answer ({status}: {message})")


def _sorted_eigenvalues(M) -> np.ndarray:
    mu = np.linalg.eigvals(M) if M.size else np.zeros(0)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


def stability(ode: ca.Function, feedback, fiber=(), *, workers: int = 2) -> Stability:
    """The :class:`Stability` of the plan of ``feedback`` (:class:`~.feedback.Feedback`) on the
    ODE f(t, z, u) it was designed on; ``fiber``: names of the fibre coordinates. The open and
    the closed loop's :func:`monodromy` are integrated side by side, each in a supervised child
    (:mod:`.supervision`: on ``workers`` cores, stopped with the plan; in this process where
    there is no fork, or for at most :data:`INLINE_STATES` states). Raises RuntimeError when
    CVODES gives up on either."""
    fb = feedback
    closed = Loop(ode, fb.t, fb.states, fb.controls, fb.rates, fb.gains)
    open_loop, closed_loop = _monodromies((closed.opened(), closed), workers)
    keep = [i for i, name in enumerate(fb.state_names) if name not in set(fiber)]
    block = open_loop[np.ix_(keep, keep)]
    return Stability(period=fb.horizon, state_names=tuple(fb.state_names),
                     periodic_states=tuple(fb.state_names[i] for i in keep), open_loop=open_loop,
                     closed_loop=closed_loop, open_multipliers=_sorted_eigenvalues(block),
                     closed_multipliers=_sorted_eigenvalues(closed_loop))
