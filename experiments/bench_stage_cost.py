#!/usr/bin/env python3
"""Where a warm solve's function time goes: the NLP functions per call, and the structured stage's
pieces per interval (issue 25).

For one member of ``experiments/scale_tasks.py`` (default ``cart_trailers_6``) the planner's NLP
is built as ``nhgait plan`` builds it (the task's N, the structured stage), compiled with the
flags the compile budget gives its C (``ocp.nlp_code.COMPILE_BUDGET``), and each Ipopt function
(``nlp_f``, ``nlp_g``, ``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l``) is timed at one point. The
stage's pieces — ``stage`` (F), ``stage_jac`` (F, J), ``stage_hess`` (∇²λᵀF) and the SX functions
they call at each of the 4M RK points, ``g_jac`` and ``g_hess`` — are timed per call through a
map over ``--calls`` points in one compiled library each (so that Python's call overhead is
amortised), with the same flags; "instructions" are CasADi's (the MX functions': calls and
glue; the SX functions': scalar operations). Prints the best of ``--repeats`` timings (µs or ms per call),
``glue`` = stage_hess − 4M (g_jac + g_hess): the MX code between the calls, and writes
``out/bench_stage_cost.json``. ``--interpreted`` runs CasADi's virtual machine instead of compiled
code (the smoke test).

Usage: python experiments/bench_stage_cost.py [--member cart_trailers_6] [--calls 200]
       [--repeats 5] [--interpreted]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import sibling

NLP_FUNCTIONS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")
STAGE_PIECES = ("stage", "stage_jac", "stage_hess", "g_jac", "g_hess")


def _problem(member: str):
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.tasks.sources import resolve
    scene = scene_from_text(sibling.load("scale_tasks").scene_with_task(member), member)
    return prepare(resolve(scene)).problem


def _compiled(functions: list, name: str, interpreted: bool) -> tuple:
    """(the functions, loaded from one library compiled with the budget's flags, the flags)."""
    import casadi as ca

    from nhgait.dynamics.numerics.compiler import Toolchain, build_library
    from nhgait.ocp.nlp_code import COMPILE_BUDGET
    if interpreted:
        return functions, None
    cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    for f in functions:
        cg.add(f)
    source = cg.dump()
    flags = COMPILE_BUDGET.choose(len(source))[0] or ("-O0",)
    lib = build_library(source, Toolchain(flags=flags), salt=f"bench_stage_cost casadi {ca.__version__}",
                        label=f"compile {len(source) / 1e6:.2f} MB of C with {' '.join(flags)}")
    return [ca.external(f.name(), str(lib.path)) for f in functions], flags


def _best(f, args, repeats: int, per: int) -> float:
    """The best of ``repeats`` timings of ``f(*args)``, seconds per one of its ``per`` calls."""
    f(*args)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f(*args)
        times.append(time.perf_counter() - t0)
    return min(times) / per


def measure(member: str, calls: int, repeats: int, interpreted: bool) -> dict:
    import numpy as np

    from nhgait.ocp import OCPSolver, SolverOptions
    problem = _problem(member)
    solver = OCPSolver(problem, None, SolverOptions(jit=False))
    plain = solver.solver
    nlp_fns, flags = _compiled([plain.get_function(n) for n in NLP_FUNCTIONS], "bench_nlp", interpreted)
    stage = solver.nlp.layout.terms[0].functions
    if stage.mode != "structured":
        raise SystemExit(f"{member}: its stage is {stage.mode}; the pieces are those of a structured stage")
    pieces = {"stage": stage.step, "stage_jac": stage.jacobian, "stage_hess": stage.hessian,
              "g_jac": stage.hessian.get_function("g_jac"), "g_hess": stage.hessian.get_function("g_hess")}
    mapped, _ = _compiled([pieces[n].map(calls, "serial") for n in STAGE_PIECES], "bench_stage", interpreted)
    rng = np.random.default_rng(0)
    x = rng.normal(size=solver.nlp.n_w) * 0.1
    n_g = int(solver.nlp.g.shape[0])
    row = {"member": member, "flags": list(flags) if flags else None, "intervals": problem.intervals,
           "rk_points": 4 * stage.steps, "ode_operations": stage.ode_operations}
    for name, f in zip(NLP_FUNCTIONS, nlp_fns, strict=True):
        args = [x, []] + ([1.0, np.ones(n_g)] if name == "nlp_hess_l" else [])
        row[f"{name}_ms"] = _best(f, args, repeats, 1) * 1e3
    for name, f in zip(STAGE_PIECES, mapped, strict=True):
        args = [rng.normal(size=f.size_in(i)) * 0.1 for i in range(f.n_in())]
        row[f"{name}_us"] = _best(f, args, repeats, calls) * 1e6
        row[f"{name}_instructions"] = int(pieces[name].n_instructions())
    points = row["rk_points"]
    row["glue_us"] = row["stage_hess_us"] - points * (row["g_jac_us"] + row["g_hess_us"])
    return row


def _print(row: dict) -> None:
    code = " ".join(row["flags"]) if row["flags"] else "interpreted"
    print(f"# {row['member']}: N = {row['intervals']}, {row['rk_points']} RK points per interval, "
          f"ops(f) = {row['ode_operations']}, code: {code}")
    print("NLP function    ms per call")
    for name in NLP_FUNCTIONS:
        print(f"{name:14s}  {row[name + '_ms']:10.3f}")
    print("stage piece     µs per call  instructions")
    for name in STAGE_PIECES:
        print(f"{name:14s}  {row[name + '_us']:10.2f}  {row[name + '_instructions']:12d}")
    p, h = row["rk_points"], row["stage_hess_us"]
    print(f"stage_hess = {p} × g_hess ({p * row['g_hess_us'] / h:.0%}) + {p} × g_jac "
          f"({p * row['g_jac_us'] / h:.0%}) + glue ({row['glue_us'] / h:.0%})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--member", default="cart_trailers_6")
    ap.add_argument("--calls", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--interpreted", action="store_true")
    ap.add_argument("--out", default="out/bench_stage_cost.json")
    args = ap.parse_args(argv)
    row = measure(args.member, args.calls, args.repeats, args.interpreted)
    _print(row)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(row, indent=1))
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
