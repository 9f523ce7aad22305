"""In-memory memos: each one an explicit object, named where it is used, with its lifetime.

nhgait keeps a few values in memory so that repeated calls do not repeat expensive work: the
closed loop of a compiled model under a controller, a reduced model specialised to parameter
values, a parameter vector already checked, a loaded C library, a worker's built NLP solver.
None of them is a source of results — a missing entry is recomputed identically — and each
is one of two kinds:

* :class:`OwnerMemo` — values computed from a live object (a model's compiled functions, a
  system, a frozen controller), held weakly by that object: an entry lives exactly as long
  as its owner;
* :class:`LruMemo` — at most ``size`` values by key, the least recently used dropped first:
  an entry lives until ``size`` newer keys have been used (or the process ends).

``clear()`` empties a memo (tests, or a long-running process freeing memory). The disk cache
of derived models is :mod:`nhgait.dynamics.numerics.cache`, not a memo.
"""
from __future__ import annotations

import weakref
from collections import OrderedDict
from collections.abc import Callable

__all__ = ["OwnerMemo", "LruMemo"]


class OwnerMemo:
    """``key → value`` per owner object, dropped with the owner (weakly keyed by identity of
    a hashable owner).

    Parameters
    ----------
    what : what the memo holds (for ``repr`` and the reader).
    limit : at most this many keys per owner; beyond it values are computed and not kept.
    """

    def __init__(self, what: str, limit: int | None = None):
        self.what = what
        self.limit = limit
        self._entries: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def get(self, owner, key, make: Callable[[], object]):
        """The value of ``key`` for ``owner``, made by ``make()`` and kept the first time. An
        owner that cannot be weakly referenced or hashed is not memoised (``make()`` each call)."""
        try:
            per_owner = self._entries.setdefault(owner, {})
        except TypeError:
            return make()
        if key in per_owner:
            return per_owner[key]
        value = make()
        if self.limit is None or len(per_owner) < self.limit:
            per_owner[key] = value
        return value

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return sum(len(v) for v in self._entries.values())

    def __repr__(self) -> str:
        return f"OwnerMemo({self.what!r}, {len(self._entries)} owners)"


class LruMemo:
    """``key → value``, at most ``size`` entries, the least recently used dropped first."""

    def __init__(self, what: str, size: int):
        self.what = what
        self.size = size
        self._entries: OrderedDict = OrderedDict()

    def get(self, key, make: Callable[[], object] | None = None):
        """The value of ``key``, made by ``make()`` and kept the first time (then the most
        recently used); ``make`` may be None for a key known to be present (``key in memo``)."""
        if key in self._entries:
            self._entries.move_to_end(key)
            return self._entries[key]
        value = make()
        self._entries[key] = value
        while len(self._entries) > self.size:
            self._entries.popitem(last=False)
        return value

    def __contains__(self, key) -> bool:
        return key in self._entries

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"LruMemo({self.what!r}, {len(self._entries)}/{self.size})"
