"""The builder process of a cache: it drains the queue of optimised builds (issue 40).

Started by :func:`~.background.start_build` as ``python -m nhgait.dynamics.numerics.builder
JOB`` (JOB: its ``jit`` and ``queue`` folders and the descriptor of the builder lock it was
handed), it compiles the newest request of :mod:`.build_queue` until the queue is empty, one
compile at a time, each within its budgets and watched every :data:`~.compiler.WATCH_S` — its
cache folder gone, its request replaced or withdrawn, or its wall budget spent stop the compiler
at once (:class:`Abandoned`; a compile out of its wall budget means a machine too busy for the
builds: the builder then drops the queue and leaves); SIGTERM, SIGINT and SIGHUP end it (exit
143), its compiler's process group killed and its build folder removed (with the stop signals
held, so that a signal during the cleanup waits for it). It leaves with ``os._exit`` while it
holds the queue's mutex, having seen the queue empty: the builder lock and the mutex go with the
process, so that there is never a second builder alive and never a request left without one. Its
compiler runs at nice :data:`~.background.NICENESS` in a session (and autogroup) of its own; the
builder keeps the priority it was started with (:mod:`.background`).
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import STOP_SIGNALS, Terminated
from . import build_queue as queue
from .background import MEMORY_BYTES, NICENESS
from .compiler import STALE_BUILD_S, CompileJob, CompilerUnavailable, compile_in

__all__ = ["main", "Abandoned", "Folders"]


class Abandoned(Exception):
    """The compile is no longer wanted (its cache folder is gone, its request stale, its budget spent)."""


@dataclass(frozen=True)
class Folders:
    """The builder's ``jit`` and ``queue`` folders and their identities (device, inode) when it started."""

    jit: Path
    queue: Path
    identity: tuple

    @staticmethod
    def of(jit: Path, folder: Path) -> Folders:
        return Folders(jit, folder, _identity(jit, folder))

    def intact(self) -> bool:
        """Whether both folders are still the ones the builder started with."""
        return _identity(self.jit, self.queue) == self.identity


def _identity(*paths) -> tuple | None:
    try:
        return tuple((st.st_dev, st.st_ino) for st in (os.stat(p) for p in paths))
    except OSError:
        return None


def main(argv=None) -> int:
    """The builder: its folders and lock (JSON) in ``argv[0]`` (module docstring).
    0: the queue is empty or its cache gone, 143: stopped by a signal."""
    job = json.loads((sys.argv[1:] if argv is None else argv)[0])

    def stop(signum, frame):
        raise Terminated()
    for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(signum, stop)
    try:          # started with the stop signals blocked (:func:`_spawn`): a pending one raises here
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
        folders = Folders.of(Path(job["jit"]), Path(job["queue"]))
        if folders.identity is None:
            return 0
        return _serve(folders, int(job["lock"]))
    except Terminated:
        return 143


def _serve(folders: Folders, lock: int) -> int:
    """Build the newest request until the queue is empty (seen so under its mutex, where the
    lock is let go) or the cache folder is gone."""
    from .cache import remove_stale_temporaries
    remove_stale_temporaries(folders.jit, ".build-", max_age_s=STALE_BUILD_S)
    while folders.intact():
        request = _next(folders)
        if request is not None and _build(folders, request):
            continue
        if request is not None:           # over its wall budget: the machine is too busy for them all
            for other in queue.pending(folders.queue):
                queue.withdraw(folders.queue, other.path, other.inode)
        with queue.mutex(folders.queue):
            if not _has_requests(folders.queue):
                os._exit(0)     # the lock and the mutex go with the process: never two builders alive
    return 0


def _next(folders: Folders):
    """The newest request still to build; those built or failed meanwhile are dropped."""
    for request in queue.pending(folders.queue):
        key = request.key
        if (folders.jit / f"{key}.failed").exists() or ((folders.jit / f"{key}.json").exists()
                                                        and (folders.jit / f"{key}.so").exists()):
            queue.withdraw(folders.queue, request.path, request.inode)
            continue
        return request
    return None


def _build(folders: Folders, request) -> bool:
    """Compile ``request`` into the cache within its budgets, watched (module docstring); the
    request is withdrawn whatever happens (a failure leaves ``<key>.failed``). False when the
    compile ran out of its wall budget: a compiler at nice 19 that cannot finish in 10× its
    estimate is starved by the machine's load (0 s of CPU in 200 s at load 17, measured), and the
    builder drops the whole queue and leaves — the next plan asks again."""
    from .cache import temporary_prefix
    source, h = request.source(), request.header
    deadline = time.monotonic() + float(h["budget_s"])

    def watch() -> None:
        if not folders.intact():
            raise Abandoned("its cache folder is gone")
        if not request.current():
            raise Abandoned("a newer request replaced it, or it was withdrawn")
        if time.monotonic() > deadline:
            raise Abandoned(f"over its budget of {h['budget_s']:.0f} s")
    if source is None:
        queue.withdraw(folders.queue, request.path, request.inode)
        return True
    try:
        tmp = Path(tempfile.mkdtemp(dir=folders.jit, prefix=temporary_prefix(".build-")))
    except OSError:                       # the cache folder went: the loop ends
        return True
    task = CompileJob(source=source, command=list(h["command"]), flags=tuple(h["flags"]),
                      libs=tuple(h["libs"]), salt=h["salt"], key=request.key, label="background build",
                      memory_bytes=MEMORY_BYTES, cpu_seconds=float(h["cpu_s"]), niceness=NICENESS,
                      measure=True, watch=watch)
    failure, in_time = None, True
    try:
        compile_in(task, folders.jit, tmp)
    except CompilerUnavailable as exc:
        failure = str(exc)
    except Abandoned:
        in_time = time.monotonic() <= deadline
    except OSError:
        pass
    finally:          # a stop signal waits until the build folder is gone (then it ends the builder)
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            if failure is not None and request.current() and folders.intact():
                _write_failure(folders.jit, request.key, failure, tmp)
            shutil.rmtree(tmp, ignore_errors=True)
            queue.withdraw(folders.queue, request.path, request.inode)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    return in_time


def _write_failure(directory: Path, key: str, reason: str, tmp: Path) -> None:
    record = tmp / f"{key}.failed"
    with contextlib.suppress(OSError):
        record.write_text(json.dumps({"reason": reason, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}))
        os.replace(record, directory / f"{key}.failed")




def _has_requests(folder: Path) -> bool:
    try:
        return any(name.endswith(queue.SUFFIX) for name in os.listdir(folder))
    except OSError:
        return False


if __name__ == "__main__":
    sys.exit(main())
