"""How :func:`~.driver.simulate` integrates, stated once: :class:`SimulationOptions`.

Every option of ``simulate`` besides the model, the time span, the initial state and the
controller — the parameter values among them — is a field here, with its default and its
meaning, and nowhere else: ``simulate(model, t_span, q0, q̇0, method="Radau", rtol=1e-9)`` builds one
``SimulationOptions`` from its keywords (an unknown keyword is a
:class:`~nhgait.dynamics.errors.ModelError` naming the close matches), and every integration
route reads the same object from its :class:`~.integrators.RunRequest`.

The strings a user writes are checked here (:meth:`~SimulationOptions.name_problems`,
:meth:`~SimulationOptions.combination_problems`, :meth:`~SimulationOptions.value_problems`)
and resolved here, once, into what the machinery uses: the constraint stabilisation object
(:attr:`~SimulationOptions.stabilisation`), whether IDAS integrates a DAE form
(:attr:`~SimulationOptions.idas`) and whether SUNDIALS evaluates the inputs
(:attr:`~SimulationOptions.sundials`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from nhgait.dynamics.suggestions import known_names

from ..derivation.formulation_base import STABILISATIONS, Stabilisation, stabilisation_named
from ..errors import ModelError
from .integrators import SCIPY_METHODS

__all__ = ["SimulationOptions", "METHODS", "COMPILED_METHODS", "DAE_FORMS", "SINGULAR_EVENT_TOL"]

#: the compiled explicit Runge–Kutta methods → their scheme
COMPILED_METHODS = {"compiled": "DOP853", "compiled-DOPRI5": "DOPRI5"}
#: every value of ``method``
METHODS = tuple(SCIPY_METHODS) + ("CVODES",) + tuple(COMPILED_METHODS) + ("auto",)
#: the methods that can project the state after every step (``stabilization="projection"``)
PROJECTING_METHODS = tuple(SCIPY_METHODS) + tuple(COMPILED_METHODS)
#: every value of ``dae``
DAE_FORMS = ("index1", "idas")
#: default threshold of the singular-set event (the measure is 1 far from the set, 0 on it)
SINGULAR_EVENT_TOL = 1e-6


@dataclass(frozen=True)
class SimulationOptions:
    """The options of one simulation.

    Attributes
    ----------
    method : one of :data:`METHODS` (see :mod:`.driver`); ignored with ``dae="idas"``.
    rtol, atol : integrator tolerances (SUNDIALS: reltol, abstol).
    t_eval : (N,) output times in t_span, optional; None reports every accepted step (SUNDIALS:
        the interval ends).
    dae : {"index1", "idas"} — how a DAE form is integrated (see :mod:`.driver`).
    stabilization : {None, "baumgarte", "projection"} — constraint stabilisation of the DAE forms.
    baumgarte : (alpha, beta) — ġ + 2αg + β²∫g = 0 when ``stabilization="baumgarte"``.
    max_step : largest step of the scipy and compiled solvers.
    max_steps : cap on accepted steps (SUNDIALS: per output interval); reaching it ends the run
        with status −2.
    singular_tol : the run stops (status −4) where the singular-set measure falls below this;
        None (or 0) disables the event.
    outputs : sequence of names, optional — integrate only what they depend on (:mod:`.closure`).
    quantities : mapping name → sympy expression of (q, q̇, parameters), optional — named
        quantities that ``outputs`` may refer to (a scene's ``[quantities]``).
    params : dict or (n_params,) array, optional — parameter values overriding the system's
        defaults; checked like the defaults (finite, positive-definite kinetic metric).

    Examples
    --------
    >>> options = SimulationOptions(method="RK45", rtol=1e-6)
    >>> options.method, options.atol, options.idas
    ('RK45', 1e-10, False)
    >>> SimulationOptions.from_keywords(options, rtol=1e-9).rtol
    1e-09
    >>> SimulationOptions.from_keywords(mehtod="RK45")
    Traceback (most recent call last):
    ...
    nhgait.dynamics.errors.ModelError: invalid simulation request: 1 problem(s)
      - unknown option 'mehtod': did you mean 'method'? (options: ...)
    """

    method: str = "DOP853"
    rtol: float = 1e-8
    atol: float = 1e-10
    t_eval: object = None
    dae: str = "index1"
    stabilization: str | None = None
    baumgarte: tuple = (1.0, 0.0)
    max_step: float = np.inf
    max_steps: int = 1_000_000
    singular_tol: float | None = SINGULAR_EVENT_TOL
    outputs: object = None
    quantities: dict | None = None
    params: object = None

    @classmethod
    def from_keywords(cls, options: SimulationOptions | None = None, **keywords) -> SimulationOptions:
        """``options`` (default: every default) with ``keywords`` replacing fields; a keyword
        that names no option is a :class:`ModelError`."""
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = [k for k in keywords if k not in names]
        if unknown:
            raise ModelError([f"unknown option {k!r}{known_names(k, names, label='options')}"
                              for k in unknown], title="invalid simulation request")
        return dataclasses.replace(options or cls(), **keywords)

    # ------------------------------------------------------------------ resolved at the boundary
    @property
    def idas(self) -> bool:
        """A DAE form is integrated by IDAS with λ algebraic (``dae="idas"``)."""
        return self.dae == "idas"

    @property
    def sundials(self) -> bool:
        """SUNDIALS integrates (IDAS, or ``method="CVODES"``): the inputs must be CasADi
        expressions of the state."""
        return self.idas or self.method == "CVODES"

    @property
    def stabilisation_type(self) -> type | None:
        """The :class:`~nhgait.dynamics.derivation.formulation_base.Stabilisation` type the
        option names (None for an unknown name)."""
        return STABILISATIONS.get(self.stabilization)

    @cached_property
    def stabilisation(self) -> Stabilisation:
        """The stabilisation object of a checked request (with its Baumgarte gains)."""
        return stabilisation_named(self.stabilization, self.baumgarte)

    # ------------------------------------------------------------------ checks
    def name_problems(self) -> list:
        """The method, DAE form and stabilisation that are not known."""
        problems = []
        if self.method not in METHODS:
            problems.append(f"unknown method {self.method!r} (choose from {', '.join(METHODS)})")
        if self.dae not in DAE_FORMS:
            problems.append(f"unknown dae form {self.dae!r} (choose from {', '.join(DAE_FORMS)})")
        if self.stabilization not in STABILISATIONS:
            problems.append(f"unknown stabilization {self.stabilization!r} (None, 'baumgarte' or "
                            "'projection')")
        return problems

    def combination_problems(self) -> list:
        """Projection with a route that cannot project; Baumgarte gains that are not a pair
        of finite non-negative numbers."""
        problems = []
        kind = self.stabilisation_type
        if kind is not None and kind.projects and (self.idas or self.method not in PROJECTING_METHODS):
            problems.append("stabilization='projection' needs dae='index1' and a scipy or compiled "
                            "method (the state is projected after every step)")
        if kind is not None and kind.feeds_back:
            try:
                alpha, beta = (float(v) for v in self.baumgarte)
                if not (alpha >= 0 and beta >= 0 and np.isfinite(alpha + beta)):
                    problems.append("baumgarte = (alpha, beta) must be finite and ≥ 0, got "
                                    f"{self.baumgarte!r}")
            except (TypeError, ValueError):
                problems.append(f"baumgarte must be a pair (alpha, beta), got {self.baumgarte!r}")
        return problems

    def value_problems(self, t0: float | None, tf: float | None) -> list:
        """The step cap, the tolerances, the event threshold and the output times (checked
        against the span [t0, tf] when it is valid)."""
        problems = []
        if not (isinstance(self.max_steps, (int, np.integer)) and self.max_steps > 0):
            problems.append(f"max_steps must be a positive integer, got {self.max_steps!r}")
        if not (0 < self.rtol < 1 and 0 < self.atol < np.inf):   # rtol = inf: steps of any size, a hang
            problems.append("rtol must lie in (0, 1) and atol be positive and finite, got "
                            f"rtol={self.rtol!r}, atol={self.atol!r}")
        if self.singular_tol is not None and not (0 <= self.singular_tol < 1):
            problems.append(f"singular_tol must be in [0, 1) or None, got {self.singular_tol!r}")
        if self.t_eval is not None and t0 is not None:
            problems += _t_eval_problems(self.t_eval, t0, tf)
        return problems

    def settings(self, model) -> dict:
        """The options as ``Trajectory.settings`` reports them (``dae`` only for a DAE form)."""
        gains = self.stabilisation.gains
        return {"method": self.method, "dae": self.dae if model.dae_options_apply else None,
                "rtol": self.rtol, "atol": self.atol, "stabilization": self.stabilization,
                "baumgarte": None if gains is None else tuple(gains),
                "max_step": self.max_step, "max_steps": self.max_steps}


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


class Span(NamedTuple):
    """A time span as given: its ``problems`` (sentences) and its ends ``t0``, ``tf`` (None
    when it is not a pair of numbers)."""

    problems: list
    t0: float | None
    tf: float | None


def checked_span(t_span) -> Span:
    """``t_span`` read as (t0, tf), with its problems."""
    try:
        t0, tf = (float(v) for v in t_span)
    except (TypeError, ValueError):
        return Span([f"t_span must be a pair (t0, tf), got {t_span!r}"], None, None)
    if not (math.isfinite(t0) and math.isfinite(tf) and tf > t0):
        return Span([f"t_span must be increasing and finite, got ({t0:g}, {tf:g})"], t0, tf)
    return Span([], t0, tf)
