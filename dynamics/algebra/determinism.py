"""Derivations that do the same work every time: sympy's random choices seeded.

sympy factors multivariate polynomials by Wang's algorithm (``factor``, ``factor_list``), which
evaluates them at *random* integer points drawn from ``sympy.core.random``'s generator, seeded
from the operating system at import. Its running time depends on those points: the singular-set
determinant of one generated 4-link chain factored in 7 s in one process and had not finished
after 25 minutes in another (the same input, another draw). :func:`seeded` runs a block with
that generator seeded by a fixed value and gives the caller's state back afterwards, so a
derivation's work (and its time) is a function of its input alone.

>>> import sympy as sp
>>> x, y = sp.symbols("x y")
>>> with seeded():
...     sp.factor(x**2 - y**2)
(x - y)*(x + y)
"""
from __future__ import annotations

from contextlib import contextmanager

__all__ = ["seeded", "SEED"]

#: the seed of sympy's generator during a derivation
SEED = 24


@contextmanager
def seeded(seed: int = SEED):
    """sympy's random generators (``sympy.core.random.rng`` and the assumptions' shuffle)
    seeded with ``seed`` inside the block, restored after it."""
    from sympy.core import random as sympy_random
    generators = (sympy_random.rng, sympy_random._assumptions_rng)
    states = [g.getstate() for g in generators]
    for g in generators:
        g.seed(seed)
    try:
        yield
    finally:
        for g, state in zip(generators, states, strict=True):
            g.setstate(state)
