"""A 6-coordinate robot planned as a user plans it (issue 19): the two-steering snakeboard
(x, y, θ, ψ, φ_f, φ_b; 2 constraints, 10 reduced states) from its scene text with the benchmark task (0.5 m
forward in 2π s, fibre at rest at both ends, rotor and wheels periodic), at N = 20 and
interpreted, against the independent hand-written transcription of
``experiments/reference_scale_ocp.py`` at the same N (KanesMethod model in (q, u_ind),
its own guess, Ipopt, exact Hessian).

Both discretise the same continuous problem with RK4 ×4 per interval, so their optima agree
to the solvers' tolerances (measured: 5.6e-8 relative), not merely to the discretisation error."""
import experiment_scripts
import numpy as np
import pytest

from nhgait.gaits.planner import plan

reference = experiment_scripts.load("reference_scale_ocp")
scale_tasks = experiment_scripts.load("scale_tasks")

MEMBER, N = "snakeboard_two_steering", 20


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    scene = tmp_path_factory.mktemp("scale") / f"{MEMBER}.toml"
    scene.write_text(scale_tasks.scene_with_task(MEMBER))       # scene + [task], as users write it
    return plan(str(scene), intervals=N, jit=False)


@pytest.fixture(scope="module")
def hand_written():
    return reference.build(MEMBER, N=N, jit=False, expand=False).solve()


def test_six_coordinate_robot_is_planned_and_verified(planned):
    assert planned.success, planned.diagnosis
    assert planned.model.system.n == 6
    assert planned.model.system.k == 2
    assert len(planned.solution.state_names) == 2 * 6 - 2
    verification = planned.solution.verification
    assert verification.success
    assert verification.max_error <= 1e-6


def test_objective_equals_the_independent_transcription(planned, hand_written):
    assert hand_written["success"], hand_written["status"]
    assert planned.solution.objective == pytest.approx(hand_written["objective"], rel=1e-6)


def test_task_holds_on_the_plan(planned):
    """Ends as the task states them, incl. the conditions the planner dropped as implied
    (ẏ, θ̇ at rest follow from θ = 0, ẋ = 0) to the verification tolerance 1e-6, read off the
    independent re-simulation (DOP853, rtol 1e-10) of the optimal inputs, mapped to (q, q̇)."""
    sol = planned.solution
    names = list(planned.model.system.coordinates)
    z = sol.verification.states
    qdot_of = sol.problem.model.numeric["qdot"]
    q = z[:len(names)].T
    qdot = np.array([np.asarray(qdot_of(z[:, k], sol.problem.params)).ravel() for k in range(z.shape[1])])
    for end, row in (("initial", 0), ("final", -1)):
        np.testing.assert_allclose(qdot[row, :3], 0.0, atol=1e-6, err_msg=f"{end}: fibre at rest")
    np.testing.assert_allclose(q[-1, [names.index("x"), names.index("theta")]], [0.5, 0.0], atol=1e-6)
    for c in ("psi", "phi_f", "phi_b"):
        i = names.index(c)
        assert q[-1, i] == pytest.approx(q[0, i], abs=1e-6)
        assert qdot[-1, i] == pytest.approx(qdot[0, i], abs=1e-6)
    assert np.all(np.abs(q[:, [names.index("phi_f"), names.index("phi_b")]]) <= 1.0 + 1e-8)


def test_a_chart_that_covers_the_ends_is_chosen():
    """A cart with two on-axle trailers, straight at rest at both ends (n = 6, k = 4). The
    default fiber (x, y, θ, φ) carries all four constraints, and at β = 0 their columns of ω on
    that fiber have rank 3 (rows: cart no-slip, rolling, two trailer no-slips; the last three
    act on (y, θ) only) — evaluated here from the scene's ω, not by the reduction. The planner
    takes fiber (x, y, θ) instead and reaches the independent transcription's optimum."""
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    member = "cart_trailers_2"
    scene = scene_from_text(scale_tasks.scene_with_task(member), member)
    system = scene.system
    omega = system.omega().xreplace({**{q: 0 for q in system.q},
                                               **{s: v for s, v in zip(system.param_symbols,
                                                                       system.param_values, strict=True)}})
    fiber = [system.coordinates.index(c) for c in ("x", "y", "theta", "phi")]
    assert np.linalg.matrix_rank(np.array(omega[:, fiber], dtype=float)) == 3
    from nhgait.dynamics import derive
    default = derive(system, "reduced")                       # fiber (x, y, theta, phi)
    assert float(default.numeric["singular"](np.zeros(6), default.numeric.params(None))) == 0.0
    result = plan(scene, intervals=N, jit=False)
    assert result.success, result.diagnosis
    assert tuple(result.model.layout.fiber) == ("x", "y", "theta")
    hand = reference.build(member, N=N, jit=False, expand=False).solve()
    assert hand["success"]
    assert result.solution.objective == pytest.approx(hand["objective"], rel=1e-6)


def test_fitted_roll_out_ends_where_the_task_ends():
    """The cart with one trailer (velocity states θ̇, φ̇ driven by the inputs): the first guess
    is the kinematic roll-out fitted to the task, and its last node is the task's final
    configuration (x = 3, y = 0.3, θ = β₁ = 0) to 1e-3 (the fit trades the last digits for a
    gentler motion, module ``nhgait.gaits.planning.fitted``; the ends are 3 m apart); for the 3-link snake
    (states are shape rates) a shape loop stays first."""
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning.guesses import candidates
    from nhgait.gaits.tasks.sources import resolve
    cart = prepare(resolve(scene_from_text(scale_tasks.scene_with_task("cart_trailers_1"), "c"))).problem
    first = candidates(cart)[0]
    assert first.label == "fitted roll-out"
    names = list(cart.model.system.coordinates)
    end = first.states[:len(names), -1]
    target = {"x": 3.0, "y": 0.3, "theta": 0.0, "beta1": 0.0}
    np.testing.assert_allclose([end[names.index(k)] for k in target], list(target.values()), atol=1e-3)
    np.testing.assert_allclose(first.states[:len(names), 0], 0.0, atol=0)      # starts at the task's start
    snake = prepare(resolve(scene_from_text(scale_tasks.scene_with_task("snake_3"), "s"))).problem
    assert candidates(snake)[0].label != "fitted roll-out"
    assert candidates(snake)[1].label == "fitted roll-out"


def test_a_chart_whose_reconstruction_fails_at_the_ends_is_replaced():
    """The cart with three trailers, straight at both ends: the default chart's q̇(q, P) is not
    finite at q = 0 (the pivot block on (x, y, θ, φ) loses rank there, as for two trailers;
    its singular measure once reported 1.0 there by dropping a NaN); the planner's chart is
    regular there and its reconstruction finite."""
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    from nhgait.dynamics.progress import Progress
    from nhgait.gaits.planning.charts import derive_for_task
    from nhgait.gaits.tasks.sources import resolve
    scene = scene_from_text(scale_tasks.scene_with_task("cart_trailers_3"), "c3")
    model = derive_for_task(scene.system, resolve(scene).task, None, Progress.silent())
    assert tuple(model.layout.fiber) == ("x", "y", "theta")
    z = np.concatenate([np.zeros(7), [0.4, 0.6]])
    assert np.all(np.isfinite(np.asarray(model.numeric["qdot"](z, model.numeric.params(None)))))
