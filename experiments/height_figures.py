#!/usr/bin/env python3
"""The height-function figures of docs/geometry.md (issue 42, item 3), headless.

For the wheeled 3-link snake (``tests/scenes/snake3.toml``, principally kinematic) over
(α₁, α₂) ∈ [−1, 1]² and the snakeboard (mixed) over (ψ, φ): the height functions of x, y, θ with
the connection's arrows, and for the snake a circular loop of radius 0.2 around (0.3, −0.2) with
its Stokes estimate, its body-velocity integral and the constraint equations' own answer
printed. For the snakeboard also Shammas's scaled-momentum heights H̄ = H − σ̄Γ̄ in their parts,
and for circles of radius ε around (ψ, φ) = (0.2, 0.3) from rest the Stokes estimates ∬H̄ and
∬H against the full reduced ODE (``fibre_motion``, 2000 midpoint steps). Writes
``snake3_heights.png``, ``snakeboard_heights.png`` and ``snakeboard_scaled_heights.png`` into
``--out`` (default docs/img).

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
    from nhgait.dynamics.geometry.heights import HeightGrid, evaluate_heights, height_function
    from nhgait.dynamics.geometry.prescribed import fibre_motion
    from nhgait.dynamics.geometry.stokes import loop_displacement, stokes_displacement
    from nhgait.gaits.figures.geometry import heights_figure
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene(str(ROOT / "tests" / "scenes" / "snake3.toml"))
    snake = derive(scene.system, "reduced")
    connection = local_connection(snake)
    units = {"x": "m", "y": "m", "theta": "rad", "alpha1": "rad", "alpha2": "rad"}
    grid = evaluate_heights(connection, "alpha1", "alpha2",
                            HeightGrid(bounds={"alpha1": (-1, 1), "alpha2": (-1, 1)}, points=61, units=units))
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
    units = {"x": "m", "y": "m", "theta": "rad", "psi": "rad", "phi": "rad"}
    box = HeightGrid(bounds={"psi": (-1, 1), "phi": (-1, 1)}, points=41, units=units)
    heights_figure(evaluate_heights(local_connection(board), "psi", "phi", box)).savefig(
        out / "snakeboard_heights.png", dpi=100)
    _snakeboard_scaled(board, box, out)
    if not args.quiet:
        print(f"wrote snake3_heights.png, snakeboard_heights.png, snakeboard_scaled_heights.png into {out}",
              file=sys.stderr)
    return 0


def _log_se2(x, y, th):
    """The se(2) element whose exponential is the pose (x, y, θ)."""
    a = th / 2 / np.tan(th / 2) if abs(th) > 1e-12 else 1.0
    return np.array([a * x + th / 2 * y, -th / 2 * x + a * y, th])


def _snakeboard_scaled(board, box, out: Path) -> None:
    """The scaled-momentum heights of the snakeboard in their parts, with a circle of radius
    0.2 around (0.2, 0.3); the Stokes estimates against the reduced ODE for ε = 0.2, 0.1, 0.05."""
    import sympy as sp

    from nhgait.dynamics.geometry.connection_fields import local_connection
    from nhgait.dynamics.geometry.heights import evaluate_heights, height_function
    from nhgait.dynamics.geometry.prescribed import FibreIntegrator
    from nhgait.dynamics.geometry.scaled_momentum import scaled_momentum
    from nhgait.dynamics.geometry.stokes import stokes_displacement
    from nhgait.gaits.figures.geometry import height_parts_figure
    momentum = scaled_momentum(board, "psi", "phi")
    connection = local_connection(board)
    centre = np.array([0.2, 0.3])
    t = np.linspace(0, 2 * np.pi, 2001)
    loop = (centre[0] + 0.2 * np.cos(t), centre[1] + 0.2 * np.sin(t))
    grid = evaluate_heights(connection, "psi", "phi", box, momentum=momentum)
    height_parts_figure(grid, loop=loop, components=("x", "theta")).savefig(
        out / "snakeboard_scaled_heights.png", dpi=90)
    system = board.system
    values = dict(zip(system.param_symbols, system.param_vector(), strict=True))
    scaled, plain = (sp.lambdify(system.q[3:5], height_function(connection, "psi", "phi", momentum=m)
                                 .subs(values), "numpy") for m in (momentum, None))
    integrator = FibreIntegrator(board)
    print("snakeboard, circle around (psi, phi) = (0.2, 0.3) from rest, counter-clockwise from "
          "(0.2 + eps, 0.3):")
    print(f"{'eps':>6} {'simulated x, theta':>24} {'Stokes H-bar':>22} {'err':>7} {'Stokes H':>22} "
          f"{'err':>7}")
    for eps in (0.2, 0.1, 0.05):
        a, b = centre[0] + eps * np.cos(t), centre[1] + eps * np.sin(t)
        exact = _log_se2(*integrator(t, np.vstack([np.zeros((3, t.size)), a, b])).fiber[:, -1])
        row = [f"{eps:6.3f}", f"{exact[0]:+.3e}, {exact[2]:+.3e}"]
        for H in (scaled, plain):
            s = stokes_displacement(H, a[:-1], b[:-1])
            row += [f"{s[0]:+.3e}, {s[2]:+.3e}", f"{np.linalg.norm(s - exact) / np.linalg.norm(exact):7.2%}"]
        print(" ".join(row))


if __name__ == "__main__":
    sys.exit(main())
