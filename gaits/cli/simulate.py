"""``nhgait simulate <scene.toml | built-in> [--method compiled] [--columns all] --out out/traj.csv``
(registered by :mod:`nhgait.gaits.cli.main`).

Integrates the scene's ``[simulation]`` table and writes a CSV whose header names each column's
unit (``t [s]``, ``x [m]`` …: from the scene's ``[units]`` table, "SI" where it names none).
When the scene states ``[simulation].outputs``, only the states those outputs depend on are
integrated (``--all-states`` integrates everything) and the CSV holds t and the outputs. The
summary line gives the number of states integrated, and the run time apart from the one-off
compilation of the integrator (``method="compiled"``: the first run of a model compiles C code,
later runs load it from the cache).

``--set KEY=VALUE`` changes the ``[simulation]`` table without editing the file (``t_final=20``,
``q0.x=0.5``, ``qdot0.theta=1``, ``inputs.F=0.2*sin(t)``, ``params.m=2``; the parser of
:mod:`nhgait.dynamics.derivation.assignments`, shared with ``plan`` and ``sweep``). ``--plot DIR`` writes
``time_series.png`` and ``path.png`` (:mod:`nhgait.gaits.trajectory_plots`).
"""
from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["add_simulate_parser", "cmd_simulate"]

COLUMNS = ("q", "qdot", "all", "state", "outputs")


def cmd_simulate(args) -> int:
    """Run the scene's [simulation] (with the command line's overrides), write the CSV and the
    figures asked for, print a summary; exit status 1 when the run stopped early."""
    from nhgait.dynamics import load_scene
    _check_arguments(args)
    scene = load_scene(args.scene, overrides=args.overrides)
    model, traj, outputs = _run(args, scene)
    columns = args.columns or ("outputs" if outputs else "q")
    if columns == "outputs" and not traj.outputs:
        from nhgait.dynamics.errors import ModelError
        raise ModelError(["--columns outputs needs [simulation].outputs in the scene"],
                         title="invalid request")
    out = None
    if args.out is not None:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        traj.to_csv(out, columns=columns, units=dict(scene.units or {}))
    _print_summary(scene, traj)
    if out is not None:
        print(f"  wrote {out} (columns: {columns})")
    if args.plot is not None:
        from ..trajectory_plots import write_trajectory_figures
        files = write_trajectory_figures(traj, model, args.plot, units=dict(scene.units or {}),
                                         drawing=scene.drawing, params=scene.simulation.parameters)
        print(f"  wrote {', '.join(str(f) for f in files)}")
    if not traj.success:
        print(f"simulation stopped: {traj.message}", file=sys.stderr)
        return 1
    return 0


def _check_arguments(args) -> None:
    """A known --method and somewhere to write (--out or --plot)."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.simulation.driver import METHODS
    if args.method is not None and args.method not in METHODS:
        from nhgait.dynamics.suggestions import known_names
        raise ModelError([f"--method {args.method!r} is not a method{known_names(args.method, METHODS, label='methods')}"],
                         title="invalid simulation request")
    if args.out is None and args.plot is None:
        raise ModelError(["give --out FILE.csv, --plot DIR or both"], title="invalid simulation request")


def _run(args, scene) -> tuple:
    """(model, Trajectory, the outputs asked for) of the scene's [simulation], the command
    line's options first."""
    from nhgait.dynamics import derive, simulate  # functions via the lazy exports
    from nhgait.dynamics.derivation.formulation_protocol import protocol_named
    from nhgait.dynamics.errors import ModelError
    spec = scene.simulation
    if spec is None:
        raise ModelError([f"{scene.source} has no [simulation] table (q0, qdot0, t_final, samples)"],
                         title="cannot simulate")
    form = args.formulation or spec.formulation or "reduced"
    model = derive(scene.system, form, use_cache=not args.no_cache)
    rtol = args.rtol if args.rtol is not None else (spec.rtol or 1e-8)
    atol = args.atol if args.atol is not None else (spec.atol or rtol * 1e-2)
    outputs = None if args.all_states else spec.outputs
    kwargs = {"dae": args.dae} if protocol_named(form).dae_options_apply else {}
    traj = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, controller=spec.controller,
                    params=spec.parameters or None, method=args.method or spec.method or "DOP853",
                    rtol=rtol, atol=atol, t_eval=spec.t_eval, outputs=outputs,
                    quantities=scene.quantities or None, **kwargs)
    return model, traj, outputs


def _print_summary(scene, traj) -> None:
    """What ran, how far, at what cost; the end state and the run's own checks."""
    import numpy as np
    used, total = traj.diagnostics["state_count"]
    status = "" if traj.success else " — STOPPED"
    print(f"{scene.system.name}: {traj.formulation} formulation, {traj.method}, {used} of {total} states "
          f"integrated ({', '.join(traj.state_names)}), {len(traj.t)} samples to "
          f"t = {traj.t[-1]:.6g} s ({traj.nfev} evaluations, {_timing(traj)}){status}")
    if "fallback" in traj.settings:
        print(f"  note: {traj.settings['fallback']}")
    if "auto" in traj.settings:
        print(f"  auto: {traj.settings['auto']}")
    finite = np.isfinite(traj.q[-1])
    q_end = ", ".join(f"{c}={v:.8g}" for c, v, ok in zip(scene.system.coordinates, traj.q[-1], finite) if ok)
    print(f"  q(t_end): {q_end}")
    if traj.constraint_residual.size and np.isfinite(traj.constraint_residual).all():
        print(f"  max |ω(q)q̇| = {np.abs(traj.constraint_residual).max():.3g}, "
              f"max |energy balance| = {np.nanmax(np.abs(traj.energy_balance)):.3g}")
    if traj.holonomic_residual is not None and traj.holonomic_residual.size:
        print(f"  max |h(q)| = {np.nanmax(np.abs(traj.holonomic_residual)):.3g} (drift from the holonomic "
              "constraints kept)")
    if "recommendation" in traj.diagnostics:
        print(f"  {traj.diagnostics['recommendation']}")


def _timing(traj) -> str:
    """"run 0.087 s" or "run 0.087 s + compiling the integrator 1.07 s (once per model; cached)"."""
    compile_s = float(traj.diagnostics.get("compile_time_s") or 0.0)
    run = f"run {traj.wall_time_s - compile_s:.3f} s"
    if compile_s <= 0:
        return run
    return f"{run} + compiling the integrator {compile_s:.3f} s (once per model; cached for the next run)"


def add_simulate_parser(subparsers):
    """Add the ``simulate`` subcommand to an argparse ``subparsers`` object (the method is
    checked when the command runs: the list lives with the integrators, a heavy import)."""
    p = subparsers.add_parser("simulate", help="integrate a scene's [simulation] and write a CSV")
    p.add_argument("scene")
    p.add_argument("--formulation", choices=["reduced", "lagrange", "hamilton"])
    p.add_argument("--rtol", type=float)
    p.add_argument("--atol", type=float)
    p.add_argument("--method",
                   help="scipy (DOP853, RK45, Radau, BDF, LSODA, RK23), CVODES, compiled "
                        "(Dormand-Prince 8(5,3) in C), compiled-DOPRI5, auto (compiled, switches to "
                        "CVODES when stiff); default: the scene's method or DOP853")
    p.add_argument("--dae", choices=["index1", "idas"], default="index1",
                   help="DAE forms: index-reduced ODE (default) or CasADi IDAS")
    p.add_argument("--columns", choices=COLUMNS,
                   help="q (default), qdot (q and velocities), all (also inputs, multipliers, "
                        "constraint residuals, energy, work, energy balance), state, outputs "
                        "(default when the scene states [simulation].outputs)")
    p.add_argument("--all-states", action="store_true",
                   help="integrate every state even when the scene states its outputs")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="change the scene's [simulation] (repeatable): t_final=20, samples=401, q0.x=0.5, "
                        "qdot0.theta=1, inputs.F=0.2*sin(t), params.m=2, rtol=1e-10, method=compiled")
    p.add_argument("--out", default=None, help="CSV path, e.g. out/traj.csv")
    p.add_argument("--plot", default=None, metavar="DIR",
                   help="write time_series.png (coordinates and inputs with units) and path.png (x-y path "
                        "with the scene's [drawing]) into DIR")
    p.add_argument("--no-cache", action="store_true")
    p.set_defaults(func=cmd_simulate)
    return p
