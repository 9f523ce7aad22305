"""Benchmark (issue 8): how the reduced derivation scales with the system.

For every member of the families of ``experiments/scaling_systems.py`` (cart with k trailers,
wheeled N-link snake with and without a head rotor, the issue's two reproduction cases) and
the thesis systems, in one run:

* cold ``derive(system, "reduced")`` time (symbolic steps + CasADi functions, no cache; sympy's
  cache and nhgait's memo cleared before every repeat), median of ``--repeats``;
* ``nhgait derive <scene> --no-cache`` wall time (a fresh process: imports, derivation,
  printing), median; and the in-process printing time of ``to_text()``;
* ``LagrangesMethod`` (form_lagranges_equations + rhs()) and ``KanesMethod``
  (kanes_equations) on the independent physical models of ``tests/oracles.py``, medians, each
  capped at ``--cap`` seconds;
* the operation count of the CasADi right-hand side ż = f(t, z, u, params);
* oracle agreement: max relative |q̈ − q̈_Kane| at 100 random consistent states (of 120
  random configurations, the 20 nearest the singular set are dropped).

Writes a JSON file, a PNG (derivation time and RHS operations against n) and prints a table.
Usage: python experiments/bench_scaling.py [--repeats 3] [--members a,b] [--out out/bench_scaling]
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "experiments"))

BUILTINS = ("unicycle", "snakeboard")


def _fresh():
    from sympy.core.cache import clear_cache

    from nhgait.dynamics.algebra.trig import forget_normal_forms
    clear_cache()
    forget_normal_forms()


class _Timeout(Exception):
    pass


def _capped(fn, cap):
    """fn() with a wall-clock cap (SIGALRM); returns seconds or None when capped."""
    def alarm(*_):
        raise _Timeout
    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(int(cap))
    t0 = time.perf_counter()
    try:
        fn()
        return time.perf_counter() - t0
    except _Timeout:
        return None
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _median(fn, repeats, cap):
    times = []
    for _ in range(repeats):
        _fresh()
        t = _capped(fn, cap)
        if t is None:
            return None
        times.append(t)
    return statistics.median(times)


def _system(name):
    if name in BUILTINS:
        from nhgait.dynamics import builtin
        return builtin(name)
    import scaling_systems
    return scaling_systems.system(name)


def _scene_text(name):
    if name in BUILTINS:
        return (ROOT / "dynamics" / "derivation" / "scenes" / f"{name}.toml").read_text()
    import scaling_systems
    return scaling_systems.scene_text(name)


def _mechanics(name, kind):
    """A callable that runs sympy's LagrangesMethod (equations + rhs()) or KanesMethod on the
    oracle's physical description of ``name`` (timed from the description onwards)."""
    import oracles
    from sympy.physics.mechanics import LagrangesMethod, Lagrangian

    def run():
        mdl = oracles.model_description(name)
        if kind == "lagrange":
            lm = LagrangesMethod(Lagrangian(mdl["N"], *mdl["bodies"]), mdl["q"], forcelist=mdl["loads"],
                                 frame=mdl["N"], nonhol_coneqs=mdl["constraints"])
            lm.form_lagranges_equations()
            lm.rhs()
            return
        oracles.kanes_method(mdl, mdl["dependent_sets"][0])
    return run


def _cli_time(name, repeats, cap):
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / f"{name}.toml"
        scene.write_text(_scene_text(name))
        env = dict(os.environ, NHGAIT_CACHE_DIR=str(Path(tmp) / "cache"))
        exe = [sys.executable, "-m", "nhgait.gaits.cli.main"] if not _has_script() else [_script()]
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            try:
                subprocess.run(exe + ["derive", str(scene), "--no-cache"], env=env, check=True,
                               capture_output=True, timeout=cap)
            except subprocess.TimeoutExpired:
                return None
            times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _script():
    return str(Path(sys.executable).parent / "nhgait")


def _has_script():
    return Path(_script()).exists()


def measure(name, repeats, cap, cli=True, agreement=True):
    """One member's row of the table (times in seconds, None when capped)."""
    from nhgait.dynamics import derive
    system = _system(name)
    row = {"name": name, "n": system.n, "k": system.k}
    row["derive_s"] = _median(lambda: derive(system, "reduced", use_cache=False), repeats, cap)
    model = derive(system, "reduced", use_cache=False)
    row["form"] = model.form
    row["rhs_ops"] = int(model.numeric["rhs"].n_instructions())
    t0 = time.perf_counter()
    model.to_text()
    row["print_s"] = time.perf_counter() - t0
    row["cli_s"] = _cli_time(name, repeats, cap) if cli else None
    row["lagrange_s"] = _median(_mechanics(name, "lagrange"), repeats, cap)
    row["kane_s"] = _median(_mechanics(name, "kane"), repeats, cap)
    if agreement:
        from oracles import agreement as oracle_agreement
        from oracles import oracle
        row["oracle_error"] = oracle_agreement(system, model, oracle(name))
    else:
        row["oracle_error"] = None
    return row


def _ratio(a, b):
    return None if a is None or b is None else a / b


def _fmt(x, spec=".3f"):
    return "—" if x is None else format(x, spec)


def table(rows, cap) -> str:
    head = ("| member | n | k | form | derive (s) | ÷ Lagrange+rhs | ÷ Kane | print (s) | CLI (s) | "
            "RHS ops | q̈ error vs Kane |\n|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        lag = (_fmt(_ratio(r["derive_s"], r["lagrange_s"]), ".2f") if r["lagrange_s"]
               else f"> cap ({cap:.0f} s)")
        lines.append(f"| {r['name']} | {r['n']} | {r['k']} | {r['form']} | {_fmt(r['derive_s'])} | {lag} | "
                     f"{_fmt(_ratio(r['derive_s'], r['kane_s']), '.2f')} | {_fmt(r['print_s'])} | "
                     f"{_fmt(r['cli_s'], '.2f')} | {r['rhs_ops']} | {_fmt(r['oracle_error'], '.1e')} |")
    return "\n".join(lines)


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    fams = {"cart_trailers": "cart + k trailers", "snake_rotor": "snake + rotor", "snake": "N-link snake"}
    for key, label in fams.items():
        sel = [r for r in rows if r["name"].startswith(key + "_") and
               (key != "snake" or not r["name"].endswith("_rotor"))]
        sel.sort(key=lambda r: r["n"])
        if not sel:
            continue
        n = [r["n"] for r in sel]
        a1.plot(n, [r["derive_s"] for r in sel], "o-", label=f"{label}: nhgait reduced")
        a1.plot(n, [r["lagrange_s"] for r in sel], "x--", label=f"{label}: LagrangesMethod+rhs")
        a2.plot(n, [r["rhs_ops"] for r in sel], "o-", label=label)
    nn = np.arange(4, 12)
    a2.plot(nn, 60 * nn ** 2, "k:", label="∝ n² (reference)")
    a2.plot(nn, 6 * nn ** 3, "k-.", label="∝ n³ (reference)")
    for ax, title, ylabel in ((a1, "cold derivation", "seconds"),
                              (a2, "CasADi right-hand side", "operations")):
        ax.set_yscale("log")
        ax.set_xlabel("n (coordinates)")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    import scaling_systems
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cap", type=float, default=120.0, help="seconds per timed call")
    ap.add_argument("--members", default=None, help="comma-separated names (default: all)")
    ap.add_argument("--no-cli", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "out" / "bench_scaling"))
    args = ap.parse_args(argv)
    names = args.members.split(",") if args.members else \
        list(BUILTINS) + [m for fam in scaling_systems.FAMILIES.values() for m in fam]
    rows = []
    for name in names:
        row = measure(name, args.repeats, args.cap, cli=not args.no_cli)
        rows.append(row)
        print(f"{name}: {row}", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_scaling.json").write_text(json.dumps(rows, indent=2))
    plot(rows, out / "bench_scaling.png")
    print(f"\nmedians of {args.repeats}, one run, machine shared; ratios = nhgait derive / reference")
    print(table(rows, args.cap))
    print(f"\nwrote {out / 'bench_scaling.json'} and {out / 'bench_scaling.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
