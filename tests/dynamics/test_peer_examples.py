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

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
RTOL = 1e-10


@pytest.mark.parametrize("scene, name", [("opty_parallel_park", "opty_bicycle"), ("opty_garage", "opty_car3"),
                                         ("opty_pylons", "opty_car3")])
def test_scene_equals_optys_kanes_method(scene, name):
    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation.input.scene import load_scene
    system = load_scene(str(EXAMPLES / f"{scene}.toml")).system
    worst = agreement(system, derive(system, "reduced"), oracle(name))
    assert worst < RTOL, f"{scene}: max relative q̈ error {worst:.3g}"


def test_the_benchmarks_richardson_extrapolation_and_state_order(tmp_path):
    """experiments/bench_peers.py: J(N) = 5 + 3 (1/N)² gives J∞ = 5 from N, 2N, 4N; nhgait's
    answer in opty's state order: the bicycle's body velocities of the mass centre, the
    three-body car's absolute front-axle rate u_f = q̇0 + q̇f (opty's kinematic equation)."""
    import json

    import experiment_scripts
    import numpy as np
    bench = experiment_scripts.load("bench_peers")
    assert bench._richardson([5 + 3 / N ** 2 for N in (10, 20, 40)]) == pytest.approx(5.0, rel=1e-12)
    q = np.array([[0.0, 1.0], [0.0, 2.0], [0.0, np.pi / 2], [0.1, 0.2]])          # n × (N + 1)
    qdot = np.array([[1.0, 0.0], [0.0, 2.0], [0.5, 0.25], [0.3, -0.1]])
    trajectory = {"t": [0.0, 1.0], "q": q.T.tolist(), "qdot": qdot.T.tolist(), "u": [[1.0, 2.0]],
                  "control_names": ["Fb", "Tf"], "states": {"near1": [0.0, 0.3], "near2": [0.0, 0.2]}}
    path = tmp_path / "solution.json"
    path.write_text(json.dumps({"trajectory": trajectory}))
    car = np.array(bench.opty_trajectory(str(path), "car3")["states"])
    assert np.allclose(car[7], qdot[2] + qdot[3])
    assert np.allclose(car[8:], [[0.0, 0.3], [0.0, 0.2]])
    trajectory["control_names"] = ["F", "T"]
    path.write_text(json.dumps({"trajectory": trajectory}))
    bike = bench.opty_trajectory(str(path), "bicycle")
    assert np.allclose(np.array(bike["states"])[4:6, 1], [2.0, 0.0])      # heading π/2: ẏ = 2 is forward
    assert bike["input_names"] == ["F(t)", "T(t)"]
