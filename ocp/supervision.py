"""Solver attempts in supervised child processes: bounded in time, stopped at once.

A solver that loops inside its C code never returns to Python, so neither a Python signal
handler nor a time limit checked in Python can stop it. Each attempt therefore runs in a child
forked for it, which the parent supervises::

    results = supervise([Job(run, limit=30.0, failed=make_failure), ...], workers=2)

* **The parent waits in Python**: short ``poll`` waits on the children's pipes, so its
  signal handlers run at once (SIGINT → KeyboardInterrupt, the CLI's SIGTERM →
  :class:`~nhgait.dynamics.errors.Terminated`, a budget's alarm → BudgetSpent). It starts up
  to ``workers`` children at once (two guesses on two cores) and returns the results in the
  order of the jobs.
* **Limits**: a child still running ``limit`` seconds after it started is killed (SIGKILL) and
  its result is ``failed("Time_Limit_Exceeded", message, seconds)``.
* **Any exception in the parent** (KeyboardInterrupt, Terminated, BudgetSpent, ...) kills and
  reaps every child before it propagates: no child outlives the call. The stop signals are
  blocked while a child is forked and registered, so that their handlers run in this code —
  never inside ``os.fork``'s at-fork hooks, where Python would drop their exception.
* **Cores**: a child may run its NLP functions' OpenMP maps on its share of the cores (the
  cores over ``workers``, :func:`~nhgait.dynamics.numerics.openmp.share`); the parent stays on
  one thread (a process that forks must not have run a team of threads).
* **A child** ignores SIGINT (Ctrl-C is the parent's to handle), dies on SIGTERM, gets SIGKILL
  when the parent thread that forked it dies (``PR_SET_PDEATHSIG`` on Linux; it exits at once
  if the parent is already gone), sends its result pickled through a pipe and leaves with
  ``os._exit``: it never runs the parent's ``atexit`` handlers or finalizers (such as the one
  that removes a private JIT folder, :mod:`.solver`). An exception raised by ``run`` is sent
  back and raised again in the parent (bad input stays bad input).
* **A child that dies** by a signal the parent did not send (a crash: SIGSEGV, SIGKILL from
  outside, out of memory) gives ``failed("Solver_Died", ...)`` naming the signal — except
  SIGTERM/SIGINT sent to the whole process group (``timeout``, Ctrl-C): the parent got it too,
  and its pending handler is given a moment to run (and end the plan) before the death is
  classified.
* **Without fork** (not POSIX) every job runs in this process, one after the other; only a
  solver's own time option bounds it (said once on ``progress``).

Jobs run in forked children, so ``run`` may be any callable — nothing is pickled on the way
in — and its result must pickle (a :class:`~.solution.Solution` with ``problem=None``).
"""
from __future__ import annotations

import os
import pickle
import select
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from nhgait.dynamics.errors import STOP_SIGNALS
from nhgait.dynamics.numerics import openmp

__all__ = ["Job", "supervise", "can_fork", "POLL_S", "HANDLER_PAUSE_S"]

#: seconds between the parent's checks of limits (its signal handlers run at once regardless)
POLL_S = 0.05
#: ... and while a child that closed its pipe is exiting
EXIT_POLL_S = 0.002
#: after a child died of SIGTERM/SIGINT, how long the parent waits for its own handler to run
HANDLER_PAUSE_S = 0.2
#: Linux prctl option: signal the child when the thread that forked it dies
_PR_SET_PDEATHSIG = 1


@dataclass(frozen=True)
class Job:
    """One attempt: ``run()`` gives its (picklable) result; ``limit`` seconds of wall time (None:
    unbounded); ``failed(status, message, seconds)`` makes the result of an attempt that gave
    none (killed at its limit, died)."""

    run: Callable[[], Any]
    limit: float | None
    failed: Callable[[str, str, float], Any]


def can_fork() -> bool:
    """Whether attempts can run in forked children here."""
    return os.name == "posix" and hasattr(os, "fork") and hasattr(signal, "pthread_sigmask")


def supervise(jobs, *, workers: int = 1, progress=None, meanwhile=None) -> list:
    """The results of ``jobs`` in order, each run in a supervised child, up to ``workers`` at
    once (see the module docstring). ``meanwhile``: a callable run once in this process while
    the first children work (the planner imports what its figures will need there: time the
    parent would spend waiting; its signal handlers still run, a limit is checked after it)."""
    jobs = list(jobs)
    if not can_fork():
        _say_in_process(progress, "no fork here")
        return [job.run() for job in jobs]
    pending, running, results = list(enumerate(jobs)), {}, [None] * len(jobs)
    threads = openmp.share(workers)
    try:
        while pending or running:
            while pending and len(running) < max(1, int(workers)):
                index, job = pending.pop(0)
                try:
                    _start(job, index, running, threads)
                except OSError as exc:        # no process to be had (limits, memory): in this one
                    _say_in_process(progress, f"cannot start a process: {exc.strerror or exc}")
                    results[index] = _Returned(job.run())
            if meanwhile is not None and running:
                meanwhile, then = None, meanwhile
                then()
            for index, outcome in _poll(running):
                results[index] = outcome
                del running[index]
    except BaseException:
        for child in running.values():
            child.kill()
        raise
    return [_value(r) for r in results]


def _start(job: Job, index: int, running: dict, threads: int) -> None:
    """Fork the child of ``job`` into ``running[index]`` with the stop signals blocked: a
    signal arriving meanwhile is handled once the child is registered (to be killed with the
    others), not inside ``os.fork``'s at-fork hooks — where Python ignores the handler's
    exception ("Exception ignored in: <function _releaseLock ...>") and the plan would go on."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        running[index] = _Child.start(job, blocked, threads)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _say_in_process(progress, why: str) -> None:
    if progress is not None:
        progress.note_once("attempts in process",
                           f"  solver attempts run in this process ({why}): only Ipopt's "
                           "own wall-time limit bounds them, and a signal waits until the solver returns")


@dataclass(frozen=True)
class _Returned:
    """What a child sent: its result, or the exception it raised (``raised``)."""

    value: Any
    raised: bool = False


def _value(result: _Returned):
    """A child's result, or its exception raised again here."""
    if result.raised:
        raise result.value
    return result.value


def _poll(running: dict) -> list:
    """Wait up to POLL_S for the children's pipes; read what came; [(index, result)] of the
    children that finished (answered, died or were killed at their limit)."""
    by_fd = {child.fd: child for child in running.values() if not child.eof}
    leaving = len(by_fd) < len(running)              # a child at the end of its pipe exits within ms
    for fd in _readable(list(by_fd), EXIT_POLL_S if leaving else POLL_S):
        by_fd[fd].read()
    done = []
    for index, child in running.items():
        status = child.exited()
        if status is not None:
            child.drain()                            # what an exited child left in the pipe
            done.append((index, child.finish(status)))
        elif child.over_limit():
            done.append((index, _Returned(child.stop())))
    return done


def _readable(fds: list, timeout: float) -> list:
    """The fds among ``fds`` ready to read within ``timeout`` seconds (signal handlers run meanwhile)."""
    if hasattr(select, "poll"):
        poller = select.poll()
        for fd in fds:
            poller.register(fd, select.POLLIN | select.POLLHUP | select.POLLERR)
        return [fd for fd, _ in poller.poll(timeout * 1000.0)]
    return select.select(fds, [], [], timeout)[0]  # pragma: no cover - no poll()


class _Child:
    """One forked attempt: its pid, the read end of its pipe (non-blocking), what it sent so far."""

    def __init__(self, job: Job, pid: int, fd: int):
        self.job, self.pid, self.fd = job, pid, fd
        self.started = time.monotonic()
        self.chunks: list = []
        self.reaped = self.closed = self.eof = False

    @classmethod
    def start(cls, job: Job, mask, threads: int = 1) -> _Child:
        _flush_python_streams()                      # nothing buffered is written twice
        parent = os.getpid()
        prctl = _prctl()
        read, write = os.pipe()
        try:
            pid = os.fork()
        except OSError:
            os.close(read)
            os.close(write)
            raise
        if pid == 0:                                 # pragma: no cover - the child (measured by the tests)
            os.close(read)
            _child(job, write, parent, prctl, mask, threads)
        os.close(write)
        os.set_blocking(read, False)
        return cls(job, pid, read)

    def seconds(self) -> float:
        return time.monotonic() - self.started

    def over_limit(self) -> bool:
        return self.job.limit is not None and self.seconds() > self.job.limit

    def read(self) -> bool:
        """Read what is there (``eof`` set at the end of the pipe); True when something came."""
        try:
            chunk = os.read(self.fd, 1 << 20)
        except BlockingIOError:
            return False
        self.eof = not chunk
        if chunk:
            self.chunks.append(chunk)
        return bool(chunk)

    def drain(self) -> None:
        """Read whatever is left in the pipe."""
        while not self.eof and self.read():
            pass

    def exited(self) -> int | None:
        """The wait status of a child that has exited (reaped now), else None."""
        pid, status = os.waitpid(self.pid, os.WNOHANG)
        if pid == 0:
            return None
        self.reaped = True
        return status

    def finish(self, status: int) -> _Returned:
        """The result of a child that has ended: what it sent, or how it died."""
        self.reaped = True
        self._close()
        data = b"".join(self.chunks)
        if data and os.WIFEXITED(status):
            kind, value = pickle.loads(data)
            return _Returned(value, raised=kind != "ok")
        return _Returned(self._died(status))

    def _died(self, status: int):
        if os.WIFSIGNALED(status):
            sig = os.WTERMSIG(status)
            if sig in (signal.SIGTERM, signal.SIGINT):
                time.sleep(HANDLER_PAUSE_S)          # a signal to the whole group: our handler ends the plan
            name = signal.Signals(sig).name if sig in set(signal.Signals) else f"signal {sig}"
            return self.job.failed("Solver_Died", f"the solver's process died of {name} after "
                                   f"{self.seconds():.1f} s", self.seconds())
        return self.job.failed("Solver_Died", f"the solver's process ended with exit status "
                               f"{os.WEXITSTATUS(status)} without an answer", self.seconds())

    def stop(self):
        """Kill a child over its limit: the attempt's failed result."""
        seconds = self.seconds()
        self.kill()
        return self.job.failed("Time_Limit_Exceeded",
                               f"stopped after {seconds:.1f} s: the attempt's time limit "
                               f"is {self.job.limit:.1f} s", seconds)

    def kill(self) -> None:
        """SIGKILL and reap; the pipe closed."""
        if not self.reaped:
            self.reaped = True
            try:
                os.kill(self.pid, signal.SIGKILL)
                os.waitpid(self.pid, 0)
            except (ProcessLookupError, ChildProcessError):   # pragma: no cover - gone already
                pass
        self._close()

    def _close(self) -> None:
        if not self.closed:
            self.closed = True
            os.close(self.fd)


def _prctl():
    """libc's prctl on Linux (looked up in the parent: the child only calls it), else None."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes
    return ctypes.CDLL(None).prctl


def _child(job: Job, write: int, parent: int, prctl, mask, threads: int) -> None:  # pragma: no cover
    """The child's whole life (module docstring): never returns. ``mask``: the signal mask to
    restore once its own handlers are set; ``threads``: its OpenMP grant (it forks nothing)."""
    status = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.set_wakeup_fd(-1)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:                    # the parent ended before that
            os._exit(1)
        openmp.grant(threads)
        try:
            answer = ("ok", job.run())
        except BaseException as exc:  # noqa: BLE001 - handed to the parent, raised there
            answer = ("error", _picklable(exc))
        _send(write, pickle.dumps(answer, protocol=pickle.HIGHEST_PROTOCOL))
    except BaseException:  # noqa: BLE001 - nothing may escape a forked child
        status = 1
    finally:
        try:
            _flush_c_streams()
        finally:
            os._exit(status)


def _picklable(exc: BaseException) -> BaseException:
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001 - any pickling failure: the text instead
        import traceback
        return RuntimeError(f"{type(exc).__name__}: {exc}\n{''.join(traceback.format_exception(exc)[-8:])}")


def _send(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]
    os.close(fd)


def _flush_python_streams() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):       # closed, or a broken pipe: nothing to write twice
            continue


def _flush_c_streams() -> None:  # pragma: no cover - runs in the child
    """The solver's own log (C stdio, ``--verbose``) is not lost to ``os._exit``."""
    _flush_python_streams()
    try:
        import ctypes
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass
