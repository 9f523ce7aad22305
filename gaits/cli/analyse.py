"""``nhgait analyse <scene.toml | built-in> [--at name=value ...] [--outputs a,b] [--heights a,b]
[--figure F] [--json]``
(registered by :mod:`nhgait.gaits.cli.main`): whether the robot can move, and what its outputs see.

At one state (rest at the scene's ``[simulation] q0``, else q = 0, unless ``--at`` names
coordinates, velocities ``<q>_dot`` or momenta, inputs and parameters) it prints

* the thesis Table 2.1 type of the reduced model;
* the growth vector of the constraint distribution, the degree of nonholonomy and the
  brackets that give each new direction (:func:`nhgait.dynamics.geometry.growth_vector`);
* the accessibility rank of the reduced control system, the bracket depth it needs, and
  whether a conserved momentum confines the motion (:func:`~nhgait.dynamics.geometry.accessibility`);
* with ``--outputs``, the observability rank of those outputs and the unobservable states
  (:func:`~nhgait.dynamics.geometry.observability`);
* with ``--heights a,b``, the height functions of the shape plane (a, b) at the point: the
  connection's H (momentum held at zero) and, for a mixed system with one momentum, Shammas's
  scaled-momentum H̄ = H − σ̄_abΓ̄ (:mod:`nhgait.dynamics.geometry.scaled_momentum`); with
  ``--figure F`` their figure over the task's bounds of a and b (else the point ± 1) is written.

Ranks are numeric (CasADi AD, SVD with the relative tolerance stated in the output). ``--json``
prints one object: ``growth_vector``, ``degree_of_nonholonomy``, ``accessibility`` {``rank``,
``dimension``, ``depth``, …} and, with ``--outputs``, ``observability`` {``rank``,
``dimension``, ``unobservable``, …}, with ``--heights`` ``heights`` {``pair``, ``connection``,
``scaled_momentum``, ``units``, …}. Exit status 0, or 2 for bad input (every unknown name in
one message, with "did you mean …?").
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

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
    pair = _pair(args.heights, model, problems)
    if args.figure is not None and pair is None:
        problems.append("--figure draws the height functions: give --heights a,b too")
    if problems:
        raise ModelError(problems, title="invalid analysis request")
    q0 = scene.simulation.q0 if scene.simulation is not None and scene.simulation.q0 is not None else None
    point = analysis_point(model, at, q0=q0)
    with progress.phase("brackets of the constraint distribution and of the control system"):
        growth = growth_vector(model, point)
        access = accessibility(model, point)
        observe = (observability(model, point, outputs, scene.quantities) if outputs is not None else None)
    analyses = _Analyses(growth=growth, access=access, observe=observe)
    heights = None
    if pair is not None:
        with progress.phase(f"height functions over ({', '.join(pair)})"):
            heights = heights_at(model, scene, point, pair, figure=args.figure)
    note = _bounds_note(scene)
    if args.json:
        out = _as_dict(model, point, analyses, note, RANK_TOL)
        if heights is not None:
            out["heights"] = heights.as_dict()
        print(json.dumps(out, indent=1))
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
    if heights is not None:
        print(heights.to_text())
    return 0


class _Analyses(NamedTuple):
    """The three rank analyses at one point: ``growth`` (the constraint distribution's growth
    vector), ``access`` (the control system's accessibility rank) and ``observe`` (the
    observability rank of the ``--outputs``, else None)."""

    growth: Any
    access: Any
    observe: Any


def _as_dict(model, point, analyses: _Analyses, note, tol) -> dict:
    """The ``--json`` object."""
    growth, access, observe = analyses
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


def _pair(text, model, problems) -> tuple | None:
    """``--heights a,b`` → (a, b), two different shape coordinates of ``model``."""
    if text is None:
        return None
    from nhgait.dynamics.suggestions import known_names
    shape = [model.system.coordinates[i] for i in model.layout.free]
    names = [n.strip() for n in text.split(",") if n.strip()]
    if len(names) != 2 or names[0] == names[1]:
        problems.append(f"--heights {text!r}: give two different shape coordinates a,b "
                        f"(shape: {', '.join(shape) or 'none'})")
        return None
    bad = [f"--heights: {n!r} is not a shape coordinate{known_names(n, shape, label='shape coordinates')}"
           for n in names if n not in shape]
    problems += bad
    return None if bad else tuple(names)


@dataclass(frozen=True, kw_only=True)
class HeightsAtPoint:
    """The height functions of one shape plane at the analysis point (``--heights``):
    ``connection`` fibre name → H (momentum at zero), ``scaled`` → H̄ (or None, with the reason
    in ``note``), ``units`` fibre name → unit text of a height, ``figure`` the file written."""

    pair: tuple
    at: dict
    connection: dict
    scaled: dict | None
    note: str
    units: dict
    figure: str | None

    def to_text(self) -> str:
        def row(values):
            return ", ".join(f"{k} = {v:.4g}" + (f" {self.units[k]}" if self.units[k] else "")
                             for k, v in values.items())
        a, b = self.pair
        lines = [f"height functions over ({a}, {b}) at {a}={self.at[a]:.4g}, {b}={self.at[b]:.4g} "
                 "(body displacement per unit area of a small counter-clockwise loop):",
                 f"  connection, momentum held at zero: {row(self.connection)}"]
        if self.scaled is not None:
            lines.append("  scaled momentum (from rest, an elliptical loop; docs/geometry.md): "
                         f"{row(self.scaled)}")
        if self.note:
            lines.append(f"  note: {self.note}")
        if self.figure:
            lines.append(f"  figure: {self.figure}")
        return "\n".join(lines)

    def as_dict(self) -> dict:
        return {"pair": list(self.pair), "at": self.at, "connection": self.connection,
                "scaled_momentum": self.scaled, "note": self.note or None, "units": self.units,
                "figure": self.figure}


def _height_units(scene, pair, fiber) -> dict:
    from nhgait.dynamics.units import unit_of
    ua, ub = (unit_of(n, scene.units, scene.system) for n in pair)
    below = f"{ua}²" if ua == ub and ua else "·".join(u for u in (ua, ub) if u)
    return {k: (f"{unit_of(k, scene.units, scene.system) or '1'}/{below}" if below else
                unit_of(k, scene.units, scene.system)) for k in fiber}


def _figure_box(scene, point_at, pair) -> dict:
    """The task's bounds of the pair where finite, else the point ± 1."""
    bounds = dict((scene.task or {}).get("bounds", {}) or {})
    box = {}
    for n in pair:
        low, high = (float(v) for v in bounds.get(n, (math.nan, math.nan)))
        box[n] = (low, high) if math.isfinite(low) and math.isfinite(high) and low < high else \
            (point_at[n] - 1.0, point_at[n] + 1.0)
    return box


def heights_at(model, scene, point, pair, *, figure=None) -> HeightsAtPoint:
    """H (and H̄ for a mixed system with one momentum) of the plane ``pair`` at ``point`` by the
    compiled route (:func:`~nhgait.dynamics.geometry.heights.evaluate_heights_numeric`); the
    figure over :func:`_figure_box` written to ``figure`` when given."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.geometry.connection_fields import numeric_connection
    from nhgait.dynamics.geometry.heights import HeightGrid, evaluate_heights_numeric
    from nhgait.dynamics.geometry.reconstruction import reconstruction
    connection = numeric_connection(model, dict(zip((s.name for s in model.system.param_symbols),
                                                    map(float, point.params), strict=True)))
    at = dict(zip(model.system.coordinates, map(float, point.q), strict=True))
    near = HeightGrid(bounds={n: (at[n] - 1e-3, at[n] + 1e-3) for n in pair}, points=3, at=at)
    plain = evaluate_heights_numeric(connection, *pair, near)
    scaled, note, equation = None, "", None
    if model.layout.d == 1:
        equation = reconstruction(model)
        try:
            scaled = evaluate_heights_numeric(connection, *pair, near, equation=equation)
        except ModelError as error:
            note, equation = f"no scaled-momentum height: {'; '.join(error.problems)}", None
    elif model.layout.d > 1:
        note = f"the scaled-momentum heights are for one nonholonomic momentum ({model.layout.d} here)"
    units = _height_units(scene, pair, connection.fiber)
    if figure is not None:
        _write_figure(connection, pair, HeightGrid(bounds=_figure_box(scene, at, pair), points=41, at=at,
                                                   units=_names_units(scene, (*pair, *connection.fiber))),
                      equation, figure)

    def centre(h):
        return {k: float(h.heights[i, 1, 1]) for i, k in enumerate(h.fiber)}
    return HeightsAtPoint(pair=pair, at=at, connection=centre(plain),
                          scaled=None if scaled is None else centre(scaled), note=note, units=units,
                          figure=None if figure is None else str(figure))


def _names_units(scene, names) -> dict:
    from nhgait.dynamics.units import unit_of
    return {n: unit_of(n, scene.units, scene.system) for n in names}


def _write_figure(connection, pair, grid, equation, path) -> None:
    from nhgait.dynamics.geometry.heights import evaluate_heights_numeric
    from nhgait.gaits.figures.geometry import height_parts_figure, heights_figure
    heights = evaluate_heights_numeric(connection, *pair, grid, equation=equation)
    if heights.momentum_part is None:
        fig = heights_figure(heights)
    else:
        moving = [k for i, k in enumerate(heights.fiber)
                  if np.nanmax(np.abs(heights.heights[i]), initial=0) > 0]
        fig = height_parts_figure(heights, components=moving or None)
    fig.savefig(path, dpi=90)


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
    p.add_argument("--heights", default=None, metavar="A,B",
                   help="height functions of the shape plane (A, B) at the point; for a mixed system also "
                        "Shammas's scaled-momentum form")
    p.add_argument("--figure", default=None, metavar="FILE.png",
                   help="with --heights: write their figure (over the task's bounds of A and B, else ±1)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--version", choices=["A", "B"], help="g = identity (A) or SE(2)-type (B)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--no-cache", action="store_true", help="derive afresh; do not read or write the cache")
    p.set_defaults(func=cmd_analyse)
    return p
