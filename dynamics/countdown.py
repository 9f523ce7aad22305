"""Progress of a job made of a known number of items, with an estimate of the time left.

::

    countdown = Countdown(90, stream=sys.stderr, what="points")
    for item in items:
        ...
        countdown.step(f"reduced/DOP853 rtol 1e-08: error 3.1e-09")
    # [  12.3 s] 7/90 points: reduced/DOP853 rtol 1e-08: error 3.1e-09 — about 2 min 26 s left

The estimate is the mean time per finished item times the items left (items that take longer,
such as tighter tolerances, come later, so it is a lower estimate at first; the line says
"about"). ``stream`` None: silent (``--quiet``). Nothing global; one object per job.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

__all__ = ["Countdown", "duration"]


def duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``1 h 02 min``."""
    seconds = max(0.0, float(seconds))
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, sec = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {sec:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


@dataclass(eq=False)
class Countdown:
    """``total`` items; :meth:`step` after each one prints a line with the estimate."""

    total: int
    stream: object = None
    what: str = "items"
    started: float = field(default_factory=time.perf_counter)
    done: int = 0

    def elapsed(self) -> float:
        return time.perf_counter() - self.started

    def remaining_s(self) -> float:
        """Estimated seconds left (mean time per finished item × items left)."""
        if self.done == 0:
            return float("nan")
        return self.elapsed() / self.done * max(0, self.total - self.done)

    def line(self, text: str = "") -> str:
        left = self.total - self.done
        tail = ("done" if left <= 0 else f"about {duration(self.remaining_s())} left")
        body = f"{self.done}/{self.total} {self.what}" + (f": {text}" if text else "")
        return f"[{self.elapsed():7.1f} s] {body} — {tail}"

    def step(self, text: str = "") -> None:
        """One item finished: count it and print the line (when not silent)."""
        self.done += 1
        if self.stream is not None:
            print(self.line(text), file=self.stream, flush=True)
