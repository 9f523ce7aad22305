"""Where results go: output locations checked before the work, one writer per output, and a
result that survives a write that fails.

Every command that writes (``plan``, ``simulate``, ``sweep``, ``bench``, ``reproduce``) checks
its ``--out`` at the start, before any derivation, so that a bad location costs nothing:

* :func:`output_directory` — a directory that exists or can be created: not empty text, not a
  file or a device where a directory is needed, on a file system that takes a write (a probe
  file of :data:`PROBE_BYTES` is written and removed in the folder itself or, when it does not
  exist yet, in its nearest existing parent: read-only, full and over-quota locations are
  found here). Nothing is created.
* :func:`output_file` — a file to (re)write: not a directory, not a device or FIFO (a CSV
  written to ``/dev/full`` would fail at the end), in a folder that passes the same checks.

Each refusal is one :class:`~nhgait.dynamics.errors.ModelError` (exit status 2).

:func:`output_lock` makes one process the writer of a directory (a sweep store, a plan's
``--out``): it holds an exclusive ``flock`` on ``DIR/.nhgait-lock`` while it writes; a second
run is refused at once with the first one's process id, host, command and start time. The
kernel releases the lock when its holder dies, even by kill -9 (the file stays, unlocked, and
the next run takes it over). Platforms without ``fcntl`` run unlocked.

:func:`staged` writes a command's files whole or not at all: ``write(folder)`` writes them into a
staging folder inside the output directory, ``.writing-<pid>-*`` (removed whatever happens),
then each is moved into place (a rename on the same file system). A writer killed by kill -9
cannot remove its folder: the next writer of that directory does (:func:`clear_stale_staging`,
the folders of processes no longer running).

:func:`rescue` writes a result whose location failed at the end (disk full, removed, made
read-only meanwhile) to a fallback it names — ``$TMPDIR/nhgait-rescued-<time>-<pid>/``, else
``~/nhgait-rescued-…`` — or, when no folder takes it, prints it on standard output: a write
that fails never loses the result.
"""
from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import socket
import stat
import sys
import tempfile
import time
from pathlib import Path

from nhgait.dynamics.errors import ModelError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = ["output_directory", "output_file", "output_lock", "staged", "staging_folder", "move_into",
           "rescue", "write_failure", "LOCK_NAME", "STAGING_PREFIX", "clear_stale_staging", "PROBE_BYTES"]

#: bytes written by the probe (one block): a full, read-only or over-quota location cannot take them
PROBE_BYTES = 4096
#: the name of a staging folder inside an output directory starts with this, then the writer's pid
STAGING_PREFIX = ".writing-"
#: the lock file a writer holds in its output directory
LOCK_NAME = ".nhgait-lock"
_TITLE = "invalid output location"
_KINDS = ((stat.S_ISREG, "a file"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"))


def output_directory(path, option: str = "--out") -> Path:
    """``path`` as a directory nhgait may write (see the module docstring), or a ModelError."""
    folder = _named(path, option, "a directory")
    kind = _kind(folder)
    if kind not in (None, "a directory"):
        raise ModelError([f"{option} {folder} is {kind}: a directory is needed"], title=_TITLE)
    _probe(folder if kind else _existing_parent(folder, option), option, folder)
    return folder


def output_file(path, option: str = "--out") -> Path:
    """``path`` as a file nhgait may (re)write: not a directory, device or FIFO, in a folder
    that passes :func:`output_directory`'s checks."""
    file = _named(path, option, "a file")
    kind = _kind(file)
    if kind not in (None, "a file"):
        raise ModelError([f"{option} {file} is {kind}: a regular file is needed"], title=_TITLE)
    parent = file.parent
    parent_kind = _kind(parent)
    if parent_kind not in (None, "a directory"):
        raise ModelError([f"{option} {file}: its folder {parent} is {parent_kind}"], title=_TITLE)
    _probe(parent if parent_kind else _existing_parent(parent, option), option, file)
    return file


def _named(path, option: str, what: str) -> Path:
    if path is None or not str(path).strip():
        raise ModelError([f"{option} is empty: name {what}"], title=_TITLE)
    return Path(str(path)).expanduser()


def _kind(path: Path) -> str | None:
    """"a directory", "a file", "a character device", … for what ``path`` is now (links
    followed), None when nothing is there."""
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):     # not there (a file above it is found later)
        return None
    except OSError as exc:
        raise ModelError([f"{path} cannot be inspected ({exc.strerror})"], title=_TITLE) from None
    if stat.S_ISDIR(mode):
        return "a directory"
    return next((label for test, label in _KINDS if test(mode)), "not a file or directory")


def _existing_parent(folder: Path, option: str) -> Path:
    """The nearest existing ancestor of ``folder`` (it must be a directory: it will hold it)."""
    for parent in folder.absolute().parents:
        kind = _kind(parent)
        if kind == "a directory":
            return parent
        if kind is not None:
            raise ModelError([f"{option} {folder} cannot be created: {parent} is {kind}"], title=_TITLE)
    raise ModelError([f"{option} {folder} cannot be created: no existing folder above it"], title=_TITLE)


def _probe(folder: Path, option: str, target: Path) -> None:
    """Write and remove :data:`PROBE_BYTES` in ``folder``: a ModelError naming the reason when
    the file system does not take them."""
    name = None
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".nhgait-probe-")
        with os.fdopen(fd, "wb") as fh:
            fh.write(b"\0" * PROBE_BYTES)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise ModelError([f"{option} {target} cannot be written: {_why(exc, folder)}"],
                         title=_TITLE) from None
    finally:
        if name is not None:
            with contextlib.suppress(OSError):
                os.unlink(name)


def _why(exc: OSError, folder: Path) -> str:
    reasons = {errno.EROFS: f"{folder} is on a read-only file system",
               errno.ENOSPC: f"no space left on the device of {folder}",
               errno.EDQUOT: f"the disk quota of {folder} is exhausted",
               errno.EFBIG: "the file-size limit (ulimit -f) is too small",
               errno.EACCES: f"permission denied in {folder}", errno.EPERM: f"permission denied in {folder}"}
    return reasons.get(exc.errno, f"{exc.strerror or exc} in {folder}")


def write_failure(exc: BaseException, where) -> str:
    """One line for a write to ``where`` that failed: the reason, not a traceback."""
    if isinstance(exc, OSError):
        return f"writing {where} failed: {_why(exc, Path(str(where)))}"
    return f"writing {where} failed: {exc}"


# ----------------------------------------------------------------------------- one writer
@contextlib.contextmanager
def output_lock(directory, command: str):
    """Hold ``directory``'s writer lock (created with the directory) while the block runs; a
    second writer is refused at once (ModelError naming the first). See the module docstring."""
    directory = Path(directory)
    created = not directory.exists()
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ModelError([f"{directory} cannot be created: {_why(exc, directory.parent)}"],
                         title=_TITLE) from None
    try:
        if fcntl is None:  # pragma: no cover - Windows
            yield
            return
        fd = _acquire(directory / LOCK_NAME, directory)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "command": command,
                                      "started": time.strftime("%Y-%m-%d %H:%M:%S")}).encode(), 0)
            clear_stale_staging(directory)    # the one writer now: a killed run's staging goes
            yield
        finally:
            with contextlib.suppress(OSError):
                os.unlink(directory / LOCK_NAME)       # removed while still held: see _acquire
            os.close(fd)
    finally:
        if created:                # a run that wrote nothing (bad input) leaves no empty folder
            with contextlib.suppress(OSError):
                directory.rmdir()


def _acquire(path: Path, directory: Path) -> int:
    """An open descriptor of ``path`` holding its exclusive lock. A lock file removed by its
    previous holder between our open and our lock is not the lock any more: open again."""
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0)
                         | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as exc:
            raise ModelError([f"{directory} cannot be locked for writing: {_why(exc, directory)}"],
                             title=_TITLE) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise ModelError([f"{directory} is being written by another nhgait run ({holder}): "
                              "wait for it to finish, or choose another --out"],
                             title="output directory in use") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path, follow_symlinks=False).st_ino
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)


def _holder(fd: int) -> str:
    try:
        data = json.loads(os.pread(fd, 4096, 0) or b"{}")
        return (f"process {data['pid']} on {data['host']}, `{data['command']}`, started {data['started']}")
    except (OSError, ValueError, KeyError, TypeError):
        return "a process that has not yet said which"


# ----------------------------------------------------------------------------- staged writes
def staged(out, write) -> list:
    """The files ``write(staging)`` wrote (a list of paths in ``staging``), moved into ``out``
    (created): each file whole or not at all (module docstring). Returns their paths in ``out``."""
    with staging_folder(out) as staging:
        return move_into(out, [Path(path) for path in write(staging)])


@contextlib.contextmanager
def staging_folder(out):
    """A staging folder ``out/.writing-<pid>-*`` (``out`` created), removed on leaving with
    whatever is still in it, and registered meanwhile so that the stop watchdog removes it too
    (:func:`~nhgait.dynamics.errors.temporary_folder`). Stale staging folders of writers no
    longer running are removed first (:func:`clear_stale_staging`)."""
    from nhgait.dynamics.errors import temporary_folder
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    clear_stale_staging(out)
    with tempfile.TemporaryDirectory(dir=out, prefix=f"{STAGING_PREFIX}{os.getpid()}-") as staging, \
            temporary_folder(staging):
        yield Path(staging)


def move_into(out, paths) -> list:
    """``paths`` (files written whole in a staging folder of ``out``) moved into ``out``, each
    by one rename; their new paths."""
    out = Path(out)
    for path in paths:
        os.replace(path, out / Path(path).name)
    return [out / Path(path).name for path in paths]


def clear_stale_staging(out) -> list:
    """Remove the staging folders ``out/.writing-<pid>-*`` of writers that no longer run (a run
    killed by kill -9 cannot remove its own), and those of no stated pid; a live writer's
    folder is kept. Returns the folders removed."""
    removed = []
    for folder in Path(out).glob(f"{STAGING_PREFIX}*"):
        pid = folder.name[len(STAGING_PREFIX):].split("-", 1)[0]
        if folder.is_dir() and not folder.is_symlink() and not (pid.isdigit() and _running(int(pid))):
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    return removed


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists on this machine (signal 0 probes without sending)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


# ----------------------------------------------------------------------------- rescue
def rescue(name: str, content, what: str = "result") -> str:
    """Write ``content`` as ``name`` into the first fallback folder that takes it (see the
    module docstring); print it on standard output when none does. ``content`` is text, data
    (written as JSON) or a function writing the file at the path it is given. Returns a
    sentence for the summary saying where it went."""
    if callable(content):
        write = content
    else:
        text = content if isinstance(content, str) else json.dumps(content, indent=1, default=_plain)

        def write(path):
            Path(path).write_text(text)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    for base in (Path(tempfile.gettempdir()), Path.home()):
        folder = base / f"nhgait-rescued-{stamp}-{os.getpid()}"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            write(folder / name)
        except OSError:
            continue
        return f"the {what} was saved to {folder / name}"
    try:
        text = _in_memory(write) if callable(content) else text
    except OSError:
        return f"the {what} ({name}) could not be saved: no fallback folder took it"
    sys.stdout.write(f"----- {name} -----\n{text}\n----- end of {name} -----\n")
    sys.stdout.flush()
    return f"the {what} ({name}) is printed above: no fallback folder could be written"


def _in_memory(write) -> str:
    """What ``write(path)`` writes, through an anonymous in-memory file (Linux ``memfd``; never
    a file on a disk, never standard output reopened — that would truncate a redirected one)."""
    if not hasattr(os, "memfd_create"):
        raise OSError(errno.ENOSYS, "no in-memory file on this system")
    fd = os.memfd_create("nhgait-rescue")
    try:
        write(Path(f"/proc/self/fd/{fd}"))
        os.lseek(fd, 0, os.SEEK_SET)
        with os.fdopen(os.dup(fd), "r") as fh:
            return fh.read()
    finally:
        os.close(fd)


def _plain(value):
    """JSON for numpy arrays and scalars (``tolist``); text for anything else."""
    return value.tolist() if hasattr(value, "tolist") else str(value)
