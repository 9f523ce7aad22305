"""Errors raised by nhgait for bad input.

Every validation collects *all* the problems it finds and raises them together in one
:class:`ModelError`, so a user fixes a scene file in one pass instead of one error at a time.
"""
from __future__ import annotations

import signal


class ModelError(ValueError):
    """A system, scene or state that nhgait cannot accept.

    Attributes
    ----------
    problems : tuple of str
        One sentence per problem found.
    """

    def __init__(self, problems, *, title: str = "invalid system"):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = tuple(problems)
        self.title = title
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{title}: {len(self.problems)} problem(s)\n{lines}")


class SingularConfigurationError(ModelError):
    """A configuration on the singular set of a reduction (e.g. dependent constraints)."""

    def __init__(self, problems, *, title: str = "configuration on the singular set"):
        super().__init__(problems, title=title)


class Terminated(BaseException):
    """SIGTERM received (the command line turns the signal into this exception): unwinds like
    KeyboardInterrupt — every cleanup runs, child processes are killed — and ``nhgait`` exits
    143. A ``BaseException``, so that no ``except Exception`` on the way swallows it."""


#: the signals whose Python handlers end a run by raising — Ctrl-C (KeyboardInterrupt), the
#: command line's SIGTERM (:class:`Terminated`), a time budget's SIGALRM (``BudgetSpent``). Code
#: that starts a child process blocks them until the child is registered to be killed (and the
#: child restores the mask), so that the exception cannot land between the two and leave the
#: child running (:mod:`nhgait.dynamics.numerics.compiler`, :mod:`nhgait.ocp.supervision`).
STOP_SIGNALS = frozenset(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGALRM") if hasattr(signal, name))
