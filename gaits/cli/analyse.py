"""``nhgait analyse <scene.toml | built-in> [--at name=value ...] [--outputs a,b] [--json]``
(registered by :mod:`nhgait.gaits.cli.main`): whether the robot can move, and what its outputs see.

At one state (rest at the scene's ``[simulation] q0``, else q = 0, unless ``--at`` names
coordinates, velocities ``<q>_dot`` or momenta, inputs and parameters) it prints

* the thesis Table 2.1 type of the reduced model;
* the growth vector of the constraint distribution, the degree of nonholonomy and the
  brackets that give each new direction (:func:`nhgait.dynamics.geometry.growth_vector`);
* the accessibility rank of the reduced control system, the bracket depth it needs, and
  whether a conserved momentum confines the motion (:func:`~nhgait.dynamics.geometry.accessibility`);
* with ``--outputs``, the observability rank of those outputs and the unobservable states
  (:func:`~nhgait.dynamics.geometry.observability`).

Ranks are numeric (CasADi AD, SVD with the relative tolerance stated in the output). ``--json``
prints one object: ``growth_vector``, ``degree_of_nonholonomy``, ``accessibility`` {``rank``,
``dimension``, ``depth``, …} and, with ``--outputs``, ``observability`` {``rank``,
``dimension``, ``unobservable``, …}. Exit status 0, or 2 for bad input (every unknown name in
one message, with "did you mean …?").
"""
from __future__ import annotations

import json

__all__ = ["add_analyse_parser", "cmd_analyse"]


def _point_values(texts, problems) -> dict:
    """``--at`` texts ``name=value`` → {name: number}; values may be constant expressions."""
    from nhgait.dynamics.derivation.input.assignments import parse_assignment
    from nhgait.dynamics.derivation.input.expressions import number_problems
    out = {}
    for text in texts:
        a = parse_assignment(text, problems, example="phi=0.5 or x_dot=1")
        if a is None:
            continue
        out[a.key] = number_problems(a.value, f"--at {a.key}", problems)
    return out


def _bounds_note(scene) -> str | None:
    """A sentence on the task's bounds, when the scene states some: ranks are local."""
    task = scene.task or {}
    bounded = sorted(task.get("bounds", {}) or {})
    if not bounded and task.get("control_bounds") is None:
        return None
    what = (f"bounds on {', '.join(bounded)}" if bounded else "") + (
        (" and " if bounded else "") + "bounded inputs" if task.get("control_bounds") is not None else "")
    return (f"the scene's task states {what}: the ranks above are local (which directions exist near "
            "this state), not whether a target is reachable within those bounds")


def cmd_analyse(args) -> int:
    from nhgait.dynamics import derive, load_scene
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.geometry import accessibility, analysis_point, growth_vector, observability
    from nhgait.dynamics.geometry.distribution import RANK_TOL, point_problems
    from nhgait.dynamics.geometry.observability import output_problems
    from nhgait.dynamics.progress import Progress
    progress = Progress.silent() if args.quiet or args.json else Progress.to_stderr()
    scene = load_scene(args.scene)
    problems: list = []
    at = _point_values(args.at, problems)
    outputs = [o.strip() for o in args.outputs.split(",") if o.strip()] if args.outputs is not None else None
    with progress.phase(f"derive the reduced ODE of {scene.system.name} (cached after the first run)"):
        model = derive(scene.system, "reduced", version=args.version, use_cache=not args.no_cache)
    problems += point_problems(model, {k: v for k, v in at.items() if v == v})
    if outputs is not None:
        problems += output_problems(model, outputs, scene.quantities)
    if problems:
        raise ModelError(problems, title="invalid analysis request")
    q0 = scene.simulation.q0 if scene.simulation is not None and scene.simulation.q0 is not None else None
    point = analysis_point(model, at, q0=q0)
    with progress.phase("brackets of the constraint distribution and of the control system"):
        growth = growth_vector(model, point)
        access = accessibility(model, point)
        observe = (observability(model, point, outputs, scene.quantities) if outputs is not None else None)
    note = _bounds_note(scene)
    if args.json:
        print(json.dumps(_as_dict(model, point, growth, access, observe, note, RANK_TOL), indent=1))
        return 0
    print(f"analysis of {scene.system.name} at {point.describe(model)}")
    print(f"  thesis Table 2.1 type: {model.classification}; state z = ({', '.join(model.state_names)}); "
          f"ranks by SVD, relative tolerance {RANK_TOL:g}")
    print(growth.to_text())
    print(access.to_text())
    if note:
        print(f"  note: {note}")
    if observe is not None:
        print(observe.to_text())
    return 0


def _as_dict(model, point, growth, access, observe, note, tol) -> dict:
    """The ``--json`` object."""
    names = model.system.coordinates
    out = {
        "system": model.system.name, "classification": model.classification, "rank_tolerance": tol,
        "point": {"q": dict(zip(names, map(float, point.q), strict=True)),
                  "qdot": dict(zip(names, map(float, point.qdot), strict=True)),
                  "z": dict(zip(model.state_names, map(float, point.z), strict=True)),
                  "at_rest": point.at_rest},
        "growth_vector": list(growth.ranks), "degree_of_nonholonomy": growth.degree_of_nonholonomy,
        "brackets": [{"depth": depth, "bracket": name,
                      "direction": _direction(value, growth.coordinates),
                      "expression": growth.expression(name)}
                     for depth, found in enumerate(growth.new_directions, start=2) for name, value in found],
        "accessibility": {"rank": access.rank, "dimension": access.dimension, "depth": access.depth,
                          "ranks": list(access.ranks), "full": access.full, "confined": access.confined,
                          "unreached": list(access.unreached), "reason": access.reason,
                          "control_affine": access.control_affine},
    }
    if note:
        out["note"] = note
    if observe is not None:
        out["observability"] = {"outputs": list(observe.outputs), "rank": observe.rank,
                                "dimension": observe.dimension, "depth": observe.depth,
                                "observable": observe.observable, "unobservable": list(observe.unobservable),
                                "unobservable_directions": list(observe.hidden)}
    return out


def _direction(value, names) -> dict:
    scale = max(abs(float(v)) for v in value) or 1.0
    return {nm: float(v) for nm, v in zip(names, value, strict=True) if abs(v) > 1e-9 * scale}


def add_analyse_parser(subparsers):
    """Add the ``analyse`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("analyse", help="growth vector, accessibility and observability at a state")
    p.add_argument("scene", help="scene file (.toml) or built-in name (unicycle, snakeboard, ...)")
    p.add_argument("--at", action="extend", nargs="+", default=[], metavar="NAME=VALUE",
                   help="the state: coordinates, velocities <q>_dot or momenta, inputs, parameters "
                        "(repeatable; the rest 0 — at rest — and q from the scene's [simulation] q0)")
    p.add_argument("--outputs", default=None, metavar="A,B",
                   help="outputs for the observability rank: coordinates, velocities <q>_dot, momenta, "
                        "[quantities] of the scene")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--version", choices=["A", "B"], help="g = identity (A) or SE(2)-type (B)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--no-cache", action="store_true", help="derive afresh; do not read or write the cache")
    p.set_defaults(func=cmd_analyse)
    return p
