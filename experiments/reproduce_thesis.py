#!/usr/bin/env python3
"""Reproduce the thesis's simulations (§3.3) and compare every formulation with an independent
KanesMethod reference.

The reference integrates the Kane's-method oracle of ``tests/oracles.py`` (built from frames,
points and bodies with sympy.physics.mechanics, nothing shared with nhgait's derivations) with
scipy DOP853 at rtol = atol = 1e-12, under the same controller and initial state. Writes
``summary.json`` (with a ``kane`` run and its deviations) and the figures into ``--out``.

Usage::

    python experiments/reproduce_thesis.py [--out out/reproduce] [--rtol 1e-10] [--no-idas]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

REPO = Path(__file__).resolve().parents[1]
KANE_RTOL = 1e-12
KANE_ATOL = 1e-12


def _oracle(name):
    tests = str(REPO / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    from oracles import oracle  # noqa: E402  (tests/ is not a package of nhgait)
    return oracle(name)


def kane_reference(name, t_eval, q0, qdot0, controller, params=None):
    """KanesMethod + DOP853 (rtol 1e-12) solution on ``t_eval``.

    Parameters
    ----------
    name : built-in system name; t_eval : (N,) increasing times starting at the initial time;
    q0, qdot0 : (n,) consistent initial state; controller : u = controller(t, q, q̇);
    params : dict of parameter values overriding the system's defaults.

    Returns
    -------
    ("kane", q (N, n), info) with info = {"wall_time_s", "nfev", "success", "message", "method"}.
    """
    from nhgait.dynamics.derivation.models import builtin

    system = builtin(name)
    values = dict(zip((s.name for s in system.param_symbols), system.param_values, strict=True))
    values.update(params or {})
    o = _oracle(name)
    pv = np.array([float(values[p]) for p in o.parameters])
    n = len(o.coordinates)
    if tuple(o.coordinates) != tuple(system.coordinates) or tuple(o.inputs) != tuple(system.inputs):
        raise RuntimeError(f"oracle {name} orders q or u differently from the engine")

    def rhs(t, y):
        q, qd = y[:n], y[n:]
        return np.r_[qd, o.qddot(q, qd, controller(t, q, qd), pv)]

    start = time.perf_counter()
    sol = solve_ivp(rhs, (float(t_eval[0]), float(t_eval[-1])), np.r_[q0, qdot0], method="DOP853",
                    rtol=KANE_RTOL, atol=KANE_ATOL, t_eval=t_eval)
    info = {"wall_time_s": time.perf_counter() - start, "nfev": int(sol.nfev),
            "success": bool(sol.success), "message": sol.message,
            "method": f"KanesMethod + DOP853 (rtol {KANE_RTOL:g}, atol {KANE_ATOL:g})"}
    return "kane", sol.y[:n].T, info


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/reproduce", help="output folder (default out/reproduce)")
    parser.add_argument("--rtol", type=float, default=1e-10, help="engine tolerance (default 1e-10)")
    parser.add_argument("--no-idas", action="store_true", help="skip the IDAS runs")
    args = parser.parse_args(argv)

    from nhgait.gaits.bench.reproduction import reproduce
    from nhgait.gaits.cli.reproduce import print_summary

    summary = reproduce(args.out, rtol=args.rtol, idas=not args.no_idas, reference=kane_reference)
    print_summary(summary)
    print(f"wrote {Path(args.out) / 'summary.json'} and the figures")
    ok = all(run.get("success", True) for name in ("unicycle", "snakeboard")
             for run in summary[name]["runs"].values())
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
