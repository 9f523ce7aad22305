"""nhgait.gaits — gait tasks, guesses, the planner, plots; :mod:`.sweeps`, :mod:`.cli`, :mod:`.bench`.

Entry points (imported lazily): :func:`plan` (:mod:`.planner`), :func:`sweep` (:mod:`.sweeps.driver`).
"""
from __future__ import annotations

import importlib

_EXPORTS = {"plan": "planner", "sweep": "sweeps.driver", "load_sweep": "sweeps.driver"}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'nhgait.gaits' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value
