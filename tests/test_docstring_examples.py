"""The runnable examples (``>>>``) in the docstrings of the entry points a user calls first —
derive, the scene loader, simulate and its options, Trajectory, linearise, plan and Solution,
sweep — run as doctests, so the documentation cannot drift from the code. Each example checks
what it shows against something independent of the code under test (a closed form, the task's
target, a conservation law) or shows only names and shapes; none prints a computed number
that the code alone decides."""
from __future__ import annotations

import doctest
import importlib

import pytest

#: the modules whose docstrings hold the examples
MODULES = ("nhgait.dynamics.derivation.formulations", "nhgait.dynamics.derivation.input.scene",
           "nhgait.dynamics.simulation.driver", "nhgait.dynamics.simulation.options",
           "nhgait.dynamics.simulation.trajectory", "nhgait.dynamics.linearisation.linearised",
           "nhgait.dynamics.suggestions", "nhgait.gaits", "nhgait.gaits.sweeps.driver",
           "nhgait.dynamics.units", "nhgait.dynamics.geometry.reconstruction",
           "nhgait.gaits.planning.options")
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _tests(name):
    return [t for t in doctest.DocTestFinder().find(importlib.import_module(name)) if t.examples]


@pytest.mark.parametrize("name", MODULES)
def test_the_examples_of_the_module_run(name):
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in _tests(name):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0, f"{result.failed} example(s) of {name} failed (see the captured output)"


def test_there_are_at_least_twenty_example_lines():
    assert sum(len(t.examples) for name in MODULES for t in _tests(name)) >= 20
