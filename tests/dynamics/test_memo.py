"""The in-memory memos (dynamics/memo.py): an LRU of ``size`` keys drops the least recently
used first; an owner memo keeps a value exactly as long as its owner lives and makes a value
again (not kept) for an owner it cannot hold weakly or beyond its per-owner limit."""
from __future__ import annotations

import gc

from nhgait.dynamics.memo import LruMemo, OwnerMemo


class _Owner:
    pass


def test_lru_drops_the_least_recently_used_key():
    made = []
    memo = LruMemo("squares", size=2)

    def square(k):
        return lambda: made.append(k) or k * k

    assert memo.get(2, square(2)) == 4 and memo.get(3, square(3)) == 9
    assert memo.get(2, square(2)) == 4               # 2 is now the most recent: 3 goes next
    assert memo.get(4, square(4)) == 16
    assert 3 not in memo and 2 in memo and 4 in memo and len(memo) == 2
    assert made == [2, 3, 4]                          # 2 made once
    memo.clear()
    assert len(memo) == 0


def test_owner_memo_lives_as_long_as_its_owner():
    memo, calls = OwnerMemo("per owner", limit=2), []
    owner = _Owner()

    def make(value):
        return lambda: calls.append(value) or value

    assert memo.get(owner, "a", make(1)) == 1 and memo.get(owner, "a", make(99)) == 1
    assert memo.get(owner, "b", make(2)) == 2 and memo.get(owner, "c", make(3)) == 3
    assert memo.get(owner, "c", make(4)) == 4         # beyond the limit: made again, not kept
    assert len(memo) == 2 and calls == [1, 2, 3, 4]
    del owner
    gc.collect()
    assert len(memo) == 0


def test_an_owner_that_cannot_be_weakly_held_is_not_memoised():
    memo, calls = OwnerMemo("ints"), []
    for _ in range(2):
        assert memo.get(7, "k", lambda: calls.append(1) or "v") == "v"
    assert calls == [1, 1] and len(memo) == 0
