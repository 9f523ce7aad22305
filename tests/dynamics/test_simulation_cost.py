"""What a simulate() call keeps cheap (issue 16, item 7) without changing what it reports:
the condition numbers of ``Trajectory.diagnostics`` computed when first read, against an
independent evaluation of the kinetic metric; the memos a call reads (the compiler command per
environment, the force jump times per parameter values) with their documented lifetimes; the
no-compiler fallback through the memo."""
import math
import pickle

import numpy as np
import pytest

from nhgait.dynamics import System, derive, simulate
from nhgait.dynamics.numerics.compiler import COMPILER_COMMANDS, compiler_command
from nhgait.dynamics.simulation.controllers import snakeboard_pd

SNAKE_Q0, SNAKE_QDOT0 = np.array([0.0, 0.0, 0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0, 1.0, 0.0])


def _independent_conditions(system, q_rows):
    """max cond M(q) and max cond ω M⁻¹ ωᵀ over the rows, from the system's own sympy
    expressions (lambdified: nothing shared with the CasADi outputs of the closed loop)."""
    mass, omega, _ = system.numeric_functions()
    pv = system.param_vector()
    metric, gram = [], []
    for q in q_rows:
        M = np.asarray(mass(q, pv), dtype=float)
        W = np.asarray(omega(q, pv), dtype=float)
        metric.append(np.linalg.cond(M))
        gram.append(np.linalg.cond(W @ np.linalg.solve(M, W.T)))
    return max(metric), max(gram)


@pytest.mark.parametrize("formulation", ["lagrange", "hamilton"])
def test_condition_numbers_read_on_request_match_an_independent_metric(formulation):
    # the velocity part's metric is M (lagrange, in q̇) or M⁻¹ (hamilton, in p): cond is cond M
    model = derive("snakeboard", formulation)
    traj = simulate(model, (0.0, 2 * math.pi), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(),
                    method="compiled", rtol=1e-9, atol=1e-11, t_eval=np.linspace(0, 2 * math.pi, 41))
    assert traj.success, traj.message
    metric, gram = _independent_conditions(model.system, traj.q)
    assert traj.diagnostics["max_cond_metric"] == pytest.approx(metric, rel=1e-8)
    assert traj.diagnostics["max_cond_gram"] == pytest.approx(gram, rel=1e-8)


def test_diagnostics_is_a_read_only_mapping_with_every_documented_key():
    model = derive("snakeboard", "lagrange")
    traj = simulate(model, (0.0, 1.0), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(), method="compiled")
    d = traj.diagnostics
    for key in ("integrated_states", "state_count", "min_singular_measure", "max_cond_metric",
                "max_cond_gram"):
        assert key in d
    plain = dict(d)
    assert all(isinstance(plain[k], float) for k in ("max_cond_metric", "max_cond_gram"))
    assert plain["max_cond_metric"] >= 1.0
    assert pickle.loads(pickle.dumps(d)) == d
    assert "max_cond_metric" in repr(d)
    with pytest.raises(TypeError):
        d["max_cond_metric"] = 0.0


def test_compiler_command_is_remembered_per_environment(tmp_path, monkeypatch):
    with_gcc, empty = tmp_path / "with", tmp_path / "empty"
    with_gcc.mkdir()
    empty.mkdir()
    fake = with_gcc / "gcc"
    fake.write_text("#!/bin/sh\nexit 0\n")
    fake.chmod(0o755)
    monkeypatch.delenv("NHGAIT_CC", raising=False)
    monkeypatch.delenv("CC", raising=False)
    COMPILER_COMMANDS.clear()
    monkeypatch.setenv("PATH", str(with_gcc))
    assert compiler_command() == ["gcc"]
    monkeypatch.setenv("PATH", str(empty))          # another $PATH: looked up again
    assert compiler_command() is None
    monkeypatch.setenv("PATH", str(with_gcc))
    fake.unlink()                                   # same environment: the memo answers …
    assert compiler_command() == ["gcc"]
    COMPILER_COMMANDS.clear()                       # … until it is cleared
    assert compiler_command() is None
    monkeypatch.setenv("NHGAIT_CC", "/nonexistent/bin/cc")
    assert compiler_command() is None
    COMPILER_COMMANDS.clear()


def test_force_jump_times_follow_the_parameter_values():
    system = System(coordinates=["x", "y"], lagrangian="m*(x_dot**2 + y_dot**2)/2",
                    forces={"x": "Heaviside(t - t_s)"}, parameters={"m": 2.0, "t_s": 1.0})
    assert system.force_jump_times() == (1.0,)
    assert system.force_jump_times({"t_s": 2.5}) == (2.5,)
    assert system.force_jump_times({"t_s": 0.5, "m": 3.0}) == (0.5,)
    assert system.force_jump_times() == (1.0,)
    # the run is split there: m ẍ = H(t − t_s) gives x(3) = (3 − t_s)²/(2m)
    traj = simulate(derive(system, "reduced"), (0.0, 3.0), [0, 0], [0, 0], params={"t_s": 2.5},
                    t_eval=[0.0, 3.0], rtol=1e-10, atol=1e-12)
    assert traj.settings["segments"] == 2
    assert traj.q[-1, 0] == pytest.approx(0.5 ** 2 / 4.0, abs=1e-10)


def test_every_step_output_and_grid_output_agree(models):
    # the compiled route hands over its blocks as arrays: the accepted steps as output, and the
    # same run sampled on a grid at those times, give the same states (dense output at a step's
    # end is the step's end state to rounding)
    model = models["snakeboard"]["reduced"]
    steps = simulate(model, (0.0, 5.0), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(),
                     method="compiled", rtol=1e-8, atol=1e-10)
    grid = simulate(model, (0.0, 5.0), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(),
                    method="compiled", rtol=1e-8, atol=1e-10, t_eval=steps.t)
    assert steps.success
    assert grid.success
    assert len(steps.t) == steps.n_steps + 1
    np.testing.assert_array_equal(grid.t, steps.t)
    np.testing.assert_allclose(grid.state, steps.state, rtol=0, atol=1e-12)
    np.testing.assert_allclose(grid.energy_balance, steps.energy_balance, rtol=0, atol=1e-12)


def _hadamard_ratios(system, q_rows):
    """det S / Π Sᵢᵢ of S = ω M⁻¹ ωᵀ at each row, from the system's lambdified expressions."""
    mass, omega, _ = system.numeric_functions()
    pv = system.param_vector()
    ratios = []
    for q in q_rows:
        M, W = np.asarray(mass(q, pv), dtype=float), np.asarray(omega(q, pv), dtype=float)
        S = W @ np.linalg.solve(M, W.T)
        ratios.append(np.linalg.det(S) / np.prod(np.diag(S)))
    return np.array(ratios)


@pytest.mark.parametrize("method", ["compiled", "DOP853"])
def test_singular_measure_read_on_request_matches_an_independent_hadamard_ratio(method):
    # the compiled route evaluates the diagnostic blocks only when read; both routes report the
    # smallest measure over the output points
    model = derive("snakeboard", "hamilton")
    traj = simulate(model, (0.0, 2 * math.pi), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(),
                    method=method, rtol=1e-9, atol=1e-11, t_eval=np.linspace(0.5, 2 * math.pi, 31))
    assert traj.success, traj.message
    expected = _hadamard_ratios(model.system, traj.q).min()
    assert traj.diagnostics["min_singular_measure"] == pytest.approx(expected, rel=1e-9)


def test_to_state_from_many_threads_equals_one_at_a_time():
    # the initial-state map's buffer is shared per model: concurrent calls must not mix
    from concurrent.futures import ThreadPoolExecutor

    from nhgait.dynamics.derivation.states import consistent_velocities, to_state
    model = derive("snakeboard", "hamilton")
    rng = np.random.default_rng(3)
    states = []
    for _ in range(64):
        q = rng.uniform(-1, 1, 5)
        given = {name: rng.uniform(-1, 1) for name in ("phi", "theta", "psi")}
        states.append((q, consistent_velocities(model.system, q, given)))
    one_at_a_time = [to_state(model, q, qd) for q, qd in states]
    mass = model.system.numeric_functions().mass
    pv = model.system.param_vector()
    for (q, qd), x in zip(states, one_at_a_time, strict=True):       # p = M(q) q̇, independently
        assert np.allclose(x, np.r_[q, np.asarray(mass(q, pv), dtype=float) @ qd], rtol=1e-12, atol=1e-12)
    with ThreadPoolExecutor(8) as pool:
        for _ in range(5):
            concurrent = list(pool.map(lambda s: to_state(model, *s), states))
            assert all(np.array_equal(a, b) for a, b in zip(concurrent, one_at_a_time, strict=True))


def test_a_compiled_trajectory_pickles_before_its_diagnostics_are_read():
    """A trajectory goes to a worker or a file with its lazy diagnostics unread: the copy holds
    the values, equal to the independent condition numbers (rel 1e-8)."""
    model = derive("snakeboard", "lagrange")
    traj = simulate(model, (0.0, 1.0), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(), method="compiled",
                    rtol=1e-9, atol=1e-11, t_eval=np.linspace(0.0, 1.0, 21))
    copy = pickle.loads(pickle.dumps(traj))
    metric, gram = _independent_conditions(model.system, copy.q)
    assert copy.diagnostics["max_cond_metric"] == pytest.approx(metric, rel=1e-8)
    assert copy.diagnostics["max_cond_gram"] == pytest.approx(gram, rel=1e-8)
    np.testing.assert_array_equal(copy.q, traj.q)
