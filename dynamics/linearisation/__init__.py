"""Linearisation of a derived model about an equilibrium or a straight steady motion, and its
eigenvalues against speed (docs/linearisation.md).

* :func:`linearise` (:mod:`.linearised`) — A, B, the eigenvalues and their modes
  (:class:`Linearisation`) of the reduced ODE about a :class:`ReferenceMotion`
  (:mod:`.reference`: an equilibrium, or straight steady motion at a forward speed);
* :func:`stability_chart` (:mod:`.chart`) — the eigenvalues over a range of speeds and the
  speeds where stability changes, refined by root finding (:class:`StabilityChart`).
"""
from __future__ import annotations

from nhgait.lazy import lazy_getattr

_EXPORTS = {
    "linearise": "linearised", "Linearisation": "linearised", "Mode": "linearised",
    "ReferenceMotion": "reference", "reference_motion": "reference",
    "stability_chart": "chart", "StabilityChart": "chart", "StabilityChange": "chart",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
