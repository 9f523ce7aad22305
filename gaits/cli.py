"""The ``nhgait`` command line: one module per subcommand, registered here.

    nhgait derive <scene.toml | built-in> ...      (gaits/cli_derive.py)
    nhgait simulate <scene.toml | built-in> ...    (gaits/cli_simulate.py)
    nhgait reproduce [--out DIR] ...               (gaits/cli_reproduce.py)
    nhgait plan <system> ... --out DIR             (gaits/cli_plan.py)

Errors in the user's input print one clear message (every problem listed) and exit with
status 2; no traceback from sympy or CasADi.
"""
from __future__ import annotations

import argparse
import importlib
import sys

#: (module, function adding the subcommand), in the order of ``nhgait --help``
SUBCOMMANDS = (
    ("nhgait.gaits.cli_derive", "add_derive_parser"),
    ("nhgait.gaits.cli_simulate", "add_simulate_parser"),
    ("nhgait.gaits.cli_bench", "add_bench_parser"),
    ("nhgait.gaits.cli_reproduce", "add_reproduce_parser"),
    ("nhgait.gaits.cli_plan", "add_plan_parser"),
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="nhgait", description="Dynamics and gait planning of nonholonomic robots.")
    sub = parser.add_subparsers(dest="command", required=True)
    for module, adder in SUBCOMMANDS:
        getattr(importlib.import_module(module), adder)(sub)
    return parser


def main(argv=None) -> int:
    from nhgait.dynamics.errors import ModelError
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ModelError as exc:
        print(f"nhgait: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
