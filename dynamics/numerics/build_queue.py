"""The queue of optimised builds of one cache, and the lock that keeps one builder for it (issue 40).

A plan that wants the optimised library of its NLP for the next run does not start a compiler:
it puts a **request** into the cache's queue folder ``<cache dir>/builds/`` and starts a builder
only when none is running (:mod:`.background`). One builder drains the queue, one compile at a
time, and leaves when it is empty::

    with mutex(folder):
        put(folder, header, source)  # the request file <slot>.req (atomic), None: cannot write
        lock = claim(folder)         # None: a builder runs; else start one with this lock
    pending(folder)                  # the requests waiting, newest first (headers only)
    holder(folder)                   # the running builder: BuilderInfo(pid, started) or None

* **One request per slot.** A request is the file ``<slot>.req``: one JSON header line (the
  library's key, its compiler, flags and libraries, the key's salt, the SHA-256 of the source,
  the estimate and the budgets, who asked and when) followed by the C source. ``slot`` hashes
  the structure it was asked for (the robot and the task, ``OptimalControlProblem.name``), so a
  newer request for the same robot and task — an edit with ``--set`` that changes the C — replaces
  the older one with ``os.replace``: the stale request is dropped, and a builder compiling it
  sees the file change (another inode) and kills its compiler.
* **One builder per cache.** The builder holds an exclusive ``flock`` of ``builder.lock`` for its
  whole life. A requester takes the queue's short ``mutex`` lock, writes its request and tries
  the builder lock without waiting: it gets it only when no builder runs, and then — still
  under the mutex — hands that very lock (the open file) to the builder it starts
  (``pass_fds``) and writes the builder's pid into it: two plans can never start two
  builders. A builder leaves only once it has seen the queue empty *under the mutex* and let
  go of its lock there, so a request written meanwhile is never left without a builder.
* **Withdrawn by whoever asked.** A plan that is stopped removes its own requests
  (:func:`withdraw`, only the file it wrote: same inode); ``nhgait cache stop`` removes them all.

The lock file holds the running builder's pid and start time (written by the process that
started it), for ``nhgait cache``. Everything here is POSIX (``fcntl``); elsewhere there are no
background builds.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Request", "BuilderInfo", "queue_dir", "slot_name", "put", "pending", "withdraw", "holder",
           "claim", "record_holder", "mutex", "QUEUE_FOLDER", "LOCK_FILE", "SUFFIX", "REQUEST_TTL_S"]

#: the queue's folder in the cache directory
QUEUE_FOLDER = "builds"
#: the running builder's lock file (its content: the builder's pid and start time)
LOCK_FILE = "builder.lock"
#: the short lock taken to change the queue
MUTEX_FILE = ".mutex"
#: a request's file suffix
SUFFIX = ".req"
#: a request older than this (s) is dropped unbuilt: the robot it was for is long forgotten
REQUEST_TTL_S = 3600.0


@dataclass(frozen=True, kw_only=True)
class Request:
    """A request read from the queue: its ``path`` and that file's ``inode`` (a newer request
    for the slot is another file), the library ``key``, the ``header`` (module docstring), the
    time it was ``requested`` (epoch s) and the offset of the source in the file."""

    path: Path
    inode: int
    key: str
    header: dict
    requested: float
    offset: int

    def source(self) -> str | None:
        """The C source, or None when the file changed or is damaged (its SHA-256 differs)."""
        try:
            with open(self.path, "rb") as fh:
                if os.fstat(fh.fileno()).st_ino != self.inode:
                    return None
                fh.seek(self.offset)
                data = fh.read()
        except OSError:
            return None
        return data.decode() if hashlib.sha256(data).hexdigest() == self.header.get("sha256") else None

    def current(self) -> bool:
        """Whether this request is still the one queued for its slot (not withdrawn, not replaced)."""
        try:
            return os.stat(self.path).st_ino == self.inode
        except OSError:
            return False


@dataclass(frozen=True)
class BuilderInfo:
    """The running builder of a queue: its ``pid`` and ``started`` (epoch s)."""

    pid: int
    started: float


def queue_dir(cache: Path, *, create: bool = True) -> Path | None:
    """``cache/builds`` when it passes the cache's trust rules (created 0700), else None."""
    from .cache import trusted_dir
    try:
        return trusted_dir(Path(cache) / QUEUE_FOLDER, create=create)
    except OSError:
        return None


def slot_name(slot: str) -> str:
    """The file name stem of the slot ``slot`` (the robot and task it stands for, hashed)."""
    return hashlib.sha256(slot.encode()).hexdigest()[:24]


@contextlib.contextmanager
def mutex(folder: Path):
    """The queue's short exclusive lock (``flock`` of :data:`MUTEX_FILE`; released if its holder dies)."""
    import fcntl
    fd = os.open(folder / MUTEX_FILE, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def put(folder: Path, header: dict, source: str) -> tuple | None:
    """Queue ``source`` under ``header["slot"]``, replacing that slot's older request:
    ``(path, inode)`` of the request file, or None when it cannot be written. The caller holds
    the :func:`mutex` and then tries the builder lock (:func:`claim`)."""
    data = json.dumps({**header, "requested": time.time()}).encode() + b"\n" + source.encode()
    target = folder / f"{slot_name(header['slot'])}{SUFFIX}"
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-")
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, target)
        tmp = None
        return target, os.stat(target).st_ino
    except OSError:
        return None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def claim(folder: Path) -> int | None:
    """The builder lock's file descriptor, locked (exclusive, without waiting), or None when a
    builder holds it (or it cannot be opened)."""
    import fcntl
    try:
        fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def record_holder(fd: int, pid: int) -> None:
    """Write the builder's ``pid`` and start time into the lock file ``fd`` it holds."""
    with contextlib.suppress(OSError):
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps({"pid": pid, "started": time.time()}).encode(), 0)


def holder(folder: Path, *, under_mutex: bool = False) -> BuilderInfo | None:
    """The running builder of the queue ``folder`` (its lock is held), or None. The test takes
    the lock (shared) for an instant, so it is made under the :func:`mutex` (taken here unless
    the caller holds it): a requester's :func:`claim` never meets it."""
    if not under_mutex:
        try:
            with mutex(folder):
                return holder(folder, under_mutex=True)
        except OSError:
            return None
    import fcntl
    try:
        fd = os.open(folder / LOCK_FILE, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            return None                    # nobody holds it: no builder
        except OSError:
            pass
        try:
            info = json.loads(os.pread(fd, 4096, 0) or b"{}")
            return BuilderInfo(int(info["pid"]), float(info["started"]))
        except (OSError, ValueError, KeyError, TypeError):
            return None
    finally:
        os.close(fd)


def _read(path: Path) -> Request | None:
    try:
        with open(path, "rb") as fh:
            inode = os.fstat(fh.fileno()).st_ino
            line = fh.readline(1 << 16)
        header = json.loads(line)
        return Request(path=path, inode=inode, key=str(header["key"]), header=header,
                       requested=float(header["requested"]), offset=len(line))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def pending(folder: Path) -> list:
    """The requests of the queue ``folder``, newest first; damaged or expired ones
    (:data:`REQUEST_TTL_S`) are removed."""
    found = []
    try:
        paths = [folder / name for name in os.listdir(folder) if name.endswith(SUFFIX)]
    except OSError:
        return []
    now = time.time()
    for path in paths:
        request = _read(path)
        if request is None or now - request.requested > REQUEST_TTL_S:
            if path.exists():
                withdraw(folder, path, None if request is None else request.inode)
            continue
        found.append(request)
    return sorted(found, key=lambda r: -r.requested)


def withdraw(folder: Path, path: Path, inode: int | None) -> bool:
    """Remove the request ``path`` if it is still the file ``inode`` (None: whatever it is),
    under the mutex; whether it was removed."""
    with mutex(folder):
        try:
            if inode is not None and os.stat(path).st_ino != inode:
                return False
            os.unlink(path)
            return True
        except OSError:
            return False
