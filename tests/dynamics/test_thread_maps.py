"""The stage maps on threads: CasADi's own threaded map (dynamics/numerics/thread_maps.py).

The reference is a closed form written with numpy (and CasADi's virtual machine), to 1e-13 —
and any block count, run on threads or in the calling thread (the grant), gives the same bits
as the serial map, since each point's arithmetic is unchanged (blocks of consecutive points,
the last padded when the count does not divide the points). Compiled by every compiler found
(the fast one and the optimising one); none found: those tests skip, and the map still
evaluates in CasADi's virtual machine.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics import openmp
from nhgait.dynamics.numerics.compiler import Toolchain, build_library, compiler_command
from nhgait.dynamics.numerics.fast_compiler import fast_compiler
from nhgait.dynamics.numerics.thread_maps import CREATE, map_threads, threaded_map, with_grant

POINTS = 7      # an odd count: blocks of unequal length, the last one padded
CASADI_3_8 = tuple(int(v) for v in ca.__version__.split(".")[:2]) >= (3, 8)


def _point() -> ca.Function:
    """A point function with a value and its Jacobian (the shape of the planner's stage maps)."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p")
    value = ca.vertcat(ca.sin(x[0] * x[1]) + p * x[2] ** 2, ca.exp(-x[2]) * ca.cos(x[0]))
    return ca.Function("point", [x, p], [value, ca.jacobian(value, x)])


def _mapped(threads: int) -> ca.Function:
    """The sum over the 7 columns of the point's value, and the mapped Jacobians, on ``threads``."""
    X, P = ca.MX.sym("X", 3, POINTS), ca.MX.sym("P", 1, POINTS)
    values, jacobians = threaded_map(_point(), POINTS, threads)(X, P)
    return ca.Function("stage_sum", [X, P], [ca.sum2(values), jacobians])


def _closed_form(X: np.ndarray, P: np.ndarray) -> list:
    """The same two outputs written out with numpy (an independent reference)."""
    x0, x1, x2, p = X[0], X[1], X[2], P[0]
    values = np.vstack([np.sin(x0 * x1) + p * x2 ** 2, np.exp(-x2) * np.cos(x0)])
    jac = np.zeros((2, 3 * POINTS))
    for k in range(POINTS):
        c = np.cos(x0[k] * x1[k])
        jac[:, 3 * k:3 * k + 3] = [[x1[k] * c, x0[k] * c, 2 * p[k] * x2[k]],
                                   [-np.exp(-x2[k]) * np.sin(x0[k]), 0.0, -np.exp(-x2[k]) * np.cos(x0[k])]]
    return [values.sum(axis=1, keepdims=True), jac]


def _source(function: ca.Function) -> str:
    generator = ca.CodeGenerator("maps.c", {"with_header": False})
    generator.add(function)
    return generator.dump()


def _inputs():
    rng = np.random.default_rng(3)
    return rng.uniform(-1.5, 1.5, (3, POINTS)), rng.uniform(0.2, 2.0, (1, POINTS))


def _compilers() -> list:
    found = []
    fast = fast_compiler()
    if fast is not None:
        found.append(pytest.param((fast.command, fast.flags, fast.libs), id="fast"))
    if compiler_command() is not None:
        found.append(pytest.param((None, ("-O1",), ("-lm",)), id="optimising"))
    return found or [pytest.param(None, marks=pytest.mark.skip(reason="no C compiler"))]


def test_the_threaded_map_agrees_with_a_closed_form_in_casadis_virtual_machine():
    X, P = _inputs()
    for threads in (1, 2, 3, POINTS):
        for got, want in zip(_mapped(threads)(X, P), _closed_form(X, P), strict=True):
            np.testing.assert_allclose(np.asarray(got), want, rtol=1e-13, atol=1e-14)


@pytest.fixture
def granted():
    """Restore the process's grant (one thread) after a test that changes it."""
    yield openmp.grant
    openmp.grant(1)


@pytest.mark.parametrize("compiler", _compilers())
def test_compiled_threaded_maps_give_the_serial_bits_on_any_grant(compiler, tmp_path, monkeypatch, granted):
    """Blocks 1, 2, 3 and 7, the library's count set by the grant (1: the blocks in the calling
    thread; 2 and 64: on threads): the same bits as the serial map, which meets the closed form."""
    import ctypes
    import os
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    command, flags, libs = compiler
    X, P = _inputs()
    reference = [np.asarray(v) for v in _mapped(1)(X, P)]
    for want, closed in zip(reference, _closed_form(X, P), strict=True):
        np.testing.assert_allclose(want, closed, rtol=1e-13, atol=1e-14)
    for threads in (1, 2, 3, POINTS):
        source = with_grant(_source(_mapped(threads)))
        lib = build_library(source, Toolchain(command, flags, libs), salt="thread maps test")
        compiled = ca.external("stage_sum", str(lib.path))
        openmp.limit(lib.path)
        for grant in (1, 2, 64):
            granted(grant)
            if threads > 1 and CASADI_3_8:                    # the grant reaches the loaded library
                count = ctypes.c_int.in_dll(ctypes.CDLL(str(lib.path), mode=os.RTLD_NOLOAD),
                                            openmp.THREADS_SYMBOL)
                assert count.value == grant
            answer = [np.asarray(v) for v in compiled(X, P)]
            assert all(np.array_equal(a, b) for a, b in zip(answer, reference, strict=True)), (threads, grant)


@pytest.mark.skipif(not CASADI_3_8, reason="CasADi < 3.8 generates the serial loop")
def test_casadi_generates_threads_for_the_map():
    """The speed rests on CasADi's ThreadMap code generation (CasADi ≥ 3.8) and the grant on its
    macros being overridable: fail loudly if a CasADi release stops generating the thread
    creation for a threaded map or defines the macros unconditionally (then the prelude's are
    not used and the library ignores the grant)."""
    source = _source(_mapped(2))
    assert CREATE + "threads[i]" in source and "CASADI_THREAD_JOIN(threads[i])" in source
    for macro in ("CASADI_THREAD_HANDLE", "CASADI_THREAD_CREATE", "CASADI_THREAD_JOIN"):
        assert f"#ifndef {macro}" in source, macro
    assert CREATE not in _source(_mapped(1))                         # one thread: the serial map
    serial = _source(_mapped(1))
    assert with_grant(source).startswith("/* nhgait") and with_grant(serial) == serial


def test_the_thread_count_is_the_usable_cores_capped_by_the_points_and_the_user(monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    cores = openmp.share(1)
    assert map_threads(10 ** 6) == cores and map_threads(1) == 1 and map_threads(0) == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert map_threads(50) == 1
    assert "CASADI_THREAD_CREATE" not in _source(_mapped(map_threads(POINTS)))
