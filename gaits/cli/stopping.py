"""How ``nhgait`` stops on SIGINT, SIGTERM and SIGHUP: at once, in any phase, leaving nothing behind.

:func:`stop_signals` is the context the command line runs each subcommand in:

* **SIGTERM** raises :class:`~nhgait.dynamics.errors.Terminated` (exit 143), as does **SIGHUP**
  (exit 129: the terminal closed; left alone when ignored, as under ``nohup``), **SIGINT**
  KeyboardInterrupt (exit 130; left ignored when the shell started us with it ignored, as a
  background job): they unwind like any exception, so a running C compiler is killed and its
  files removed (:mod:`nhgait.dynamics.numerics.compiler`), supervised solver processes are killed
  (:mod:`nhgait.ocp.supervision`), a half-written cache entry or output file is removed, and
  the optimised builds started in the background are cancelled (:func:`cancel_background_builds`).
* **A stop is remembered** (:class:`Stop`): the handler's exception can be replaced on its
  way up — raised inside CasADi's argument conversion, SWIG's overload dispatch answers
  "Wrong number or type of arguments" (a ``NotImplementedError``) — so the command line turns
  any exception that follows a stop signal back into the stop (exit 130/143, not "internal
  error").
* **A watchdog** covers what a Python handler cannot: the main thread inside C code that does
  not return (CasADi building a large NLP, a solver run in this process where there is no
  fork), and a handler whose exception is swallowed because it ran where Python ignores
  exceptions (an ``os.register_at_fork`` hook, a ``__del__``: "Exception ignored in ...").
  Python's C-level handler writes each signal's number to a wakeup pipe
  (``signal.set_wakeup_fd``) whatever the main thread is doing; a daemon thread reads it and,
  if the process is still alive :data:`FORCE_AFTER_S` seconds later, writes the same message
  and ends it with ``os._exit(128 + signal)``. A normal stop (kill the children, remove the
  temporary files, print) takes milliseconds, so the watchdog mostly meets a process stuck
  in C; it also met one writing the figures of a plan on a loaded machine (1 of 60 runs of
  ``experiments/stress_sigterm.py``), so it first removes the staging folders registered by
  :func:`~nhgait.dynamics.errors.temporary_folder` (the outputs' ``.writing-*``). Before it ends
  the process it kills every process descended from it (Linux ``/proc``) but the background
  builders (told to stop by SIGTERM, they remove their build folders themselves): supervised
  children and compilers die with the main thread anyway (``PR_SET_PDEATHSIG``), but the compiler's own
  helpers (cc1, as) would not. The one thing a forced end can leave is a compiler's build folder when the
  signal came while the compiler was being started (its stop signals blocked, on a machine so
  loaded that starting it took 1.5 s: 1 of 54 runs of ``experiments/stress_sigterm.py``); the
  next build removes it once it is stale.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager
from typing import NamedTuple

from nhgait.dynamics.errors import Terminated, clear_stops, note_stop, remove_temporary_folders

__all__ = ["stop_signals", "Stop", "Ending", "exit_now", "end_process", "cancel_background_builds",
           "FORCE_AFTER_S", "EXIT_STATUS", "MESSAGES"]

#: how long after a stop signal the watchdog ends a process that is still running (s)
FORCE_AFTER_S = 1.5
#: exit status per signal (the shell's 128 + signal number)
EXIT_STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129}
#: what ``nhgait`` says when it stops on a signal
MESSAGES = {signal.SIGINT: "nhgait: interrupted", signal.SIGTERM: "nhgait: terminated",
            signal.SIGHUP: "nhgait: hung up"}


class Ending(NamedTuple):
    """How ``nhgait`` ends on a stop signal: its exit ``status`` (128 + signal) and the
    ``message`` it prints."""

    status: int
    message: str


class Stop:
    """The stop signal received while :func:`stop_signals` was in force (``signal``: None
    until one comes)."""

    def __init__(self):
        self.signal: int | None = None

    def exception(self) -> BaseException:
        """The exception the signal stands for: Terminated (SIGTERM, SIGHUP) or KeyboardInterrupt."""
        return Terminated() if self.signal in (signal.SIGTERM, signal.SIGHUP) else KeyboardInterrupt()

    def ending(self) -> Ending:
        """The :class:`Ending` of a :class:`Terminated` stop: SIGHUP's or SIGTERM's."""
        signum = signal.SIGHUP if self.signal == signal.SIGHUP else signal.SIGTERM
        return Ending(status=EXIT_STATUS[signum], message=MESSAGES[signum])

    def handler(self, signum, frame):
        self.signal = signum
        note_stop(signum)
        raise self.exception()


@contextmanager
def stop_signals():
    """SIGTERM → Terminated, SIGINT → KeyboardInterrupt, with the watchdog (module docstring);
    yields the :class:`Stop`; everything put back on leaving. Outside the main thread nothing
    is changed."""
    stop = Stop()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    previous = _install(stop)
    read, write = os.pipe()
    os.set_blocking(write, False)
    old_fd = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
    done = threading.Event()
    threading.Thread(target=_watch, args=(read, frozenset(previous), done), name="nhgait-stop-watchdog",
                     daemon=True).start()
    try:
        yield stop
    finally:
        done.set()                 # the stop came to its end here: nothing to force
        clear_stops()
        signal.set_wakeup_fd(old_fd)
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        os.close(write)            # the watchdog reads the end of the pipe and leaves


def _install(stop: Stop) -> dict:
    """The handlers of ``stop`` for SIGTERM (always), SIGINT (unless ignored or someone
    else's) and SIGHUP (unless ignored: ``nohup``); the previous handlers by signal."""
    previous = {signal.SIGTERM: signal.signal(signal.SIGTERM, stop.handler)}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, stop.handler)
    if signal.getsignal(signal.SIGHUP) is signal.SIG_DFL:
        previous[signal.SIGHUP] = signal.signal(signal.SIGHUP, stop.handler)
    return previous


def _watch(read: int, ours: frozenset, done: threading.Event) -> None:
    """The watchdog thread: the number of each signal caught arrives on the pipe ``read``;
    ``done`` is set when :func:`stop_signals` is left."""
    try:
        while True:
            data = os.read(read, 64)
            if not data:
                return
            for signum in data:
                if signum in ours and not done.wait(FORCE_AFTER_S):
                    _force_exit(signum)
    finally:
        os.close(read)


def _kill_descendants(spare=()) -> None:
    """SIGKILL every live process descended from this one (read from ``/proc``; elsewhere
    nothing), except the processes ``spare`` and theirs (the background builders: told to stop
    by SIGTERM, they remove their build folders themselves)."""
    children: dict = {}
    try:
        entries = [e.name for e in os.scandir("/proc") if e.name.isdigit()]
    except OSError:
        return
    for pid in entries:
        try:
            with open(f"/proc/{pid}/stat") as fh:
                ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        children.setdefault(ppid, []).append(int(pid))
    stack, found = [os.getpid()], []
    while stack:
        for child in children.get(stack.pop(), ()):
            if child in spare:
                continue
            found.append(child)
            stack.append(child)
    for pid in found:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            continue


def cancel_background_builds() -> int:
    """Stop the optimised builds this process started in the background
    (:mod:`nhgait.dynamics.numerics.background`): a stopped command leaves no compiler running
    and no build folder (a command that ends normally leaves them to finish into the cache).
    How many were running."""
    background = sys.modules.get("nhgait.dynamics.numerics.background")
    return background.BUILDERS.cancel() if background is not None else 0


def exit_now(status: int) -> int:
    """End the process with ``status`` once a stop's cleanup is done: the ``atexit`` handlers
    run (``weakref.finalize`` objects, multiprocessing's), the streams are flushed, and the
    interpreter's teardown — 0.6–1 s with CasADi, SciPy and matplotlib loaded, several seconds
    on a loaded machine, nothing of which the stop needs — is skipped."""
    import atexit
    try:
        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(status)
    return status  # pragma: no cover - never reached


def end_process(status: int) -> int:
    """End a command that finished by itself with ``status``, as the interpreter would — its
    threads joined (``threading._shutdown``: thread pools told to stop first), the ``atexit``
    handlers run, the streams flushed — but without the teardown of every module and object
    (:func:`exit_now`). The background builders are detached and go on (they are meant to)."""
    shutdown = getattr(threading, "_shutdown", None)
    if shutdown is not None:
        shutdown()
    return exit_now(status)


def _force_exit(signum: int) -> None:  # pragma: no cover - measured by tests/test_interrupts.py
    """End the process now: it has not stopped by itself (module docstring)."""
    try:
        background = sys.modules.get("nhgait.dynamics.numerics.background")
        spare = set()
        if background is not None:            # the optimised builds: told to stop and clean up
            background.BUILDERS.terminate()
            spare = {p.pid for p in background.BUILDERS.running()}
        _kill_descendants(spare)
        remove_temporary_folders()            # the staging folder of outputs being written
        sys.stderr.write(f"{MESSAGES[signum]} (forced: still running {FORCE_AFTER_S:g} s after the signal)\n")
        sys.stderr.flush()
    finally:
        os._exit(EXIT_STATUS[signum])
