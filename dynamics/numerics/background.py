"""The optimised library built in the background, for the next run (issues 25 and 40).

A cold plan must not wait for gcc -O1 (2–250 s on the planner's C): it solves with code that is
ready at once (:mod:`.fast_compiler`, or interpreted functions) and asks for the optimised
build, which **the cache's one builder** compiles into the content-hash cache of
:mod:`.compiler` while the plan goes on; the next run (or this process, between its attempts:
``OCPSolver.adopt_optimised``) loads the library from the cache::

    build = start_build(source, Toolchain(flags=("-O1",)), salt="nlp …", slot="snakeboard/forward",
                        estimate_s=37)
    build.state, build.pid, build.key            # "started" or "queued", the builder's pid, "ab12…"

The builder (``python -m nhgait.dynamics.numerics.builder``, :mod:`.builder`) is:

* **One per cache, fed by a queue.** :func:`start_build` writes a request into the cache's queue
  (:mod:`.build_queue`: ``<cache dir>/builds/<slot>.req``) and starts a builder only when none
  runs — the builder lock is taken with ``flock`` under the queue's mutex and handed to the
  builder it starts, so two plans never start two. The builder drains the queue newest request
  first, one compile at a time, and leaves when it is empty. The newest request per ``slot``
  (the robot and the task: an edit with ``--set`` that changes the C replaces the older request)
  wins: the builder drops a stale request, and kills its compiler when the request it is
  compiling is replaced or withdrawn.
* **Bounded.** Each compile has a budget of wall time (:func:`budgets`: a multiple of the
  estimate) and of CPU time per compiler process (``RLIMIT_CPU``, so that a loaded machine does
  not turn into a failure); at its wall budget the compiler is killed and the request dropped
  (tried again by the next plan), at its CPU budget the build counts as failed. The compiler's
  address space is bounded too (:data:`MEMORY_BYTES`). A builder whose cache folder is gone (its
  ``jit/`` or ``builds/`` folder removed or replaced) stops at once — checked between compiles
  and every :data:`~.compiler.WATCH_S` during one, its compiler killed.
* **Stoppable.** SIGTERM, SIGINT and SIGHUP end the builder within a fraction of a second: the
  compiler's process group is killed and its build folder removed (a builder killed by
  SIGKILL takes gcc with it, ``PR_SET_PDEATHSIG``). ``nhgait`` stopped by SIGINT, SIGTERM or
  SIGHUP withdraws its requests (:meth:`Builders.cancel`) and stops the builder when nothing is
  left in the queue; ``nhgait cache stop`` withdraws every request and stops the builder.
* **Detached and finished atomically.** It runs in its own session, so a plan that returns
  does not stop it: a plan that takes 5 s still leaves the library its 60 s compile makes. It
  compiles with :func:`~.compiler.compile_in` into its own build folder
  ``jit/.build-<host>-<builder pid>-…`` (removed whatever happens) and moves the library and
  then its record into place with ``os.replace``: a reader sees the whole library or none.
* **Modest.** Its compiler runs at ``nice`` 19 in a session of its own, whose autogroup is set
  to nice 19 too: where Linux groups the processes of each session (``sched_autogroup``)
  niceness counts only within a group and the groups share the cores equally — a nice-19
  compiler in a group of nice 0 took a whole core from a plan's two threads (the 8-link snake's
  NLP functions on the fast compiler's threads: 248 ms a call, as on one thread; 129 ms with
  the group at nice 19). The builder itself, which only waits and watches (a few ``stat`` calls
  every :data:`~.compiler.WATCH_S`), keeps the plan's priority, so that it answers a signal or a
  deleted cache at once on a loaded machine (at nice 19 and load 14–18 it took 7–9 s).
* **Accountable.** ``nhgait cache`` lists the requests waiting and the running builder (pid,
  age). The record ``<key>.json`` holds the compiler's seconds and peak resident memory
  (``compile_s``, ``compiler_peak_mb``); a compiler that fails writes ``<key>.failed`` (its
  message), and that build is not requested again (delete the file to retry).

``$NHGAIT_BACKGROUND_BUILDS=0`` (or ``nhgait plan --no-background-build``, :func:`builds_off`)
asks for no build (the test suite; CI machines that should not leave work running after a command).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import STOP_SIGNALS
from . import build_queue as queue
from .compiler import (
    Toolchain,
    compiler_command,
    library_dir,
    library_key,
)

__all__ = ["BackgroundBuild", "Builders", "BUILDERS", "start_build", "wait_for_build", "background_allowed",
           "builds_off", "budgets", "stop_builds", "MEMORY_BYTES", "NICENESS", "PENDING", "SKIP",
           "BUILDER_MODULE"]

#: the builder process's module (:mod:`.builder`), run with ``python -m``
BUILDER_MODULE = "nhgait.dynamics.numerics.builder"
#: the compiler's address space limit (bytes; gcc -O1 on 4 MB of CasADi's C: 0.66 GB resident)
MEMORY_BYTES = 2 * 1024 ** 3
#: the builder's niceness (the lowest priority)
NICENESS = 19
#: how long :meth:`Builders.cancel` lets a builder clean up before it is killed (s)
CANCEL_WAIT_S = 2.0
#: the states of a build that is still to come (a builder started for it, or queued to the running one)
PENDING = ("started", "queued")
#: how to do without the build (said with every pending build)
SKIP = "skip it with --no-background-build or NHGAIT_BACKGROUND_BUILDS=0"
#: the compile budgets (:func:`budgets`): wall = max(WALL_MIN_S, WALL_FACTOR × estimate),
#: CPU per compiler process = max(CPU_MIN_S, CPU_FACTOR × estimate); the estimates of
#: ``CompileBudget`` were measured on a loaded 2-core machine (gcc -O1 on 4 MB: 56–71 s quiet).
#: The wall budget is generous because a nice-19 compiler on a machine at load 10–20 gets a
#: small share of a core; the CPU budget is what catches a compile that would never end
WALL_FACTOR, WALL_MIN_S, CPU_FACTOR, CPU_MIN_S = 10.0, 300.0, 4.0, 60.0
#: the estimate (s per MB of C) when the caller gives none
DEFAULT_S_PER_MB = 22.0


def budgets(estimate_s: float) -> tuple:
    """(wall seconds, CPU seconds) a compile estimated at ``estimate_s`` may take (module docstring)."""
    return max(WALL_MIN_S, WALL_FACTOR * estimate_s), max(CPU_MIN_S, CPU_FACTOR * estimate_s)


@dataclass(frozen=True, kw_only=True)
class BackgroundBuild:
    """What was done for the next run: ``state`` is "started" (a builder started for it,
    ``pid``), "queued" (for the builder ``pid`` already running), "off"
    ($NHGAIT_BACKGROUND_BUILDS=0), "failed before" or "unavailable" (``reason`` says why);
    ``key`` the library's cache key, ``flags`` and ``compiler`` the optimised build's,
    ``estimate_s`` and ``budget_s`` its estimated and longest wall time."""

    state: str
    flags: tuple
    compiler: str = ""
    key: str = ""
    pid: int | None = None
    reason: str = ""
    estimate_s: float = 0.0
    budget_s: float = 0.0

    def describe(self) -> dict:
        return {"state": self.state, "flags": list(self.flags), "compiler": self.compiler, "key": self.key,
                "pid": self.pid, "reason": self.reason, "estimate_s": round(self.estimate_s, 1),
                "budget_s": round(self.budget_s, 1), "summary": self.summary()}

    def text(self) -> str:
        """"gcc -O1 building in the background (builder pid 123, …) for the next run" and the like."""
        what = f"{self.compiler} {' '.join(self.flags)}".strip()
        if self.state in PENDING:
            verb = "building" if self.state == "started" else "queued for the builder already running"
            return (f"{what} {verb} in the background for the next run (builder pid {self.pid}, nice "
                    f"{NICENESS}, about {self.estimate_s:.0f} s, stopped after {self.budget_s:.0f} s at "
                    f"most; {SKIP}; `nhgait cache` lists it)")
        return f"{what} not built in the background: {self.reason}"

    def summary(self) -> str:
        """The plan summary's words for a pending build (empty otherwise)."""
        if self.state not in PENDING:
            return ""
        what = f"{self.compiler} {' '.join(self.flags)}".strip()
        return (f"{what} pending in the background for the next run (builder pid {self.pid}, about "
                f"{self.estimate_s:.0f} s; {SKIP})")


class Builders:
    """The builds this process asked for (their request files) and the builders it started
    (their ``Popen`` objects): :meth:`cancel` on a stop, :meth:`wait` where a caller wants the
    library now (benchmarks, tests). This is process state — like the children
    :mod:`subprocess` tracks — not an option."""

    def __init__(self):
        self._procs: list = []
        self._requests: list = []          # (queue folder, request path, inode)

    def add(self, proc: subprocess.Popen | None, request: tuple) -> None:
        self._procs = [p for p in self._procs if p.poll() is None] + ([proc] if proc is not None else [])
        self._requests = [r for r in self._requests if _current(r) and r[1] != request[1]] + [request]

    def running(self) -> list:
        """The builders this process started that are still running."""
        return [p for p in self._procs if p.poll() is None]

    def pending(self) -> list:
        """This process's requests still in their queue: (queue folder, path, inode)."""
        return [r for r in self._requests if _current(r)]

    def wait(self, timeout: float | None = None, poll: float = 0.05) -> bool:
        """Wait until every request of this process was served (its library built, or failed,
        or dropped) or no builder is left to serve it (True), or ``timeout`` seconds passed (False)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while any(queue.holder(folder) is not None for folder, _, _ in self.pending()):
            if deadline is not None and time.monotonic() > deadline:
                return False
            time.sleep(poll)
        for proc in self._procs:               # reap the builders that left
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(CANCEL_WAIT_S)
        return True

    def terminate(self) -> None:
        """Withdraw this process's requests and SIGTERM a builder left with nothing to do,
        without waiting: the stop watchdog's way, which has no time to wait."""
        for folder in self._withdraw():
            _stop_idle(folder, wait=False)

    def cancel(self) -> int:
        """Withdraw this process's requests (a builder compiling one kills its compiler and
        goes on with the others) and stop the builder when the queue is left empty (SIGTERM:
        it kills its compiler and removes its folder; SIGKILL after :data:`CANCEL_WAIT_S`);
        how many requests were withdrawn."""
        pending = self.pending()
        for folder in self._withdraw():
            _stop_idle(folder, wait=True)
        self._procs = [p for p in self._procs if p.poll() is None]     # the ended ones reaped
        return len(pending)

    def _withdraw(self) -> set:
        folders = set()
        for folder, path, inode in self._requests:
            queue.withdraw(folder, path, inode)
            folders.add(folder)
        self._requests = []
        return folders


def _current(request: tuple) -> bool:
    try:
        return os.stat(request[1]).st_ino == request[2]
    except OSError:
        return False


def _stop_idle(folder: Path, *, wait: bool) -> bool:
    """SIGTERM the builder of the queue ``folder`` when no request is left in it (then SIGKILL
    after :data:`CANCEL_WAIT_S` with ``wait``); whether one was stopped."""
    info = queue.holder(folder)
    if info is None or _has_requests(folder) or not _is_builder(info.pid):
        return False
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.kill(info.pid, signal.SIGTERM)
    if not wait:
        return True
    deadline = time.monotonic() + CANCEL_WAIT_S
    while _alive(info.pid) and time.monotonic() < deadline:
        time.sleep(0.02)
    if _alive(info.pid):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(info.pid, signal.SIGKILL)
        deadline = time.monotonic() + CANCEL_WAIT_S
        while _alive(info.pid) and time.monotonic() < deadline:
            time.sleep(0.01)
    return True


def stop_builds(cache: Path) -> tuple:
    """Withdraw every request of the cache directory ``cache``'s queue and stop its builder
    (``nhgait cache stop``): (requests withdrawn, the builder's pid or None)."""
    folder = queue.queue_dir(cache, create=False)
    if folder is None:
        return 0, None
    withdrawn = sum(queue.withdraw(folder, r.path, r.inode) for r in queue.pending(folder))
    info = queue.holder(folder)
    return withdrawn, info.pid if info is not None and _stop_idle(folder, wait=True) else None


def _has_requests(folder: Path) -> bool:
    try:
        return any(name.endswith(queue.SUFFIX) for name in os.listdir(folder))
    except OSError:
        return False


def _is_builder(pid: int) -> bool:
    """Whether ``pid`` runs this module (read from ``/proc``; elsewhere taken to be so)."""
    try:
        return BUILDER_MODULE.encode() in Path(f"/proc/{pid}/cmdline").read_bytes()
    except FileNotFoundError:
        return not Path("/proc/self").exists() and _alive(pid)
    except OSError:
        return False


#: the builds and builders of this process (see :class:`Builders`)
BUILDERS = Builders()


def background_allowed() -> bool:
    """False when ``$NHGAIT_BACKGROUND_BUILDS`` says no (0, off, no, false)."""
    return os.environ.get("NHGAIT_BACKGROUND_BUILDS", "1").strip().lower() not in ("0", "off", "no", "false")


@contextlib.contextmanager
def builds_off(off: bool = True):
    """``$NHGAIT_BACKGROUND_BUILDS=0`` while the block runs (``off`` False: unchanged), the
    variable put back afterwards (``nhgait plan --no-background-build``)."""
    if not off:
        yield
        return
    old = os.environ.get("NHGAIT_BACKGROUND_BUILDS")
    os.environ["NHGAIT_BACKGROUND_BUILDS"] = "0"
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("NHGAIT_BACKGROUND_BUILDS", None)
        else:
            os.environ["NHGAIT_BACKGROUND_BUILDS"] = old


def start_build(source: str, toolchain: Toolchain, *, salt: str, slot: str = "",
                estimate_s: float | None = None, builders: Builders = BUILDERS) -> BackgroundBuild:
    """Ask for the optimised build of ``source`` with ``toolchain`` (its command None: the
    optimising compiler, :func:`~.compiler.compiler_command`; module docstring) and return at
    once: the request replaces the older one of ``slot`` (the robot and task; empty: the key
    alone), and a builder is started when none runs. A build that cannot or should not be
    asked for says why (``state``, ``reason``)."""
    flags, libs = toolchain.flags, toolchain.libs
    command = list(toolchain.command) if toolchain.command is not None else compiler_command()
    if command is None:
        return BackgroundBuild(state="unavailable", flags=flags,
                               reason="no C compiler found (looked for $NHGAIT_CC, $CC, gcc and cc)")
    name = Path(command[0]).name
    if os.name != "posix":
        return BackgroundBuild(state="unavailable", flags=flags, compiler=name,
                               reason="background builds need POSIX")
    if not background_allowed():
        return BackgroundBuild(state="off", flags=flags, compiler=name,
                               reason="$NHGAIT_BACKGROUND_BUILDS is off")
    directory = library_dir()
    folder = None if directory is None else queue.queue_dir(directory.parent)
    if folder is None:
        return BackgroundBuild(state="unavailable", flags=flags, compiler=name,
                               reason="the cache directory cannot be used")
    key = library_key(source, flags=flags, salt=salt, libs=libs, command=command)
    failed = _failure(directory, key)
    if failed:
        return BackgroundBuild(state="failed before", flags=flags, compiler=name, key=key,
                               reason=f"{failed} (delete {directory / key}.failed to try again)")
    estimate = DEFAULT_S_PER_MB * len(source) / 1e6 if estimate_s is None else float(estimate_s)
    wall, cpu = budgets(estimate)
    header = {"key": key, "slot": f"{slot} | {' '.join(flags)}" if slot else key, "command": command,
              "flags": list(flags), "libs": list(libs),
              "salt": salt, "sha256": hashlib.sha256(source.encode()).hexdigest(), "estimate_s": estimate,
              "budget_s": wall, "cpu_s": cpu, "requester": os.getpid()}
    built = dict(state="started", flags=flags, compiler=name, key=key, estimate_s=estimate, budget_s=wall)
    with queue.mutex(folder):
        return _ask(directory, folder, (header, source), built, builders)


def _ask(directory: Path, folder: Path, request: tuple, built: dict, builders: Builders) -> BackgroundBuild:
    """Under the queue's mutex: write the request, and start a builder when none runs."""
    put = queue.put(folder, *request)
    if put is None:
        return BackgroundBuild(**{**built, "state": "unavailable", "reason": "cannot write the build queue"})
    path, inode = put
    lock = queue.claim(folder)
    if lock is None:                    # a builder runs: it takes the request
        builders.add(None, (folder, path, inode))
        info = queue.holder(folder, under_mutex=True)
        return BackgroundBuild(**{**built, "state": "queued", "pid": info.pid if info else None})
    try:
        proc = _spawn(directory, folder, lock)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(path)
        return BackgroundBuild(**{**built, "state": "unavailable",
                                  "reason": f"cannot start the builder ({exc.strerror})"})
    finally:
        os.close(lock)
    builders.add(proc, (folder, path, inode))
    return BackgroundBuild(**built, pid=proc.pid)


def _spawn(directory: Path, folder: Path, lock: int) -> subprocess.Popen:
    """The builder process of the jit folder ``directory`` and the queue ``folder``, holding the
    builder lock ``lock`` (its pid written there); the stop signals blocked while it starts,
    so that it is always registered."""
    job = json.dumps({"jit": str(directory), "queue": str(folder), "lock": lock})
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        proc = subprocess.Popen([sys.executable, "-m", BUILDER_MODULE, job], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True, close_fds=True, pass_fds=(lock,))
        queue.record_holder(lock, proc.pid)
        return proc
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _failure(directory: Path, key: str) -> str | None:
    """The message of an earlier failed build of ``key``, or None."""
    try:
        return json.loads((directory / f"{key}.failed").read_text())["reason"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def wait_for_build(key: str, pid: int | None, timeout: float, *, directory: Path | None = None,
                   poll: float = 0.2) -> bool:
    """Wait until the library ``key`` is in the cache's ``jit/`` folder ``directory`` (None: this
    process's) or the builder ``pid`` is gone (True), or ``timeout`` seconds passed (False) —
    for a process that did not start the builder (a benchmark waiting for the build a finished
    ``nhgait plan`` started)."""
    deadline = time.monotonic() + timeout
    directory = library_dir() if directory is None else Path(directory)
    while time.monotonic() < deadline:
        if directory is not None and (directory / f"{key}.json").exists():
            return True
        if pid is None or not _alive(pid):
            return True
        time.sleep(poll)
    return False


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie counts as gone)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        state = ""
    if state in ("Z", "X"):
        with contextlib.suppress(ChildProcessError):
            os.waitpid(pid, os.WNOHANG)
        return False
    return True
