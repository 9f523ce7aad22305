"""``nhgait linearize <scene.toml | built-in> [--speed V | --speeds 0:10:101 --out DIR]
[--set ...] [--json]`` (registered by :mod:`nhgait.gaits.cli.main`).

Linearises the reduced ODE about an equilibrium at rest (no speed) or the straight steady
motion at forward speed V of the scene's planar frame, and prints A, B, the eigenvalues and
the states each belongs to (:func:`nhgait.dynamics.linearisation.linearise`). ``--speeds``
linearises at every speed of a grid, prints the speeds where stability changes (refined by
root finding) and, with ``--out``, draws ``eigenvalues.png`` and writes ``eigenvalues.json``
(:func:`nhgait.dynamics.linearisation.stability_chart`). ``--json`` prints one JSON object
instead of text (``eigenvalues`` as [re, im] pairs).

``--set`` keys: ``q.<coordinate>=value`` (the configuration; the others 0), ``inputs.<input>=value``
(constant inputs; the others 0), ``params.<parameter>=value``. Values are numbers or constant
expressions (``pi/10``). Exit status 0, or 2 for bad input (a reference that is not at rest
is bad input: the error names the rates that are not zero).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

__all__ = ["add_linearize_parser", "cmd_linearize", "parse_settings"]

SET_KEYS = ("q", "inputs", "params")


def parse_settings(assignments, system) -> dict:
    """``--set`` texts → {"configuration": {...}, "inputs": {...}, "params": {...}}; one error
    lists every problem."""
    from nhgait.dynamics.derivation.input.assignments import parse_assignment
    from nhgait.dynamics.derivation.input.expressions import number_problems
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.suggestions import known_names
    problems: list = []
    out = {"configuration": {}, "inputs": {}, "params": {}}
    known = {"q": tuple(system.coordinates), "inputs": tuple(system.inputs),
             "params": tuple(system.parameters)}
    target = {"q": "configuration", "inputs": "inputs", "params": "params"}
    for text in assignments:
        a = parse_assignment(text, problems, example="q.lean=0.1 or params.m=2")
        if a is None:
            continue
        head = "q" if a.parts[0] == "q0" else "params" if a.parts[0] == "parameters" else a.parts[0]
        if head not in SET_KEYS or len(a.parts) != 2:
            problems.append(f"--set {a.text!r}: expected q.<coordinate>, inputs.<input> or "
                            "params.<parameter>")
            continue
        if a.parts[1] not in known[head]:
            problems.append(f"--set {a.text!r}: {a.parts[1]!r} is not one of the {head}"
                            f"{known_names(a.parts[1], known[head])}")
            continue
        value = number_problems(a.value, f"--set {a.key}", problems)
        out[target[head]][a.parts[1]] = value
    if problems:
        raise ModelError(problems, title="invalid --set")
    return out


def cmd_linearize(args) -> int:
    from nhgait.dynamics import derive, load_scene
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.linearisation import linearise, stability_chart
    from nhgait.dynamics.linearisation.chart import parse_speeds
    from nhgait.dynamics.progress import Progress
    if args.speed is not None and args.speeds is not None:
        raise ModelError(["give --speed V or --speeds start:stop:count, not both"],
                         title="invalid linearisation request")
    if args.out is not None and args.speeds is None:
        raise ModelError(["--out draws the eigenvalues against speed: give --speeds too"],
                         title="invalid linearisation request")
    progress = Progress.silent() if args.quiet or args.json else Progress.to_stderr()
    speeds = parse_speeds(args.speeds) if args.speeds is not None else None
    scene = load_scene(args.scene)
    settings = parse_settings(args.overrides, scene.system)
    with progress.phase(f"derive the reduced ODE of {scene.system.name} (cached after the first run)"):
        model = derive(scene.system, "reduced", use_cache=not args.no_cache)
    if speeds is None:
        lin = linearise(model, speed=args.speed, **settings)
        print(json.dumps(lin.to_dict(), indent=1) if args.json
              else lin.to_text(matrices=not args.no_matrices))
        return 0
    with progress.phase(f"linearise at {len(speeds)} speeds and refine the changes of stability"):
        chart = stability_chart(model, speeds, progress=progress, **settings)
    if args.json:
        print(json.dumps(chart.to_dict(), indent=1))
    else:
        print(chart.to_text())
    if args.out is not None:
        from ..figures.stability import write_eigenvalue_figure
        out = Path(args.out)
        path = write_eigenvalue_figure(chart, out,
                                       title=f"{scene.system.name}: eigenvalues of straight steady motion")
        (out / "eigenvalues.json").write_text(json.dumps(chart.to_dict(), indent=1))
        print(f"  wrote {path} and {out / 'eigenvalues.json'}", file=sys.stderr if args.json else sys.stdout)
    return 0


def add_linearize_parser(subparsers):
    """Add the ``linearize`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("linearize",
                              help="linearise about an equilibrium or a steady motion; eigenvalues")
    p.add_argument("scene", help="scene file (.toml) or built-in name (rolling_disc, whipple_bicycle, ...)")
    p.add_argument("--speed", type=float,
                   help="straight steady motion of the planar frame at this forward speed [m/s]")
    p.add_argument("--speeds",
                   help="start:stop:count (e.g. 0:10:101) or v1,v2,...: eigenvalues against speed")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="q.<coordinate>=value, inputs.<input>=value, params.<parameter>=value (repeatable)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (eigenvalues as [re, im] pairs)")
    p.add_argument("--no-matrices", action="store_true", help="print the eigenvalues without A and B")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="with --speeds: write eigenvalues.png and eigenvalues.json")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--no-cache", action="store_true")
    p.set_defaults(func=cmd_linearize)
    return p
