"""The symmetry search beyond 8 coordinates: a given fibre is tested alone, otherwise only the
subsets that can be symmetries, and it chooses what the full enumeration of all 2ⁿ − 1 subsets
(the reference, run here too) chooses. Times are measured by experiments/bench_symmetry.py."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from nhgait.dynamics import System
from nhgait.dynamics.derivation import symmetry
from nhgait.dynamics.errors import ModelError

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))


def particles(n, fiber=False, extra=""):
    names = ["x", "y", "theta"] + [f"z{i}" for i in range(n - 3)]
    kinetic = " + ".join(f"m*{c}_dot**2/2" for c in names if c != "theta")
    return System(coordinates=names, lagrangian=f"{kinetic} + I*theta_dot**2/2{extra}",
                  constraints=["sin(theta)*x_dot - cos(theta)*y_dot"],
                  parameters={"m": 1.0, "I": 0.1, "k": 0.5},
                  fiber=[c for c in names if c != "theta"] if fiber else None)


def _full(system):
    """The reference: every subset tested (the thesis's Table 3.1 at any n)."""
    limit = symmetry.FULL_TABLE_MAX_N
    symmetry.FULL_TABLE_MAX_N = system.n
    try:
        return symmetry.symmetry_test(system)
    finally:
        symmetry.FULL_TABLE_MAX_N = limit


def test_a_given_fiber_is_tested_alone_at_twenty_coordinates():
    """n = 20 with the fibre given: one row (it enumerated 2²⁰ − 1 subsets, > 120 s), full,
    and the table says why it holds one row."""
    test = symmetry.symmetry_test(particles(20, fiber=True))
    assert len(test.candidates) == 1
    assert test.chosen_by == "user"
    assert test.chosen.verdict == symmetry.FULL
    assert test.chosen.fiber == tuple(c for c in particles(20).coordinates if c != "theta")
    assert "the given fiber is tested alone" in test.table_markdown()


def _cart(k):
    import scaling_systems
    return scaling_systems.system(f"cart_trailers_{k}")


@pytest.mark.parametrize("make", [lambda: particles(10), lambda: particles(11, extra=" - k*cos(z0)*z1"),
                                  lambda: _cart(5)], ids=["10 coordinates", "11 with a coupled potential",
                                                          "cart with 5 trailers (9)"])
def test_the_pruned_search_chooses_what_the_full_enumeration_chooses(make):
    system = make()
    assert system.n > symmetry.FULL_TABLE_MAX_N
    pruned, full = symmetry.symmetry_test(system), _full(system)
    assert pruned.chosen.fiber == full.chosen.fiber
    assert pruned.chosen.group == full.chosen.group
    assert len(pruned.candidates) < len(full.candidates) == 2 ** system.n - 1
    assert "subsets tested" in pruned.search


def test_a_search_over_its_budget_takes_the_best_found_with_a_note():
    """Budget 50 at n = 12: the sets of two coordinates (66) do not fit; the best of the single
    coordinates (principally kinematic) is taken, and the note asks for the fibre."""
    test = symmetry.symmetry_test(particles(12), max_candidates=50)
    assert len(test.chosen.fiber) == 1
    assert test.chosen.verdict == symmetry.KINEMATIC
    assert "the search stopped after" in test.search
    assert "fiber = [...]" in test.search


def test_a_search_over_its_budget_without_an_admissible_fibre_asks_for_it():
    """Budget 5 at n = 12: even the 11 single coordinates that can be symmetries do not fit:
    one error naming the remedy."""
    with pytest.raises(ModelError,
                       match=r"symmetry search over 12 coordinates .* name the fibre coordinates"):
        symmetry.symmetry_test(particles(12), max_candidates=5)


def test_no_subset_that_can_be_a_symmetry_is_one_clear_error():
    """Every coordinate in the potential and no planar frame: no subset can be a symmetry."""
    system = System(coordinates=[f"z{i}" for i in range(10)], parameters={},
                    lagrangian=" + ".join(f"z{i}_dot**2/2 - cos(z{i})" for i in range(10)),
                    constraints=["z0_dot - z1_dot"])
    with pytest.raises(ModelError, match=r"(?s)no candidate group .* L or ω depends on every coordinate"):
        symmetry.symmetry_test(system)
