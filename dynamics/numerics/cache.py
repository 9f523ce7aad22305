"""On-disk cache of derived models and compiled artefacts, keyed by SHA-256 content hashes.

What a key covers
-----------------
:func:`cache_key` hashes everything that shapes a derived model: the system's *structure*
(coordinate, parameter and input names, L, ω, τ, fiber and planar frame — :meth:`System.
canonical_text`), the formulation and options, the source of every module of
``nhgait.dynamics`` and the versions of nhgait, Python, sympy, CasADi and numpy. Parameter
*values* are not in the key: every derivation keeps the parameters symbolic, and
:func:`nhgait.dynamics.derivation.formulations.derive` binds the caller's system (name and values) to the
loaded object, so an entry can never return another caller's values. :func:`make_key` hashes
arbitrary parts together with the same code and version stamp (for other artefacts, e.g.
specialised models, whose key must then include the parameter values themselves).

Trust rules (as pip's and Python's bytecode caches)
---------------------------------------------------
* the directory is created with mode 0700;
* a directory or entry that is group- or world-writable or owned by another user is refused
  with a warning (the result is recomputed and not written there);
* an entry is a format line, a JSON header (key, type, size and SHA-256 of the payload) and
  the payload — its key, a newline and the pickle, so the SHA-256 covers the key and an entry
  proves which input it belongs to; the header, the payload's SHA-256 and the key inside it are
  checked *before* anything is unpickled, so an entry written for another key or type (or
  another scene's entry with its header key rewritten), truncated, or with one bit flipped on
  disk is refused with a warning and rebuilt — never deserialised (a damaged pickle of CasADi
  objects can crash the interpreter);
* compiled libraries are loaded only through :func:`trusted_file` with their recorded SHA-256.

Faults cost at most a rebuild: entries are written to a temporary file of the same directory
and renamed into place (``os.replace``), so a reader never sees a partial entry and concurrent
derivations of one model leave one valid entry; a directory that cannot be written (read-only,
full, over quota, over ``ulimit -f``) gives one warning and the run goes on uncached; a
temporary file left by a writer that was killed (``.tmp-<host>-<pid>-…``: its process is gone,
or it is older than :data:`STALE_TMP_S`) is removed by the next write.

Location: ``$NHGAIT_CACHE_DIR`` if set, else the user's cache directory
(``$XDG_CACHE_HOME/nhgait`` or ``~/.cache/nhgait``; ``~/Library/Caches/nhgait`` on macOS,
``%LOCALAPPDATA%\\nhgait`` on Windows).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import pickle
import shutil
import socket
import stat
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from functools import lru_cache
from importlib import metadata
from pathlib import Path

__all__ = ["cache_dir", "cache_key", "make_key", "code_stamp", "load", "store", "path_for",
           "Provenance", "trusted_dir", "trusted_file", "file_sha256", "UntrustedCacheWarning",
           "temporary_prefix", "remove_stale_temporaries", "unwritable_warning", "STALE_TMP_S"]

class UntrustedCacheWarning(UserWarning):
    """A cache directory or entry was refused by the trust rules."""


@dataclass(frozen=True)
class Provenance:
    """Where a derived model came from.

    Attributes
    ----------
    key : SHA-256 cache key of the structure, formulation, options, code and versions.
    created : ISO-8601 UTC time the derivation that produced the equations ran.
    derive_time_s : wall time of that derivation.
    cache_hit : True when this object was loaded from the cache (else derived now).
    load_time_s : time to read the entry (0 when derived now).
    versions : "nhgait=…, python=…, sympy=…, casadi=…, numpy=…".
    """

    key: str
    created: str
    derive_time_s: float
    cache_hit: bool
    load_time_s: float
    versions: str


def cache_dir() -> Path:
    """The cache directory (not created)."""
    env = os.environ.get("NHGAIT_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "nhgait"
    if os.name == "nt":
        return Path(os.environ.get("LOCALAPPDATA", Path.home())) / "nhgait"
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "nhgait"


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "none"


@lru_cache(maxsize=1)
def versions() -> str:
    """Versions that shape cached objects (read once per process)."""
    return (f"nhgait={_version('nhgait')}, python={sys.version_info[0]}.{sys.version_info[1]}, "
            f"sympy={_version('sympy')}, casadi={_version('casadi')}, numpy={_version('numpy')}")


@lru_cache(maxsize=1)
def code_stamp() -> str:
    """SHA-256 of the source of every module of ``nhgait.dynamics`` and of :func:`versions`:
    any change of the derivation code or of a dependency invalidates every key."""
    h = hashlib.sha256(versions().encode())
    here = Path(__file__).parents[1]   # nhgait.dynamics: every subpackage
    for path in sorted(here.rglob("*.py")) + sorted(here.rglob("*.c")):
        h.update(str(path.relative_to(here)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def make_key(*parts: str) -> str:
    """SHA-256 of ``parts`` (strings), the code stamp and the versions."""
    h = hashlib.sha256()
    for part in (*parts, code_stamp()):
        h.update(str(part).encode())
        h.update(b"\0")
    return h.hexdigest()


def cache_key(system, formulation: str, options: str = "") -> str:
    """Key of a derived model: the system's structure, the formulation, the options, the code
    and the versions (parameter values are bound outside the cached object)."""
    return make_key("model", system.canonical_text(), formulation, options)


def path_for(key: str, suffix: str = ".pkl") -> Path:
    return cache_dir() / f"{key}{suffix}"


# ------------------------------------------------------------------------------ trust rules
def _untrusted_reason(path: Path) -> str | None:
    """Why ``path`` must not be trusted (None when it may be)."""
    try:
        st = path.lstat()
    except OSError as exc:
        return f"cannot be inspected ({exc.strerror})"
    if stat.S_ISLNK(st.st_mode):
        return "is a symbolic link"
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        return f"is owned by another user (uid {st.st_uid})"
    if os.name != "nt" and st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"is writable by group or others (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def _file_reason(path: Path) -> str | None:
    """Why the cache file ``path`` must not be read: the trust rules, or not a regular file (a
    FIFO planted there would block the reader, a directory cannot be read)."""
    reason = _untrusted_reason(path)
    if reason is not None:
        return reason
    try:
        return None if stat.S_ISREG(path.lstat().st_mode) else "is not a regular file"
    except OSError as exc:               # removed meanwhile
        return f"cannot be inspected ({exc.strerror})"


def trusted_dir(path: Path | None = None, *, create: bool = True) -> Path | None:
    """The cache directory ``path`` (default :func:`cache_dir`) if it may be trusted: created
    with mode 0700 when missing, refused (warning, None) when it is group/world-writable, a
    link or owned by another user."""
    path = Path(path) if path is not None else cache_dir()
    if not path.exists():
        if not create:
            return None
        try:
            path.mkdir(mode=0o700, parents=True, exist_ok=True)
        except OSError as exc:
            warnings.warn(f"cannot create the cache directory {path} ({exc.strerror}); "
                          "results are not cached", UntrustedCacheWarning, stacklevel=1)
            return None
    reason = _untrusted_reason(path)
    if reason:
        warnings.warn(f"refusing the cache directory {path}: it {reason}; results are recomputed "
                      "and not cached (fix with chmod 700 or set NHGAIT_CACHE_DIR)",
                      UntrustedCacheWarning, stacklevel=1)
        return None
    return path


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def trusted_file(path: Path, sha256: str | None = None) -> bool:
    """May ``path`` (e.g. a compiled library) be loaded? Its directory and the file pass the
    trust rules and, when ``sha256`` is given, its content hash matches. A refusal warns."""
    path = Path(path)
    if not path.exists():
        return False
    if trusted_dir(path.parent, create=False) is None:
        return False
    reason = _file_reason(path)
    if reason is None and sha256 is not None and file_sha256(path) != sha256:
        reason = "does not match its recorded SHA-256 (modified after it was written)"
    if reason:
        warnings.warn(f"refusing cached file {path}: it {reason}; it is rebuilt",
                      UntrustedCacheWarning, stacklevel=2)
        return False
    return True


# ------------------------------------------------------------------------------ entries
#: first line of an entry: the format (an entry of another format is not read)
_MAGIC = b"NHGAIT-CACHE-ENTRY 3\n"
#: longest header line read (the header is JSON: key, type, size and SHA-256 of the payload)
_HEADER_MAX = 4096
#: an entry's temporary file: ``.tmp-<host>-<pid>-<random><suffix>``, so that the next run can
#: tell a writer that died (same host, no such process) from one that is writing now
TMP_PREFIX = ".tmp-"
#: a temporary file older than this (seconds) is removed whoever wrote it
STALE_TMP_S = 3600.0


def _type_name(tp: type) -> str:
    return f"{tp.__module__}.{tp.__qualname__}"


def _read_entry(path: Path, key: str, types: tuple):
    """The payload bytes of the entry at ``path`` once its header names this key and one of
    ``types`` and the payload's size and SHA-256 match the header; else :class:`ValueError`
    saying why. Nothing is deserialised here."""
    with path.open("rb") as fh:
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise ValueError("not an nhgait cache entry of this format")
        line = fh.readline(_HEADER_MAX)
        try:
            header = json.loads(line)
        except ValueError:
            raise ValueError("its header is damaged") from None
        if not isinstance(header, dict) or header.get("key") != key:
            raise ValueError("it was written for another key")
        if header.get("type") not in {_type_name(t) for t in types}:
            raise ValueError(f"it holds a {header.get('type')}, expected "
                             f"{' or '.join(_type_name(t) for t in types)}")
        size = header.get("size")
        if not isinstance(size, int) or size < 0 or size > path.stat().st_size:
            raise ValueError("its header is damaged")
        payload = fh.read(size + 1)
    if len(payload) != size:
        raise ValueError(f"it is truncated or extended ({len(payload)} payload bytes, {size} written)")
    if hashlib.sha256(payload).hexdigest() != header.get("sha256"):
        raise ValueError("its bytes do not match the SHA-256 written with them (damaged on disk)")
    return _unkeyed(key, payload)


def _keyed(key: str, pickled: bytes) -> bytes:
    """The checked payload of an entry: its key, a newline, then the pickle. The SHA-256 of
    the header covers the key too, so an entry proves which input it belongs to: one whose
    header key was rewritten to another scene's is refused (:func:`_unkeyed`)."""
    return key.encode() + b"\n" + pickled


def _unkeyed(key: str, payload: bytes) -> bytes:
    """The pickle of a checked payload (:func:`_keyed`) once the key inside it is ``key``; else
    :class:`ValueError` (the header names one key, the checked payload another)."""
    inside, newline, pickled = payload.partition(b"\n")
    if not newline or inside != key.encode():
        raise ValueError("it was written for another key (its checked payload names "
                         f"{inside[:16].decode('utf-8', 'replace')}…, not {key[:16]}…)")
    return pickled


def load(key: str, expected_type: type | tuple, *, suffix: str = ".pkl"):
    """The cached object for ``key`` if the entry passes the trust rules, was written for this
    key, holds an instance of ``expected_type`` and its bytes match the SHA-256 written with
    them; else None (with a warning for a bad entry, which the caller rebuilds). The payload is
    unpickled only after all of that is checked."""
    path = path_for(key, suffix)
    if not path.exists():
        return None
    if trusted_dir(path.parent, create=False) is None:
        return None
    reason = _file_reason(path)
    if reason:
        warnings.warn(f"refusing cache entry {path}: it {reason}; it is recomputed",
                      UntrustedCacheWarning, stacklevel=2)
        return None
    types = expected_type if isinstance(expected_type, tuple) else (expected_type,)
    try:
        obj = pickle.loads(_read_entry(path, key, types))
    except Exception as exc:  # corrupt, foreign or from an incompatible version: rebuild it
        why = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
        warnings.warn(f"ignoring unreadable cache entry {path} ({why}); it is rebuilt",
                      UntrustedCacheWarning, stacklevel=2)
        return None
    if not isinstance(obj, types):
        warnings.warn(f"ignoring cache entry {path}: it holds a {type(obj).__name__}, expected "
                      f"{' or '.join(t.__name__ for t in types)}", UntrustedCacheWarning, stacklevel=2)
        return None
    return obj


def store(key: str, obj, *, suffix: str = ".pkl") -> Path | None:
    """Write ``obj`` atomically under ``key``: the entry is the format line, a JSON header
    (key, type, size and SHA-256 of the payload) and the pickled payload, written to a
    temporary file of the same directory and renamed into place. Returns None when the
    directory is not trusted or cannot be written (read-only, full, over quota or over the
    file-size limit: one warning, the run goes on uncached)."""
    folder = trusted_dir()
    if folder is None:
        return None
    remove_stale_temporaries(folder)
    payload = _keyed(key, pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))
    header = json.dumps({"key": key, "type": _type_name(type(obj)), "size": len(payload),
                         "sha256": hashlib.sha256(payload).hexdigest()}).encode() + b"\n"
    path, tmp = path_for(key, suffix), None
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=temporary_prefix(), suffix=suffix)
        with os.fdopen(fd, "wb") as fh:
            fh.write(_MAGIC + header)
            fh.write(payload)
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        unwritable_warning(folder, exc)
        return None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    return path


def unwritable_warning(folder: Path, exc: OSError) -> None:
    """One warning for a cache directory that could not be written: the same text and place for
    every entry (``stacklevel=1``), so Python's default warning filter shows it once per run."""
    warnings.warn(f"cannot write the cache directory {folder} ({exc.strerror or exc}); results "
                  "are not cached (free space, fix its permissions or set NHGAIT_CACHE_DIR)",
                  UntrustedCacheWarning, stacklevel=1)


# ------------------------------------------------------------------------------ temporaries
def _host_tag() -> str:
    """A short tag of this machine (temporary files on a shared file system name their host)."""
    return hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]


def temporary_prefix(kind: str = TMP_PREFIX) -> str:
    """``<kind><host>-<pid>-``: the prefix of a temporary file or folder this process writes."""
    return f"{kind}{_host_tag()}-{os.getpid()}-"


def _writer_is_gone(name: str, kind: str) -> bool:
    """Did the process that named this temporary (:func:`temporary_prefix`) die? Only a writer
    on this host can be checked: one on another host is taken to be alive (its temporary goes
    once it is :data:`STALE_TMP_S` old)."""
    parts = name[len(kind):].split("-", 2)
    if len(parts) < 3 or parts[0] != _host_tag() or not parts[1].isdigit():
        return False
    pid = int(parts[1])
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:          # exists, owned by someone else
        return False
    return False


def remove_stale_temporaries(folder: Path, kind: str = TMP_PREFIX, *, max_age_s: float = STALE_TMP_S) -> int:
    """Remove the temporaries ``<kind>*`` of ``folder`` left by a writer that died (killed
    during a write: its process is gone) or older than ``max_age_s``; a writer running now keeps
    its own. Returns how many were removed."""
    now, removed = time.time(), 0
    try:
        entries = [e for e in os.scandir(folder) if e.name.startswith(kind)]
    except OSError:
        return 0
    for entry in entries:
        try:
            age = now - entry.stat(follow_symlinks=False).st_mtime
        except FileNotFoundError:          # its writer renamed or removed it meanwhile
            continue
        if age > max_age_s or _writer_is_gone(entry.name, kind):
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
            removed += 1
    return removed


def now() -> str:
    """The current UTC time, ISO 8601 (for :class:`Provenance`)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")
