"""``nhgait reproduce``: the thesis's simulations (§3.3), figures and a JSON summary.

Registered by ``nhgait.gaits.cli.main`` through :func:`add_reproduce_parser`.
"""
from __future__ import annotations


def add_reproduce_parser(subparsers):
    """Add the ``reproduce`` subcommand to an argparse ``subparsers`` object."""
    parser = subparsers.add_parser(
        "reproduce", help="reproduce the thesis's unicycle and snakeboard simulations",
        description="Simulate the thesis's PD-controlled unicycle (t in [0, 2π]) and snakeboard "
                    "(t in [0, 10π]) with every formulation; write summary.json and Figs. "
                    "3.8–3.11, 3.13–3.17 as PNG.")
    parser.add_argument("--out", default="out/reproduce", help="output folder (default out/reproduce)")
    parser.add_argument("--rtol", type=float, default=1e-10,
                        help="relative tolerance of every run, atol = rtol·1e-2 (default 1e-10)")
    parser.add_argument("--no-idas", action="store_true",
                        help="skip the CasADi IDAS runs of the DAE forms")
    parser.add_argument("--columns", choices=["q", "qdot", "all"], default=None,
                        help="also write every run as <case>_<run>.csv: q (coordinates), qdot (and "
                             "velocities) or all (and inputs, multipliers, energy, work)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    parser.set_defaults(func=run)
    return parser


def run(args) -> int:
    """Run the reproduction; print a summary table; 0 when every run reached the end."""
    import sys

    from ..bench.reproduction import reproduce
    from ..files.outputs import output_directory
    out = output_directory(args.out)        # before any derivation: exit 2 for a bad location
    summary = reproduce(out, rtol=args.rtol, idas=not args.no_idas, columns=getattr(args, "columns", None),
                        progress=None if getattr(args, "quiet", False) else sys.stderr)
    print_summary(summary)
    if summary.get("unwritten"):
        print(f"NOT WRITTEN: {summary['unwritten']}")
        return 1
    n_csv = sum(len(summary[c].get("csv", [])) for c in ("unicycle", "snakeboard"))
    print(f"wrote {args.out}/summary.json and "
          f"{sum(len(summary[c].get('figures', [])) for c in ('unicycle', 'snakeboard'))} figures"
          + (f" and {n_csv} CSV files ({args.columns} columns)" if n_csv else ""))
    ok = all(r.get("success", True) for c in ("unicycle", "snakeboard") for r in summary[c]["runs"].values())
    return 0 if ok else 1


def print_summary(summary) -> None:
    """One line per run: final x, y, max |ω q̇|, max |energy balance|, max deviation in q from the
    reference run (``kane`` if present, else ``reduced``), wall time and evaluations."""
    for case in ("unicycle", "snakeboard"):
        data = summary[case]
        runs = data["runs"]
        ref = "kane" if "kane" in runs else "reduced"
        print(f"\n{case}  (t_final = {data['t_final']:.6g} s, reference: {ref})")
        print(f"  {'run':<15}{'x(T)':>13}{'y(T)':>13}{'max|ωq̇|':>11}{'max|ΔE−W|':>11}"
              f"{'max|Δq|':>11}{'wall [s]':>10}{'nfev':>9}")
        for label, run in runs.items():
            dev = 0.0 if label == ref else _deviation(data["max_deviation_q"], label, ref)
            fq = run["final_q"]
            res = run.get("max_abs_constraint_residual", float("nan"))
            eb = run.get("max_abs_energy_balance", float("nan"))
            print(f"  {label:<15}{fq['x']:>13.8f}{fq['y']:>13.8f}{res:>11.1e}{eb:>11.1e}"
                  f"{dev:>11.1e}{run.get('wall_time_s', float('nan')):>10.3f}{run.get('nfev', 0):>9d}")


def _deviation(table, a, b):
    return table.get(f"{a} vs {b}", table.get(f"{b} vs {a}", float("nan")))
