"""On-disk cache of derived models, keyed by a SHA-256 content hash.

The key hashes the system's canonical text (coordinates, L, ω, τ, names — not the parameter
values, which stay symbolic in every derivation), the formulation and options, and the source
of the derivation modules, so a change of nhgait's own derivation code invalidates old entries.
Entries are pickles of the frozen result objects, compiled CasADi functions included (stored
through CasADi's serialisation), written atomically.

Location: ``$NHGAIT_CACHE_DIR`` if set, else the user's cache directory
(``$XDG_CACHE_HOME/nhgait`` or ``~/.cache/nhgait``; ``~/Library/Caches/nhgait`` on macOS,
``%LOCALAPPDATA%\\nhgait`` on Windows).
"""
from __future__ import annotations

import hashlib
import os
import pickle
import sys
import tempfile
import warnings
from pathlib import Path

_DERIVATION_MODULES = ("system.py", "symbolic.py", "symmetry.py", "lagrange.py",
                       "hamilton.py", "numeric.py", "bridge.py", "steps.py", "reduction/__init__.py",
                       "reduction/arithmetic.py", "reduction/setup.py", "reduction/connection.py",
                       "reduction/legendre.py", "reduction/poisson.py", "reduction/equations.py",
                       "reduction/model.py")
_SOURCE_HASH: str | None = None


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


def _source_hash() -> str:
    global _SOURCE_HASH
    if _SOURCE_HASH is None:
        h = hashlib.sha256()
        here = Path(__file__).parent
        for name in _DERIVATION_MODULES:
            h.update((here / name).read_bytes())
        _SOURCE_HASH = h.hexdigest()
    return _SOURCE_HASH


def cache_key(system, formulation: str, options: str = "") -> str:
    """SHA-256 of the system's content, the formulation, options and the derivation code."""
    h = hashlib.sha256()
    for part in (system.canonical_text(), formulation, options, _source_hash(),
                 f"python{sys.version_info[:2]}"):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()


def path_for(key: str) -> Path:
    return cache_dir() / f"{key}.pkl"


def load(key: str):
    """The cached object for ``key``, or None (a corrupt entry is reported and ignored)."""
    path = path_for(key)
    if not path.exists():
        return None
    try:
        with path.open("rb") as fh:
            return pickle.load(fh)
    except Exception as exc:  # corrupt or from an incompatible version: rebuild it
        warnings.warn(f"ignoring unreadable cache entry {path} ({type(exc).__name__}: {exc})")
        return None


def store(key: str, obj) -> Path:
    """Write ``obj`` atomically; returns the path."""
    path = path_for(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".pkl")
    try:
        with os.fdopen(fd, "wb") as fh:
            pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
