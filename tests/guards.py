"""A hang guard for tests that run code in-process which must not hang (hostile input): it fails
the test only when the block has not returned after ``seconds`` (generous, so that it fails on a
hang and never on a loaded machine). No wall-clock assertion: timing goes to the benchmarks."""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

import pytest

HANG_S = 120.0


@contextmanager
def no_hang(what: str = "", seconds: float = HANG_S):
    """Fail with ``what`` if the block runs longer than ``seconds`` (SIGALRM through
    ``setitimer``; in the main thread only, elsewhere the block runs unguarded). The previous
    handler and timer are restored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def hung(signum, frame):
        pytest.fail(f"no answer after {seconds:g} s (a hang): {what}", pytrace=False)

    previous = signal.signal(signal.SIGALRM, hung)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
