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
* an entry is a pickle whose first record is a header naming the key and the expected type;
  an entry written for another key, or an object of the wrong type, is rejected and rebuilt;
* compiled libraries are loaded only through :func:`trusted_file` with their recorded SHA-256.

Entries are written atomically (temporary file + ``os.replace``), so concurrent derivations
of one model leave one valid entry.

Location: ``$NHGAIT_CACHE_DIR`` if set, else the user's cache directory
(``$XDG_CACHE_HOME/nhgait`` or ``~/.cache/nhgait``; ``~/Library/Caches/nhgait`` on macOS,
``%LOCALAPPDATA%\\nhgait`` on Windows).
"""
from __future__ import annotations

import hashlib
import os
import pickle
import stat
import sys
import tempfile
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from functools import lru_cache
from importlib import metadata
from pathlib import Path

__all__ = ["cache_dir", "cache_key", "make_key", "code_stamp", "load", "store", "path_for",
           "Provenance", "trusted_dir", "trusted_file", "file_sha256", "UntrustedCacheWarning"]

_FORMAT = "nhgait-cache-1"


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
                          "results are not cached", UntrustedCacheWarning, stacklevel=3)
            return None
    reason = _untrusted_reason(path)
    if reason:
        warnings.warn(f"refusing the cache directory {path}: it {reason}; results are recomputed "
                      "and not cached (fix with chmod 700 or set NHGAIT_CACHE_DIR)",
                      UntrustedCacheWarning, stacklevel=3)
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
    reason = _untrusted_reason(path)
    if reason is None and sha256 is not None and file_sha256(path) != sha256:
        reason = "does not match its recorded SHA-256 (modified after it was written)"
    if reason:
        warnings.warn(f"refusing cached file {path}: it {reason}; it is rebuilt",
                      UntrustedCacheWarning, stacklevel=2)
        return False
    return True


# ------------------------------------------------------------------------------ entries
class _EntryUnpickler(pickle.Unpickler):
    """Reads only the header record: plain strings and dicts, no class is resolved, so a
    planted file cannot run code before the header is checked."""

    def find_class(self, module, name):  # pragma: no cover - only planted files get here
        raise pickle.UnpicklingError(f"header refers to {module}.{name}")


def _type_name(tp: type) -> str:
    return f"{tp.__module__}.{tp.__qualname__}"


def load(key: str, expected_type: type | tuple, *, suffix: str = ".pkl"):
    """The cached object for ``key`` if the entry passes the trust rules, was written for this
    key and holds an instance of ``expected_type``; else None (with a warning for a bad entry)."""
    path = path_for(key, suffix)
    if not path.exists():
        return None
    if trusted_dir(path.parent, create=False) is None:
        return None
    reason = _untrusted_reason(path)
    if reason:
        warnings.warn(f"refusing cache entry {path}: it {reason}; it is recomputed",
                      UntrustedCacheWarning, stacklevel=2)
        return None
    types = expected_type if isinstance(expected_type, tuple) else (expected_type,)
    try:
        with path.open("rb") as fh:
            header = _EntryUnpickler(fh).load()
            if not (isinstance(header, dict) and header.get("format") == _FORMAT
                    and header.get("key") == key and header.get("type") in {_type_name(t) for t in types}):
                raise pickle.UnpicklingError("not an nhgait cache entry for this key and type")
            obj = pickle.load(fh)
    except Exception as exc:  # corrupt, foreign or from an incompatible version: rebuild it
        warnings.warn(f"ignoring unreadable cache entry {path} ({type(exc).__name__}: {exc})",
                      UntrustedCacheWarning, stacklevel=2)
        return None
    if not isinstance(obj, types):
        warnings.warn(f"ignoring cache entry {path}: it holds a {type(obj).__name__}, expected "
                      f"{' or '.join(t.__name__ for t in types)}", UntrustedCacheWarning, stacklevel=2)
        return None
    return obj


def store(key: str, obj, *, suffix: str = ".pkl") -> Path | None:
    """Write ``obj`` atomically under ``key`` (None when the directory is not trusted)."""
    folder = trusted_dir()
    if folder is None:
        return None
    path = path_for(key, suffix)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as fh:
            pickle.dump({"format": _FORMAT, "key": key, "type": _type_name(type(obj))}, fh,
                        protocol=pickle.HIGHEST_PROTOCOL)
            pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def now() -> str:
    """The current UTC time, ISO 8601 (for :class:`Provenance`)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")
