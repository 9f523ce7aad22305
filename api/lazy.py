"""Lazy public names of a package (PEP 562): importing ``nhgait.dynamics`` does no symbolic
work; its public names are imported from their submodules on first use."""
from __future__ import annotations

import importlib
import sys


def lazy_getattr(package: str, exports: dict):
    """A module ``__getattr__`` for ``package``: ``exports`` maps a public name to the submodule
    (relative to ``package``) that defines it; the name is imported on first use and bound in
    the package. Other names raise AttributeError."""
    def __getattr__(name):
        try:
            module = exports[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(f".{module}", package), name)
        setattr(sys.modules[package], name, value)
        return value
    return __getattr__
