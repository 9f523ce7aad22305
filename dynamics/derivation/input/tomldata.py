"""TOML text as data: scene files and the built-in task library are read here (``tomllib``,
or ``tomli`` on Python 3.10), with no symbolic import, so that reading them stays cheap."""
from __future__ import annotations

try:
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from ...errors import ModelError

__all__ = ["read_toml"]


def read_toml(text: str, source: str, error=ModelError) -> dict:
    """A TOML document as a dict; a syntax error is one ``error`` naming ``source``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error([f"TOML syntax error: {exc}"], title=f"invalid file {source}") from None
    except RecursionError:        # tomllib parses nested arrays and inline tables recursively
        raise error(["TOML syntax error: arrays or inline tables nested too deeply (a scene needs "
                     "a few levels)"],
                    title=f"invalid file {source}") from None
