"""Smoke test of the hand-written reference NLP of issue 19 (experiments/reference_scale_ocp.py):
the smallest member (the 3-link snake) at N = 20, interpreted (no compiler), its optimum
re-simulated on the independent multiplier DAE and checked against the task as written."""
import math

import experiment_scripts
import numpy as np
import pytest

reference = experiment_scripts.load("reference_scale_ocp")
scale_tasks = experiment_scripts.load("scale_tasks")


@pytest.fixture(scope="module")
def snake3():
    ref = reference.build("snake_3", N=20, jit=False, expand=False)
    return ref, ref.solve()


def test_snake3_solves_and_resimulates(snake3):
    ref, res = snake3
    assert res["success"], res["status"]
    assert ref.n_states == 2 * 5 - 3
    assert ref.c_bytes == 0
    assert res["q"].shape == (21, 5)
    assert res["u"].shape == (20, 2)
    assert res["coordinates"] == ["x", "y", "theta", "alpha1", "alpha2"]
    # effort objective: exactly sum_k h |u_k|^2
    h = ref.T / ref.N
    assert res["objective"] == pytest.approx(h * np.sum(res["u"] ** 2), rel=1e-12)
    ver = reference.resimulate(ref, res)
    # RK4 x4 at h = 0.3 s: the re-simulation (another model, DOP853 rtol 1e-10) agrees to the
    # discretisation error (measured 8.5e-6 at N = 20)
    assert ver["success"]
    assert ver["node_error"] < 1e-4
    # every condition of the task as written, incl. the dropped redundant ones
    # (alpha1_dot, alpha2_dot periodic) holds on the re-simulated trajectory
    assert ver["condition_error"] < 1e-4, ver["worst_condition"]
    task = scale_tasks.TASKS["snake_3"]
    assert set(task["periodic"]) <= {k.split(".", 1)[1] for k in ver["condition_errors"]
                                      if k.startswith("periodic.")}


def test_snake3_boundary_conditions_at_nodes(snake3):
    ref, res = snake3
    q0, qT = res["q"][0], res["q"][-1]
    np.testing.assert_allclose(q0[:3], 0.0, atol=1e-9)
    np.testing.assert_allclose(qT[:3], [0.3, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(qT[3:], q0[3:], atol=1e-7)                  # periodic joints
    np.testing.assert_allclose(res["z"][5:, -1], res["z"][5:, 0], atol=1e-7)  # periodic rates
    assert np.all(res["q"][:, 3] >= 0.2 - 1e-8)
    assert np.all(res["q"][:, 4] <= -0.2 + 1e-8)
    assert np.max(np.abs(res["u"])) <= 5.0 + 1e-8


def test_translation_of_redundant_conditions():
    """At rest (every q_dot = 0) is (theta_dot, phi_dot) = 0 for the cart; fibre at rest is
    v = 0 for the two-steering board; the snake's trailing joint rates are implied."""
    ode = reference.reduced_ode("cart_trailers_1")
    tr = reference.transcribe(ode, scale_tasks.task("cart_trailers_1"))
    n = ode.n
    assert list(tr.lbz0[n:]) == [0.0, 0.0] == list(tr.ubzN[n:])
    assert math.isinf(tr.lbzN[ode.coordinates.index("phi")])               # wheel angle free
    board = reference.reduced_ode("snakeboard_two_steering")
    tb = reference.transcribe(board, scale_tasks.task("snakeboard_two_steering"))
    iv = board.n + board.independent.index("v")
    assert tb.lbz0[iv] == tb.ubz0[iv] == tb.lbzN[iv] == tb.ubzN[iv] == 0.0
    assert any("fixed at t = T" in note for note in tb.notes)             # psi(T) = psi(0) = 0
    snake = reference.reduced_ode("snake_4")
    ts = reference.transcribe(snake, scale_tasks.task("snake_4"))
    assert any("alpha3_dot" in note and "implied" in note for note in ts.notes)


def test_scene_with_task_round_trip():
    tomllib = pytest.importorskip("tomllib")
    assert len(scale_tasks.MEMBERS) == 13
    assert set(scale_tasks.TASKS) == set(scale_tasks.MEMBERS)
    for member in ("snake_3", "cart_trailers_1", "snakeboard_two_steering"):
        data = tomllib.loads(scale_tasks.scene_with_task(member))
        assert data["task"] == scale_tasks.TASKS[member]
        assert data["system"]["name"] == member


@pytest.mark.slow
@pytest.mark.parametrize("member", ["snake_3", "cart_trailers_1", "snakeboard_two_steering"])
def test_reduced_ode_matches_oracle(member):
    check = reference.check_model(member, count=20)
    assert check["vs_oracle"] < 1e-9
    assert check["vs_multiplier_dae"] < 1e-9
