"""The ``nhgait`` command line.

    nhgait derive <scene.toml | built-in> [--formulation reduced|lagrange|hamilton|all]
                  [--steps latex|markdown] [--table] [--version A|B] [--no-cache]
    nhgait simulate <scene.toml | built-in> [--formulation reduced|lagrange|hamilton]
                  [--rtol R] [--atol A] [--method M] [--dae index1|idas] --out traj.csv
    nhgait reproduce [--out DIR] ...          (thesis Figs. 3.8–3.17)
    nhgait plan <system> --gait <name> ... --out DIR

Errors in the user's input print one clear message (every problem listed) and exit with
status 2; no traceback from sympy or CasADi.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def _scene(arg):
    from nhgait.dynamics.scene import load_scene
    return load_scene(arg)


def cmd_derive(args) -> int:
    from nhgait.dynamics import derive
    from nhgait.dynamics.symmetry import symmetry_test
    scene = _scene(args.scene)
    system = scene.system
    forms = ["reduced", "lagrange", "hamilton"] if args.formulation == "all" else [args.formulation]
    for form in forms:
        t0 = time.perf_counter()
        model = derive(system, form, version=args.version, use_cache=not args.no_cache)
        dt = time.perf_counter() - t0
        print(model.to_text())
        print(f"  ({form}: {dt:.3f} s{', no cache' if args.no_cache else ''})\n")
        if form == "reduced":
            if args.table:
                print(model.symmetry.table_markdown() + "\n")
            if args.checks:
                _print_checks(model)
            if args.steps == "markdown":
                print(model.steps.to_markdown(model.symbol_names))
            elif args.steps == "latex":
                print(model.steps.to_latex(model.symbol_names))
    if args.table and "reduced" not in forms:
        print(symmetry_test(system).table_markdown())
    return 0


def _print_checks(model) -> None:
    import sympy as sp
    from nhgait.dynamics import jacobi_test
    res = jacobi_test(model)
    print(f"Jacobi identity of the reduced bracket: {'holds' if res.jacobi_holds else 'fails'} "
          f"(max relative Jacobiator {res.jacobiator:.2g}); constraints "
          f"{'holonomic' if res.holonomic else 'nonholonomic'} (max |ω[X_a, X_b]| {res.holonomy:.2g}); "
          f"thesis §2.2.2 (Jacobi ⇔ holonomic): {'consistent' if res.consistent else 'INCONSISTENT'}")
    print(f"classification (thesis Table 2.1): {model.classification}")
    print("initial-state map (Tables 3.2–3.3), P = Xᵀ M(q) q̇ on ω(q)q̇ = 0:")
    for s, e in zip(model.momenta, model.momenta_of_velocity):
        print(f"  {s} = {sp.sstr(e)}")
    if model.singular_set:
        print("singular set: " + " or ".join(f"{sp.sstr(e)} = 0" for e in model.singular_set))
    print()


def cmd_simulate(args) -> int:
    from nhgait.dynamics import derive
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.simulation import simulate
    scene = _scene(args.scene)
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="nhgait", description="Dynamics and gait planning of nonholonomic robots.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("derive", help="derive and print the equations of motion")
    p.add_argument("scene", help="scene file (.toml) or built-in name (unicycle, snakeboard, ...)")
    p.add_argument("--formulation", choices=["reduced", "lagrange", "hamilton", "all"], default="reduced")
    p.add_argument("--steps", choices=["latex", "markdown"], help="also print every step of the 20-step method")
    p.add_argument("--table", action="store_true", help="print the full-symmetry-group table (thesis Table 3.1)")
    p.add_argument("--checks", action="store_true",
                   help="Jacobi/holonomy test, Table 2.1 class, the (q, q̇) → state map and the singular set")
    p.add_argument("--version", choices=["A", "B"], help="g = identity (A) or SE(2)-type (B)")
    p.add_argument("--no-cache", action="store_true", help="derive afresh; do not read or write the cache")
    p.set_defaults(func=cmd_derive)

    p = sub.add_parser("simulate", help="integrate a scene's [simulation] and write a CSV")
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

    for module, adder in (("nhgait.gaits.cli_reproduce", "add_reproduce_parser"),
                          ("nhgait.gaits.cli_plan", "add_plan_parser")):
        try:
            mod = __import__(module, fromlist=[adder])
        except ModuleNotFoundError as exc:  # pragma: no cover - only while a module is missing
            if exc.name != module:
                raise
            continue
        getattr(mod, adder)(sub)
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
