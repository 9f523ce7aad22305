#!/usr/bin/env python3
"""Benchmark of ``nhgait sweep``: scaling with workers, Dask overhead, warm vs cold starts.

1. Throughput: a 40-point P1 sweep (unicycle parallel park, N = 50, final.y × final.theta,
   warm-started continuation) on the local process pool with 1 and with 2 workers; the pool
   is started and its workers import nhgait before the clock runs (model derivation and
   solver builds are inside the timing). Median wall time of ``--repeats`` runs each, the
   runs alternating 1, 2, 1, 2, …; ratio = time(1 worker) / time(2 workers); and how many
   points ran at once on average (the points' own wall times over the sweep's).
2. Dask overhead per point: a realistic point (a P2 job with its warm start, answered with a
   solution-sized dict) sent through ``DaskBackend("local:1")`` to a function that does no
   work: seconds per point with 2 tasks in flight (as the sweep driver keeps them), minus
   the same call in this process (also: one isolated round trip), for tasks of 1, 2 and 4
   points (a sweep's continuation chains, ``--chain``), against the median Ipopt time of a
   P2 (snakeboard forward) N = 50 solve (the planner's ``plan``). How many points a task
   carries in a real sweep is counted on a 40-point P2 grid shaped like the issue's example
   (10 distances × 4 horizons), swept on ``DaskBackend("local:2")``.
3. Continuation: a P2 N = 50 grid (final.x × horizon) swept warm and cold (every point from
   the planner's guesses) on 2 workers; ratio of the Ipopt iterations summed over the points
   (every solve a point needed, failed candidates included).

Writes ``out/bench_sweep.json``. The machine's cores may be shared: quote the ratios measured
in one run.

Usage: python experiments/bench_sweep.py [--quick] [--repeats 3] [--out out/bench_sweep.json]
"""
from __future__ import annotations

import argparse
import json
import operator
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

_echo = operator.itemgetter(1)      # a picklable function that does no work: payload → answer
_carried = operator.attrgetter("warm")     # the same for a job carrying its answer as ``warm``


CHAINS = (1, 2, 4)


def _warm_up(backend) -> None:
    """Import nhgait's planner in every worker (not part of a sweep's timing)."""
    from nhgait.gaits.sweeps.backends import warm_up
    warm_up(backend)


def timed_sweep(case, grid, backend, *, warm_start=True):
    from nhgait.gaits.sweeps.driver import RunOptions, run_sweep
    from nhgait.gaits.sweeps.store import SweepStore
    with tempfile.TemporaryDirectory() as tmp, SweepStore(tmp) as store:
        t0 = time.perf_counter()
        # prepares the other workers
        result = run_sweep(case, grid, backend, store, RunOptions(warm_start=warm_start))
        return time.perf_counter() - t0, result


def throughput(repeats: int, axes) -> dict:
    from nhgait.gaits.sweeps.backends import ProcessPool
    from nhgait.gaits.sweeps.grid import parse_grid
    from nhgait.gaits.sweeps.point import describe_case
    case = describe_case("unicycle", "parallel-park", overrides=["intervals=50"])
    grid = parse_grid(axes)
    times = {1: [], 2: []}
    solved, busy = {}, {1: [], 2: []}
    for _ in range(repeats):
        for workers in (1, 2):
            with ProcessPool(workers) as pool:
                _warm_up(pool)
                wall, result = timed_sweep(case, grid, pool)
            times[workers].append(wall)
            solved[workers] = sum(r.success for r in result.records)
            busy[workers].append(sum(r.wall_time_s for r in result.records) / wall)
    med = {w: statistics.median(t) for w, t in times.items()}
    return {"points": grid.size, "grid": list(axes), "times_s": times, "median_s": med, "solved": solved,
            "speedup_2_over_1": med[1] / med[2],
            "concurrency": {w: statistics.median(b) for w, b in busy.items()}}


def dask_overhead(samples: int, solves: int, scene=("snakeboard", "forward")) -> dict:
    from nhgait.gaits.planner import plan
    from nhgait.gaits.sweeps.backends import DaskBackend
    from nhgait.gaits.sweeps.point import PointJob, describe_case, warm_data
    p2 = [plan(*scene, overrides=["intervals=50"], animate=False, jit=False) for _ in range(solves)]
    solve_s = statistics.median(r.solution.solve_time_s for r in p2)
    case = describe_case(*scene, overrides=["intervals=50"])
    solution = p2[-1].solution.to_dict()
    job = PointJob(case, "0-0", case.task, case.params, warm_data(solution), "0-1")
    answer = {"solution": solution, "warm": warm_data(solution), "objective": solution["objective"]}
    payload = (job, answer)
    local = []
    for _ in range(samples):
        t0 = time.perf_counter()
        _echo(payload)
        local.append(time.perf_counter() - t0)
    trips, pipelined = [], {k: [] for k in CHAINS}
    with DaskBackend("local:1") as backend:
        backend.submit(_echo, payload).result()
        for _ in range(samples):
            t0 = time.perf_counter()
            backend.submit(_echo, payload).result()
            trips.append(time.perf_counter() - t0)
        for _ in range(3):
            for k in CHAINS:
                pipelined[k].append(_pipelined(backend, payload, samples, k) - statistics.median(local))
    per_point = {k: statistics.median(v) for k, v in pipelined.items()}
    return {"p2_solve_s": solve_s, "p2_iterations": p2[-1].solution.iterations,
            "dask_round_trip_s": statistics.median(trips) - statistics.median(local),
            "dask_overhead_s": per_point[1], "overhead_fraction_of_p2_solve": per_point[1] / solve_s,
            "overhead_per_point_s_by_chain": per_point,
            "overhead_fraction_of_p2_solve_by_chain": {k: v / solve_s for k, v in per_point.items()},
            "round_trip_fraction_of_p2_solve": (statistics.median(trips) - statistics.median(local))
            / solve_s, "samples": samples}


def _pipelined(backend, payload, count: int, chain: int = 1) -> float:
    """Seconds per point for ``count`` tasks of ``chain`` points each, kept 2 per worker in
    flight as the sweep driver does."""
    import concurrent.futures as cf

    from nhgait.gaits.sweeps.point import solve_chain
    t0 = time.perf_counter()
    in_flight, sent = set(), 0
    while sent < count or in_flight:
        while sent < count and len(in_flight) < 2 * backend.workers:
            if chain == 1:
                in_flight.add(backend.submit(_echo, payload))
            else:
                # the sweep's own chain task; each "solve" answers with the answer its job carries
                carrier = replace(payload[0], warm=payload[1])
                in_flight.add(backend.submit(solve_chain, _carried, (carrier,) * chain, False))
            sent += 1
        done, in_flight = cf.wait(in_flight, return_when=cf.FIRST_COMPLETED)
        for f in done:
            f.result()
    return (time.perf_counter() - t0) / (count * chain)


def dask_chains(axes, scene=("snakeboard", "forward")) -> dict:
    """Points per task when ``axes`` are swept on a 2-worker local Dask cluster."""
    from nhgait.gaits.sweeps.backends import DaskBackend
    from nhgait.gaits.sweeps.grid import parse_grid
    from nhgait.gaits.sweeps.point import describe_case
    case = describe_case(*scene, overrides=["intervals=50"])
    grid = parse_grid(axes)
    sizes = []

    class Counting(DaskBackend):
        def submit(self, fn, *args):
            sizes.append(len(args[1]) if fn.__name__ == "solve_chain" else 1)
            return super().submit(fn, *args)

    with Counting("local:2") as backend:
        _warm_up(backend)
        sizes.clear()
        wall, result = timed_sweep(case, grid, backend)
    points = sum(sizes) - (backend.workers - 1)          # the prepare tasks carry no point
    tasks = len(sizes) - (backend.workers - 1)
    return {"points": grid.size, "solved": sum(r.success for r in result.records), "tasks": tasks,
            "points_per_task": points / tasks, "wall_s": wall, "chain": backend.chain,
            "objectives": [r.objective for r in result.records]}


def continuation(axes, scene=("snakeboard", "forward")) -> dict:
    from nhgait.gaits.sweeps.backends import ProcessPool
    from nhgait.gaits.sweeps.grid import parse_grid
    from nhgait.gaits.sweeps.point import describe_case
    case = describe_case(*scene, overrides=["intervals=50"])
    grid = parse_grid(axes)
    out = {"grid": list(axes), "points": grid.size}
    with ProcessPool(2) as pool:
        _warm_up(pool)
        for label, warm in (("warm", True), ("cold", False)):
            wall, result = timed_sweep(case, grid, pool, warm_start=warm)
            out[label] = {"wall_s": wall, "solved": sum(r.success for r in result.records),
                          "iterations": sum(r.total_iterations for r in result.records),
                          "objectives": [r.objective for r in result.records],
                          "point_wall_median_s": statistics.median(r.wall_time_s for r in result.records)}
    out["iteration_ratio_warm_over_cold"] = out["warm"]["iterations"] / max(out["cold"]["iterations"], 1)
    return out


def _throughput_section(report: dict, repeats: int, p1_axes) -> None:
    """Section 1 (printed, and added to ``report``): the sweep's throughput with 1 and 2 workers."""
    t = report["throughput"] = throughput(max(1, repeats), p1_axes)
    print(f"1. throughput, P1 N=50, {t['points']} points ({' × '.join(p1_axes)}), {repeats} runs each:")
    print(f"   1 worker  median {t['median_s'][1]:.2f} s  runs {[round(x, 2) for x in t['times_s'][1]]}")
    print(f"   2 workers median {t['median_s'][2]:.2f} s  runs {[round(x, 2) for x in t['times_s'][2]]}")
    print(f"   speed-up 2 workers / 1 worker = {t['speedup_2_over_1']:.2f}  (target ≥ 1.7); solved "
          f"{t['solved']}")
    print("   points running at once (Σ point wall / sweep wall, median): 1 worker "
          f"{t['concurrency'][1]:.2f}, "
          f"2 workers {t['concurrency'][2]:.2f} — below 2 while the centre is solved cold and when the "
          f"cores are shared")


def _dask_section(report: dict, samples: int, solves: int, p2, dask_axes) -> None:
    """Section 2 (printed, and added to ``report``): Dask's per-point overhead (skipped when Dask
    is not installed)."""
    from nhgait.dynamics.errors import ModelError
    try:
        d = report["dask"] = dask_overhead(samples, solves, p2)
    except ModelError as exc:  # pragma: no cover - Dask not installed
        print(f"2. Dask overhead: skipped ({exc})")
    else:
        print(f"2. Dask per-point overhead (LocalCluster, 1 worker; a {p2[0]} job and a "
              "solution-sized answer): "
              f"{d['dask_overhead_s'] * 1e3:.1f} ms per point with 2 points in flight as the "
              "sweep keeps them "
              f"(median of 3 × {d['samples']}), {d['dask_round_trip_s'] * 1e3:.1f} ms for one "
              "isolated round trip;")
        print(f"   {'/'.join(p2)} N=50 solve median {d['p2_solve_s'] * 1e3:.1f} ms ({d['p2_iterations']} "
              f"iterations) → {100 * d['overhead_fraction_of_p2_solve']:.1f} % for one point per task, "
              f"{100 * d['round_trip_fraction_of_p2_solve']:.1f} % isolated")
        for k in CHAINS:
            print(f"   tasks of {k} point{'s' if k > 1 else ' '}: "
                  f"{d['overhead_per_point_s_by_chain'][k] * 1e3:5.1f} ms per point "
                  f"= {100 * d['overhead_fraction_of_p2_solve_by_chain'][k]:4.1f} % of the solve")
        ch = d["sweep"] = dask_chains(dask_axes, p2)
        m = ch["points_per_task"]
        lo = max(k for k in CHAINS if k <= m)
        hi = min((k for k in CHAINS if k >= m), default=lo)
        f = d["overhead_fraction_of_p2_solve_by_chain"]
        est = f[lo] if hi == lo else f[lo] + (f[hi] - f[lo]) * (m - lo) / (hi - lo)
        d["overhead_fraction_in_sweep"] = est
        print(f"   a Dask sweep of {' × '.join(dask_axes)} (local:2, chain {ch['chain']}): "
              f"{ch['points']} points in {ch['tasks']} tasks = {m:.2f} points per task ({ch['solved']} "
              f"solved) → overhead ≈ {100 * est:.1f} % of a solve per point (target ≤ 10 %)")


def _continuation_section(report: dict, p2_axes, p2) -> None:
    """Section 3 (printed, and added to ``report``): warm against cold starts along the grid."""
    c = report["continuation"] = continuation(p2_axes, p2)
    print(f"3. continuation, {'/'.join(p2)} N=50, {c['points']} points ({' × '.join(p2_axes)}), 2 workers:")
    print(f"   warm: {c['warm']['iterations']} Ipopt iterations, {c['warm']['solved']} solved, "
          f"{c['warm']['wall_s']:.1f} s")
    print(f"   cold: {c['cold']['iterations']} Ipopt iterations, {c['cold']['solved']} solved, "
          f"{c['cold']['wall_s']:.1f} s")
    print(f"   iterations warm / cold = {c['iteration_ratio_warm_over_cold']:.2f}  (target ≤ 0.60)")
    if "dask" in report:
        point = c["warm"]["point_wall_median_s"]
        report["dask"]["overhead_fraction_of_warm_point"] = report["dask"]["dask_overhead_s"] / point
        print("   a warm point in its worker (set-up reuse, solve, re-simulation): median "
              f"{point * 1e3:.0f} ms → "
              f"Dask overhead {100 * report['dask']['overhead_fraction_of_warm_point']:.1f} % of "
              "a whole point")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes, P1 only (smoke test)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="out/bench_sweep.json")
    args = ap.parse_args(argv)
    if args.quick:
        p1_axes, p2_axes, samples, solves = ["final.y=0.45,0.55"], ["final.y=0.45,0.55"], 3, 1
        p2, dask_axes = ("unicycle", "parallel-park"), ["final.y=0.45,0.55"]
    else:
        p1_axes, p2_axes, samples, solves = ["final.y=0.3:0.75:10", "final.theta=-0.15:0.15:4"], \
            ["final.x=0.6:1.4:5", "horizon=5.5:7.0:3"], 50, 3
        p2 = ("snakeboard", "forward")
        # the shape of the example grid (10 distances × 4 horizons): rays of 4–5 points
        dask_axes = ["final.x=0.6:1.5:10", "horizon=5.5:7.0:4"]
    report = {"note": "2 cores shared with other work: compare ratios measured in this run"}
    print("nhgait sweep benchmark (machine possibly shared: ratios are from this one run)")
    _throughput_section(report, args.repeats, p1_axes)
    _dask_section(report, samples, solves, p2, dask_axes)
    _continuation_section(report, p2_axes, p2)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=1, default=float))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
