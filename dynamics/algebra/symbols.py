"""The symbols every layer shares: ``TIME``, the time t the forces of a system may depend on
(the derivations carry it along; the numeric functions take it as their first argument)."""
from __future__ import annotations

import sympy as sp

__all__ = ["TIME"]

TIME = sp.Symbol("t", real=True)
