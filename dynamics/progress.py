"""Where long work says what it is doing: phases with their times, notes, heartbeats.

One small object is handed down explicitly (never a module-level setting) to every function
that may run for more than a few seconds::

    progress = Progress.to_stderr()           # the CLI; Progress.silent() for --quiet (default)
    with progress.phase("compile 2.3 MB of C with gcc -O1 (about 30 s)"):
        ...                                   # prints "… compile …" and then "  done in 28.1 s"
    progress.note("guess 2 of 41: psi:phi 2:1 (the previous one was infeasible)")
    progress.heartbeat("compiling", elapsed)  # at most every ``interval`` seconds
    progress.note_once("no-fork", "solver attempts run in this process")   # the first time only

Lines go to a text stream (stderr) prefixed with the elapsed time of the whole run, so a
user can see which phase takes the time. ``verbose`` asks the solvers for their own logs.
"""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

__all__ = ["Progress"]


@dataclass(eq=False)
class Progress:
    """A reporter (see the module docstring). ``stream`` None: silent."""

    stream: object = None
    verbose: bool = False
    interval: float = 5.0
    started: float = field(default_factory=time.perf_counter)
    _last_beat: float = 0.0
    _said: set = field(default_factory=set)

    @classmethod
    def silent(cls) -> Progress:
        return cls(None)

    @classmethod
    def to_stderr(cls, *, verbose: bool = False) -> Progress:
        return cls(sys.stderr, verbose=verbose)

    @property
    def enabled(self) -> bool:
        return self.stream is not None

    def note(self, text: str) -> None:
        """One line, prefixed with the elapsed time of the run."""
        if self.stream is None:
            return
        print(f"[{time.perf_counter() - self.started:7.1f} s] {text}", file=self.stream, flush=True)

    def note_once(self, key: str, text: str) -> None:
        """:meth:`note` the first time ``key`` is given (a remark that applies to the whole run)."""
        if key not in self._said:
            self._said.add(key)
            self.note(text)

    @contextmanager
    def phase(self, name: str):
        """Announce ``name``; on exit say how long it took (or that it was interrupted). A stop
        the command line received and whose exception was lost on its way up (inside a C
        extension that clears Python errors: :func:`~nhgait.dynamics.errors.raise_if_stopped`)
        is raised again when a phase begins or ends, so that the run ends there rather than
        going on to its last phase."""
        from .errors import raise_if_stopped
        raise_if_stopped()
        start = time.perf_counter()
        self.note(f"{name} …")
        try:
            yield self
            raise_if_stopped()
        except BaseException:
            self.note(f"  {name}: stopped after {time.perf_counter() - start:.1f} s")
            raise
        self.note(f"  done in {time.perf_counter() - start:.1f} s")

    def heartbeat(self, text: str, elapsed: float) -> None:
        """A 'still working' line once ``elapsed`` passes ``interval`` seconds, then at most every
        ``interval`` seconds."""
        now = time.perf_counter()
        if elapsed >= self.interval and now - self._last_beat >= self.interval:
            self._last_beat = now
            self.note(f"  … {text} ({elapsed:.0f} s)")
