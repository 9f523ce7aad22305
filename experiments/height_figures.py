#!/usr/bin/env python3
"""The height-function figures of docs/geometry.md (issue 42, item 3), headless.

For the wheeled 3-link snake (``tests/scenes/snake3.toml``, principally kinematic) over
(α₁, α₂) ∈ [−1, 1]² and the snakeboard (mixed: the geometric part) over (ψ, φ): the height
functions of x, y, θ with the connection's arrows, and for the snake a circular loop of radius
0.2 around (0.3, −0.2) with its Stokes estimate, its body-velocity integral and the constraint
equations' own answer printed. Writes ``snake3_heights.png`` and ``snakeboard_heights.png``
into ``--out`` (default docs/img).

Usage: python experiments/height_figures.py [--out docs/img] [--quiet]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "img"))
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    import sympy as sp

    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation.input.scene import load_scene
    from nhgait.dynamics.derivation.models import snakeboard
    from nhgait.dynamics.geometry.connection_fields import local_connection, numeric_connection
    from nhgait.dynamics.geometry.heights import evaluate_heights, height_function
    from nhgait.dynamics.geometry.prescribed import fibre_motion
    from nhgait.dynamics.geometry.stokes import loop_displacement, stokes_displacement
    from nhgait.gaits.figures.geometry import heights_figure
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene(str(ROOT / "tests" / "scenes" / "snake3.toml"))
    snake = derive(scene.system, "reduced")
    connection = local_connection(snake)
    units = {"x": "m", "y": "m", "theta": "rad", "alpha1": "rad", "alpha2": "rad"}
    grid = evaluate_heights(connection, "alpha1", "alpha2", bounds={"alpha1": (-1, 1), "alpha2": (-1, 1)},
                            points=61, units=units)
    t = np.linspace(0, 2 * np.pi, 401)
    a, b = 0.3 + 0.2 * np.cos(t), -0.2 + 0.2 * np.sin(t)
    heights_figure(grid, loop=(a, b)).savefig(out / "snake3_heights.png", dpi=100)
    system = snake.system
    H = sp.lambdify(system.q[3:5], height_function(connection, "alpha1", "alpha2").subs(
        dict(zip(system.param_symbols, system.param_vector(), strict=True))), "numpy")
    q = np.vstack([np.zeros((3, t.size)), a, b])
    rows = {"Stokes ∬H": stokes_displacement(H, a[:-1], b[:-1]),
            "body-velocity integral": loop_displacement(numeric_connection(snake), q).total,
            "reconstruction (exact)": fibre_motion(snake, t, q).fiber[:, -1]}
    for name, value in rows.items():
        print(f"{name:24s} x = {value[0]:+.4f} m, y = {value[1]:+.4f} m, theta = {value[2]:+.4f} rad")
    board = derive(snakeboard(), "reduced")
    grid = evaluate_heights(local_connection(board), "psi", "phi", bounds={"psi": (-1, 1), "phi": (-1, 1)},
                            points=41, units={"x": "m", "y": "m", "theta": "rad", "psi": "rad", "phi": "rad"})
    heights_figure(grid).savefig(out / "snakeboard_heights.png", dpi=100)
    if not args.quiet:
        print(f"wrote {out / 'snake3_heights.png'} and {out / 'snakeboard_heights.png'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
