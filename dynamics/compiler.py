"""The C compiler: generated C into a cached, trusted shared library, killable and clean.

:func:`build_library` is the one way nhgait compiles C (the compiled integrator of
:mod:`.compiled` and the NLP functions of :mod:`nhgait.ocp.solver`)::

    lib = build_library(source, flags=("-O1",), salt="nlp", progress=progress)
    lib.path, lib.cached, lib.compile_s, lib.c_bytes

* **Cache with trust rules.** The library lives in ``<cache dir>/jit/<key>.so`` with
  ``key`` = SHA-256 of the source, the compiler command, the flags and ``salt``; a record
  ``<key>.json`` holds the library's SHA-256. A cached library is used only when
  :func:`~.cache.trusted_file` accepts both (directory 0700, owned by the user, not
  group/world-writable, content hash unchanged); otherwise it is rebuilt. An untrusted cache
  directory means a private temporary directory (``Library.private``; the caller removes it).
* **Atomic.** Compilation happens in ``jit/.build-<random>/``; the library and then its record
  are moved into place with ``os.replace``, so no reader ever sees half a library, and a
  library without its record is never loaded.
* **Interrupts clean up.** The compiler runs as a child in its own process group. Any
  exception while waiting — KeyboardInterrupt (Ctrl-C), the SystemExit the CLI raises on
  SIGTERM, a timeout — kills the whole group (gcc, cc1, as) and removes the build folder. On
  Linux the compiler also gets SIGKILL if this process dies without cleaning up
  (``PR_SET_PDEATHSIG``), and build folders left by such a death are removed by the next
  build once they are an hour old.
* **Talks.** Compiling takes seconds to minutes: a :class:`~.progress.Progress` gets a
  heartbeat while the compiler runs.

Compiler: ``$NHGAIT_CC``, else ``$CC``, else ``gcc``, else ``cc`` (:func:`compiler_command`);
none found raises :class:`CompilerUnavailable` (callers fall back to interpreted code).
"""
from __future__ import annotations

import hashlib
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Library", "CompilerUnavailable", "build_library", "compiler_command", "jit_dir",
           "STALE_BUILD_S"]

#: a build folder older than this is left over from a process that died: removed
STALE_BUILD_S = 3600.0


class CompilerUnavailable(RuntimeError):
    """No working C compiler, or it failed (the message says why)."""


@dataclass(frozen=True)
class Library:
    """A compiled shared library: ``path``; ``cached`` when it came from the cache;
    ``compile_s`` the compiler's wall time (0 when cached); ``c_bytes`` the source size;
    ``private`` when it lives in a private temporary folder the caller must remove."""

    path: Path
    key: str
    cached: bool
    compile_s: float
    c_bytes: int
    flags: tuple
    private: bool = False


def compiler_command() -> list | None:
    """The C compiler command (``$NHGAIT_CC``, else ``$CC``, else gcc, else cc), or None when
    none is found."""
    text = os.environ.get("NHGAIT_CC") or os.environ.get("CC")
    if text:
        command = shlex.split(text)
        return command if command and shutil.which(command[0]) else None
    for name in ("gcc", "cc"):
        if shutil.which(name):
            return [name]
    return None


def jit_dir() -> Path:
    from .cache import cache_dir
    return cache_dir() / "jit"


def _key(source: str, command: list, flags: tuple, salt: str) -> str:
    return hashlib.sha256("\0".join([source, " ".join(command), " ".join(flags), salt]).encode()).hexdigest()


def _cached(directory: Path, key: str) -> Path | None:
    """``directory/key.so`` when it and its record pass the trust rules, else None."""
    from .cache import trusted_file
    so, record = directory / f"{key}.so", directory / f"{key}.json"
    if not (so.exists() and record.exists()) or not trusted_file(record):
        return None
    try:
        recorded = json.loads(record.read_text())["library_sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return so if trusted_file(so, recorded) else None


def _remove_stale_builds(directory: Path) -> None:
    now = time.time()
    for entry in directory.glob(".build-*"):
        try:
            if now - entry.stat().st_mtime > STALE_BUILD_S:
                shutil.rmtree(entry, ignore_errors=True)
        except OSError:
            continue


def _die_with_parent() -> None:  # pragma: no cover - runs in the child
    """preexec: SIGKILL this child when the parent dies (Linux prctl PR_SET_PDEATHSIG)."""
    os.setpgrp()
    if sys.platform.startswith("linux"):
        import ctypes
        try:
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)
        except OSError:
            pass


def _run(cmd: list, progress, label: str, timeout: float | None) -> subprocess.CompletedProcess:
    """Run the compiler, killing its process group on any exception (see the module docstring)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=_die_with_parent if os.name == "posix" else None)
    try:
        while True:
            try:
                out, _ = proc.communicate(timeout=1.0)
                return subprocess.CompletedProcess(cmd, proc.returncode, out, "")
            except subprocess.TimeoutExpired:
                elapsed = time.perf_counter() - start
                if timeout is not None and elapsed > timeout:
                    raise CompilerUnavailable(f"the C compiler took more than {timeout:.0f} s ({label})") from None
                if progress is not None:
                    progress.heartbeat(f"{label}", elapsed)
    except BaseException:
        _kill(proc)
        raise


def _kill(proc: subprocess.Popen) -> None:
    try:
        if os.name == "posix":
            os.killpg(proc.pid, signal.SIGKILL)
        else:  # pragma: no cover
            proc.kill()
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def build_library(source: str, *, flags: tuple = ("-O1",), salt: str = "", libs: tuple = ("-lm",),
                  progress=None, label: str = "compiling", timeout: float | None = None) -> Library:
    """Compile ``source`` (or load it from the cache): see the module docstring."""
    from .cache import file_sha256, trusted_dir
    command = compiler_command()
    if command is None:
        cc = os.environ.get("NHGAIT_CC") or os.environ.get("CC")
        raise CompilerUnavailable(f"no C compiler found ({'$CC = ' + repr(cc) if cc else 'looked for gcc and cc'})")
    flags = tuple(flags)
    key = _key(source, command, flags, salt)
    directory = trusted_dir(jit_dir())
    private = directory is None
    if private:
        directory = Path(tempfile.mkdtemp(prefix="nhgait-jit-"))
    else:
        found = _cached(directory, key)
        if found is not None:
            return Library(found, key, True, 0.0, len(source), flags)
        _remove_stale_builds(directory)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=directory, prefix=".build-") as tmp:
        c_file, so_tmp = Path(tmp) / f"{key}.c", Path(tmp) / f"{key}.so"
        c_file.write_text(source)
        cmd = [*command, *flags, "-fPIC", "-shared", str(c_file), "-o", str(so_tmp), *libs]
        try:
            proc = _run(cmd, progress, label, timeout)
        except OSError as exc:
            raise CompilerUnavailable(f"cannot run the C compiler {command[0]!r} ({exc.strerror})") from None
        if proc.returncode != 0 or not so_tmp.exists():
            tail = " | ".join((proc.stdout or "").strip().splitlines()[-3:])
            raise CompilerUnavailable(f"the C compiler failed ({' '.join(command + list(flags))}): {tail}")
        os.chmod(so_tmp, 0o700)
        record = Path(tmp) / f"{key}.json"
        record.write_text(json.dumps({"library_sha256": file_sha256(so_tmp), "compiler": command,
                                      "flags": list(flags), "salt": salt, "c_bytes": len(source),
                                      "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}))
        os.chmod(record, 0o600)
        os.replace(so_tmp, directory / f"{key}.so")
        os.replace(record, directory / f"{key}.json")
    return Library(directory / f"{key}.so", key, False, time.perf_counter() - start, len(source), flags, private)
