"""nhgait.gaits — gait tasks, guesses, the planner, plots; :mod:`.sweeps`, :mod:`.cli`, :mod:`.bench`.

Entry points (imported lazily): :func:`plan` (:mod:`.planner`), :func:`sweep` (:mod:`.sweeps.driver`).
"""
from __future__ import annotations

from nhgait.lazy import lazy_getattr

_EXPORTS = {"plan": "planner", "sweep": "sweeps.driver", "load_sweep": "sweeps.driver"}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
