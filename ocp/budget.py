"""Wall-clock budgets: how long a plan may take, and how long each solver attempt may run.

A :class:`Budget` starts when it is made and runs out ``seconds`` later (None: never)::

    budget = Budget(270.0, "default: 120 s + 30 s per coordinate (n = 5)")
    with budget.stage("derivation"):          # SIGALRM at the deadline: BudgetSpent inside
        model = derive(...)
    limit = budget.limit(attempt_seconds)     # min(the attempt's limit, the time left)
    budget.check("continuation")              # BudgetSpent when nothing is left

* **Stages interrupt.** Inside ``stage(name)`` a spent budget raises :class:`BudgetSpent`
  wherever the main thread is — in sympy, in the compiler's wait (which kills the compiler and
  removes its files), in the verification's integrator: a ``SIGALRM`` timer armed
  at the deadline, repeated every second until the stage is left (a swallowed exception does
  not end the budget; the previous handler and timer restored on leaving; only in the main
  thread — elsewhere the stage checks at its start and end). ``stage(name, interrupt=False)``
  only names the phase: the solver attempts are bounded by their supervisor
  (:mod:`.supervision`), which kills a child at ``limit`` and never needs an interrupt.
* :class:`BudgetSpent` is a ``BaseException`` (like KeyboardInterrupt: no ``except
  Exception`` on the way swallows it); it carries an :class:`Overrun` — the phase it ran out
  in, the budget and where it came from — which the planner turns into a clean failure.

The default rules (docs/gait-planning.md, "Time limits"):

* a plan: :func:`default_plan_seconds` = ``PLAN_BASE_S + PLAN_PER_COORDINATE_S · n`` (120 s +
  30 s per coordinate: 270 s for a 5-coordinate snake, 420 s for 10 coordinates — the cold
  plans of ``experiments/bench_scale.py`` take 7–75 s, 275 s for the 8-link snake whose -O1
  compile alone takes 250 s);
* one solver attempt: :func:`default_attempt_seconds` = ``EVALUATIONS_PER_ITERATION ·
  max_iter · t_eval`` clipped to [``ATTEMPT_FLOOR_S``, ``ATTEMPT_CAP_S``], ``t_eval`` the
  measured seconds of one evaluation of every NLP function the solver uses
  (:meth:`~nhgait.ocp.solver.OCPSolver.evaluation_seconds`).
"""
from __future__ import annotations

import math
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

__all__ = ["Budget", "BudgetSpent", "Overrun", "default_plan_seconds", "default_attempt_seconds",
           "PLAN_BASE_S", "PLAN_PER_COORDINATE_S", "ATTEMPT_FLOOR_S", "ATTEMPT_CAP_S",
           "EVALUATIONS_PER_ITERATION", "KILL_GRACE_S", "MAX_ALARM_S"]

#: a plan's default budget: this much plus PLAN_PER_COORDINATE_S per coordinate (seconds)
PLAN_BASE_S = 120.0
PLAN_PER_COORDINATE_S = 30.0
#: one attempt's default limit: this many evaluations of the NLP functions per iteration allowed
#: (an iteration evaluates each about once plus its line-search trials and factorises the KKT
#: matrix; measured 0.45–0.98 evaluation times per iteration on the snakeboard P2, more only on
#: solves so short that the floor applies, docs/gait-planning.md) ...
EVALUATIONS_PER_ITERATION = 5.0
#: ... never less than this (a process start, a loaded machine) nor more than this (seconds)
ATTEMPT_FLOOR_S = 10.0
ATTEMPT_CAP_S = 300.0
#: after an attempt's limit, the seconds its solver has to stop itself and answer (Ipopt's
#: ``max_wall_time``) before the supervisor kills it
KILL_GRACE_S = 2.0
#: a stage's alarm repeats this often (seconds) after its deadline until the stage is left: an
#: exception raised by the handler can be swallowed on its way up (:func:`_arm`)
REPEAT_S = 1.0
#: the longest delay a stage's alarm is armed for (seconds, 30 days): a deadline further away
#: (``--time-limit 1e10``) is approached in steps of this, each re-armed by the alarm itself —
#: ``setitimer`` refuses delays past ~292 years (nanoseconds in 64 bits: "timestamp out of range")
MAX_ALARM_S = 30 * 86400.0


def default_plan_seconds(n_coordinates: int) -> float:
    """The default budget of a plan of a robot with ``n_coordinates`` (module docstring)."""
    return PLAN_BASE_S + PLAN_PER_COORDINATE_S * int(n_coordinates)


def default_attempt_seconds(evaluation_s: float, max_iter: int) -> float:
    """The default limit of one solver attempt: ``max_iter`` iterations at
    :data:`EVALUATIONS_PER_ITERATION` evaluations of ``evaluation_s`` seconds, clipped."""
    if not math.isfinite(evaluation_s) or evaluation_s <= 0:
        return ATTEMPT_FLOOR_S
    return float(min(ATTEMPT_CAP_S,
                     max(ATTEMPT_FLOOR_S, EVALUATIONS_PER_ITERATION * max_iter * evaluation_s)))


@dataclass(frozen=True)
class Overrun:
    """Where a budget ran out: the ``phase``, the budget's ``seconds`` and ``source`` (what set
    it), and the ``elapsed`` seconds when it was noticed."""

    phase: str
    seconds: float
    source: str
    elapsed: float

    def lines(self, option: str = "--time-limit SECONDS") -> list:
        """The diagnosis: what ran out, where, and what to change."""
        return [f"the time budget of {self.seconds:g} s ({self.source}) ran out during {self.phase} "
                f"(after {self.elapsed:.1f} s)",
                f"to give it more time: {option} (or time_limit = SECONDS in [task]); to need less: fewer "
                "intervals, a nearer target, or a warm start from a previous solution"]


class BudgetSpent(BaseException):
    """The budget ran out (:class:`Overrun` in ``overrun``)."""

    def __init__(self, overrun: Overrun):
        self.overrun = overrun
        super().__init__(f"the time budget of {overrun.seconds:g} s ran out during {overrun.phase}")


@dataclass(eq=False)
class Budget:
    """``seconds`` from ``started`` (``time.monotonic``); None: unlimited. ``source`` says what
    set it (an option, the task, the default rule); ``phase`` is the phase running now."""

    seconds: float | None
    source: str = ""
    started: float = field(default_factory=time.monotonic)
    phase: str = "start-up"

    @classmethod
    def unlimited(cls) -> Budget:
        return cls(None, "unlimited")

    @property
    def limited(self) -> bool:
        return self.seconds is not None

    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def remaining(self) -> float:
        """Seconds left (inf when unlimited, ≤ 0 when spent)."""
        return math.inf if self.seconds is None else self.seconds - self.elapsed()

    def spent(self) -> bool:
        return self.remaining() <= 0.0

    def overrun(self, phase: str | None = None) -> Overrun:
        return Overrun(phase or self.phase, float(self.seconds or math.inf), self.source, self.elapsed())

    def check(self, phase: str | None = None) -> None:
        """:class:`BudgetSpent` when the budget is spent."""
        if self.spent():
            raise BudgetSpent(self.overrun(phase))

    def limit(self, seconds: float | None) -> float | None:
        """An attempt's limit within this budget: min(``seconds``, the time left), None when
        both are unlimited."""
        left = self.remaining()
        if seconds is None:
            return None if math.isinf(left) else max(left, 0.0)
        return max(min(float(seconds), left), 0.0)

    def describe(self) -> str:
        return "unlimited" if self.seconds is None else f"{self.seconds:g} s ({self.source})"

    @contextmanager
    def stage(self, phase: str, *, interrupt: bool = True):
        """Run a phase within the budget (module docstring): checked on entry and on leaving;
        with ``interrupt``, interrupted at the deadline in the main thread."""
        outer, self.phase = self.phase, phase
        self.check()
        armed = interrupt and self.limited and _can_alarm()
        previous = _arm(self, self.remaining()) if armed else None
        try:
            yield self
        except Exception as exc:       # the alarm raised inside a C extension comes back wrapped
            spent = _spent_within(exc)
            if spent is None:
                raise
            raise spent from None
        finally:
            if armed:
                _disarm(previous)
            self.phase = outer
        self.check(phase)


def _spent_within(exc: BaseException) -> BudgetSpent | None:
    """The :class:`BudgetSpent` that ``exc`` wraps, if any: the alarm's exception raised while a
    C extension was running comes back as that extension's error with BudgetSpent as its cause
    or context (CasADi's ``DM.__array__``: "SystemError: … returned a result with an exception
    set")."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, BudgetSpent):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _can_alarm() -> bool:
    return hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()


def _arm(budget: Budget, seconds: float) -> tuple:
    """Raise BudgetSpent in the main thread after ``seconds``, and again every
    :data:`REPEAT_S` until disarmed — an exception raised by a signal handler can be lost
    (inside CasADi's SWIG argument conversion, which clears the error and tries the next
    overload: a plan's verification once ran on for minutes past its one-shot alarm). Returns
    (previous handler, previous timer (delay, interval), the time armed) for :func:`_disarm`."""
    def ran_out(signum, frame):
        left = budget.remaining()
        if left > 0.0:                  # a far deadline, approached in steps of MAX_ALARM_S
            signal.setitimer(signal.ITIMER_REAL, _alarm_delay(left), REPEAT_S)
            return
        raise BudgetSpent(budget.overrun())
    handler = signal.signal(signal.SIGALRM, ran_out)
    timer = signal.setitimer(signal.ITIMER_REAL, _alarm_delay(seconds), REPEAT_S)
    return handler, timer, time.monotonic()


def _alarm_delay(seconds: float) -> float:
    """``seconds`` as a delay ``setitimer`` accepts: at least 1 ms, at most :data:`MAX_ALARM_S`."""
    return min(max(seconds, 1e-3), MAX_ALARM_S)


def _disarm(previous: tuple) -> None:
    """Stop the timer, put back the previous handler and whatever was left of a previous timer."""
    handler, (delay, interval), armed = previous
    signal.setitimer(signal.ITIMER_REAL, 0.0)
    signal.signal(signal.SIGALRM, handler)
    if delay > 0.0:
        signal.setitimer(signal.ITIMER_REAL, _alarm_delay(delay - (time.monotonic() - armed)), interval)
