"""Benchmark: derivation time of each formulation against sympy's KanesMethod and
LagrangesMethod on the same systems, in the same run, plus the cached reload time.

Each timing is the median of ``--repeats`` runs; sympy's global cache and nhgait's memo of
simplified expressions are cleared before every run, so no run profits from an earlier one.
The Kane and Lagrange models are the independent physical models of ``tests/oracles.py``
(frames, bodies, contact-point constraints), timed from model construction to
``kanes_equations`` / ``form_lagranges_equations``.

Usage: python experiments/bench_derivation.py [--repeats 5] [--systems unicycle,snakeboard]
       [--json out/bench_derivation.json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def _fresh():
    from sympy.core.cache import clear_cache

    from nhgait.dynamics.algebra.trig import forget_normal_forms
    clear_cache()
    forget_normal_forms()


def _kane(name):
    import oracles
    mdl = oracles.model_description(name)
    return oracles.kanes_method(mdl, mdl["dependent_sets"][0])


def _lagrange(name):
    import oracles
    from sympy.physics.mechanics import LagrangesMethod, Lagrangian
    mdl = oracles._MODELS[name]()
    L = Lagrangian(mdl["N"], *mdl["bodies"])
    lm = LagrangesMethod(L, mdl["q"], forcelist=mdl["loads"], frame=mdl["N"],
                         nonhol_coneqs=mdl["constraints"])
    lm.form_lagranges_equations()
    return lm


def _ours(formulation):
    def run(name):
        from nhgait.dynamics import builtin
        from nhgait.dynamics.derivation.hamilton import derive_hamiltonian
        from nhgait.dynamics.derivation.lagrange import derive_lagrangian
        from nhgait.dynamics.derivation.reduction import derive_reduced
        system = builtin(name)
        return {"reduced": derive_reduced, "lagrange": derive_lagrangian,
                "hamilton": derive_hamiltonian}[formulation](system)
    return run


def _time(fn, name, repeats):
    times = []
    for _ in range(repeats):
        _fresh()
        t0 = time.perf_counter()
        fn(name)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


def _reload_times(name, repeats):
    """(in-process derive() with a warm cache, whole fresh process incl. imports) medians."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NHGAIT_CACHE_DIR=cache)
        code = ("import time; t0 = time.perf_counter(); from nhgait.dynamics import derive, builtin; "
                f"s = builtin({name!r}); t1 = time.perf_counter(); m = derive(s); m.numeric; "
                "t2 = time.perf_counter(); print(t2 - t1, t2 - t0)")
        subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True)  # fill
        inproc, whole = [], []
        for _ in range(repeats):
            out = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                                 capture_output=True, text=True).stdout.split()
            inproc.append(float(out[0]))
            whole.append(float(out[1]))
    return statistics.median(inproc), statistics.median(whole)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--systems", default="unicycle,snakeboard")
    ap.add_argument("--json", default=str(ROOT / "out" / "bench_derivation.json"))
    args = ap.parse_args(argv)
    methods = {"KanesMethod": _kane, "LagrangesMethod": _lagrange,
               "nhgait reduced (20 steps)": _ours("reduced"),
               "nhgait lagrange DAE": _ours("lagrange"), "nhgait hamilton DAE": _ours("hamilton")}
    results = {}
    for name in args.systems.split(","):
        results[name] = {}
        for label, fn in methods.items():
            med, all_ = _time(fn, name, args.repeats)
            results[name][label] = {"median_s": med, "runs_s": all_}
        rin, rwhole = _reload_times(name, args.repeats)
        results[name]["cached reload (derive call)"] = {"median_s": rin}
        results[name]["cached reload (fresh process, incl. imports)"] = {"median_s": rwhole}
    print(f"derivation time, median of {args.repeats} (s); ratio = time / KanesMethod")
    for name, rows in results.items():
        kane = rows["KanesMethod"]["median_s"]
        print(f"\n{name}")
        for label, r in rows.items():
            print(f"  {label:48s} {r['median_s']:8.3f}   x{r['median_s'] / kane:6.2f}")
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(f"\nwrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
