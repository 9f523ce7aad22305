"""Supervised solver attempts and time budgets (issue 24, item 2): the pieces, in this process.

:func:`nhgait.ocp.supervision.supervise` runs each job in a forked child: results in order, up
to ``workers`` at once, a child killed at its limit, a child killed from outside reported as a
failed attempt, an exception in the parent kills every child, and a child never runs the
parent's finalizers. :class:`nhgait.ocp.budget.Budget` interrupts a stage at its deadline; a plan
whose budget runs out fails cleanly, naming the phase. The whole-process behaviour (signals to
``nhgait plan``, ``--time-limit``) is in tests/test_interrupts.py.

Wall-clock bounds here bound how soon something stops (correctness), never how fast work is.
"""
from __future__ import annotations

import io
import os
import signal
import threading
import time
import weakref
from pathlib import Path

import pytest

from nhgait.ocp.budget import (
    ATTEMPT_CAP_S,
    ATTEMPT_FLOOR_S,
    Budget,
    BudgetSpent,
    default_attempt_seconds,
    default_plan_seconds,
)
from nhgait.ocp.supervision import Job, can_fork, supervise

needs_fork = pytest.mark.skipif(not can_fork() or not Path("/proc/self/stat").exists(),
                                reason="needs fork and /proc")


def _alive(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def _failed(status, message, seconds):
    return ("failed", status, message)


def _wait_for(path: Path, timeout: float = 120.0) -> str:
    """The text of ``path`` once it exists (polled); fails after ``timeout`` s (a hang guard)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and path.read_text():
            return path.read_text()
        time.sleep(0.01)
    pytest.fail(f"{path} never appeared")


def _sleep_in_c(pid_file: Path):
    """A job that writes its pid and then sits in C (libc sleep: SIGINT is ignored in a child,
    so nothing brings it back to Python)."""
    def run():
        import ctypes
        pid_file.write_text(str(os.getpid()))
        ctypes.CDLL(None).sleep(3600)
        return "woke up"
    return run


# ----------------------------------------------------------------------------- supervise
@needs_fork
def test_results_come_back_in_order_from_children_two_at_once(tmp_path):
    """Each job runs in its own child (its pid is not ours); with workers=2 two jobs run at
    once — each waits for the other's marker, which only a concurrent run can give."""
    def meet(mine: str, other: str):
        def run():
            (tmp_path / mine).write_text("here")
            deadline = time.monotonic() + 120.0              # a hang guard
            while not (tmp_path / other).exists() and time.monotonic() < deadline:
                time.sleep(0.01)
            return (mine, os.getpid(), (tmp_path / other).exists())
        return run

    out = supervise([Job(meet("a", "b"), 240.0, _failed), Job(meet("b", "a"), 240.0, _failed),
                     Job(lambda: ("c", os.getpid(), True), None, _failed)], workers=2)
    assert [o[0] for o in out] == ["a", "b", "c"]
    assert all(o[2] for o in out)                          # a and b met: they ran at the same time
    assert len({o[1] for o in out} | {os.getpid()}) == 4   # three children, none of them us


@needs_fork
def test_a_child_over_its_limit_is_killed_and_reported(tmp_path):
    """A job stuck in C (an hour's sleep) past its limit: the failed result
    ``Time_Limit_Exceeded``, its process gone (how soon after the limit is no test's business)."""
    pid_file = tmp_path / "pid"
    out, = supervise([Job(_sleep_in_c(pid_file), 0.5, _failed)])
    assert out[:2] == ("failed", "Time_Limit_Exceeded")
    assert "time limit is 0.5 s" in out[2]
    assert not _alive(int(pid_file.read_text()))


@needs_fork
def test_a_child_killed_from_outside_is_a_failed_attempt_not_a_hang(tmp_path):
    """SIGKILL to a running child (a crash, the OOM killer): a failed result naming the signal;
    the next job still runs."""
    pid_file = tmp_path / "pid"

    def kill_it():
        os.kill(int(_wait_for(pid_file)), signal.SIGKILL)

    killer = threading.Thread(target=kill_it, daemon=True)
    killer.start()
    out = supervise([Job(_sleep_in_c(pid_file), 120.0, _failed), Job(lambda: "next", None, _failed)])
    killer.join()
    assert out[0][:2] == ("failed", "Solver_Died")
    assert "SIGKILL" in out[0][2]
    assert out[1] == "next"


@needs_fork
def test_an_exception_in_the_job_is_raised_in_the_parent():
    """Bad input stays bad input: the job's ProblemError comes back as itself."""
    from nhgait.ocp import ProblemError

    def bad():
        raise ProblemError(["intervals = 0 must be an integer ≥ 1"])

    with pytest.raises(ProblemError, match="intervals = 0"):
        supervise([Job(bad, None, _failed)])


@needs_fork
def test_an_interrupt_in_the_parent_kills_every_child_at_once(tmp_path):
    """KeyboardInterrupt (as Ctrl-C raises it) while two children sit in C (an hour's sleep): it
    propagates and both children are gone when it does. The interrupt is a real SIGINT to the
    main thread, which blocks it while it forks. (It was ``_thread.interrupt_main``, which no
    mask blocks: one landing in the parent's at-fork hooks — the second child may write its pid
    before they have run — is dropped there, "Exception ignored"; once, on a loaded machine, the
    interrupt was lost and the test waited on the children's hour-long sleep.)"""
    pids = [tmp_path / "a", tmp_path / "b"]
    main = threading.main_thread().ident

    def interrupt_when_both_run():
        try:
            for path in pids:
                _wait_for(path)
        finally:                              # a child that never starts: fail, do not hang
            signal.pthread_kill(main, signal.SIGINT)

    # Ctrl-C as Python handles it by default, also when this process inherited SIGINT ignored
    # (a background job of a non-interactive shell: Python then installs no handler of its own)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Thread(target=interrupt_when_both_run, daemon=True).start()
        with pytest.raises(KeyboardInterrupt):
            supervise([Job(_sleep_in_c(path), None, _failed) for path in pids], workers=2)
    finally:
        signal.signal(signal.SIGINT, previous)
    children = [int(path.read_text()) for path in pids]
    assert not any(_alive(pid) for pid in children)


@needs_fork
def test_a_child_never_runs_the_parents_finalizers(tmp_path):
    """The parent's weakref.finalize (like the one removing a private JIT folder) runs once,
    in the parent, when it should — not when a child ends."""
    marker = tmp_path / "finalized"

    class Owner:
        pass

    owner = Owner()
    weakref.finalize(owner, marker.write_text, "by the parent")
    assert supervise([Job(lambda: os.getpid(), None, _failed)])[0] != os.getpid()
    assert not marker.exists()
    del owner
    assert marker.read_text() == "by the parent"


def test_without_fork_the_jobs_run_here_and_this_is_said_once(monkeypatch):
    """Where there is no fork the jobs run in this process, in order, and the progress says
    so once per run."""
    from nhgait.dynamics.progress import Progress
    from nhgait.ocp import supervision
    monkeypatch.setattr(supervision, "can_fork", lambda: False)
    stream = io.StringIO()
    progress = Progress(stream)
    assert supervise([Job(os.getpid, 1.0, _failed)] * 2, progress=progress) == [os.getpid()] * 2
    assert supervise([Job(lambda: 3, 1.0, _failed)], progress=progress) == [3]
    assert stream.getvalue().count("solver attempts run in this process") == 1


# ----------------------------------------------------------------------------- budgets
def test_a_stage_is_interrupted_at_its_deadline_and_the_alarm_put_back():
    """A pure-Python loop inside ``stage`` ends with BudgetSpent naming the stage, not before
    the deadline; the SIGALRM handler in place before is in place after."""
    def mine(signum, frame):
        raise AssertionError("not expected")

    before = signal.signal(signal.SIGALRM, mine)
    try:
        budget = Budget(0.3, "test")
        with pytest.raises(BudgetSpent) as spent:
            with budget.stage("derivation"):
                while True:
                    sum(range(100))
        assert spent.value.overrun.phase == "derivation"
        assert spent.value.overrun.elapsed >= 0.3
        assert signal.getsignal(signal.SIGALRM) is mine
        assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    finally:
        signal.signal(signal.SIGALRM, before)


def test_the_alarm_inside_a_c_extension_is_still_the_budget():
    """The alarm's BudgetSpent raised while a C extension runs (CasADi converting a DM during the
    verification's integration) comes back as that extension's SystemError "returned a result
    with an exception set", BudgetSpent its cause: the stage gives back the BudgetSpent (a plan
    once exited 3, an internal error, instead of failing on its budget)."""
    budget = Budget(0.2, "test")
    with pytest.raises(BudgetSpent) as spent:
        with budget.stage("verification"):
            while True:
                try:
                    sum(range(100))
                except BudgetSpent as exc:
                    raise SystemError("<function DM.__array__> returned a result with an "
                                      "exception set") from exc
    assert spent.value.overrun.phase == "verification"
    with pytest.raises(SystemError):                 # any other error passes through unchanged
        with Budget(10.0, "test").stage("verification"):
            raise SystemError("not the budget")


def test_a_swallowed_alarm_comes_again():
    """A handler's exception can be lost on its way up (CasADi's argument conversion clears it
    and tries the next overload): the stage's alarm repeats after its deadline until the stage
    is left, so a lost BudgetSpent is followed by another one about a second later — a plan's
    verification once integrated on for minutes past its budget. (The spin's 120 s is a hang
    guard: without the repeat the stage would end without BudgetSpent.)"""
    budget, swallowed = Budget(0.2, "test"), []
    t0 = time.monotonic()

    def spin():
        while time.monotonic() - t0 < 120.0:
            sum(range(100))

    with pytest.raises(BudgetSpent):
        with budget.stage("verification"):
            for attempt in range(2):
                try:
                    spin()
                except BudgetSpent:
                    if attempt == 0:           # the first one is lost, as inside SWIG
                        swallowed.append(time.monotonic() - t0)
                        continue
                    raise
    again = time.monotonic() - t0
    assert swallowed
    assert swallowed[0] >= 0.2
    assert again > swallowed[0]                         # the repeat (REPEAT_S = 1 s later on a quiet machine)
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_a_far_deadline_arms_a_timer_the_platform_accepts(monkeypatch):
    """``--time-limit 1e10`` (or 1e300): a number of seconds, however large — kept as given,
    never an OverflowError ("timestamp out of range for platform time_t") from ``setitimer``.
    The alarm is armed for at most MAX_ALARM_S and re-arms itself while time is left; the
    handler and timer before the stage are put back."""
    from nhgait.ocp import budget as budget_module
    for seconds in (1e10, 1e300):
        budget = Budget(seconds, "test")
        with budget.stage("derivation"):
            delay, interval = signal.getitimer(signal.ITIMER_REAL)
            assert 0.0 < delay <= budget_module.MAX_ALARM_S
            assert budget.remaining() > 1e9
        assert budget.seconds == seconds
        assert budget.describe() == f"{seconds:g} s (test)"
        assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    monkeypatch.setattr(budget_module, "MAX_ALARM_S", 0.1)       # the steps, made short
    budget = Budget(0.35, "test")
    with pytest.raises(BudgetSpent) as spent:
        with budget.stage("verification"):
            while True:
                sum(range(100))
    assert spent.value.overrun.elapsed >= 0.35           # the early alarms re-armed, not raised


def test_a_budget_limits_attempts_to_the_time_left():
    """100 s started 60 s ago: an attempt gets the 40 s left, less the time this test took
    (bounded by clock readings around it, not by a guess of the machine's speed)."""
    before = time.monotonic()
    budget = Budget(100.0, "test", started=before - 60.0)
    limits = budget.limit(1000.0), budget.limit(None)
    took = time.monotonic() - before
    assert all(40.0 - took <= limit <= 40.0 for limit in limits), (limits, took)
    assert budget.limit(5.0) == 5.0
    assert Budget.unlimited().limit(None) is None
    assert Budget.unlimited().limit(7.0) == 7.0
    spent = Budget(1.0, "test", started=time.monotonic() - 2.0)
    assert spent.spent()
    assert spent.limit(5.0) == 0.0
    with pytest.raises(BudgetSpent, match="ran out during the solves"):
        spent.check("the solves")


def test_the_default_rules():
    """The documented rules: 120 s + 30 s per coordinate; max_iter × 5 evaluations, clipped."""
    assert default_plan_seconds(5) == 270.0
    assert default_plan_seconds(10) == 420.0
    assert default_attempt_seconds(0.01, 500) == 25.0
    assert default_attempt_seconds(1e-6, 500) == ATTEMPT_FLOOR_S
    assert default_attempt_seconds(10.0, 500) == ATTEMPT_CAP_S


def test_the_task_states_its_time_limit():
    """``time_limit`` in [task]: parsed with the other keys, refused unless positive, kept in
    the table written back."""
    from nhgait.gaits.tasks.statement import parse_task
    from nhgait.ocp import ProblemError
    base = {"horizon": 2.0, "intervals": 10, "final": {"x": 1.0}}
    assert parse_task(base).time_limit is None
    task = parse_task({**base, "time_limit": 90})
    assert task.time_limit == 90.0
    assert parse_task(task.to_dict()).time_limit == 90.0
    assert parse_task({**base, "time_limit": "inf"}).time_limit == float("inf")
    with pytest.raises(ProblemError) as bad:
        parse_task({**base, "time_limit": -5, "intervals": 0})
    assert "[task].time_limit = -5 must be a positive number of seconds" in str(bad.value)
    assert "intervals" in str(bad.value)                        # every problem at once


def test_a_plan_whose_budget_runs_out_fails_naming_the_phase(tmp_path):
    """A budget too short for the derivation: no attempt, no file, a failure whose diagnosis
    names the budget, the phase and the option to change."""
    from nhgait.gaits.plan_summary import summary_lines
    from nhgait.gaits.planner import plan
    result = plan("unicycle", "parallel-park", intervals=10, time_limit=1e-3, out_dir=tmp_path / "out")
    assert not result.success
    assert result.solution is None
    assert result.attempts == ()
    assert result.overrun.phase == "derivation"
    assert result.overrun.seconds == 1e-3
    assert result.files == ()
    assert not (tmp_path / "out" / "solution.json").exists()
    text = "\n".join(summary_lines(result))
    assert "FAILED (time budget spent)" in text
    assert ("the time budget of 0.001 s (--time-limit / plan(time_limit=...)) ran out "
            "during derivation" in text)
    assert "--time-limit SECONDS" in text


def test_a_plan_with_a_huge_time_limit_runs_as_if_unlimited(tmp_path):
    """``time_limit=1e300`` (``--time-limit 1e300``): the plan runs and succeeds, its budget the
    number given — once an internal error (OverflowError) from the stage's alarm."""
    from nhgait.gaits.planner import plan
    result = plan("unicycle", "parallel-park", intervals=10, time_limit=1e300)
    assert result.success
    assert result.overrun is None


def test_the_task_time_limit_is_the_plans_budget(monkeypatch):
    """``time_limit`` in the task is used when no ``time_limit`` is given, and said."""
    from nhgait.dynamics.progress import Progress
    from nhgait.gaits.planner import plan_budget
    from nhgait.gaits.tasks.sources import resolve
    stream = io.StringIO()
    budget = plan_budget(resolve("unicycle", "parallel-park", overrides=["time_limit=45"]),
                         progress=Progress(stream))
    assert budget.seconds == 45.0
    assert budget.source == "[task] time_limit"
    assert "time budget: 45 s ([task] time_limit)" in stream.getvalue()
    to_plan = resolve("unicycle", "parallel-park")
    n = len(to_plan.scene.system.coordinates)
    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))       # an idle machine
    assert plan_budget(to_plan).seconds == default_plan_seconds(n) == 120.0 + 30.0 * n


def test_the_default_budget_grows_with_a_busy_machine(monkeypatch):
    """On a machine whose load average is L on C cores each process gets about C/L of a core:
    the default budget is scaled by L/C (at least 1, at most CONTENTION_CAP) and says so; a
    time given by the caller or the task is kept as given (issue 40)."""
    from nhgait.gaits.planner import plan_budget
    from nhgait.gaits.planning import time_limits
    from nhgait.gaits.tasks.sources import resolve
    to_plan = resolve("unicycle", "parallel-park")
    n = len(to_plan.scene.system.coordinates)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    monkeypatch.setattr(os, "getloadavg", lambda: (5.0, 5.0, 5.0))       # 2.5 runnable per core
    budget = plan_budget(to_plan)
    assert budget.seconds == pytest.approx(2.5 * default_plan_seconds(n), rel=1e-12)
    assert "busy machine (load average 5.0 on 2 cores)" in budget.source
    assert plan_budget(to_plan, 30.0).seconds == 30.0
    monkeypatch.setattr(os, "getloadavg", lambda: (40.0, 40.0, 40.0))
    assert plan_budget(to_plan).seconds == pytest.approx(time_limits.CONTENTION_CAP * default_plan_seconds(n))


def test_a_sweep_point_out_of_time_is_a_failed_point_naming_the_budget(tmp_path):
    """``nhgait sweep --time-limit``: each point gets its own budget; a point that runs out is
    recorded failed (``Time_Limit_Exceeded``) with a message naming the budget and the option,
    and the sweep completes."""
    from nhgait.gaits.sweeps.driver import sweep
    result = sweep("unicycle", "parallel-park", ["final.y=0.4,0.5"], out=tmp_path / "sweep", workers=0,
                   overrides=["intervals=10"], options={"time_limit": 1e-3})
    assert result.complete
    assert len(result.records) == 2
    for record in result.records:
        assert not record.success
        assert record.status == "Time_Limit_Exceeded"
        assert "the time budget of 0.001 s (--time-limit per point) ran out during" in record.message
        assert "--time-limit SECONDS (per point)" in record.message


def test_a_stop_stays_a_stop_whatever_it_becomes_on_its_way_up(monkeypatch, capsys):
    """SIGTERM whose Terminated is replaced on its way up (as SWIG's overload dispatch answers
    a failed argument conversion with NotImplementedError) or dropped (by a ``__del__``): the
    command still exits 143 saying "terminated" — not "internal error", not 0."""
    from nhgait.dynamics.errors import Terminated
    from nhgait.gaits.cli import main as cli
    from nhgait.gaits.cli import plan as plan_command

    def replaced(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5.0)                      # the handler raises here
        except Terminated:
            raise NotImplementedError("Wrong number or type of arguments for overloaded function") from None
        return 0

    def dropped(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5.0)
        except Terminated:
            pass
        return 0

    before = signal.getsignal(signal.SIGTERM)
    for run in (replaced, dropped):
        monkeypatch.setattr(plan_command, "run", run)
        assert cli.main(["plan", "unicycle", "--out", "unused"]) == 143
        err = capsys.readouterr().err
        assert "nhgait: terminated" in err
        assert "internal error" not in err
    assert signal.getsignal(signal.SIGTERM) is before             # put back
    time.sleep(2.0)                             # the watchdog, past its 1.5 s, has not ended this process


def test_a_stop_lost_in_one_phase_ends_the_run_before_the_next(monkeypatch, capsys):
    """SIGTERM whose Terminated a C extension swallows inside one phase (here: dropped): the
    run does not go on to its next phase (a plan would write its files) — the next phase is
    never entered, the command exits 143."""
    from nhgait.dynamics.errors import Terminated
    from nhgait.dynamics.progress import Progress
    from nhgait.gaits.cli import main as cli
    from nhgait.gaits.cli import plan as plan_command
    entered = []

    def two_phases(args):
        progress = Progress.silent()
        with progress.phase("first"):
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5.0)
            except Terminated:
                pass                              # lost, as inside CasADi's SWIG wrappers
        with progress.phase("second"):
            entered.append("second")
        return 0

    monkeypatch.setattr(plan_command, "run", two_phases)
    assert cli.main(["plan", "unicycle", "--out", "unused"]) == 143
    assert entered == []
    assert "nhgait: terminated" in capsys.readouterr().err


@needs_fork
def test_meanwhile_runs_once_in_the_parent_while_the_children_work(tmp_path):
    """``meanwhile`` (the planner's imports for its figures) runs once, in this process, after
    the first children started and before their results are collected: the children each
    wait for a file that only ``meanwhile`` writes, so they can answer only if it ran while
    they were alive."""
    flag = tmp_path / "meanwhile-ran"
    calls = []

    def waits_for_flag():
        while not flag.exists():
            os.sched_yield()
        return os.getpid()

    def meanwhile():
        calls.append(os.getpid())
        flag.write_text("ran")

    jobs = [Job(waits_for_flag, 60.0, lambda status, message, seconds: None) for _ in range(3)]
    pids = supervise(jobs, workers=2, meanwhile=meanwhile)
    assert calls == [os.getpid()]                          # once, here
    assert all(pid is not None and pid != os.getpid() for pid in pids)
