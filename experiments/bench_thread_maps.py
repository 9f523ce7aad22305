#!/usr/bin/env python3
"""What running a planner's stage maps on several threads buys, per compiler and map mode (issue 44).

A planner's NLP function time is almost all the stage Jacobian and Hessian mapped over the N
intervals (``ocp/derivatives.py``). This script times one such pair of maps — the Jacobian and
the Lagrangian Hessian of an RK4 step (``--substeps`` sub-steps) of a chain of ``--links`` coupled
pendulum-like joints (2 × links states, links inputs: trigonometric coupling of every joint with
its neighbours, the shape of a wheeled snake's reduced dynamics), mapped over ``--intervals``
points — generated as C by CasADi and compiled by each compiler found:

* ``serial`` — ``Function.map(N, "serial")``: one loop;
* ``thread`` — ``Function.map(N, "thread", T)``: CasADi's own threaded map (its generated C
  starts T POSIX threads per call and joins them, CasADi ≥ 3.8), T = the usable cores, with the
  planner's thread macros in front (``thread_maps.with_grant``; this process is granted T);
* ``openmp`` — ``Function.map(N, "openmp")`` compiled with ``-fopenmp`` (gcc only; the Tiny C
  Compiler ignores the pragma: the serial loop).

Each variant's answer is checked against CasADi's virtual machine (serial map) to 1e-12 before
it is timed. Prints the median of ``--repeats`` calls (interleaved) and the ratio serial/variant
per compiler. Ratios are measured in one run on one machine; compare ratios, not absolute times.

Usage: python experiments/bench_thread_maps.py [--links 5] [--intervals 50] [--substeps 2]
       [--repeats 21] [--no-gcc]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time

import casadi as ca
import numpy as np

from nhgait.dynamics.numerics import openmp
from nhgait.dynamics.numerics.compiler import CompilerUnavailable, Toolchain, build_library, compiler_command
from nhgait.dynamics.numerics.fast_compiler import fast_compiler
from nhgait.dynamics.numerics.thread_maps import threaded_map, with_grant


def stage(links: int, substeps: int, h: float = 0.05) -> tuple:
    """(Jacobian function, Hessian function) of one RK4 step of the chain (module docstring):
    ``jac(x, u) -> (F, dF/d[x;u])``, ``hess(x, u, lam) -> d²(lamᵀF)/d[x;u]²``."""
    q, v, u = ca.SX.sym("q", links), ca.SX.sym("v", links), ca.SX.sym("u", links)

    def rhs(q, v):
        acc = []
        for j in range(links):
            left = ca.sin(q[j] - q[j - 1]) * v[j - 1] ** 2 if j > 0 else 0
            right = ca.sin(q[j] - q[j + 1]) * v[j + 1] ** 2 if j + 1 < links else 0
            acc.append(u[j] - 0.3 * v[j] - ca.sin(q[j]) - 0.5 * (left + right) * ca.cos(q[j]))
        return v, ca.vertcat(*acc)

    z = ca.vertcat(q, v)
    x = z
    for _ in range(substeps):
        k1 = ca.vertcat(*rhs(x[:links], x[links:]))
        k2 = ca.vertcat(*rhs(*(ca.vertsplit(x + h / 2 * k1, [0, links, 2 * links]))))
        k3 = ca.vertcat(*rhs(*(ca.vertsplit(x + h / 2 * k2, [0, links, 2 * links]))))
        k4 = ca.vertcat(*rhs(*(ca.vertsplit(x + h * k3, [0, links, 2 * links]))))
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    w = ca.vertcat(z, u)
    lam = ca.SX.sym("lam", 2 * links)
    jac = ca.Function("stage_jac", [z, u], [x, ca.jacobian(x, w)])
    hess = ca.Function("stage_hess", [z, u, lam], [ca.tril(ca.hessian(ca.dot(lam, x), w)[0])])
    return jac, hess


def mapped(jac, hess, n: int, mode: str, threads: int) -> ca.Function:
    """One function evaluating both maps over n points (as ``nlp_hess_l`` + ``nlp_jac_g``)."""
    Z, U, L = (ca.MX.sym(name, f.size1_in(i), n) for name, f, i in (("Z", jac, 0), ("U", jac, 1),
                                                                      ("L", hess, 2)))
    if mode == "thread":
        mj, mh = threaded_map(jac, n, threads), threaded_map(hess, n, threads)
    else:
        mj, mh = (openmp.parallel_map(f, n) if mode == "openmp" else f.map(n, "serial") for f in (jac, hess))
    F, J = mj(Z, U)
    return ca.Function("maps", [Z, U, L], [F, J, mh(Z, U, L)])


def compiled(function: ca.Function, command, flags, libs) -> ca.Function:
    generator = ca.CodeGenerator("maps.c", {"with_header": False})
    generator.add(function)
    lib = build_library(with_grant(generator.dump()), Toolchain(command, flags, libs),
                        salt="bench_thread_maps")
    out = ca.external("maps", str(lib.path))
    openmp.limit(lib.path)
    return out


def median_ms(function, args, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        function(*args)
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--links", type=int, default=5)
    parser.add_argument("--intervals", type=int, default=50)
    parser.add_argument("--substeps", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--no-gcc", action="store_true", help="the fast compiler only (gcc takes minutes)")
    args = parser.parse_args(argv)
    os.environ.setdefault("NHGAIT_CACHE_DIR", tempfile.mkdtemp(prefix="nhgait-bench-thread-maps-"))
    threads = openmp.share(1)
    openmp.before_load()
    openmp.grant(threads)
    jac, hess = stage(args.links, args.substeps)
    n = args.intervals
    rng = np.random.default_rng(0)
    inputs = [rng.uniform(-1, 1, (jac.size1_in(0), n)), rng.uniform(-1, 1, (jac.size1_in(1), n)),
              rng.uniform(-1, 1, (hess.size1_in(2), n))]
    reference = [np.asarray(v) for v in mapped(jac, hess, n, "serial", 1)(*inputs)]
    compilers = []
    fast = fast_compiler()
    if fast is not None:
        compilers.append((fast.name, fast.command, fast.flags, fast.libs, ("serial", "thread")))
    if compiler_command() is not None and not args.no_gcc:
        compilers.append(("gcc -O1", None, ("-O1",), ("-lm",), ("serial", "thread")))
        compilers.append(("gcc -O1 -fopenmp", None, ("-O1", openmp.FLAG), ("-lm",), ("openmp",)))
    print(f"stage maps: {args.links} links ({2 * args.links} states), RK4 x {args.substeps}, "
          f"{n} intervals; threads T = {threads}; median of {args.repeats} calls", file=sys.stderr)
    functions = {}
    for label, command, flags, libs, modes in compilers:
        for mode in modes:
            try:
                f = compiled(mapped(jac, hess, n, mode, threads), command, flags, libs)
            except CompilerUnavailable as exc:
                print(f"{label} {mode}: {exc}", file=sys.stderr)
                continue
            for got, want in zip((np.asarray(v) for v in f(*inputs)), reference, strict=True):
                np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
            functions[(label, mode)] = f
    times = {key: [] for key in functions}
    for _ in range(3):                                       # interleaved rounds
        for key, f in functions.items():
            times[key].append(median_ms(f, inputs, args.repeats))
    print(f"{'compiler':20s} {'map':8s} {'median ms':>10s} {'serial/this':>12s}")
    for (label, mode), ms in times.items():
        base = label.replace(" -fopenmp", "")
        serial = statistics.median(times[(base, "serial")]) if (base, "serial") in times else float("nan")
        ms = statistics.median(ms)
        print(f"{label:20s} {mode:8s} {ms:10.2f} {serial / ms:12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
