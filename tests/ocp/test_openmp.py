"""The stage maps on several cores (dynamics/numerics/openmp.py, thread_maps.py, ocp/derivatives.py):
a solver built for compiled code maps its stage terms with CasADi's threaded maps (threads
started and joined within each call); a supervised child solves with the library after the
parent ran it (a child forked after a pool of threads ran can hang: this test's child would be
killed at its time limit), granted its share of the cores for any OpenMP runtime. A compiler
without OpenMP builds a source asked with -fopenmp without it (its pragmas ignored). The
reference is the same NLP solved interpreted (CasADi's virtual machine, serial maps): the same
iterations, J to 1e-9."""
import os
from dataclasses import dataclass

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics import openmp
from nhgait.dynamics.numerics.compiler import compiler_command
from nhgait.dynamics.numerics.numeric_model import NumericModel
from nhgait.ocp import InitialGuess, OCPSolver, OptimalControlProblem, SolverOptions
from nhgait.ocp.derivatives import nlp_functions
from nhgait.ocp.supervision import Job, supervise

STATES, INPUTS = ("x", "y", "theta", "v", "w"), ("a", "omega")
N = 24


@dataclass(frozen=True, eq=False)
class _Model:
    numeric: NumericModel
    state_names: tuple


def _problem() -> OptimalControlProblem:
    """A unicycle with drag parks 1 m ahead and 0.5 m aside, at rest."""
    t, z, u, p = ca.SX.sym("t"), ca.SX.sym("z", 5), ca.SX.sym("u", 2), ca.SX.sym("p", 1)
    rhs = ca.vertcat(z[3] * ca.cos(z[2]), z[3] * ca.sin(z[2]), z[4], u[0] - p[0] * z[3] * z[4] * ca.sin(z[2]),
                     u[1] - 0.5 * ca.sin(z[0]) * z[3])
    functions = {"rhs": ca.Function("rhs", [t, z, u, p], [rhs]),
                 "qdot": ca.Function("qdot", [z, p], [rhs[:3]])}
    numeric = NumericModel("reduced", STATES, INPUTS, ("c",), (0.3,), functions, n_coordinates=3)
    return OptimalControlProblem(_Model(numeric, STATES), 3.0, N, initial={n: 0.0 for n in STATES},
                                 final={"x": 1.0, "y": 0.5, "theta": 0.0, "v": 0.0, "w": 0.0},
                                 control_bounds=3.0)


def _guess() -> InitialGuess:
    s = np.linspace(0.0, 1.0, N + 1)
    states = np.zeros((5, N + 1))
    states[0], states[1] = s, 0.5 * s
    return InitialGuess(states, np.zeros((2, N)), label="straight line")


def test_a_compiler_without_openmp_builds_without_the_flag(tmp_path, monkeypatch):
    """gcc given a wrapper that refuses -fopenmp: the library is built once more without it,
    and its record and flags say so (the key keeps the flags asked for)."""
    from nhgait.dynamics.numerics.compiler import Toolchain, build_library
    real = compiler_command()
    if real is None:
        pytest.skip("no C compiler")
    wrapper = tmp_path / "cc-without-openmp"
    wrapper.write_text("#!/bin/sh\nfor a in \"$@\"; do [ \"$a\" = -fopenmp ] && exit 1; done\n"
                       f"exec {' '.join(real)} \"$@\"\n")
    wrapper.chmod(0o755)
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    source = "double twice(double x) { return 2 * x; }\n"
    lib = build_library(source, Toolchain([str(wrapper)], ("-O1", openmp.FLAG)), salt="openmp test")
    assert lib.flags == ("-O1",) and not lib.cached
    again = build_library(source, Toolchain([str(wrapper)], ("-O1", openmp.FLAG)), salt="openmp test")
    assert again.cached and again.flags == ("-O1",) and again.path == lib.path


def test_idle_threads_sleep_unless_the_user_says(monkeypatch):
    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)
    openmp.before_load()
    assert openmp.WAIT_POLICY == "PASSIVE" and os.environ["OMP_WAIT_POLICY"] == "PASSIVE"
    monkeypatch.setenv("OMP_WAIT_POLICY", "ACTIVE")
    openmp.before_load()
    assert os.environ["OMP_WAIT_POLICY"] == "ACTIVE"


def test_share_of_the_cores(monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    one = openmp.share(1)
    assert one >= 1 and openmp.share(2) == max(1, one // 2) and openmp.share(10 ** 6) == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert openmp.share(1) == 1


def _c(function) -> str:
    generator = ca.CodeGenerator("nlp.c", {"with_header": False})
    generator.add(function)
    return generator.dump()


def test_parallel_maps_generate_casadis_threaded_maps_without_casadi_warning(capfd, monkeypatch):
    """Compiled code's stage maps are CasADi's threaded maps (dynamics/numerics/thread_maps.py):
    on two threads their C starts threads; serial maps start none, and neither has OpenMP."""
    from nhgait.ocp.transcription import MultipleShooting
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    nlp = MultipleShooting().build(_problem())
    parallel, serial = nlp_functions(nlp, parallel=True), nlp_functions(nlp)
    assert "WITH_THREAD" not in capfd.readouterr().err
    if tuple(int(v) for v in ca.__version__.split(".")[:2]) >= (3, 8) and openmp.share(1) >= 2:
        assert all("CASADI_THREAD_CREATE(" in _c(parallel[name]) for name in ("nlp_jac_g", "nlp_hess_l"))
    assert not any("CASADI_THREAD_CREATE(" in _c(serial[name]) for name in ("nlp_jac_g", "nlp_hess_l"))
    names = ("nlp_jac_g", "nlp_hess_l")
    assert not any("#pragma omp" in _c(f[name]) for f in (parallel, serial) for name in names)


@pytest.mark.skipif(compiler_command() is None, reason="no C compiler")
def test_child_solves_on_its_cores_after_the_parent_ran_the_library():
    problem, guess = _problem(), _guess()
    solver = OCPSolver(problem, None, SolverOptions(jit="optimised"))
    assert solver.compiled
    parent = solver.solve(guess)                  # the parent runs the library (one thread) ...
    assert parent.success and openmp.threads() == 1

    def child():                                  # ... then a child on its share of the cores
        s = solver.solve(guess)
        return openmp.threads(), s.success, s.iterations, s.objective, np.asarray(s.z)

    threads, success, iterations, objective, states = supervise(
        [Job(child, 30.0, lambda status, message, seconds: (0, False, 0, float("nan"), None))])[0]
    assert success, "the child did not finish (a hang after fork is killed at its limit)"
    assert threads == openmp.share(1)
    reference = OCPSolver(problem, None, SolverOptions(jit=False)).solve(guess)
    assert iterations == parent.iterations == reference.iterations
    assert objective == pytest.approx(reference.objective, rel=1e-9)
    assert objective == parent.objective          # one thread or several: the same sums
    np.testing.assert_allclose(states, np.asarray(reference.z), rtol=0, atol=1e-8)
