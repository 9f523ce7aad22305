"""Planning through the one path (scene/task data → plan), for the four built-in tasks and three
robots the project writes as scene files (examples/: a car parallel-parking, a cart with a
trailer reversing into a slot, a Chaplygin sleigh driven by an internal rotor swimming 1 m).

Independent references:
* the re-simulation of ``Solution.verify`` — DOP853 at rtol 1e-10 of the *general*
  (unspecialised, momentum-coordinate) reduced model, restarted at every control switch: the
  node states agree to ≤ 1e-6 and every boundary and periodicity condition holds to ≤ 1e-6 on
  the re-simulated trajectory (N ≥ 50; the RK4 error of h = T/(4N) is the bound);
* a second formulation: the Euler–Lagrange equations with multipliers (``derive(…, "lagrange")``,
  index-1 route, DOP853 at rtol 1e-11) driven by the optimal piecewise-constant inputs from the
  optimal initial state reaches the task's final values to ≤ 1e-6;
* the hand-written CasADi reference (experiments/reference_casadi_ocp.py, its own explicit ODEs)
  for the objectives of P1–P3 at N = 50 (1e-4 relative, as in the benchmark).
"""
from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from nhgait.gaits.planner import plan

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"

#: (scene, gait or None for the scene's [task], N, reference objective at that N or None)
CASES = [("unicycle", "parallel-park", 50, 1.536285), ("snakeboard", "forward", 50, 0.109813),
         ("snakeboard", "rotate", 50, 2.110183), ("snakeboard", "lateral", 50, None),
         (str(EXAMPLES / "car.toml"), None, 60, None), (str(EXAMPLES / "cart_trailer.toml"), None, 60, None),
         (str(EXAMPLES / "rotor_sleigh.toml"), None, 60, None)]


def lagrange_final_errors(result) -> dict:
    """Re-simulate with the Lagrange DAE interval by interval; |y(T) − target| per final condition."""
    from nhgait.dynamics import derive, simulate
    from nhgait.dynamics.numerics.specialisation import body_velocity
    s = result.solution
    system = result.plan.scene.system
    lag = derive(system, "lagrange")
    n = system.n
    q, v = s.z[0, :n].copy(), s.velocities()[:, 0].copy()
    for k in range(len(s.t) - 1):
        u = s.u[k]
        run = simulate(lag, (s.t[k], s.t[k + 1]), q, v, controller=lambda t, qq, vv, u=u: u,
                       rtol=1e-11, atol=1e-12, t_eval=[s.t[k + 1]])
        assert run.success
        q, v = run.q[-1], run.qdot[-1]
    coords = tuple(system.coordinates)
    values = {c: q[i] for i, c in enumerate(coords)}
    values.update({f"{c}_dot": v[i] for i, c in enumerate(coords)})
    if system.planar_frame:
        ix, iy, ih = (coords.index(c) for c in system.planar_frame)
        for name in ("forward_velocity", "lateral_velocity"):
            values[name] = body_velocity(name, v[ix], v[iy], q[ih], np.cos, np.sin)
    errors = {}
    for name, target in result.task.final.items():
        lo, hi = target if isinstance(target, tuple) else (target, target)
        errors[name] = max(lo - values[name], values[name] - hi, 0.0)
    return errors


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = {}

    def run(case):
        if case not in out:
            scene, gait, N, _ = case
            folder = tmp_path_factory.mktemp("plan")
            out[case] = (plan(scene, gait, intervals=N, jit=False, out_dir=folder, animate=False), folder)
        return out[case]
    return run


@pytest.mark.parametrize("case", CASES, ids=[f"{Path(c[0]).stem}-{c[1] or 'task'}" for c in CASES])
def test_plans_verify(planned, case):
    result, folder = planned(case)
    s = result.solution
    assert s.success, result.attempts
    assert s.intervals if hasattr(s, "intervals") else s.settings["intervals"] >= 50
    v = s.verification
    assert v.success, v.state_errors
    assert v.max_error <= 1e-6, v.state_errors
    assert v.max_condition_error <= 1e-6, v.condition_errors
    reference = case[3]
    if reference is not None:
        assert s.objective == pytest.approx(reference, rel=1e-4)
    for name in ("solution.json", "path.png", "shape.png", "histories.png", "momentum.png"):
        assert (folder / name).stat().st_size > 1000
    assert result.guess != "none"
    assert result.guess in [a.label for a in result.attempts]


@pytest.mark.parametrize("case", CASES[4:], ids=["car", "cart_trailer", "rotor_sleigh"])
def test_second_formulation_reaches_the_targets(planned, case):
    result, _ = planned(case)
    errors = lagrange_final_errors(result)
    assert errors, errors
    assert max(errors.values()) <= 1e-6, errors


def test_solution_json_has_the_trajectory_task_and_guess(planned):
    result, folder = planned(CASES[4])
    data = json.loads((folder / "solution.json").read_text())
    for key in ("success", "status", "objective", "iterations", "solve_time_s", "setup_time_s",
                "verification_error", "settings", "trajectory", "task", "guess"):
        assert key in data, key
    tr = data["trajectory"]
    N, n, m = 60, 4, 2
    assert len(tr["t"]) == N + 1
    assert tr["coordinates"] == ["x", "y", "theta", "phi"]
    assert np.shape(tr["q"]) == (N + 1, n)
    assert np.shape(tr["qdot"]) == (N + 1, n)
    assert np.shape(tr["u"]) == (N, m)
    assert tr["inputs"] == ["F", "tau_phi"]
    # the trajectory is the car's: rear wheel without side slip at every node, ω(q)q̇ = 0
    q, qd = np.array(tr["q"]), np.array(tr["qdot"])
    assert np.max(np.abs(-np.sin(q[:, 2]) * qd[:, 0] + np.cos(q[:, 2]) * qd[:, 1])) < 1e-9
    assert data["task"]["final"]["y"] == 0.5
    assert data["task"]["intervals"] == N
    assert data["guess"]["won"] == result.guess
    assert any(t["success"] for t in data["guess"]["tried"] if result.guess.startswith(t["label"]))


#: files of other owners still naming sympy (cli/main.py: a docstring; cli/derive.py: printing)
OTHER_OWNERS = {"cli/main.py", "cli/derive.py"}


def test_gaits_layer_has_no_sympy():
    out = subprocess.run(["grep", "-rl", "sympy", str(ROOT / "gaits")], capture_output=True, text=True)
    found = {Path(p).relative_to(ROOT / "gaits").as_posix() for p in out.stdout.split()}
    assert found <= OTHER_OWNERS, found - OTHER_OWNERS


def test_zero_guess_is_never_the_only_try(models):
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning.guesses import candidates
    from nhgait.gaits.tasks.sources import resolve
    problem = prepare(resolve("snakeboard", "forward", overrides=["intervals=10"])).problem
    guesses = candidates(problem)
    moving = [g for g in guesses if np.ptp(g.states[3]) > 0.1]       # psi oscillates
    assert len(moving) >= 10
    assert guesses[-1].label == "ramps only"
    labels = {g.label.split()[1] for g in guesses if g.label.startswith("psi:phi")}
    assert {"1:1", "2:1", "3:2"} <= labels


def test_continuation_grows_an_easier_problem():
    """Continuation solves the task with its end values a quarter, half, three quarters of the
    way and then all the way, each from the last solution, and reaches the full target."""
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning.guesses import candidates
    from nhgait.gaits.planning.search import continuation
    from nhgait.gaits.tasks.sources import resolve
    from nhgait.ocp import OCPSolver, SolverOptions
    problem = prepare(resolve("snakeboard", "forward", overrides=["intervals=25", "final.x=2.0"])).problem
    solver = OCPSolver(problem, options=SolverOptions(jit=False, max_iter=200))
    search = continuation(solver, candidates(problem)[0])
    sol, attempts = search.solution, search.attempts
    assert [a.label.split()[1] for a in attempts] == ["0.25", "0.5", "0.75", "1"]
    assert sol is not None
    assert sol.success
    assert sol.state("x")[-1] == pytest.approx(2.0, abs=1e-8)


def test_parallel_candidates_agree_with_sequential():
    seq = plan("snakeboard", "rotate", intervals=25, jit=False, workers=1, verify=False, memo=False)
    par = plan("snakeboard", "rotate", intervals=25, jit=False, workers=2, verify=False, memo=False)
    assert par.success
    assert len(par.attempts) >= 2            # the first batch (two at once), then the exploration's
    best = min(a.objective for a in par.attempts if a.success)
    assert par.solution.objective == pytest.approx(best, rel=1e-12)
    # the first candidate is the same in both: its result does not depend on the process
    assert par.attempts[0].objective == pytest.approx(seq.attempts[0].objective, rel=1e-9)
    assert par.attempts[0].iterations == seq.attempts[0].iterations
    assert math.isfinite(seq.solution.objective)


def test_unknown_names_are_one_error(tmp_path):
    """Every unknown name in one error (a redundant set of values is not one: see
    tests/ocp/test_conditions.py)."""
    from nhgait.ocp import ProblemError
    with pytest.raises(ProblemError) as info:
        plan("snakeboard", {"horizon": 1.0, "final": {"zz": 1.0, "x": 1.0, "y": 0, "theta": 0, "psi": 0,
                                                      "phi": 0, "x_dot": 0, "y_dot": 0, "psi_dot": 0},
                            "control_bounds": {"tau_q": [-1, 1]}, "objective": {"tau_z": 1.0}}, jit=False)
    text = str(info.value)
    assert "unknown name 'zz'" in text
    assert "unknown input 'tau_q'" in text
    assert "unknown weight 'tau_z'" in text


def test_bad_parameter_values_are_one_error_before_any_derivation():
    """``params`` is checked like a scene's parameters: a zero mass made the reachability test
    fail with numpy's LinAlgError, a negative one was reported as an unreachable target, NaN
    without its name (a user's trial, 2026-11-29)."""
    from nhgait.ocp import ProblemError
    with pytest.raises(ProblemError) as info:
        plan("unicycle", "parallel-park", params={"zz": 1.0, "r": "two", "J_phi": float("nan")})
    text = str(info.value)
    assert text.startswith("invalid parameters: 3 problem(s)")
    assert "unknown parameter 'zz'" in text and "'two' is not a number" in text
    assert "parameter 'J_phi': nan is not finite" in text
    for mass, says in ((0.0, "is singular"), (-1.0, "not positive definite")):
        with pytest.raises(ProblemError, match=f"kinetic metric .*{says}.*m = {mass}"):
            plan("unicycle", "parallel-park", params={"m": mass})


def test_an_input_among_the_state_bounds_names_the_table_it_belongs_in():
    """A user's first task bounded the wheel torques in ``bounds``: each name of the other kind
    is one problem that says where it belongs, in both directions, and the phases' tables too."""
    from nhgait.ocp import ProblemError
    with pytest.raises(ProblemError) as info:
        plan("snakeboard", {"horizon": 1.0, "final": {"x": 1.0},
                            "bounds": {"tau_psi": [-1, 1], "phi": [-1, 1]},
                            "control_bounds": {"psi": [-1, 1], "tau_phi": [-1, 1]}}, jit=False)
    text = str(info.value)
    assert "[task].bounds: 'tau_psi' is an input: bound it in [task].control_bounds" in text
    assert "[task].control_bounds: 'psi' is not an input: bound it in [task].bounds" in text
    assert "'phi'" not in text and "'tau_phi'" not in text and "unknown" not in text
    with pytest.raises(ProblemError) as info:
        plan("snakeboard", {"phases": [{"horizon": 1.0, "intervals": 10, "final": {"x": 0.5},
                                        "bounds": {"tau_psi": [-1, 1], "zz": [0, 1]},
                                        "control_bounds": {"q": 1}},
                                       {"horizon": 1.0, "intervals": 10, "final": {"x": 1.0}}]}, jit=False)
    text = str(info.value)
    assert ("[task].phases[0].bounds: 'tau_psi' is an input: bound it in [task].phases[0].control_bounds"
            in text)
    assert "[task].phases[0].bounds: unknown name 'zz'" in text          # once "[task].[task]…state_bounds"
    assert "[task].phases[0].control_bounds: unknown input 'q'" in text


def test_warm_start_from_a_previous_solution(tmp_path):
    """A solution (object or solution.json) of a coarser grid starts a finer one: it is tried
    first, wins, and Ipopt needs fewer iterations than from the planner's own guess."""
    import pickle
    coarse = plan("snakeboard", "rotate", intervals=25, jit=False, out_dir=tmp_path, verify=False)
    fine_own = plan("snakeboard", "rotate", intervals=50, jit=False, verify=False)
    for previous in (coarse, tmp_path / "solution.json"):
        fine = plan("snakeboard", "rotate", intervals=50, jit=False, guess=previous, verify=False)
        assert fine.guess == "warm start"
        assert fine.success
        assert fine.solution.objective == pytest.approx(2.110183, rel=1e-4)       # reference, N = 50
        assert fine.solution.iterations < fine_own.solution.iterations
    assert pickle.loads(pickle.dumps(coarse.task)) == coarse.task


def test_auto_solver_falls_back_to_ipopt(monkeypatch):
    """solver="auto": FATROP first; when it finds nothing (here: every FATROP solve reported as
    failed), Ipopt plans the task and the report says which solver did what."""
    from dataclasses import replace as dc_replace

    from nhgait.gaits.planning.options import solver_order
    from nhgait.ocp import OCPSolver, ProblemError
    assert solver_order("auto") == ("fatrop", "ipopt")
    assert solver_order("auto", "collocation") == ("ipopt",)
    with pytest.raises(ProblemError, match="unknown solver 'snopt'"):
        solver_order("snopt")
    original = OCPSolver.solve

    def fatrop_fails(self, guess):
        sol = original(self, guess)
        return (dc_replace(sol, success=False, status="forced failure")
                if self.options.solver == "fatrop" else sol)
    monkeypatch.setattr(OCPSolver, "solve", fatrop_fails)
    result = plan("snakeboard", "forward", intervals=25, jit=False, verify=False, max_iter=30)
    solvers = [a.solver for a in result.attempts]
    assert result.success
    assert result.solution.settings["solver"] == "ipopt"
    assert solvers[0] == "fatrop"
    assert solvers[-1] == "ipopt"
    assert "fatrop" in solvers
    assert result.solution.objective == pytest.approx(0.110252, rel=1e-4)


def test_scene_quantities_in_a_task(tmp_path):
    """A task may name the scene's own quantities: a linear one becomes a velocity state, a
    nonlinear one a path bound (a row of g); both hold in the re-simulation."""
    text = (EXAMPLES / "car.toml").read_text()
    text = text.replace("[units]", '[quantities]\nv_rear = "cos(theta)*x_dot + sin(theta)*y_dot"\n'
                                   'speed2 = "x_dot**2 + y_dot**2"\n\n[units]')
    text = text.replace("forward_velocity", "v_rear").replace("bounds = {phi = [-0.7, 0.7]}",
                                                                "bounds = {phi = [-0.7, 0.7], speed2 = "
                                                                "[0.0, 0.16]}")
    scene = tmp_path / "car_q.toml"
    scene.write_text(text)
    result = plan(str(scene), intervals=25, jit=False)      # what is asserted holds at any N
    s = result.solution
    assert s.success
    assert s.settings["velocities"] == ["v_rear", "phi_dot"]
    assert s.verification.max_condition_error <= 1e-6
    assert s.verification.max_error <= 1e-6
    qd = s.velocities()
    assert np.max(qd[0] ** 2 + qd[1] ** 2) <= 0.16 + 1e-6          # the nonlinear path bound
