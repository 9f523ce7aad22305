"""opty's three wheeled-vehicle gallery examples as nhgait scenes (examples/opty_*.toml).

The scenes' equations against KanesMethod models written here from opty's physical
descriptions (frames, points, bodies, loads, the contact-point velocities; tests/oracles.py):
q̈ equal to 1e-10 relative at 100 random constraint-consistent states each — the same bodies,
friction and the torque on the front axle alone (a Lagrangian and generalized forces written by
hand agree with the example's own mechanics). The planned examples themselves are measured by
experiments/bench_peers.py, not here (minutes each).
"""
from __future__ import annotations

from pathlib import Path

import pytest

from oracles import agreement, oracle

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
RTOL = 1e-10


@pytest.mark.parametrize("scene, name", [("opty_parallel_park", "opty_bicycle"), ("opty_garage", "opty_car3"),
                                         ("opty_pylons", "opty_car3")])
def test_scene_equals_optys_kanes_method(scene, name):
    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation.scene import load_scene
    system = load_scene(str(EXAMPLES / f"{scene}.toml")).system
    worst = agreement(system, derive(system, "reduced"), oracle(name))
    assert worst < RTOL, f"{scene}: max relative q̈ error {worst:.3g}"
