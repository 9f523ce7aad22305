"""sympy's random choices seeded for a derivation (dynamics/algebra/determinism.py): inside the
block the generator draws the sequence of ``random.Random(SEED)`` (Python's own generator, the
independent reference), and after it the caller's generator goes on as if nothing happened."""
from __future__ import annotations

import copy
import random

from nhgait.dynamics.algebra.determinism import SEED, seeded


def test_seeded_draws_are_those_of_the_seed_and_the_state_is_given_back():
    from sympy.core import random as sympy_random
    sympy_random.rng.seed(12345)
    untouched = copy.deepcopy(sympy_random.rng)
    with seeded():
        inside = [sympy_random.rng.random() for _ in range(5)]
    after = [sympy_random.rng.random() for _ in range(3)]
    reference = random.Random(SEED)
    assert inside == [reference.random() for _ in range(5)]
    assert after == [untouched.random() for _ in range(3)]
    with seeded(7):
        assert sympy_random.rng.random() == random.Random(7).random()


def test_the_state_is_given_back_when_the_block_raises():
    from sympy.core import random as sympy_random
    before = sympy_random.rng.getstate()
    try:
        with seeded():
            sympy_random.rng.random()
            raise RuntimeError("inside")
    except RuntimeError:
        pass
    assert sympy_random.rng.getstate() == before
