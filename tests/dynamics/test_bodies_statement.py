"""Reading rigid bodies and wheels (dynamics/derivation/bodies/statement.py): the values of the
tables as written (a joint axis [0, 3, 4] normalised to [0, 3/5, 4/5] by hand, parameters as
their symbols), q = (base, body joints, wheel spins), and every problem of every table in one
list — unknown keys, a zero axis, an asymmetric inertia, a name the parameters do not declare,
a parent declared after its child."""
from __future__ import annotations

import sympy as sp

from nhgait.dynamics.derivation.bodies.statement import read_multibody

m, r, g = sp.symbols("m r g", positive=True)
NAMES = {"m": m, "r": r, "g": g}
TABLE = {"bodies": [{"name": "fork", "parent": "base", "joint": "delta", "axis": [0, 3, 4],
                     "point": [1, 0, 0], "mass": "m/2", "com": [1.0, 0, "r"],
                     "inertia": [[1, 0, 0], [0, 2, 0], [0, 0, 3]]}],
         "wheels": [{"name": "front", "parent": "fork", "spin": "phi", "centre": [1, 0, "r"],
                     "axle": [0, 1, 0], "radius": "r", "mass": 1, "inertia": [0.5, 1.0]}]}


def test_the_tables_as_written():
    problems = []
    mb = read_multibody(TABLE, NAMES, problems)
    assert not problems
    fork, = mb.bodies
    assert fork.axis == sp.Matrix([0, sp.Rational(3, 5), sp.Rational(4, 5)]) and fork.mass == m / 2
    assert fork.com == sp.Matrix([1.0, 0, r]) and fork.inertia == sp.diag(1, 2, 3)
    front, = mb.wheels
    assert (front.radius, front.axial, front.rolls) == (r, 1.0, True) and mb.gravity == g
    assert mb.coordinates == ("x", "y", "theta", "delta", "phi") and mb.joints == ("delta",)


def test_every_problem_of_every_table():
    problems = []
    bad = {"base": ["x", "y"],
           "bodies": [{"name": "arm", "parent": "hand", "joint": "a", "axis": [0, 0, 0], "point": [0, 0, 0],
                       "inertia": [[1, 2, 0], [0, 1, 0], [0, 0, 1]], "colour": "red"},
                      {"name": "hand", "parent": "base", "mass": "k*m"}],
           "wheels": [{"name": "w", "parent": "base", "spin": 3, "centre": [0, 0], "axle": [0, 1, 0],
                       "radius": "r", "rolls": "yes"}]}
    assert read_multibody(bad, NAMES, problems) is None
    said = "\n".join(problems)
    for words in ("[system].base must name the three planar base coordinates",
                  "unknown key(s) ['colour']", "'arm'.axis: the axis is zero",
                  "the inertia matrix is not symmetric", "unknown name(s) k",
                  "spin must name the wheel's rotation coordinate", "expected a list of 3 numbers",
                  "rolls must be true or false",
                  "body 'arm': its parent 'hand' is not 'base' or a body declared"):
        assert words in said, words
