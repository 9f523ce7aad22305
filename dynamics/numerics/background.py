"""The optimised library built in the background, for the next run (issue 25).

A cold plan must not wait for gcc -O1 (2–250 s on the planner's C): it solves with code that is
ready at once (:mod:`.fast_compiler`, or interpreted functions) and hands the optimised build to
a **builder**, a separate process that compiles into the content-hash cache of
:mod:`.compiler` while the plan goes on; the next run loads the library from the cache::

    build = start_build(source, flags=("-O1",), salt="nlp …")   # returns at once
    build.state, build.pid, build.key                             # "started", 12345, "ab12…"

The builder (``python -m nhgait.dynamics.numerics.background JOB`` with the C source on its
standard input, an unlinked temporary file) is:

* **Detached and finished atomically.** It runs in its own session, so the plan's exit — or a
  signal to the plan's process group — does not stop it: a plan that takes 5 s still leaves the
  library its 60 s compile makes. It compiles with :func:`~.compiler.compile_in` into its own
  build folder ``jit/.build-<host>-<builder pid>-…`` (created first, removed whatever happens)
  and moves the library and then its record into place with ``os.replace``: a reader sees the
  whole library or none. The choice against a child tied to the plan: such a child dies with
  the plan, so only plans longer than the compile would ever leave an optimised library.
* **Stopped with the plan that is stopped.** ``nhgait`` stopped by SIGINT/SIGTERM cancels the
  builders it started (:meth:`Builders.cancel`: SIGTERM; the builder kills its compiler's process
  group and removes its folder — nothing is left); a forced end (the CLI's watchdog) kills them
  with every descendant. A builder killed by SIGKILL from outside takes gcc with it
  (``PR_SET_PDEATHSIG``), but gcc's own ``cc1`` may finish its file first (it writes only into
  the build folder, which the next build removes: its process is gone) — as for a foreground
  compile. A plan called from Python and interrupted leaves its builder to finish (into the
  cache, atomically).
* **Modest.** ``nice`` 19 (the plan and other work come first; on two cores it takes the
  second when the plan runs on one), for its session's autogroup too: a builder starts a session
  of its own, and where Linux groups the processes of each session (``sched_autogroup``, on by
  default on most distributions) niceness counts only within a group and the groups share the
  cores equally — a nice-19 builder took a whole core from a plan's two threads (the 8-link
  snake's NLP functions on the fast compiler's threads: 248 ms a call, as on one thread; 129 ms
  with the group at nice 19). One compiler process at a time per cache directory (the
  builders of one cache take an exclusive ``flock`` of its ``jit/`` folder in turn; one that
  finds its library built meanwhile leaves), its address space bounded (:data:`MEMORY_BYTES`,
  ``RLIMIT_AS``; the compile budget of the caller keeps -O1 files ≤ 4.2 MB, measured
  ≤ 0.99 GB), a time limit (:data:`TIMEOUT_S`).
* **Accountable.** The record ``<key>.json`` holds the compiler's seconds and peak resident
  memory (``compile_s``, ``compiler_peak_mb``); a compiler that fails writes ``<key>.failed``
  (its message), and that build is not started again (delete the file to retry).

``$NHGAIT_BACKGROUND_BUILDS=0`` starts no builder (the test suite; CI machines that should not
leave work running after a command).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import STOP_SIGNALS, Terminated
from .compiler import (
    STALE_BUILD_S,
    CompileJob,
    CompilerUnavailable,
    compile_in,
    compiler_command,
    library_dir,
    library_key,
)

__all__ = ["BackgroundBuild", "Builders", "BUILDERS", "start_build", "wait_for_build", "background_allowed",
           "MEMORY_BYTES", "TIMEOUT_S", "NICENESS", "main"]

#: the compiler's address space limit (bytes; gcc -O1 on 4 MB of CasADi's C: 0.66 GB resident)
MEMORY_BYTES = 2 * 1024 ** 3
#: seconds after which a background compiler is stopped (the build then counts as failed)
TIMEOUT_S = 3600.0
#: where Linux keeps the niceness of this process's autogroup (absent without autogroups)
AUTOGROUP = "/proc/self/autogroup"
#: the builder's niceness (the lowest priority)
NICENESS = 19
#: how long :meth:`Builders.cancel` lets a builder clean up before it is killed (s)
CANCEL_WAIT_S = 1.0


@dataclass(frozen=True)
class BackgroundBuild:
    """What was done for the next run: ``state`` is "started" (``pid``: the builder), "off"
    ($NHGAIT_BACKGROUND_BUILDS=0), "failed before" or "unavailable" (``reason`` says why);
    ``key`` the library's cache key, ``flags`` and ``compiler`` the optimised build's."""

    state: str
    flags: tuple
    compiler: str = ""
    key: str = ""
    pid: int | None = None
    reason: str = ""

    def describe(self) -> dict:
        return {"state": self.state, "flags": list(self.flags), "compiler": self.compiler, "key": self.key,
                "pid": self.pid, "reason": self.reason}

    def text(self) -> str:
        """"gcc -O1 building in the background (pid 123) for the next run" and the like."""
        what = f"{self.compiler} {' '.join(self.flags)}".strip()
        if self.state == "started":
            return f"{what} building in the background (pid {self.pid}, nice {NICENESS}) for the next run"
        return f"{what} not built in the background: {self.reason}"


class Builders:
    """The builders this process started (their ``Popen`` objects): :meth:`cancel` on a stop,
    :meth:`wait` where a caller wants the library now (benchmarks, tests). This is process
    state — like the children :mod:`subprocess` tracks — not an option."""

    def __init__(self):
        self._procs: list = []

    def add(self, proc: subprocess.Popen) -> None:
        self._procs = [p for p in self._procs if p.poll() is None] + [proc]

    def running(self) -> list:
        return [p for p in self._procs if p.poll() is None]

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until every builder ended (True) or ``timeout`` seconds passed (False)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        for proc in self._procs:
            try:
                proc.wait(None if deadline is None else max(deadline - time.monotonic(), 0.0))
            except subprocess.TimeoutExpired:
                return False
        return True

    def terminate(self) -> None:
        """SIGTERM to every running builder, without waiting (each kills its compiler and
        removes its folder): the stop watchdog's way, which has no time to wait."""
        _sigterm(self.running())

    def cancel(self) -> int:
        """Stop every running builder (SIGTERM: it kills its compiler and removes its folder;
        SIGKILL after :data:`CANCEL_WAIT_S`); how many were running."""
        running = self.running()
        _sigterm(running)
        deadline = time.monotonic() + CANCEL_WAIT_S
        for proc in running:
            try:
                proc.wait(max(deadline - time.monotonic(), 0.0))
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        return len(running)


def _sigterm(processes) -> None:
    for proc in processes:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGTERM)


#: the builders of this process (see :class:`Builders`)
BUILDERS = Builders()


def background_allowed() -> bool:
    """False when ``$NHGAIT_BACKGROUND_BUILDS`` says no (0, off, no, false)."""
    return os.environ.get("NHGAIT_BACKGROUND_BUILDS", "1").strip().lower() not in ("0", "off", "no", "false")


def start_build(source: str, *, flags: tuple, salt: str, libs: tuple = ("-lm",),
                builders: Builders = BUILDERS) -> BackgroundBuild:
    """Start the optimised build of ``source`` in a builder (module docstring) and return at
    once; a build that cannot or should not start says why (``state``, ``reason``)."""
    flags, libs = tuple(flags), tuple(libs)
    command = compiler_command()
    if command is None:
        return BackgroundBuild("unavailable", flags,
                               reason="no C compiler found (looked for $NHGAIT_CC, $CC, "
                                                            "gcc and cc)")
    name = Path(command[0]).name
    if os.name != "posix":
        return BackgroundBuild("unavailable", flags, name, reason="background builds need POSIX")
    if not background_allowed():
        return BackgroundBuild("off", flags, name, reason="$NHGAIT_BACKGROUND_BUILDS is off")
    directory = library_dir()
    if directory is None:
        return BackgroundBuild("unavailable", flags, name, reason="the cache directory cannot be used")
    key = library_key(source, flags=flags, salt=salt, libs=libs, command=command)
    failed = _failure(directory, key)
    if failed:
        return BackgroundBuild("failed before", flags, name, key, reason=f"{failed} (delete {directory / key}"
                                                                         ".failed to try again)")
    job = {"command": command, "flags": list(flags), "libs": list(libs), "salt": salt, "key": key,
           "sha256": hashlib.sha256(source.encode()).hexdigest()}
    try:
        proc = _spawn(directory, job, source)
    except OSError as exc:
        return BackgroundBuild("unavailable", flags, name, key,
                               reason=f"cannot start the builder ({exc.strerror})")
    builders.add(proc)
    return BackgroundBuild("started", flags, name, key, proc.pid)


def _spawn(directory: Path, job: dict, source: str) -> subprocess.Popen:
    """The builder process, its source on stdin from an unlinked file of ``directory`` (nothing
    to clean up); the stop signals blocked while it starts, so that it is always registered."""
    with tempfile.TemporaryFile(dir=directory) as fh:
        fh.write(source.encode())
        fh.seek(0)
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            return subprocess.Popen([sys.executable, "-m", __name__, json.dumps(job)], stdin=fh,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                    start_new_session=True, close_fds=True)
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
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:                       # a zombie of ours counts as gone
        return os.waitpid(pid, os.WNOHANG) == (0, 0)
    except ChildProcessError:
        return True


# ----------------------------------------------------------------------------- the builder
def main(argv=None) -> int:
    """The builder: the job (JSON) in ``argv[0]``, the source on stdin (module docstring).
    0: built (or found built), 1: failed or not possible, 143: stopped."""
    job = json.loads((sys.argv[1:] if argv is None else argv)[0])

    def stop(signum, frame):
        raise Terminated()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:          # started with the stop signals blocked (:func:`_spawn`): a pending one raises here
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
        source = sys.stdin.read()
        if hashlib.sha256(source.encode()).hexdigest() != job["sha256"]:
            return 1                                   # a truncated hand-over: nothing to build
        _lowest_priority()
        return _build(job, source)
    except Terminated:
        return 143


def _lowest_priority() -> None:
    """This builder and its compiler at nice :data:`NICENESS` — and so its session's autogroup
    (:data:`AUTOGROUP`; module docstring): a process's niceness counts only against the
    processes of its own autogroup."""
    with contextlib.suppress(OSError):
        os.nice(NICENESS - os.nice(0))
    with contextlib.suppress(OSError):
        Path(AUTOGROUP).write_text(str(NICENESS))


def _build(job: dict, source: str) -> int:
    """Compile into the cache unless another builder did it meanwhile (module docstring)."""
    from .cache import remove_stale_temporaries, temporary_prefix
    directory = library_dir()
    if directory is None:
        return 1
    key = job["key"]
    remove_stale_temporaries(directory, ".build-", max_age_s=STALE_BUILD_S)
    with tempfile.TemporaryDirectory(dir=directory, prefix=temporary_prefix(".build-"),
                                     ignore_cleanup_errors=True) as tmp:
        with _exclusive(directory):
            if (directory / f"{key}.json").exists() and (directory / f"{key}.so").exists():
                return 0
            task = CompileJob(source=source, command=list(job["command"]), flags=tuple(job["flags"]),
                              libs=tuple(job["libs"]), salt=job["salt"], key=key, label="background build",
                              timeout=TIMEOUT_S, memory_bytes=MEMORY_BYTES, measure=True)
            try:
                compile_in(task, directory, Path(tmp))
            except CompilerUnavailable as exc:
                _write_failure(directory, key, str(exc), Path(tmp))
                return 1
    return 0


@contextlib.contextmanager
def _exclusive(directory: Path):
    """An exclusive ``flock`` of the folder ``directory`` (one compiler per cache at a time;
    released when the process ends, however it ends)."""
    import fcntl
    fd = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _write_failure(directory: Path, key: str, reason: str, tmp: Path) -> None:
    record = tmp / f"{key}.failed"
    record.write_text(json.dumps({"reason": reason, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}))
    os.replace(record, directory / f"{key}.failed")


if __name__ == "__main__":
    sys.exit(main())
