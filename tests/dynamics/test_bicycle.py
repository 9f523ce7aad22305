"""The Whipple bicycle (built-in ``whipple_bicycle``, built from bodies and wheels, nothing typed
from the papers' matrices) against the field's published truths:

The numbers are in experiments/whipple_published.py (data only, shared with the benchmark):

* Meijaard, Papadopoulos, Ruina, Schwab, Proc. R. Soc. A 463 (2007) 1955–1982, Table 2: the
  eigenvalues of the upright straight motion at 0, 1, …, 10 m/s (14 decimals), the weave and
  capsize speeds and, at the bifurcation speed where the two real unstable eigenvalues merge
  into the weave pair, that speed and the double eigenvalue — all to 1e-10 absolute. (The
  table as transcribed in D. L. Peterson's test of the benchmark, which matches the paper.)
* Basu-Mandal, Chatterjee, Papadopoulos, Proc. R. Soc. A 463 (2007) 1983–2003, Table 1: the
  nonlinear accelerations at a state leaning 35.6° and steering 13°, 13–14 digits (the state
  and the outputs as shipped by ``dtk.bicycle.basu_table_one_input/output``; the conversions
  ``basu_to_moore_input`` and ``moore_to_basu`` transcribed in whipple_published.py, with the
  map between Moore's coordinates and nhgait's).
"""
import experiment_scripts
import numpy as np
import pytest

from nhgait.dynamics import derive, load_scene
from nhgait.dynamics.linearisation import linearise, stability_chart

PUBLISHED = experiment_scripts.load("whipple_published")      # the papers' numbers (data only)
TABLE2, WEAVE, CAPSIZE = PUBLISHED.TABLE2, PUBLISHED.WEAVE, PUBLISHED.CAPSIZE
WEAVE_FREQUENCY, BIFURCATION, DOUBLE = PUBLISHED.WEAVE_FREQUENCY, PUBLISHED.BIFURCATION, PUBLISHED.DOUBLE
BASU_STATE, BASU_OUTPUT = PUBLISHED.BASU_STATE, PUBLISHED.BASU_OUTPUT
TOL = 1e-10


@pytest.fixture(scope="module")
def bicycle():
    return derive(load_scene("whipple_bicycle").system)


def _matched(ours, published):
    """The largest distance between the two sets of four eigenvalues, matched by sorting."""
    key = lambda v: (round(v.real, 6), v.imag)                       # noqa: E731
    a, b = sorted(np.asarray(ours, complex), key=key), sorted(np.asarray(published, complex), key=key)
    return max(abs(x - y) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("speed", sorted(TABLE2))
def test_eigenvalues_equal_the_benchmark_table(bicycle, speed):
    lin = linearise(bicycle, speed=float(speed))
    assert len(lin.eigenvalues) == 4
    assert _matched(lin.eigenvalues, TABLE2[speed]) < TOL
    assert lin.states == ("lean", "pitch", "steer", "p", "pt_lean", "pt_steer")
    assert set(lin.cyclic) == {"x", "y", "yaw", "rear", "front"}


def test_weave_and_capsize_speeds(bicycle):
    chart = stability_chart(bicycle, np.linspace(0.0, 10.0, 101))
    assert [(c.below, c.above) for c in chart.changes] == [("unstable", "stable"), ("stable", "unstable")]
    weave, capsize = (c.speed for c in chart.changes)
    assert weave == pytest.approx(WEAVE, abs=TOL)
    assert capsize == pytest.approx(CAPSIZE, abs=TOL)
    assert max(chart.changes[0].eigenvalues.imag) == pytest.approx(WEAVE_FREQUENCY, abs=TOL)
    assert chart.stable_ranges() == [(weave, capsize)]


def test_the_real_pair_merges_into_the_weave_at_the_bifurcation_speed(bicycle):
    from scipy.optimize import brentq

    def pair(v):
        lam = linearise(bicycle, speed=v).eigenvalues
        return lam[np.argsort(-lam.real)][:2]                      # the two with the largest real parts

    def discriminant(v):                                            # (λa − λb)²: > 0 real, < 0 complex
        a, b = pair(v)
        return float(((a - b) ** 2).real)
    v = brentq(discriminant, 0.5, 0.9, xtol=1e-14)
    assert v == pytest.approx(BIFURCATION, abs=TOL)
    assert pair(v).real.mean() == pytest.approx(DOUBLE, abs=TOL)


# --------------------------------------------------------------------------- Basu-Mandal
def test_nonlinear_accelerations_equal_basu_mandal_table_1(bicycle):
    got = PUBLISHED.basu_mandal_accelerations(bicycle)
    for name, value in BASU_OUTPUT.items():
        assert got[name] == pytest.approx(value, abs=1e-11), name
