"""nhgait.ocp: problem validation, transcriptions, solver outcomes, solution files.

Reference objectives are those of the hand-written CasADi reference
(experiments/reference_casadi_ocp.py, RK4 with 4 sub-steps, piecewise-constant controls).
Our state uses momenta instead of velocities; for the unicycle the two are linearly related
(identical RK4 iterates), for the snakeboard the RK4 discretisation differs by O(h⁴), measured
≤ 1e-6 relative at N = 25 — so 1e-4 relative is the stated target tolerance.
"""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from nhgait.dynamics.numerics.compiler import compiler_command
from nhgait.dynamics.numerics.fast_compiler import fast_compiler
from nhgait.ocp import Collocation, OCPSolver, OptimalControlProblem, ProblemError, SolverOptions, solve

#: these compile the NLP functions (gcc, or the fast compiler); CI may have neither
needs_a_compiler = pytest.mark.skipif(compiler_command() is None and fast_compiler() is None,
                                      reason="no C compiler")

REF_25 = {"P1": 1.543703, "P2": 0.110252, "P3": 2.162582}


@pytest.fixture(scope="module")
def unicycle(models):
    from nhgait.dynamics.numerics.specialisation import specialise
    return specialise(models["unicycle"]["reduced"])


@pytest.fixture(scope="module")
def snakeboard(models):
    from nhgait.dynamics.numerics.specialisation import specialise
    return specialise(models["snakeboard"]["reduced"], velocities=("forward_velocity", "psi_dot", "phi_dot"))


def p1(model, N=25, **kw):
    return OptimalControlProblem(model, 4.0, N, initial={n: 0.0 for n in model.state_names},
                                 final={"x": 0.0, "y": 0.5, "theta": 0.0, "p": 0.0, "pt_theta": 0.0},
                                 control_bounds=5.0, **kw)


def p1_guess(problem):
    from nhgait.gaits.planning.guesses import candidates
    return candidates(problem)[0]


def p2(model, N=25, **kw):
    from nhgait.gaits.tasks.sources import get_task
    from nhgait.gaits.tasks.statement import to_problem
    return to_problem(get_task("snakeboard", "forward").replace(intervals=N, **kw), model)


def test_ocp_does_not_import_sympy():
    code = ("import sys, nhgait.ocp.problem, nhgait.ocp.transcription, nhgait.ocp.solver, "
            "nhgait.ocp.solution; print('sympy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_bad_statements_list_every_problem(unicycle):
    with pytest.raises(ProblemError, match=r"(?s)horizon T = -1.*intervals N = 0.*unknown quantity 'zz'"
                                           r".*contradictory bounds lo = 2 > hi = 1.*unknown input 'tau_q'"):
        OptimalControlProblem(unicycle, -1.0, 0, initial={"zz": 0.0}, state_bounds={"phi": (2.0, 1.0)},
                              control_bounds={"tau_q": (-1, 1)})
    with pytest.raises(ValueError, match="lies outside state_bounds"):
        OptimalControlProblem(unicycle, 1.0, 10, initial={"phi": 3.0}, state_bounds={"phi": (-1, 1)})
    with pytest.raises(ValueError, match="periodic 'theta'.*cannot be equal"):
        OptimalControlProblem(unicycle, 1.0, 10, initial={"theta": 0.0}, final={"theta": 1.0},
                              periodic=["theta"])
    with pytest.raises(ValueError, match="unknown transcription"):
        OCPSolver(p1(unicycle), "shooting-stars")


def test_p1_multiple_shooting_matches_reference(unicycle):
    problem = p1(unicycle)
    sol = solve(problem, p1_guess(problem), jit=False)
    assert sol.success, sol.message
    assert sol.objective == pytest.approx(REF_25["P1"], rel=1e-4)
    # exact piecewise-constant objective: Σ h |u_k|²
    assert sol.objective == pytest.approx(problem.horizon / 25 * np.sum(sol.u ** 2), rel=1e-12)
    v = sol.verify()
    assert v.success  # RK4 (h = 0.04) vs DOP853 at rtol 1e-10
    assert v.max_error < 1e-6
    assert sol.state("y")[-1] == pytest.approx(0.5, abs=1e-9)


def test_collocation_agrees_with_shooting(unicycle):
    problem = p1(unicycle)
    ms = solve(problem, p1_guess(problem), jit=False)
    col = solve(problem, p1_guess(problem), transcription=Collocation(degree=3), jit=False)
    assert col.success, col.message
    # both converge to the continuous optimum 1.5338 with O(h^4)-size transcription differences
    assert col.objective == pytest.approx(ms.objective, rel=2e-2)


def test_failure_is_a_solution_not_an_exception(unicycle):
    problem = p1(unicycle)
    sol = solve(problem, p1_guess(problem), max_iter=2, jit=False)
    assert not sol.success
    assert sol.status == "Maximum_Iterations_Exceeded"
    # infeasible statement: reach y = 50 with |tau| <= 1e-3
    bad = OptimalControlProblem(unicycle, 1.0, 10, initial={n: 0.0 for n in unicycle.state_names},
                                final={"y": 50.0}, control_bounds=1e-3)
    sol = solve(bad, p1_guess(p1(unicycle, N=10)), max_iter=50, jit=False)
    assert sol.success is False
    assert sol.status


def test_solution_json_keys(unicycle, tmp_path):
    problem = p1(unicycle)
    sol = solve(problem, p1_guess(problem), jit=False).verified()
    data = json.loads(sol.to_json(tmp_path / "s.json").read_text())
    for key in ("success", "status", "objective", "iterations", "solve_time_s", "setup_time_s",
                "verification_error", "settings", "trajectory"):
        assert key in data
    assert data["verification_error"] == pytest.approx(sol.verification_error)
    tr = data["trajectory"]
    assert len(tr["t"]) == 26
    assert set(tr["controls"]) == {"tau_theta", "tau_phi"}
    assert np.shape(tr["q"]) == (26, 4)
    assert np.shape(tr["qdot"]) == (26, 4)
    assert np.shape(tr["u"]) == (25, 2)
    assert tr["coordinates"] == ["x", "y", "theta", "phi"]
    assert tr["inputs"] == ["tau_theta", "tau_phi"]
    # q̇ from the unicycle's rolling constraint ẋ = r cos θ φ̇ (r = 0.1), independent of the model
    q, qd = np.array(tr["q"]), np.array(tr["qdot"])
    assert np.allclose(qd[:, 0], 0.1 * np.cos(q[:, 2]) * qd[:, 3], atol=1e-12)
    assert data["verification"]["max_condition_error"] < 1e-6


@needs_a_compiler
def test_free_horizon_and_jit_cache(unicycle, tmp_path):
    problem = p1(unicycle, N=10)
    guess = p1_guess(problem)
    s1 = OCPSolver(problem, options=SolverOptions(jit=True))
    s2 = OCPSolver(problem, options=SolverOptions(jit=True))
    assert s1.jit_cached is False
    assert s2.jit_cached is True
    assert s2.compiled
    a, b = s1.solve(guess), solve(problem, guess, jit=False)
    assert a.success
    assert a.objective == pytest.approx(b.objective, rel=1e-8)
    free = problem.replace(free_horizon=(2.0, 8.0), time_weight=0.1)
    sol = solve(free, guess, jit=False)
    assert sol.success
    assert 2.0 <= sol.horizon <= 8.0
    assert sol.horizon != pytest.approx(4.0)


def test_compiled_is_the_default_and_falls_back_without_a_compiler(unicycle, monkeypatch):
    problem = p1(unicycle, N=8)
    guess = p1_guess(problem)
    monkeypatch.setenv("CC", "/nonexistent/cc")
    monkeypatch.setenv("NHGAIT_FAST_CC", "/nonexistent/tcc")
    fallback = OCPSolver(problem)                      # jit=None: compiled when a compiler exists
    assert not fallback.compiled
    assert "no C compiler found" in fallback.jit_fallback
    sol = fallback.solve(guess)
    assert sol.success
    assert sol.settings["jit"] is False
    assert "no C compiler" in sol.settings["jit_fallback"]
    monkeypatch.delenv("CC")
    monkeypatch.delenv("NHGAIT_FAST_CC")
    compiled = OCPSolver(problem)
    assert compiled.compiled
    assert compiled.jit_fallback is None
    assert compiled.solve(guess).objective == pytest.approx(sol.objective, rel=1e-9)


@needs_a_compiler
def test_compiled_library_is_loaded_only_when_trusted(unicycle):
    import os
    import warnings

    from nhgait.dynamics.numerics.cache import UntrustedCacheWarning
    problem = p1(unicycle, N=7)
    first = OCPSolver(problem, options=SolverOptions(jit=True))
    so = first.jit_path
    import json

    from nhgait.dynamics.numerics.cache import file_sha256
    assert json.loads((so.parent / (so.stem + ".json")).read_text())["library_sha256"] == file_sha256(so)
    assert oct(so.parent.stat().st_mode & 0o777) == "0o700"
    with open(so, "ab") as fh:                          # tampered after it was written
        fh.write(b"\0")
    with pytest.warns(UntrustedCacheWarning, match="does not match its recorded SHA-256"):
        again = OCPSolver(problem, options=SolverOptions(jit=True))
    assert again.jit_cached is False                    # rebuilt, not loaded
    os.chmod(so, 0o766)                                 # world-writable library
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        third = OCPSolver(problem, options=SolverOptions(jit=True))
    assert third.jit_cached is False
    assert any("writable by group or others" in str(w.message) for w in caught)


def test_fatrop_reaches_the_ipopt_optimum(snakeboard):
    """FATROP on the stage-ordered transcription (periodicity through a carried copy of the
    start values) and Ipopt on the interval-stacked one solve the same NLP: same optimum."""
    from nhgait.ocp.transcription import StageShooting
    problem = p2(snakeboard, N=25)
    guess = p1_guess(problem)
    ipopt = solve(problem, guess, jit=False)
    stages = solve(problem, guess, transcription=StageShooting(), jit=False)
    fatrop = OCPSolver(problem, options=SolverOptions(jit=False, solver="fatrop"))
    # ψ fixed at 0: φ, ψ̇, φ̇ carried
    assert fatrop.nlp.structure["N"] == 25
    assert fatrop.nlp.structure["nx"][0] == 8 + 3
    sol = fatrop.solve(guess)
    assert ipopt.success, sol.status
    assert stages.success, sol.status
    assert sol.success, sol.status
    assert ipopt.objective == pytest.approx(REF_25["P2"], rel=1e-4)
    assert stages.objective == pytest.approx(ipopt.objective, rel=1e-9)
    assert sol.objective == pytest.approx(ipopt.objective, rel=1e-6)
    assert np.max(np.abs(sol.z - ipopt.z)) < 1e-5
    v = sol.verify()
    assert v.max_condition_error < 1e-6                 # periodicity holds in the re-simulation


def test_stage_transcription_free_horizon(unicycle):
    from nhgait.ocp.transcription import StageShooting
    problem = p1(unicycle, N=10).replace(free_horizon=(2.0, 8.0), time_weight=0.1)
    guess = p1_guess(problem)
    a = solve(problem, guess, jit=False)
    b = solve(problem, guess, transcription=StageShooting(), jit=False)
    c = solve(problem, guess, jit=False, solver="fatrop")
    assert a.success
    assert b.success
    assert c.success
    assert b.objective == pytest.approx(a.objective, rel=1e-8)
    assert b.horizon == pytest.approx(a.horizon, rel=1e-6)
    assert c.objective == pytest.approx(a.objective, rel=1e-6)


def test_collocation_is_not_slowed_by_mumps_scaling(snakeboard):
    """Ipopt's automatic MUMPS scaling made collocation factorisations super-linear in N (20
    iterations, 1.3 s each at N = 100); with an explicit scaling P2 takes the shooting's ~10."""
    problem = p2(snakeboard, N=50)
    col = OCPSolver(problem, Collocation(), SolverOptions(jit=False))
    assert col.options.ipopt["mumps_scaling"] == 8
    sol = col.solve(p1_guess(problem))
    assert sol.success
    assert sol.iterations <= 12
    assert sol.objective == pytest.approx(0.109813, rel=1e-3)   # the continuous optimum, to O(h⁴)
