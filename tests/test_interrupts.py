"""Interrupts clean up (issue 19, item 8) and stop at once (issue 24, item 2).

A SIGTERM or a Ctrl-C while the C compiler runs, or while solver attempts run in their
supervised children, leaves no process and no temporary file behind, exits 143 or 130, and the
next run compiles cleanly; a half-written cache entry is never read. A solver in its C code
does not delay the end (the watchdog forces it); ``--time-limit`` ends a plan that needs longer as a
clean failure; a solver process killed from outside is a failed attempt; the watchdog ends a process
whose main thread is stuck in C.

Solver attempts that never end on their own (:data:`ENDLESS`): the real solver, run again and
again from the same start in the attempt's child — mostly inside its C code — so that a signal
sent once the children run always finds them solving. (The earlier test of this sent the
signal when it saw the pool's two workers; their two half-second solves had often finished by
then, and the plan had gone on to verify and write its figures: the exit 0 was a plan that had
ended before the signal, not a lost signal.)

A plan stopped while its optimised build runs in the background (issue 25) ends that build
too: no builder, no compiler, no build folder.

The compiler is a wrapper script (``$NHGAIT_CC``) that runs the real compiler as its child
and, while ``<tmp>/slow`` exists, sleeps 30 s before waiting for it: the tests control the
timing and never need a long compile. Processes are read from /proc. Each ``nhgait`` run is
started in a session of its own, which every process it starts shares (the compiler's own
process group included), so "no process left" means no live process in that session; a
zombie (exited, not yet reaped by init) counts as gone.

No assertion here reads a clock: how soon a stop lands is measured by
``experiments/stress_sigterm.py`` (a benchmark). Every wait below is a hang guard of
:data:`HANG_S` seconds or more that fails only when something never happens, so the suite passes
on a loaded machine.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(
    not (hasattr(os, "killpg") and hasattr(os, "fork") and Path("/proc/self/stat").exists()),
    reason="needs POSIX process groups, fork and /proc")

REAL_CC = shutil.which("gcc") or shutil.which("cc")
needs_cc = pytest.mark.skipif(REAL_CC is None, reason="no C compiler")

#: a C source that compiles in a few milliseconds
SOURCE = "int nhgait_answer(void) { return 42; }\n"
#: a plan whose NLP compiles in about a second (0.2 MB of C), in the foreground (--jit without a
#: fast compiler: the optimised build now)
PLAN = ["plan", "unicycle", "--gait", "parallel-park", "--intervals", "10", "--no-gif", "--jit"]
#: the nhgait command line with Ctrl-C raising KeyboardInterrupt, as in a terminal (a test
#: runner may have started us with SIGINT ignored, which a child would inherit)
LAUNCHER = ("import signal, sys\n"
            "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "from nhgait.gaits.cli.main import main\n"
            "sys.exit(main())\n")
#: the same with every solver attempt endless (the module docstring)
ENDLESS = ("import signal, sys\n"
           "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
           "from nhgait.ocp.solver import OCPSolver\n"
           "solve_once = OCPSolver._run\n"
           "def endless(self, w0):\n"
           "    while True:\n"
           "        solve_once(self, w0)\n"
           "OCPSolver._run = endless\n"
           "from nhgait.gaits.cli.main import main\n"
           "sys.exit(main())\n")
#: a plan whose attempts run in supervised children (FATROP first: the snakeboard's ODE is small)
PLAN_SOLVES = ["plan", "snakeboard", "--gait", "forward", "--no-jit", "--no-gif"]
#: a plan whose optimised build runs in the background (no --jit: it solves interpreted or fast)
PLAN_BACKGROUND = ["plan", "unicycle", "--gait", "parallel-park", "--intervals", "10", "--no-gif",
                   "--solver", "ipopt"]
#: the hang guard of every wait (seconds): generous, so that it fails only when a process never
#: exits or never starts, not on a loaded machine
HANG_S = 120.0


# ----------------------------------------------------------------------------- processes
@dataclass(frozen=True)
class Proc:
    """One live process as /proc/<pid>/stat tells it."""

    pid: int
    name: str
    ppid: int
    pgrp: int
    session: int


def _processes() -> list[Proc]:
    """Every live process (zombies excluded)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            text = (entry / "stat").read_text()
        except OSError:          # exited while we looked
            continue
        head, tail = text.rsplit(")", 1)
        state, ppid, pgrp, session = tail.split()[:4]
        if state not in ("Z", "X"):
            found.append(Proc(int(entry.name), head.split("(", 1)[1], int(ppid), int(pgrp), int(session)))
    return found


def _live(*, session: int | None = None, pgrp: int | None = None, ppid: int | None = None) -> list[Proc]:
    """The live processes of a session, a process group or a parent."""
    return [p for p in _processes() if (session is None or p.session == session)
            and (pgrp is None or p.pgrp == pgrp) and (ppid is None or p.ppid == ppid)]


def _wait_until(predicate, timeout: float, what: str):
    """The first true value of ``predicate()``, polled every 10 ms; fails after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.01)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")


def _kill_session(session: int) -> None:
    """SIGKILL every live process of ``session`` (processes this test started)."""
    for proc in _live(session=session):
        try:
            os.kill(proc.pid, signal.SIGKILL)
        except ProcessLookupError:   # exited meanwhile
            continue


# ----------------------------------------------------------------------------- the compiler
@dataclass(frozen=True)
class SlowCompiler:
    """The wrapper compiler in ``folder``: slow while ``folder/slow`` exists; each run appends
    its pid (= its process group, nhgait starts it in a group of its own) to ``folder/started``."""

    folder: Path

    @property
    def script(self) -> Path:
        return self.folder / "slowcc.sh"

    def slow(self, on: bool) -> None:
        flag = self.folder / "slow"
        if on:
            flag.touch()
        else:
            flag.unlink(missing_ok=True)

    def runs(self) -> list[int]:
        started = self.folder / "started"
        return [int(line) for line in started.read_text().split()] if started.exists() else []

    def group(self, *names: str) -> list[Proc] | None:
        """The live processes of the first run's process group once processes of all these
        names run in it, else None."""
        runs = self.runs()
        group = _live(pgrp=runs[0]) if runs else []
        return group if set(names) <= {p.name for p in group} else None


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """A private cache directory for this test (and the nhgait processes it starts)."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(folder))
    return folder


@pytest.fixture
def slow_cc(tmp_path, monkeypatch, cache) -> SlowCompiler:
    """``$NHGAIT_CC`` = the wrapper around the real compiler (see :class:`SlowCompiler`)."""
    compiler = SlowCompiler(tmp_path / "cc")
    compiler.folder.mkdir()
    compiler.script.write_text(
        "#!/bin/sh\n"
        f"echo $$ >> '{compiler.folder}/started'\n"
        f"'{REAL_CC}' \"$@\" &\n"
        "compiler=$!\n"
        f"if [ -e '{compiler.folder}/slow' ]; then sleep 30; fi\n"
        "wait $compiler\n")
    compiler.script.chmod(0o700)
    monkeypatch.setenv("NHGAIT_CC", str(compiler.script))
    monkeypatch.setenv("NHGAIT_FAST_CC", "/nonexistent/tcc")     # the plan compiles with the wrapper (--jit)
    monkeypatch.delenv("CC", raising=False)
    return compiler


# ----------------------------------------------------------------------------- nhgait runs
def _start(args: list, tmp_path: Path, launcher: str = LAUNCHER) -> subprocess.Popen:
    """``nhgait <args> --out <tmp>/out`` in a new session, its stdout in ``tmp/stdout.txt``,
    its stderr in ``tmp/stderr.txt``."""
    with open(tmp_path / "stderr.txt", "w") as err, open(tmp_path / "stdout.txt", "w") as out:
        return subprocess.Popen([sys.executable, "-c", launcher, *args, "--out", str(tmp_path / "out")],
                                stdout=out, stderr=err, start_new_session=True)


def _signal_and_wait(proc: subprocess.Popen, signame: str, to_group: bool, timeout: float = HANG_S) -> int:
    """Send ``signame`` to the process (SIGTERM as ``kill`` does) or to its process group (as
    Ctrl-C in a terminal does) and return its exit status; fails, after killing what is left,
    when it does not exit within ``timeout`` s."""
    sig = getattr(signal, signame)
    (os.killpg if to_group else os.kill)(proc.pid, sig)
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_session(proc.pid)
        proc.wait()
        pytest.fail(f"nhgait did not exit within {timeout:.0f} s of {signame}")


def _assert_no_process_left(session: int) -> None:
    deadline = time.monotonic() + HANG_S                # a hang guard: they end at once or never
    while _live(session=session) and time.monotonic() < deadline:
        time.sleep(0.01)
    left = _live(session=session)
    _kill_session(session)
    assert not left, f"processes of session {session} still running {HANG_S:g} s after it ended: {left}"


SIGNALS = [pytest.param("SIGTERM", 143, False, "terminated", id="SIGTERM"),
           pytest.param("SIGINT", 130, True, "interrupted", id="Ctrl-C")]


@needs_cc
@pytest.mark.parametrize("signame, status, to_group, said", SIGNALS)
def test_plan_stopped_while_compiling_leaves_nothing_and_the_next_run_compiles(
        slow_cc, cache, tmp_path, signame, status, to_group, said):
    """SIGTERM (exit 143) or Ctrl-C (130) while cc1 runs: the compiler's whole process group
    (the wrapper, gcc, cc1, the wrapper's sleep) is gone, the jit folder is empty (no build
    folder, no .c, .so or record), and the next run compiles again and leaves one library
    with a record that matches it."""
    slow_cc.slow(True)
    proc = _start(PLAN, tmp_path)
    try:
        group = _wait_until(lambda: slow_cc.group("cc1", "sleep"), HANG_S, "gcc to compile")
    except BaseException:
        _kill_session(proc.pid)
        raise
    assert {"slowcc.sh", "gcc", "cc1", "sleep"} <= {p.name for p in group}
    assert _signal_and_wait(proc, signame, to_group) == status
    assert f"nhgait: {said}" in (tmp_path / "stderr.txt").read_text()
    _assert_no_process_left(proc.pid)                    # gcc, cc1, the wrapper and its sleep
    jit = cache / "jit"
    assert sorted(p.name for p in jit.iterdir()) == []   # no .build-*, no .c, .so or record

    slow_cc.slow(False)                                  # the next run: the same key, clean
    again = subprocess.run([sys.executable, "-c", LAUNCHER, *PLAN, "--out", str(tmp_path / "again")],
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]
    assert len(slow_cc.runs()) == 2                      # compiled, not taken from the cache
    names = sorted(p.name for p in jit.iterdir())
    assert len(names) == 2
    assert names[0].endswith(".json")
    assert names[1].endswith(".so")
    from nhgait.dynamics.numerics.cache import file_sha256
    assert json.loads((jit / names[0]).read_text())["library_sha256"] == file_sha256(jit / names[1])


def _when_solving(proc: subprocess.Popen, children: int) -> list[Proc]:
    """The plan's attempt children once ``children`` of them run (the plan killed on failure)."""
    try:
        return _wait_until(lambda: len(_live(ppid=proc.pid)) >= children and _live(ppid=proc.pid), HANG_S,
                           f"{children} solver processes")
    except BaseException:
        _kill_session(proc.pid)
        raise


@needs_cc
@pytest.mark.parametrize("signame, status, to_group, said",
                         [*SIGNALS, pytest.param("SIGHUP", 129, False, "hung up", id="SIGHUP")])
def test_plan_stopped_while_its_background_build_compiles_leaves_nothing(
        slow_cc, cache, tmp_path, monkeypatch, signame, status, to_group, said):
    """The plan solves (its attempts endless) while its optimised build compiles in the
    background, in a builder of another session (issue 25): SIGTERM, Ctrl-C or SIGHUP (issue 40:
    the terminal closed) to the plan ends the builder and the compiler's whole process group
    too, and leaves no build folder (the plan itself ran interpreted: no fast compiler here,
    nothing else in the jit folder)."""
    monkeypatch.setenv("NHGAIT_BACKGROUND_BUILDS", "1")
    slow_cc.slow(True)
    proc = _start(PLAN_BACKGROUND, tmp_path, ENDLESS)
    try:
        group = _wait_until(lambda: slow_cc.group("cc1", "sleep"), HANG_S, "the background gcc to compile")
        _when_solving(proc, 2)                          # the builder and one attempt
    except BaseException:
        _kill_session(proc.pid)
        raise
    wrapper = next(p for p in group if p.pid == p.pgrp)
    builder = next(p for p in _processes() if p.pid == wrapper.ppid)
    assert builder.ppid == proc.pid  # detached
    assert builder.session == builder.pid != proc.pid
    assert _signal_and_wait(proc, signame, to_group) == status
    assert f"nhgait: {said}" in (tmp_path / "stderr.txt").read_text()
    _assert_no_process_left(proc.pid)
    _assert_no_process_left(builder.session)            # the builder
    assert not _live(pgrp=wrapper.pgrp)                 # the wrapper, gcc, cc1, its sleep
    assert sorted(p.name for p in (cache / "jit").iterdir()) == []


STOPS = [pytest.param("SIGTERM", 143, False, "terminated", id="SIGTERM"),
         pytest.param("SIGTERM", 143, True, "terminated", id="SIGTERM-to-group-as-timeout-sends-it"),
         pytest.param("SIGINT", 130, True, "interrupted", id="Ctrl-C")]


@pytest.mark.parametrize("signame, status, to_group, said", STOPS)
def test_plan_stopped_while_a_solver_iterates_in_c(cache, tmp_path, signame, status, to_group, said):
    """SIGTERM (to the plan, or to its whole group as ``timeout`` sends it) or Ctrl-C while
    the solver runs in its C code: the plan ends with 143 or 130, stopped in its solve phase, and
    no process is left (how soon: experiments/stress_sigterm.py)."""
    proc = _start(PLAN_SOLVES, tmp_path, ENDLESS)
    solvers = _when_solving(proc, 1)
    assert _signal_and_wait(proc, signame, to_group) == status
    err = (tmp_path / "stderr.txt").read_text()
    assert f"nhgait: {said}" in err
    assert "solve with fatrop from up to 12 guesses: stopped after" in err
    assert "Traceback" not in err
    assert not any(_live(ppid=p.pid) for p in solvers)
    _assert_no_process_left(proc.pid)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("signame, status, to_group, said", SIGNALS)
def test_plan_stopped_while_workers_solve_leaves_no_worker(cache, tmp_path, signame, status, to_group, said):
    """SIGTERM or Ctrl-C while two attempts solve at once (``--workers 2``): exit 143 or 130
    no worker left."""
    proc = _start([*PLAN_SOLVES, "--workers", "2"], tmp_path, ENDLESS)
    assert len(_when_solving(proc, 2)) == 2
    assert _signal_and_wait(proc, signame, to_group) == status
    assert f"nhgait: {said}" in (tmp_path / "stderr.txt").read_text()
    _assert_no_process_left(proc.pid)


def test_a_time_limit_ends_a_plan_that_needs_longer_as_a_clean_failure(cache, tmp_path):
    """``--time-limit 5`` on a plan whose attempts never end: it ends by itself (no signal sent;
    the wait is a hang guard) with exit 1, the summary naming the budget, the phase it ran out in
    (the solves, or earlier on a loaded machine) and the option; the closest point in
    solution.json and trajectory.csv when an attempt was made, and nothing else; no process left.
    (How soon after the budget it ends is the benchmark's to measure, not a test's.)"""
    proc = _start([*PLAN_SOLVES, "--time-limit", "5"], tmp_path, ENDLESS)
    try:
        status = proc.wait(timeout=HANG_S)
    except subprocess.TimeoutExpired:
        _kill_session(proc.pid)
        proc.wait()
        pytest.fail(f"the plan outlived its time limit of 5 s by {HANG_S:g} s")
    assert status == 1
    out = (tmp_path / "stdout.txt").read_text()
    assert re.search(r"wall time +([0-9.]+) s in all", out), out
    assert "FAILED (time budget spent" in out
    assert "--time-limit SECONDS" in out
    phases = ("derivation", "the initial guesses", "the NLP set-up and compilation for fatrop",
              "the solves with fatrop")
    assert any(f"the time budget of 5 s (--time-limit / plan(time_limit=...)) ran out during {phase} " in out
               for phase in phases), out
    attempted = "no attempt was made" not in out
    written = sorted(p.name for p in (tmp_path / "out").iterdir()) if (tmp_path / "out").exists() else []
    assert written == (["solution.json", "trajectory.csv"] if attempted else [])
    if attempted:
        saved = json.loads((tmp_path / "out" / "solution.json").read_text())
        assert saved["success"] is False
        assert "time budget" in saved["diagnosis"][0]
    _assert_no_process_left(proc.pid)


def test_a_solver_process_killed_from_outside_is_a_failed_attempt(cache, tmp_path):
    """SIGKILL to the attempt's process (a crash, the OOM killer): the plan reports the attempt
    as failed, naming the signal, and goes on to the next guess; then SIGTERM ends it."""
    proc = _start(PLAN_SOLVES, tmp_path, ENDLESS)
    first, = _when_solving(proc, 1)
    os.kill(first.pid, signal.SIGKILL)
    err = tmp_path / "stderr.txt"
    _wait_until(lambda: "the solver's process died of SIGKILL" in err.read_text(), HANG_S,
                "the failed attempt")
    _wait_until(lambda: [p for p in _live(ppid=proc.pid) if p.pid != first.pid], HANG_S, "the next attempt")
    assert _signal_and_wait(proc, "SIGTERM", False) == 143
    _assert_no_process_left(proc.pid)


@pytest.mark.parametrize("signame, status, to_group, said", STOPS)
def test_a_sweep_stopped_while_its_workers_solve_leaves_nothing(cache, tmp_path, signame, status, to_group,
                                                                said):
    """A sweep on the local pool (two workers, each point's attempts supervised children of a
    worker), stopped once it has stored a point: 143 or 130, no worker and no solver process left."""
    out = tmp_path / "out"
    proc = _start(["sweep", "unicycle", "--gait", "parallel-park", "--grid", "final.y=0.3:0.7:21", "--set",
                   "intervals=50", "--workers", "2"], tmp_path)
    try:
        _wait_until(lambda: len(_live(ppid=proc.pid)) >= 2 and (out / "solutions").exists()
                    and any((out / "solutions").iterdir()), 240.0, "the first point stored")
    except BaseException:
        _kill_session(proc.pid)
        raise
    assert _signal_and_wait(proc, signame, to_group) == status
    assert "nhgait" in (tmp_path / "stderr.txt").read_text()
    _assert_no_process_left(proc.pid)


@needs_cc
def test_a_library_without_its_record_is_never_loaded(cache):
    """A library whose record is missing (a writer killed between its two moves), here also
    half-written, is rebuilt rather than loaded; the rebuilt one is trusted again."""
    import ctypes

    from nhgait.dynamics.numerics.cache import file_sha256
    from nhgait.dynamics.numerics.compiler import build_library
    first = build_library(SOURCE)
    record = first.path.with_suffix(".json")
    assert build_library(SOURCE).cached
    record.unlink()                                       # a writer killed between the moves
    first.path.write_bytes(b"\x7fELF, half of it")        # ... or while writing the library
    again = build_library(SOURCE)
    assert not again.cached
    assert again.path == first.path
    assert json.loads(record.read_text())["library_sha256"] == file_sha256(again.path)
    assert ctypes.CDLL(str(again.path)).nhgait_answer() == 42
    assert build_library(SOURCE).cached


# ----------------------------------------------------------------------------- model cache
def test_a_half_written_cache_entry_is_never_read(cache, monkeypatch):
    """A model-cache write interrupted mid-way leaves no file; a complete entry still under
    its .tmp-* name (writer killed before os.replace) is not read; a truncated entry under the
    final name is refused with a warning; a whole entry is read."""
    from nhgait.dynamics.numerics import cache as entries
    key = entries.make_key("test_interrupts", "half-written")
    replace = os.replace

    def interrupt_before_the_rename(*args):
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:                  # Ctrl-C between the write and the rename
        patch.setattr(entries.os, "replace", interrupt_before_the_rename)
        with pytest.raises(KeyboardInterrupt):
            entries.store(key, {"answer": 42})
    assert entries.os.replace is replace
    assert sorted(p.name for p in cache.iterdir()) == []  # the temporary file is removed
    assert entries.load(key, dict) is None

    entries.store(key, {"answer": 42})                    # a writer killed before its os.replace:
    os.replace(entries.path_for(key), cache / ".tmp-killed.pkl")   # a complete .tmp-* file
    assert entries.load(key, dict) is None

    whole = (cache / ".tmp-killed.pkl").read_bytes()      # a non-atomic writer killed mid-way
    entries.path_for(key).write_bytes(whole[: len(whole) // 2])
    with pytest.warns(entries.UntrustedCacheWarning, match="unreadable cache entry"):
        assert entries.load(key, dict) is None
    entries.store(key, {"answer": 42})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert entries.load(key, dict) == {"answer": 42}


def _stuck_in_c(setup: str, context: str, said: str = "") -> tuple:
    """Run a script whose main thread, inside ``with stop_signals(), <context>:``, sits in a long
    C call (a large matrix product), SIGTERM it there: (exit status, its stderr, the words it
    printed after 'ready'). ``setup`` runs first; ``said`` is an expression printed after 'ready'.
    'ready' comes from a helper thread once the main thread has spent 0.2 s of its own CPU time
    since entering the block (its per-thread CPU clock, not the wall clock): it is then inside the
    product whatever the machine's load — no sleep decides when the signal is sent."""
    script = ("import subprocess, sys, threading, time, numpy as np\n"
              "from pathlib import Path\n"
              "from nhgait.dynamics.errors import temporary_folder\n"
              "from nhgait.gaits.cli.stopping import stop_signals\n"
              f"{setup}\n"
              "a = np.ones((6000, 6000))\n"
              "main = time.pthread_getcpuclockid(threading.main_thread().ident)\n"
              f"words = ['ready', str({said or repr('')})]\n"
              "def announce():\n"
              "    start = time.clock_gettime(main)\n"
              "    while time.clock_gettime(main) - start < 0.2:\n"
              "        time.sleep(0.01)\n"
              "    print(*words, flush=True)\n"
              f"with stop_signals(){', ' + context if context else ''}:\n"
              "    threading.Thread(target=announce, daemon=True).start()\n"
              "    for _ in range(100):\n"
              "        a @ a\n"
              "sys.exit(0)\n")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, env={**os.environ, "OMP_NUM_THREADS": "1",
                                                                    "OPENBLAS_NUM_THREADS": "1"})
    try:
        words = proc.stdout.readline().split()
        assert words[:1] == ["ready"], proc.stderr.read()[-2000:]
        proc.send_signal(signal.SIGTERM)
        status = proc.wait(timeout=HANG_S)
    finally:
        _kill_session(proc.pid)
    return status, proc.stderr.read(), words[1:]


def test_a_forced_end_removes_the_staging_folder_being_written(tmp_path):
    """SIGTERM while the main thread is in C inside a staged write (the outputs' ``.writing-*``
    folder): the watchdog ends the process (143) and the folder is gone with it."""
    staging = tmp_path / ".writing-test"
    status, stderr, _ = _stuck_in_c(f"staging = Path({str(staging)!r}); staging.mkdir()\n"
                                    "(staging / 'solution.json').write_text('{')",
                                    "temporary_folder(staging)")
    assert status == 143
    assert "forced" in stderr
    assert not staging.exists()


def test_the_watchdog_ends_a_process_whose_main_thread_is_stuck_in_c(tmp_path):
    """The main thread in a long C call (a large matrix product) cannot run Python's handler:
    the watchdog ends the process with 143 (forced 1.5 s after SIGTERM), saying so, and takes along
    the processes it started — here one in a process group of its own, as the compiler's."""
    status, stderr, (helper,) = _stuck_in_c(
        "helper = subprocess.Popen(['sleep', '600'], start_new_session=True)", "", "helper.pid")
    try:
        assert status == 143
        assert "nhgait: terminated (forced: still running 1.5 s after the signal)" in stderr
        _wait_until(lambda: not [p for p in _processes() if p.pid == int(helper)], HANG_S,
                    "the helper to be gone")
    finally:
        if [p for p in _processes() if p.pid == int(helper)]:
            os.kill(int(helper), signal.SIGKILL)
