"""Simple geometry of a robot for the path plot and the GIF: the ``[drawing]`` table.

Format (docs/gait-planning.md)::

    [drawing]
    frame = ["x", "y", "theta"]      # optional: the body frame (default: the planar frame)
    [[drawing.segment]]              # one table per line segment, in body coordinates (m)
    from = ["-r", 0]                 # numbers or expressions of coordinates and parameters
    to = ["r", 0]
    width = 3                        # optional line width (points)
    label = "board"                  # optional legend entry

A point (px, py) of the body frame is drawn at (x + px cos θ − py sin θ, y + px sin θ +
py cos θ). Expressions may use the coordinates (a wheel steered by φ, a trailer at angle β)
and the parameters; they are parsed by :mod:`nhgait.dynamics.derivation.input.expressions` (data, never code).
Without a drawing the path plot shows the frame's point and an arrow along its heading.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nhgait.ocp import ProblemError

__all__ = ["Drawing", "parse_drawing", "default_frame"]

DRAWING_KEYS = {"frame", "segment"}
SEGMENT_KEYS = {"from", "to", "width", "label"}


@dataclass(frozen=True, eq=False)
class Drawing:
    """Parsed geometry: ``points(q, params)`` gives the segments' end points in body coordinates."""

    frame: tuple
    function: object          # CasADi Function (q, qdot, params) -> 4·n_segments values
    widths: tuple
    labels: tuple

    @property
    def n_segments(self) -> int:
        return len(self.widths)

    def segments(self, q, params) -> list:
        """[(xs, ys), …] in the plane for configuration ``q`` (n,)."""
        q = np.asarray(q, dtype=float)
        vals = np.asarray(self.function(q, np.zeros_like(q), params)).ravel()
        return [(vals[4 * i:4 * i + 2], vals[4 * i + 2:4 * i + 4]) for i in range(self.n_segments)]


def default_frame(system):
    frame = getattr(system, "planar_frame", None)
    return tuple(frame) if frame else None


def parse_drawing(table, system, *, where: str = "[drawing]") -> Drawing | None:
    """The :class:`Drawing` of a ``[drawing]`` table (None for none); every problem listed.

    The segment end points are returned already placed in the plane: the frame's pose is part
    of the expressions, so one CasADi function gives the drawing at a configuration.
    """
    if table is None:
        return None
    from nhgait.dynamics.derivation.input.expressions import expression_problems
    from nhgait.dynamics.derivation.quantities import quantity_function

    problems = []
    if not isinstance(table, dict):
        raise ProblemError([f"{where} must be a table"], title="invalid drawing")
    unknown = set(table) - DRAWING_KEYS
    if unknown:
        problems.append(f"{where}: unknown key(s) {sorted(unknown)} (allowed: frame, segment)")
    frame = table.get("frame", default_frame(system))
    coords = tuple(system.coordinates)
    if frame is None or not isinstance(frame, (list, tuple)) or len(frame) != 3 or any(c not in coords
                                                                                       for c in frame):
        problems.append(f"{where}.frame: need three coordinates (x, y, heading) of {', '.join(coords)}, "
                        f"got {frame!r}")
        frame = None
    segments = table.get("segment", [])
    if not isinstance(segments, list) or not all(isinstance(s, dict) for s in segments):
        problems.append(f"{where}.segment must be an array of tables ([[drawing.segment]])")
        segments = []
    names = {s.name: s for s in tuple(system.q) + tuple(system.param_symbols)}
    exprs, widths, labels = {}, [], []
    for i, seg in enumerate(segments):
        w = f"{where}.segment[{i}]"
        bad = set(seg) - SEGMENT_KEYS
        if bad:
            problems.append(f"{w}: unknown key(s) {sorted(bad)} (allowed: {', '.join(sorted(SEGMENT_KEYS))})")
        for end in ("from", "to"):
            point = seg.get(end)
            if not isinstance(point, list) or len(point) != 2:
                problems.append(f"{w}.{end} must be a point [px, py], got {point!r}")
                continue
            for axis, value in zip("xy", point, strict=True):
                text = (str(value) if isinstance(value, (int, float))
                        and not isinstance(value, bool) else value)
                e = expression_problems(text, names, f"{w}.{end} {axis}", problems)
                if e is not None:
                    exprs[f"s{i}_{end}_{axis}"] = e
        width = seg.get("width", 2)
        if isinstance(width, bool) or not isinstance(width, (int, float)) or not width > 0:
            problems.append(f"{w}.width must be a positive number")
        widths.append(float(width) if isinstance(width, (int, float)) else 2.0)
        labels.append(str(seg.get("label", "")))
    if problems:
        raise ProblemError(problems, title="invalid drawing")
    placed = _placed(exprs, frame, system, len(segments))
    return Drawing(tuple(frame), quantity_function(system, placed), tuple(widths), tuple(labels))


def _placed(exprs, frame, system, n):
    """The end points in the plane: (xs0, xs1, ys0, ys1) per segment, posed by the frame."""
    q = {s.name: s for s in system.q}
    x, y, th = (q[c] for c in frame)
    cos, sin = _trig(th)
    out = {}
    for i in range(n):
        for end, k in (("from", 0), ("to", 1)):
            px, py = exprs[f"s{i}_{end}_x"], exprs[f"s{i}_{end}_y"]
            out[f"s{i}_x{k}"] = x + px * cos - py * sin
            out[f"s{i}_y{k}"] = y + px * sin + py * cos
    return {f"s{i}_{c}": out[f"s{i}_{c}"] for i in range(n) for c in ("x0", "x1", "y0", "y1")}


def _trig(theta):
    """cos θ, sin θ as expressions of the symbol θ, built by the safe parser of the dynamics layer."""
    from nhgait.dynamics.derivation.input.expressions import parse_expression
    names = {theta.name: theta}
    return (parse_expression(f"cos({theta.name})", names, "drawing frame"),
            parse_expression(f"sin({theta.name})", names, "drawing frame"))
