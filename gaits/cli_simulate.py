"""``nhgait simulate <scene.toml | built-in> ... --out traj.csv`` (registered by
:mod:`nhgait.gaits.cli`)."""
from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["add_simulate_parser", "cmd_simulate"]


def cmd_simulate(args) -> int:
    from nhgait.dynamics import derive
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.simulation import simulate
    from nhgait.dynamics.scene import load_scene
    scene = load_scene(args.scene)
    spec = scene.simulation
    if spec is None:
        raise ModelError([f"{scene.source} has no [simulation] table (q0, qdot0, t_final, samples)"],
                         title="cannot simulate")
    form = args.formulation or spec.formulation or "reduced"
    model = derive(scene.system, form, use_cache=not args.no_cache)
    rtol = args.rtol if args.rtol is not None else (spec.rtol or 1e-8)
    atol = args.atol if args.atol is not None else (spec.atol or rtol * 1e-2)
    kwargs = {}
    if form != "reduced":
        kwargs["dae"] = args.dae
    traj = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, controller=spec.controller,
                    params=spec.parameters or None, method=args.method or spec.method or "DOP853",
                    rtol=rtol, atol=atol, t_eval=spec.t_eval, **kwargs)
    if not traj.success:
        print(f"simulation failed: {traj.message}", file=sys.stderr)
        return 1
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    traj.to_csv(out)
    q_end = ", ".join(f"{c}={v:.8g}" for c, v in zip(scene.system.coordinates, traj.q[-1]))
    print(f"{scene.system.name}: {form} formulation, {len(traj.t)} samples to t = {traj.t[-1]:.6g} "
          f"({traj.nfev} evaluations, {traj.wall_time_s:.3f} s); q(t_final): {q_end}")
    import numpy as np
    if traj.constraint_residual is not None and traj.constraint_residual.size:
        print(f"  max |ω(q)q̇| = {np.abs(traj.constraint_residual).max():.3g}, "
              f"max |energy balance| = {np.abs(traj.energy_balance).max():.3g}")
    print(f"  wrote {out}")
    return 0


def add_simulate_parser(subparsers):
    """Add the ``simulate`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("simulate", help="integrate a scene's [simulation] and write a CSV")
    p.add_argument("scene")
    p.add_argument("--formulation", choices=["reduced", "lagrange", "hamilton"])
    p.add_argument("--rtol", type=float)
    p.add_argument("--atol", type=float)
    p.add_argument("--method", help="scipy method (DOP853, RK45, Radau, BDF, LSODA)")
    p.add_argument("--dae", choices=["index1", "idas"], default="index1",
                   help="DAE forms: index-reduced ODE (default) or CasADi IDAS")
    p.add_argument("--out", required=True, help="CSV path: column t, then one column per coordinate")
    p.add_argument("--no-cache", action="store_true")
    p.set_defaults(func=cmd_simulate)
    return p
