"""Errors raised by nhgait for bad input.

Every validation collects *all* the problems it finds and raises them together in one
:class:`ModelError`, so a user fixes a scene file in one pass instead of one error at a time.
"""
from __future__ import annotations

import signal
from contextlib import contextmanager


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
#: command line's SIGTERM and SIGHUP (:class:`Terminated`), a time budget's SIGALRM (``BudgetSpent``). Code
#: that starts a child process blocks them until the child is registered to be killed (and the
#: child restores the mask), so that the exception cannot land between the two and leave the
#: child running (:mod:`nhgait.dynamics.numerics.compiler`, :mod:`nhgait.ocp.supervision`).
STOP_SIGNALS = frozenset(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGALRM")
                         if hasattr(signal, name))


#: the stop signals (SIGINT, SIGTERM) the command line's handlers received during the current
#: run: process state, like the signal dispositions it mirrors; set by the handlers, cleared
#: when the command's stop handling ends (:mod:`nhgait.gaits.cli.stopping`)
_RECEIVED_STOPS: set = set()


def note_stop(signum: int) -> None:
    """Record that a stop signal was received (called by the command line's handlers)."""
    _RECEIVED_STOPS.add(signum)


def clear_stops() -> None:
    """Forget the stops received (the command's stop handling is over)."""
    _RECEIVED_STOPS.clear()


#: folders being written whose removal a forced end must not skip (:func:`temporary_folder`)
_TEMPORARY_FOLDERS: set = set()


@contextmanager
def temporary_folder(path):
    """Register ``path`` (a staging folder) while the block runs, so that a process ended by the
    stop watchdog (``os._exit``: no ``finally`` runs) removes it first
    (:func:`remove_temporary_folders`); its owner removes it as usual otherwise."""
    _TEMPORARY_FOLDERS.add(str(path))
    try:
        yield path
    finally:
        _TEMPORARY_FOLDERS.discard(str(path))


def remove_temporary_folders() -> None:
    """Remove the folders registered by :class:`temporary_folder` (the watchdog's last act)."""
    import shutil
    for path in list(_TEMPORARY_FOLDERS):
        shutil.rmtree(path, ignore_errors=True)
    _TEMPORARY_FOLDERS.clear()


def raise_if_stopped() -> None:
    """Raise the stop received again, if one was: :class:`Terminated` for SIGTERM,
    ``KeyboardInterrupt`` for SIGINT. A stop's exception can be lost on its way up when the
    handler runs inside a C extension that clears Python errors (CasADi's SWIG wrappers clear
    them while they try one overload after another), and the run then goes on; a loop of many
    short units of work (tracking samples) calls this between units, so that it stops at once
    anyway."""
    if signal.SIGTERM in _RECEIVED_STOPS:
        raise Terminated()
    if signal.SIGINT in _RECEIVED_STOPS:
        raise KeyboardInterrupt()

