"""Benchmark: the symmetry search and the whole reduced derivation against the number of
coordinates, with the fibre given and without.

The systems are n − 3 free particles beside a knife edge (x, y, θ) — every coordinate but θ is
cyclic, so every one of the 2ⁿ − 1 subsets is a candidate fibre: the worst case of the search
(issue 29: n = 16 took 50 s and n = 20 more than 120 s before the search honoured ``fiber``).
For each n: the symmetry test alone and ``derive(..., "reduced", use_cache=False)``, medians of
``--repeats`` runs with sympy's cache cleared, and the number of candidate rows tested. In one
run, also the full enumeration (every subset) up to ``--full-up-to`` coordinates, as the
reference the pruned search must agree with (same chosen fibre).

Usage: python experiments/bench_symmetry.py [--sizes 12,16,20,40] [--repeats 3] [--full-up-to 12]
       [--json out/bench_symmetry.json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path


def particles(n: int, fiber: bool):
    """The knife edge with n − 3 free particles (unit masses); ``fiber``: x, y and the particles."""
    from nhgait.dynamics import System
    names = ["x", "y", "theta"] + [f"z{i}" for i in range(n - 3)]
    kinetic = " + ".join(f"m*{c}_dot**2/2" for c in names if c != "theta")
    return System(coordinates=names, lagrangian=f"{kinetic} + I*theta_dot**2/2",
                  constraints=["sin(theta)*x_dot - cos(theta)*y_dot"], parameters={"m": 1.0, "I": 0.1},
                  fiber=[c for c in names if c != "theta"] if fiber else None, name=f"particles_{n}")


def _median_time(fn, repeats: int) -> tuple[float, object]:
    from sympy.core.cache import clear_cache
    times, out = [], None
    for _ in range(repeats):
        clear_cache()
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def measure(n: int, fiber: bool, repeats: int, full_up_to: int) -> dict:
    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation import symmetry
    system = particles(n, fiber)
    test_s, test = _median_time(lambda: symmetry.symmetry_test(system), repeats)
    derive_s, _ = _median_time(lambda: derive(system, "reduced", use_cache=False), repeats)
    row = {"n": n, "fiber given": fiber, "symmetry test s": round(test_s, 3), "derive s": round(derive_s, 3),
           "candidates tested": len(test.candidates), "subsets": 2 ** n - 1,
           "chosen": list(test.chosen.fiber)}
    if not fiber and n <= full_up_to:
        limit = symmetry.FULL_TABLE_MAX_N
        symmetry.FULL_TABLE_MAX_N = n
        try:
            full_s, full = _median_time(lambda: symmetry.symmetry_test(system), 1)
        finally:
            symmetry.FULL_TABLE_MAX_N = limit
        row.update({"full enumeration s": round(full_s, 3), "same choice as the full enumeration":
                    full.chosen.fiber == test.chosen.fiber})
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="12,16,20,40")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--full-up-to", type=int, default=12)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        for fiber in (True, False):
            row = measure(n, fiber, args.repeats, args.full_up_to)
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
