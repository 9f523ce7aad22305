"""Errors raised by nhgait for bad input.

Every validation collects *all* the problems it finds and raises them together in one
:class:`ModelError`, so a user fixes a scene file in one pass instead of one error at a time.
"""
from __future__ import annotations


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
