"""The C compiler: generated C into a cached, trusted shared library, killable and clean.

:func:`build_library` is the one way nhgait compiles C (the compiled integrator of
:mod:`.compiled` and the NLP functions of :mod:`nhgait.ocp.solver`)::

    lib = build_library(source, Toolchain(flags=("-O1",)), salt="nlp", progress=progress)
    lib.path, lib.cached, lib.compile_s, lib.c_bytes

How C becomes a library is one value, a :class:`Toolchain` (the compiler command, the flags
before ``-fPIC -shared``, the libraries after the source): the optimising compiler's
(``Toolchain()``, its command found by :func:`compiler_command`) or the fast compiler's
(:attr:`~.fast_compiler.FastCompiler.toolchain`).

* **Cache with trust rules.** The library lives in ``<cache dir>/jit/<key>.so`` with
  ``key`` = :func:`library_key`, the SHA-256 of the source, the compiler command, the flags,
  the libraries and ``salt`` (and the CPU, for code built for it: :data:`NATIVE_FLAGS`); a
  record ``<key>.json`` holds the library's SHA-256. A cached
  library is used only when :func:`~.cache.trusted_file` accepts both (directory 0700, owned
  by the user, not group/world-writable, content hash unchanged); otherwise it is rebuilt. A
  cache directory refused by the trust rules is not used for libraries either (its ``jit/``
  is never created nor read), and one that cannot be written (read-only, full) gives one
  warning: the library is then built in a private temporary directory
  (``nhgait-jit-<host>-<pid>-…`` in ``$TMPDIR``, ``Library.private``; the caller removes it
  once the library is loaded).
* **OpenMP where there is one.** A build asked for with ``-fopenmp`` (:mod:`.openmp`) whose
  compiler fails with it is built again without it (its pragmas are then ignored): the key
  keeps the flags asked for, the record and :class:`Library` the ones used.
* **Atomic.** Compilation happens in ``jit/.build-<random>/``; the library and then its record
  are moved into place with ``os.replace``, so no reader ever sees half a library, and a
  library without its record is never loaded.
* **Its temporaries are nhgait's.** The compiler runs with ``TMPDIR`` (``TMP``, ``TEMP``) set
  to the build folder, so its own temporary files (gcc's ``cc*.s``, ``cc*.o``) are removed
  with that folder, never left in the user's ``$TMPDIR``.
* **Interrupts clean up.** The compiler runs as a child in its own process group. Any
  exception while waiting — KeyboardInterrupt (Ctrl-C), the ``Terminated`` exception the CLI
  raises on SIGTERM (:mod:`nhgait.gaits.cli.stopping`), a timeout — kills the whole group (a wrapper
  script named by ``$NHGAIT_CC`` and everything it started: gcc, cc1, as) and removes the
  build folder. On Linux the compiler also gets SIGKILL if the thread that started it dies
  without cleaning up (``PR_SET_PDEATHSIG``), and build folders (and private folders) left by
  such a death — kill -9 — are removed by the next build: their name carries the host and the
  process id, so a folder whose process is gone goes at once, any other once it is
  :data:`STALE_BUILD_S` old.
* **Talks.** Compiling takes seconds to minutes: a :class:`~.progress.Progress` gets a
  heartbeat while the compiler runs.

Compiler: ``$NHGAIT_CC``, else ``$CC``, else ``gcc``, else ``cc`` (:func:`compiler_command`;
either variable may hold a command with arguments); none found raises
:class:`CompilerUnavailable` (callers fall back to interpreted code).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import STOP_SIGNALS
from ..memo import LruMemo
from . import openmp

__all__ = ["Library", "Toolchain", "CompilerUnavailable", "build_library", "cached_library",
           "compiler_command", "library_key", "jit_dir", "library_dir", "compile_in", "CompileJob",
           "STALE_BUILD_S",
           "COMPILER_COMMANDS", "NATIVE_FLAGS", "host_cpu", "builds_for_cpu", "library_by_key",
           "known_compiler", "SAME_BITS_FLAGS", "WATCH_S",
           "recorded_flags"]

#: a build folder older than this (seconds) is left over from a process that died: removed
STALE_BUILD_S = 3600.0
#: how often (s) a compile with a ``watch`` (:class:`CompileJob`) calls it
WATCH_S = 0.2
#: how long (s) :func:`_kill` waits for a killed compiler's process group to be gone
KILL_WAIT_S = 1.0
#: Linux prctl option: signal the child when the thread that forked it dies
_PR_SET_PDEATHSIG = 1
#: flags that tune the code to the compiling machine's CPU: a library built with one of them is
#: keyed by that CPU too (:func:`host_cpu`), so a cache shared with other machines never serves
#: it to a machine that cannot run it
NATIVE_FLAGS = ("-march=native", "-mcpu=native", "-mtune=native")
#: machines whose compilers (gcc, clang) accept ``-march=native`` and whose CPU :func:`host_cpu` reads
_NATIVE_MACHINES = ("x86_64", "aarch64")
#: the optimised library computes the fast compiler's bits: every a·b + c rounded twice, as
#: tcc's code does, never fused into one multiply-add (which ``-march=native`` allows gcc
#: wherever the CPU has one, and aarch64 always has). Measured (the 3-link snake's NLP):
#: gcc -O2 -march=native's ``nlp_hess_l`` differed from tcc's by up to 2.3e-6, with this flag by
#: nothing — so a cold plan (tcc's code, then the optimised library) and a warm one take the
#: same iterations to the same gait
SAME_BITS_FLAGS = ("-ffp-contract=off",)
#: compilers known to accept ``-march=native`` (a program's name, a version suffix allowed: gcc-12)
_NATIVE_COMPILERS = re.compile(r"(x86_64-linux-gnu-|aarch64-linux-gnu-)?(gcc|clang|cc)(-\d+(\.\d+)*)?")


class CompilerUnavailable(RuntimeError):
    """No working C compiler, or it failed (the message says why)."""


@dataclass(frozen=True)
class Library:
    """A compiled shared library: ``path``; ``key`` its :func:`library_key`; ``cached`` when it
    came from the cache; ``compile_s`` the compiler's wall time (0 when cached); ``c_bytes``
    the source size; ``private`` when it lives in a private temporary folder the caller must
    remove; ``peak_mb`` the compiler's peak resident memory when it was measured."""

    path: Path
    key: str
    cached: bool
    compile_s: float
    c_bytes: int
    flags: tuple
    private: bool = False
    peak_mb: float | None = None


@dataclass(frozen=True)
class Toolchain:
    """How a C file becomes a shared library: the compiler ``command`` (a program and its own
    options; None: the optimising compiler of :func:`compiler_command`), ``flags`` (before
    ``-fPIC -shared``) and ``libs`` (after the source)."""

    command: tuple | None = None
    flags: tuple = ("-O1",)
    libs: tuple = ("-lm",)

    def __post_init__(self):
        object.__setattr__(self, "flags", tuple(self.flags))
        object.__setattr__(self, "libs", tuple(self.libs))
        if self.command is not None:
            object.__setattr__(self, "command", tuple(self.command))


def _compiler_setting() -> tuple[str, str] | None:
    """(variable name, value) of the compiler chosen by the environment, or None."""
    for name in ("NHGAIT_CC", "CC"):
        if os.environ.get(name):
            return name, os.environ[name]
    return None


#: the compiler command found per environment: ($NHGAIT_CC, $CC, $PATH) → the command or None.
#: Looking it up walks $PATH (~50 µs); a simulation asks on every call. An entry lives until 16
#: other environments were seen, in practice for the process: a compiler installed into a
#: folder already on an unchanged $PATH after the first look-up is seen after ``clear()``.
COMPILER_COMMANDS = LruMemo("C compiler command per ($NHGAIT_CC, $CC, $PATH)", size=16)


def compiler_command() -> list | None:
    """The C compiler command (``$NHGAIT_CC``, else ``$CC``, else gcc, else cc), or None when
    none is found (remembered per environment, :data:`COMPILER_COMMANDS`). A variable that is
    set is final: its program missing means None."""
    environ = os.environ
    key = (environ.get("NHGAIT_CC"), environ.get("CC"), environ.get("PATH"))
    command = COMPILER_COMMANDS.get(key, _find_compiler)
    return None if command is None else list(command)


def _find_compiler() -> tuple | None:
    setting = _compiler_setting()
    if setting is not None:
        command = shlex.split(setting[1])
        return tuple(command) if command and shutil.which(command[0]) else None
    for name in ("gcc", "cc"):
        if shutil.which(name):
            return (name,)
    return None


def _command() -> list:
    """:func:`compiler_command`, or :class:`CompilerUnavailable` saying what was looked for."""
    command = compiler_command()
    if command is not None:
        return command
    setting = _compiler_setting()
    if setting is None:
        where = "looked for gcc and cc"
    else:
        name, text = setting
        where = f"${name} = {text!r}: {(shlex.split(text) or [''])[0]!r} not found"
    raise CompilerUnavailable(f"no C compiler found ({where})")


def jit_dir() -> Path:
    """``<cache dir>/jit``, where compiled libraries are kept (not created)."""
    from .cache import cache_dir
    return cache_dir() / "jit"


def host_cpu() -> str | None:
    """This machine's instruction set as text, or None when it cannot be read: on Linux x86_64
    and aarch64, the architecture with the first processor's vendor, model and feature flags
    from ``/proc/cpuinfo`` (two machines with the same text run the same instructions); elsewhere
    None, and nothing is built for the native CPU."""
    import platform
    machine = platform.machine()
    if machine not in _NATIVE_MACHINES:
        return None
    try:
        text = Path("/proc/cpuinfo").read_text(errors="replace")
    except OSError:
        return None
    fields = {}
    for line in text.splitlines():
        if not line.strip():
            break                                   # the first processor's block
        name, _, value = line.partition(":")
        fields.setdefault(name.strip(), value.strip())
    found = [fields.get(k, "") for k in ("vendor_id", "model name", "flags", "CPU implementer", "CPU part",
                                         "Features")]
    return " | ".join([machine, *found]) if any(found) else None


def known_compiler(command: list | None = None) -> bool:
    """Whether the compiler ``command`` (None: :func:`compiler_command`) names gcc, clang or cc
    (a wrapper such as ccache before it allowed): one that takes ``-march=native`` and
    :data:`SAME_BITS_FLAGS`. Another compiler named by ``$NHGAIT_CC`` may refuse them, and a
    failed background build is not retried: it gets portable flags only."""
    command = compiler_command() if command is None else command
    return bool(command) and any(_NATIVE_COMPILERS.fullmatch(Path(part).name) for part in command[:2])


def builds_for_cpu(command: list | None = None) -> bool:
    """Whether the optimised build may be tuned to this CPU: :func:`host_cpu` reads it and the
    compiler is a :func:`known_compiler`."""
    command = compiler_command() if command is None else command
    return known_compiler(command) and host_cpu() is not None


def library_key(source: str, *, flags: tuple = ("-O1",), salt: str = "", libs: tuple = ("-lm",),
                command: list | tuple | None = None) -> str:
    """The cache key of ``source`` built by :func:`build_library` with these arguments and
    ``command`` (None: the current compiler, :func:`compiler_command`): SHA-256 of all of them,
    and of :func:`host_cpu` when a flag tunes the code to it (:data:`NATIVE_FLAGS`). Raises
    :class:`CompilerUnavailable`."""
    parts = [source, list(command) if command is not None else _command(), list(flags), list(libs), salt]
    if any(f in NATIVE_FLAGS for f in flags):
        parts.append(host_cpu() or "an unknown CPU")
    return hashlib.sha256(json.dumps(parts).encode()).hexdigest()


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


def recorded_flags(library: Path, requested) -> tuple:
    """The flags ``library`` was built with, from its record: ``requested`` less any the build
    dropped (``-fopenmp`` where the compiler has no OpenMP, :func:`compile_in`)."""
    try:
        return tuple(json.loads(library.with_suffix(".json").read_text())["flags"])
    except (OSError, ValueError, KeyError, TypeError):
        return tuple(requested)


def _child_setup(mask=None, memory_bytes: int | None = None, cpu_seconds: float | None = None,
                 niceness: int | None = None):
    """The preexec function of the compiler: its own process group (with ``niceness``: its own
    session at that niceness, and so its own autogroup, set to it too), the signal mask ``mask``
    (the parent blocks the stop signals while it starts the compiler, :func:`_run`), at most
    ``memory_bytes`` of address space (``RLIMIT_AS``; None: unlimited), at most ``cpu_seconds``
    of CPU time per process (``RLIMIT_CPU``, inherited by gcc's cc1 and as; None: unlimited) and,
    on Linux, SIGKILL when the parent thread dies (exit at once if the parent died before).
    ``prctl`` is looked up here, in the parent: the forked child only calls it."""
    import resource
    parent = os.getpid()
    prctl = None
    if sys.platform.startswith("linux"):
        import ctypes
        prctl = ctypes.CDLL(None).prctl
    cpu = None if cpu_seconds is None else max(1, int(cpu_seconds))

    def setup() -> None:  # pragma: no cover - runs in the child
        if niceness is None:
            os.setpgrp()
        else:
            os.setsid()
            with contextlib.suppress(OSError):
                os.nice(niceness - os.nice(0))
            with contextlib.suppress(OSError), open("/proc/self/autogroup", "w") as fh:
                fh.write(str(niceness))
        if mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        if memory_bytes is not None:
            resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
        if cpu is not None:
            resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 1))
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
            if os.getppid() != parent:
                os._exit(1)
    return setup


def _run(cmd: list, job: CompileJob, tmpdir: Path) -> subprocess.CompletedProcess:
    """Run the compiler of ``job`` with its temporaries in ``tmpdir`` and its limits
    (``memory_bytes``, ``cpu_seconds``), killing its process group on any exception (see the
    module docstring). The stop signals are blocked until the compiler is started and their
    exception would kill it (one raised inside ``Popen`` itself left the compiler's group running)."""
    start = time.perf_counter()
    env = {**os.environ, "TMPDIR": str(tmpdir), "TMP": str(tmpdir), "TEMP": str(tmpdir)}
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS) if os.name == "posix" else None
    setup = (_child_setup(mask, job.memory_bytes, job.cpu_seconds, job.niceness) if os.name == "posix"
             else None)
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                                errors="replace", preexec_fn=setup)
    except BaseException:
        _unblock(mask)
        raise
    with proc:
        try:
            _unblock(mask)
            return _wait(proc, cmd, start, job)
        except BaseException:
            _kill(proc)
            raise


def _unblock(mask) -> None:
    if mask is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _wait(proc, cmd, start, job) -> subprocess.CompletedProcess:
    """The compiler's result, with a heartbeat every second while it runs (``job.progress``)
    and ``job.watch()`` called every :data:`WATCH_S` (it raises to stop the compile); a
    ``job.timeout`` raises :class:`CompilerUnavailable` (the caller kills the compiler)."""
    poll = WATCH_S if job.watch is not None else 1.0
    while True:
        try:
            out, _ = proc.communicate(timeout=poll)
            return subprocess.CompletedProcess(cmd, proc.returncode, out, "")
        except subprocess.TimeoutExpired:
            elapsed = time.perf_counter() - start
            if job.timeout is not None and elapsed > job.timeout:
                raise CompilerUnavailable(f"the C compiler took more than {job.timeout:.0f} "
                                          f"s ({job.label})") from None
            if job.watch is not None:
                job.watch()
            if job.progress is not None:
                job.progress.heartbeat(job.label, elapsed)


def _kill(proc: subprocess.Popen) -> None:
    """SIGKILL the compiler's process group (the compiler and every process it started), reap
    the compiler, and wait up to :data:`KILL_WAIT_S` for the rest of its group to be gone: a
    killed process still has to be scheduled to die, and a nice-19 one on a loaded machine may
    wait seconds for that (its orphans — cc1, as — would outlive the caller's return)."""
    if os.name == "posix":
        # the group may be gone already (ProcessLookupError), or hold only zombies (EPERM on macOS)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
    else:  # pragma: no cover
        proc.kill()
    proc.wait()
    deadline = time.monotonic() + KILL_WAIT_S
    while os.name == "posix" and time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except (ProcessLookupError, PermissionError):
            return
        time.sleep(0.005)


@dataclass(frozen=True, kw_only=True)
class CompileJob:
    """One compilation: the C ``source``, the compiler ``command``, ``flags`` (before the
    source), ``libs`` (after it), the key's ``salt`` and the ``key`` itself; ``progress``,
    ``label`` and ``timeout`` (wall seconds) for the waiting; ``memory_bytes``, the compiler's
    address space, and ``cpu_seconds``, its CPU time per process (None: unlimited); ``niceness``:
    the compiler in a session of its own at that niceness (its autogroup too; None: as this
    process, in a process group of its own); ``measure``:
    record the compiler's peak resident memory (meaningful in a process whose only children are
    its compilers: the background builder); ``watch``: called every :data:`WATCH_S` while the
    compiler runs, it raises to stop it (the builder: its cache folder gone, its request stale)."""

    source: str
    command: list
    flags: tuple
    libs: tuple
    salt: str
    key: str
    progress: object = None
    label: str = "compiling"
    timeout: float | None = None
    memory_bytes: int | None = None
    cpu_seconds: float | None = None
    niceness: int | None = None
    measure: bool = False
    watch: Callable[[], None] | None = None


def _compile(job: CompileJob, directory: Path) -> Library:
    """Compile ``job.source`` in a ``.build-*`` folder of ``directory`` (removed whatever
    happens) and move the library, then its record, to ``directory/key.so`` and ``key.json``."""
    from .cache import temporary_prefix
    with tempfile.TemporaryDirectory(dir=directory, prefix=temporary_prefix(".build-"),
                                     ignore_cleanup_errors=True) as tmp:
        return compile_in(job, directory, Path(tmp))


def compile_in(job: CompileJob, directory: Path, tmp: Path) -> Library:
    """:func:`_compile` in the existing build folder ``tmp`` of ``directory`` (the caller
    removes it): the library and then its record (SHA-256, compiler, flags, seconds and, with
    ``job.measure``, the compiler's peak resident memory) moved into ``directory``."""
    from .cache import file_sha256
    start = time.perf_counter()
    key, command, flags, libs = job.key, list(job.command), job.flags, job.libs
    c_file, so_tmp, record = tmp / f"{key}.c", tmp / f"{key}.so", tmp / f"{key}.json"
    c_file.write_text(job.source)
    cmd = [*command, *flags, "-fPIC", "-shared", str(c_file), "-o", str(so_tmp), *libs]
    try:
        proc = _run(cmd, job, tmp)
        if (proc.returncode != 0 or not so_tmp.exists()) and openmp.FLAG in flags:
            flags = tuple(f for f in flags if f != openmp.FLAG)   # no OpenMP here: pragmas ignored
            cmd = [*command, *flags, "-fPIC", "-shared", str(c_file), "-o", str(so_tmp), *libs]
            proc = _run(cmd, job, tmp)
    except OSError as exc:
        raise CompilerUnavailable(f"cannot run the C compiler {command[0]!r} ({exc.strerror})") from None
    if proc.returncode != 0 or not so_tmp.exists():
        tail = " | ".join((proc.stdout or "").strip().splitlines()[-3:])
        raise CompilerUnavailable(f"the C compiler failed ({' '.join(command + list(flags))}): {tail}")
    seconds, peak_mb = time.perf_counter() - start, _children_peak_mb() if job.measure else None
    os.chmod(so_tmp, 0o700)
    record.write_text(json.dumps({"library_sha256": file_sha256(so_tmp), "compiler": command,
                                  "flags": list(flags), "libs": list(libs), "salt": job.salt,
                                  "c_bytes": len(job.source), "compile_s": round(seconds, 3),
                                  "compiler_peak_mb": peak_mb,
                                  "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}))
    os.chmod(record, 0o600)
    os.replace(so_tmp, directory / f"{key}.so")
    os.replace(record, directory / f"{key}.json")
    return Library(directory / f"{key}.so", key, False, seconds, len(job.source), flags, peak_mb=peak_mb)


def _children_peak_mb() -> float | None:
    """The largest resident memory of any child process waited for so far (MB), or None."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return None
    kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return round(kb / (1024.0 if sys.platform != "darwin" else 1024.0 ** 2), 1)


def build_library(source: str, toolchain: Toolchain = Toolchain(), *, salt: str = "", progress=None,
                  label: str = "compiling", timeout: float | None = None) -> Library:
    """Compile ``source`` with ``toolchain`` (or load it from the cache): see the module
    docstring. ``salt`` only changes the key; ``progress`` gets a heartbeat labelled ``label``
    while the compiler runs, which is killed after ``timeout`` seconds (None: no limit). Raises
    :class:`CompilerUnavailable`."""
    from .cache import remove_stale_temporaries, unwritable_warning
    command = list(toolchain.command) if toolchain.command is not None else _command()
    flags, libs = toolchain.flags, toolchain.libs
    key = library_key(source, flags=flags, salt=salt, libs=libs, command=command)
    job = CompileJob(source=source, command=command, flags=flags, libs=libs, salt=salt, key=key,
               progress=progress, label=label, timeout=timeout)
    directory = _library_dir()
    if directory is not None:
        found = _cached(directory, key)
        if found is not None:
            return Library(found, key, True, 0.0, len(source), recorded_flags(found, flags))
        remove_stale_temporaries(directory, ".build-", max_age_s=STALE_BUILD_S)
        try:
            return _compile(job, directory)
        except OSError as exc:        # the cache cannot be written (read-only, full): build privately
            unwritable_warning(directory.parent, exc)
    return _compile_privately(job)


def cached_library(source: str, toolchain: Toolchain = Toolchain(), *, salt: str = "") -> Library | None:
    """The library :func:`build_library` would give for these arguments if it is in the cache
    and trusted, else None (nothing is compiled). Raises :class:`CompilerUnavailable` when
    ``toolchain.command`` is None and there is no compiler."""
    flags = toolchain.flags
    key = library_key(source, flags=flags, salt=salt, libs=toolchain.libs, command=toolchain.command)
    directory = _library_dir()
    found = None if directory is None else _cached(directory, key)
    if found is None:
        return None
    return Library(found, key, True, 0.0, len(source), recorded_flags(found, flags))


def library_dir() -> Path | None:
    """``<cache dir>/jit`` when it may be used (:func:`_library_dir`), else None."""
    return _library_dir()


def library_by_key(key: str) -> Path | None:
    """The cached library of cache key ``key`` (:func:`library_key`) when it is there and
    passes the trust rules, else None: how a plan finds the library its background build
    (:mod:`.background`) has just finished."""
    directory = _library_dir()
    return None if directory is None or not key else _cached(directory, key)


def _library_dir() -> Path | None:
    """``<cache dir>/jit`` when both it and the cache directory pass the trust rules (a refused
    cache directory is not used for libraries either), else None."""
    from .cache import trusted_dir
    if trusted_dir() is None:
        return None
    try:
        return trusted_dir(jit_dir())
    except OSError:
        return None


def _compile_privately(job: CompileJob) -> Library:
    """Compile into a private temporary folder (``Library.private``), after removing the
    private folders of processes that died; a folder that cannot be written means no compiler."""
    from .cache import remove_stale_temporaries, temporary_prefix
    remove_stale_temporaries(Path(tempfile.gettempdir()), "nhgait-jit-", max_age_s=STALE_BUILD_S)
    try:
        private = Path(tempfile.mkdtemp(prefix=temporary_prefix("nhgait-jit-")))
    except OSError as exc:
        raise CompilerUnavailable(f"cannot create a folder for the C compiler in {tempfile.gettempdir()} "
                                  f"({exc.strerror})") from None
    try:
        return replace(_compile(job, private), private=True)
    except OSError as exc:
        shutil.rmtree(private, ignore_errors=True)
        raise CompilerUnavailable(f"cannot write the C compiler's files in {private} "
                                  f"({exc.strerror})") from None
    except BaseException:
        shutil.rmtree(private, ignore_errors=True)
        raise
