"""``nhgait bench precision <scene.toml | built-in> [--tols …] [--methods …] --out out/bench``
(registered by :mod:`nhgait.gaits.cli.main`): the work-precision report of one scene.

The scene's ``[simulation]`` table (initial state, horizon, input laws, parameters, outputs) is
integrated by every formulation × method × tolerance (:mod:`nhgait.gaits.bench.work_precision`). The
reference final state is the Lagrangian DAE (index-1 route) integrated by scipy DOP853 at
rtol 1e-13, atol 1e-15 — a different formulation and implementation than the compiled and
SUNDIALS rows; its own error is estimated against the reduced ODE with the compiled DOP853 at
the same tolerance and printed. (``experiments/work_precision.py`` uses the independent
KanesMethod oracle instead, for the thesis robots.) Writes ``precision.csv``,
``precision.png`` and ``precision.md`` into ``--out``. Progress goes to stderr (``--quiet``
silences it): the number of points first, then one line per point with the count and an
estimate of the time left (:class:`nhgait.dynamics.countdown.Countdown`).
"""
from __future__ import annotations

import sys
from pathlib import Path

from nhgait.dynamics.countdown import Countdown, duration

__all__ = ["add_bench_parser", "cmd_bench_precision"]


def cmd_bench_precision(args) -> int:
    """The work-precision report of one scene: the reference run, then every formulation ×
    method × tolerance, written as CSV, PNG and Markdown into ``--out``."""
    from nhgait.dynamics import derive, load_scene
    from nhgait.dynamics.errors import ModelError
    from nhgait.gaits.bench import work_precision as wp
    from nhgait.gaits.files.outputs import output_directory
    if args.repeats < 1:
        raise ModelError([f"--repeats {args.repeats}: at least 1 timed run per point"],
                         title="invalid request")
    out = output_directory(args.out)        # before any derivation: exit 2 for a bad location
    scene = load_scene(args.scene)
    spec = scene.simulation
    if spec is None:
        raise ModelError([f"{scene.source} has no [simulation] table"], title="cannot benchmark")
    tolerances = _floats(args.tols, "--tols")
    methods = [m for m in args.methods.split(",") if m]
    formulations = _formulations(args.formulations)
    if spec.t0 != 0.0:
        raise ModelError(["bench precision needs [simulation].t0 = 0"], title="invalid request")
    models = {f: derive(scene.system, f) for f in set(formulations) | {"lagrange", "reduced"}}
    stream = None if args.quiet else sys.stderr
    reference, label, spread = _reference(spec, models, stream)
    print(f"reference: {label}; differs from the reduced ODE + compiled DOP853 (rtol 1e-13) by {spread:.2g}")
    case = wp.Case(name=scene.system.name, models=models, controller=spec.controller, q0=spec.q0,
                   qdot0=spec.qdot0, t_final=spec.t_final, reference=reference,
                   reference_label=label, params=spec.parameters or None, outputs=spec.outputs,
                   description=f"{scene.system.name}, t ∈ [0, {spec.t_final:.4g}] s")
    setups = wp.default_setups(formulations, methods, idas=not args.no_idas)
    countdown = Countdown(len(setups) * len(tolerances), stream=stream, what="points")
    if stream is not None:
        print(f"measuring {len(setups)} formulation/method set-ups × {len(tolerances)} tolerances = "
              f"{countdown.total} points, {args.repeats} timed runs each (median)", file=stream, flush=True)
    rows = wp.measure(case, setups, tolerances, repeats=args.repeats,
                      progress=lambda row: countdown.step(_point(row)))
    try:
        _write_report(rows, case, f"{label} (spread {spread:.2g})", out)
    except OSError as exc:                  # the measurements are kept: the CSV goes to a fallback
        from nhgait.gaits.files.outputs import rescue, write_failure
        where = rescue("precision.csv", lambda path: wp.write_csv(rows, path), "measurements")
        print(f"NOT WRITTEN: {write_failure(exc, out)}; {where}")
        return 1
    print(f"wrote {out}/precision.csv, precision.png, precision.md ({countdown.total} points in "
          f"{duration(countdown.elapsed())})")
    return 0


def _formulations(text: str) -> list:
    """The comma-separated formulations, each one of ``FORMULATIONS``."""
    from nhgait.dynamics import FORMULATIONS
    from nhgait.dynamics.errors import ModelError
    formulations = [f for f in text.split(",") if f]
    bad = [f for f in formulations if f not in FORMULATIONS]
    if bad:
        raise ModelError([f"unknown formulation(s) {bad} (choose from {', '.join(FORMULATIONS)})"],
                         title="invalid request")
    return formulations


def _reference(spec, models: dict, stream) -> tuple:
    """((q, q̇) at t_final, its label, its spread): the Lagrangian DAE by scipy DOP853 at rtol
    1e-13, and the largest difference to the reduced ODE by the compiled DOP853 at the same
    tolerance — two formulations, two implementations."""
    import numpy as np

    from nhgait.dynamics import simulate
    from nhgait.dynamics.errors import ModelError
    span = (spec.t0, spec.t_final)
    common = dict(controller=spec.controller, params=spec.parameters or None, t_eval=list(span),
                  rtol=1e-13, atol=1e-15)
    if stream is not None:
        print("reference runs at rtol 1e-13 (Lagrangian DAE + DOP853, reduced ODE + compiled DOP853) …",
              file=stream, flush=True)
    ref = simulate(models["lagrange"], span, spec.q0, spec.qdot0, method="DOP853", **common)
    check = simulate(models["reduced"], span, spec.q0, spec.qdot0, method="compiled", **common)
    if not (ref.success and check.success):
        raise ModelError([f"the reference run failed: {ref.message if not ref.success else check.message}"],
                         title="cannot benchmark")
    spread = float(np.max(np.abs(np.r_[ref.q[-1] - check.q[-1], ref.qdot[-1] - check.qdot[-1]])))
    label = "Lagrangian DAE (index 1) + scipy DOP853, rtol 1e-13, atol 1e-15"
    return (ref.q[-1], ref.qdot[-1]), label, spread


def _write_report(rows, case, reference: str, out: Path) -> None:
    """precision.csv, precision.png (error against wall time, named axes) and precision.md."""
    from nhgait.gaits.bench import work_precision as wp
    out.mkdir(parents=True, exist_ok=True)
    wp.write_csv(rows, out / "precision.csv")
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 6))
    wp.plot_case(rows, ax, title=f"{case.description}; error against {case.reference_label}")
    fig.tight_layout()
    fig.savefig(out / "precision.png", dpi=110)
    plt.close(fig)
    (out / "precision.md").write_text(f"{case.description}; reference {reference}\n\n"
                                      + wp.markdown_table(rows) + "\n")


def _point(r) -> str:
    return (f"{r.label:30s} rtol {r.rtol:7.0e}  error {r.error:9.2e}  {r.wall_s * 1e3:10.3f} ms  "
            f"nfev {r.nfev:8d}  states {r.states}  {r.note[:60]}").rstrip()


def _floats(text, where):
    from nhgait.dynamics.errors import ModelError
    try:
        values = [float(v) for v in text.split(",") if v]
    except ValueError:
        raise ModelError([f"{where}: {text!r} is not a comma-separated list of numbers"],
                         title="invalid request") from None
    if not values or not all(0 < v < 1 for v in values):
        raise ModelError([f"{where}: tolerances must lie in (0, 1), got {text!r}"], title="invalid request")
    return values


def add_bench_parser(subparsers):
    """Add the ``bench`` subcommand (``bench precision SCENE``) to an argparse ``subparsers``."""
    p = subparsers.add_parser("bench", help="benchmarks: `bench precision SCENE` (work-precision report)")
    sub = p.add_subparsers(dest="bench", required=True)
    q = sub.add_parser("precision", help="final-state error against wall time for every formulation, "
                                         "method and tolerance of a scene's [simulation]")
    q.add_argument("scene")
    q.add_argument("--tols", default="1e-4,1e-6,1e-8,1e-10,1e-12")
    q.add_argument("--methods", default="RK45,DOP853,Radau,LSODA,CVODES,compiled")
    q.add_argument("--formulations", default="reduced,lagrange,hamilton")
    q.add_argument("--no-idas", action="store_true", help="skip the IDAS route of the DAE forms")
    q.add_argument("--repeats", type=int, default=5, help="timed runs per point (median; at least 1)")
    q.add_argument("--out", default="out/bench", help="output folder (default out/bench)")
    q.add_argument("--quiet", action="store_true", help="no progress on stderr")
    q.set_defaults(func=cmd_bench_precision)
    return p
