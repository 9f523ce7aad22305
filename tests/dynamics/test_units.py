"""Unit inference (dynamics/units.py) on the unicycle and the snakeboard, against the units a
physicist writes: positions in m, heading and joint angles in rad, rates per second, torques
in N·m, forces in N, conjugate momenta in N·s or N·m·s; the scene's own table first."""
from __future__ import annotations

import pytest

from nhgait.dynamics import load_scene
from nhgait.dynamics.units import pretty, unit_of


@pytest.fixture(scope="module")
def snakeboard():
    return load_scene("snakeboard")


def test_pretty_prints_products_and_squares():
    assert pretty("kg*m**2") == "kg·m²" and pretty("N*m") == "N·m" and pretty("m^2") == "m²"


def test_units_without_a_system():
    assert unit_of("t") == "s" and unit_of("energy") == "J" and unit_of("forward_velocity") == "m/s"
    assert unit_of("x") == "" and unit_of("tau", {"tau": "N*m"}) == "N·m"
    assert unit_of("x_dot", {"x": "m"}) == "m/s"


def test_snakeboard_units(snakeboard):
    system, units = snakeboard.system, snakeboard.units
    coords = tuple(system.coordinates)
    assert unit_of("x", units, system) == "m" and unit_of("y", units, system) == "m"
    for name in coords[2:]:
        assert unit_of(name, units, system) == "rad", name
        assert unit_of(f"{name}_dot", units, system) == "rad/s", name
        assert unit_of(f"pt_{name}", units, system) == "N·m·s", name
    assert unit_of("pt_x", units, system) == "N·s"
    for name in system.inputs:
        assert unit_of(name, units, system) == "N·m", name
    assert unit_of("no_such_column", units, system) == ""
