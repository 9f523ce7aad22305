""""Did you mean …?" for every unknown name: the close matches and the list of known names.

One helper for every error that names something the user wrote and nhgait does not know (a
symbol of the Lagrangian, a constraint or a force, a task name, a ``--set`` key, a gait, a
scene, a method)::

    >>> "unknown symbol 'thetadot'" + known_names("thetadot", ["x", "theta", "x_dot", "theta_dot"])
    "unknown symbol 'thetadot': did you mean 'theta_dot' or 'theta'? (known: x, theta, x_dot, theta_dot)"

Close matches come from :func:`difflib.get_close_matches` (ratio ≥ 0.6), with a second try
that ignores case and underscores (``thetadot`` ↔ ``theta_dot``, ``Theta`` ↔ ``theta``).
No sympy here: every layer may import this module.
"""
from __future__ import annotations

import difflib

__all__ = ["close_matches", "did_you_mean", "known_names"]

#: longest list of known names written out in full (longer lists end in "… and N more")
KNOWN_MAX = 40


def _squash(name: str) -> str:
    return str(name).replace("_", "").replace("-", "").lower()


def close_matches(name, known, n: int = 3) -> list:
    """Up to ``n`` known names close to ``name``, best first."""
    known = [str(k) for k in known]
    found = difflib.get_close_matches(str(name), known, n=n, cutoff=0.6)
    squashed = {}
    for k in known:
        squashed.setdefault(_squash(k), k)
    for match in difflib.get_close_matches(_squash(name), list(squashed), n=n, cutoff=0.75):
        if squashed[match] not in found:
            found.append(squashed[match])
    return found[:n]


def did_you_mean(name, known) -> str:
    """"did you mean 'a'?" / "did you mean 'a' or 'b'?", or "" when nothing is close."""
    found = close_matches(name, known)
    if not found:
        return ""
    return "did you mean " + " or ".join(repr(f) for f in found) + "?"


def known_names(name, known, *, label: str = "known", sep: str = ": ") -> str:
    """The end of an error message: ``sep`` + the suggestion (if any), then the list of
    known names in parentheses, e.g. ``": did you mean 'm'? (parameters: m, I)"`` or
    ``" (parameters: m, I)"``."""
    known = [str(k) for k in known]
    listed = ", ".join(known[:KNOWN_MAX]) + (f", … and {len(known) - KNOWN_MAX} more"
                                             if len(known) > KNOWN_MAX else "")
    hint = did_you_mean(name, known)
    return (sep + hint if hint else "") + f" ({label}: {listed or 'none'})"
