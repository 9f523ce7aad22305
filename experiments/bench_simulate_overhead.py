#!/usr/bin/env python3
"""What a ``simulate(..., method="compiled")`` call costs beyond its C integrator (issue 16).

The thesis's snakeboard PD run (10π s, the state of ``nhgait reproduce``) on the reduced ODE,
compiled DOP853 at rtol 1e-7: the whole ``simulate`` call, with every accepted step as output
(``t_eval=None``) and with ``t_eval=[0, T]``, against the time spent inside the C integrator
itself (``CompiledLoop.run``, measured by wrapping it during the same calls). The closed loop is
compiled and cached by a first call; the runs of the three rows take turns so that a shared
machine's load falls on all alike. Prints medians and ratios from one run and writes
``out/bench_simulate_overhead.json``. Compare the ratios, not the absolute times.

Usage: python experiments/bench_simulate_overhead.py [--repeats 31] [--rtol 1e-7]
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=31)
    parser.add_argument("--rtol", type=float, default=1e-7)
    parser.add_argument("--out", default="out/bench_simulate_overhead.json")
    args = parser.parse_args(argv)

    from nhgait.dynamics import builtin, derive, simulate
    from nhgait.dynamics.simulation.controllers import snakeboard_pd
    from nhgait.gaits.bench.reproduction import thesis_initial_state
    from nhgait.gaits.bench.work_precision import c_integrator_timer

    model = derive(builtin("snakeboard"), "reduced")
    controller = snakeboard_pd()
    q0, qdot0 = thesis_initial_state(model, controller, None)
    t_final = 10 * math.pi

    def call(t_eval):
        return simulate(model, (0.0, t_final), q0, qdot0, controller=controller, method="compiled",
                        rtol=args.rtol, atol=args.rtol * 1e-2, t_eval=t_eval)

    first = call(None)                      # compiles (or loads) the closed loop
    assert first.success, first.message
    rows = {"steps": None, "ends": [0.0, t_final]}
    wall = {k: [] for k in rows}
    inner = {k: [] for k in rows}
    n_out = {}
    with c_integrator_timer() as core:
        for _ in range(args.repeats):
            for name, t_eval in rows.items():
                core.clear()
                start = time.perf_counter()
                tr = call(t_eval)
                wall[name].append(time.perf_counter() - start)
                inner[name].append(sum(core))
                n_out[name] = len(tr.t)

    result = {}
    print(f"snakeboard PD, 10π s, compiled DOP853, rtol {args.rtol:g}; medians of {args.repeats} "
          f"({first.n_steps} accepted steps, {first.nfev} evaluations)")
    print(f"{'output':<22}{'call [ms]':>11}{'C integrator [ms]':>19}{'call / integrator':>19}")
    for name in rows:
        w, c = statistics.median(wall[name]), statistics.median(inner[name])
        result[name] = {"call_ms": 1e3 * w, "integrator_ms": 1e3 * c, "ratio": w / c, "outputs": n_out[name]}
        label = "every step" if name == "steps" else "t_eval = [0, T]"
        print(f"{label + f' ({n_out[name]})':<22}{1e3 * w:>11.2f}{1e3 * c:>19.2f}{w / c:>19.2f}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rtol": args.rtol, "repeats": args.repeats, "rows": result}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
