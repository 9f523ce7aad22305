"""``nhgait simulate <scene.toml | built-in> [--method compiled] [--columns all] --out out/traj.csv``
(registered by :mod:`nhgait.gaits.cli.main`).

Integrates the scene's ``[simulation]`` table and writes a CSV whose header names each column's
unit (``t [s]``, ``x [m]`` …: the scene's ``[units]`` table, else the inference the figures use,
:func:`nhgait.dynamics.units.unit_of`; "SI" where neither places it).
When the scene states ``[simulation].outputs``, only the states those outputs depend on are
integrated (``--all-states`` integrates everything) and the CSV holds t and the outputs. The
summary line gives the number of states integrated, and the run time apart from the one-off
compilation of the integrator (``method="compiled"``: the first run of a model compiles C code,
later runs load it from the cache).

``--set KEY=VALUE`` changes the ``[simulation]`` table without editing the file (``t_final=20``,
``q0.x=0.5``, ``qdot0.theta=1``, ``inputs.F=0.2*sin(t)``, ``params.m=2``; the parser of
:mod:`~nhgait.dynamics.derivation.input.assignments`, shared with ``plan`` and ``sweep``).
``--plot DIR`` writes
``time_series.png``, ``path.png`` and ``checks.png`` (the constraint residual and the energy
balance; :mod:`nhgait.gaits.figures.trajectory`).
"""
from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

__all__ = ["add_simulate_parser", "cmd_simulate"]

COLUMNS = ("q", "qdot", "all", "state", "outputs")


def cmd_simulate(args) -> int:
    """Run the scene's [simulation] (with the command line's overrides), write the CSV and the
    figures asked for, print a summary; exit status 1 when the run stopped early."""
    from nhgait.dynamics import load_scene
    _check_arguments(args)
    out, plot = _checked_outputs(args)
    scene = load_scene(args.scene, overrides=args.overrides)
    model, traj, outputs, compile_s = _run(args, scene)
    columns = args.columns or ("outputs" if outputs else "q")
    if columns == "outputs" and not traj.outputs:
        from nhgait.dynamics.errors import ModelError
        raise ModelError(["--columns outputs needs [simulation].outputs in the scene"],
                         title="invalid request")
    _print_summary(scene, traj, compile_s)
    units = dict(scene.units or {})
    written = _write_csv(traj, out, columns, units, model.system) if out is not None else True
    if plot is not None and not _write_figures(traj, model, scene, plot):
        if out is None:                       # the figures were the only output: keep the run
            _write_csv(traj, None, columns, units, model.system)
        written = False
    if not traj.success:
        print(f"simulation stopped: {traj.message}", file=sys.stderr)
        return 1
    return 0 if written else 1


def _checked_outputs(args) -> tuple:
    """(the CSV path or None, the figure folder or None), checked before any derivation
    (:mod:`nhgait.gaits.files.outputs`: exit 2 for a location that cannot be written)."""
    from ..files.outputs import output_directory, output_file
    out = output_file(args.out) if args.out is not None else None
    plot = output_directory(args.plot, "--plot") if args.plot is not None else None
    return out, plot


def _write_csv(traj, out: Path | None, columns: str, units: dict, system) -> bool:
    """Write the CSV to ``out``; a write that fails (or ``out`` None) saves it to a fallback it
    names. True when written to ``out``."""
    from ..files.outputs import rescue, write_failure

    def write(path):
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        traj.to_csv(path, columns=columns, units=units, system=system)
    if out is None:
        print(f"  the run is kept: {rescue('trajectory.csv', write, 'trajectory')}")
        return False
    try:
        write(out)
    except OSError as exc:
        print(f"  NOT WRITTEN: {write_failure(exc, out)}; {rescue(out.name, write, 'trajectory')}")
        return False
    print(f"  wrote {out} (columns: {columns})")
    return True


def _write_figures(traj, model, scene, plot: Path) -> bool:
    """time_series.png, path.png and checks.png into ``plot``; a failure is reported (the CSV
    holds the run)."""
    from ..figures.trajectory import write_trajectory_figures
    from ..files.outputs import write_failure
    from ..tasks.sources import figure_tables
    tables = figure_tables(scene)              # a built-in's [drawing] from its gait library, as plan's
    try:
        files = write_trajectory_figures(traj, model, plot, units=tables.units, drawing=tables.drawing,
                                         params=scene.simulation.parameters)
    except OSError as exc:
        print(f"  figures NOT WRITTEN: {write_failure(exc, plot)}")
        return False
    print(f"  wrote {', '.join(str(f) for f in files)}")
    return True


def _check_arguments(args) -> None:
    """A known --method and somewhere to write (--out or --plot)."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.simulation.driver import METHODS
    if args.method is not None and args.method not in METHODS:
        from nhgait.dynamics.suggestions import known_names
        raise ModelError([f"--method {args.method!r} is not a "
                          f"method{known_names(args.method, METHODS, label='methods')}"],
                         title="invalid simulation request")
    if args.out is None and args.plot is None:
        raise ModelError(["give --out FILE.csv, --plot DIR or both"], title="invalid simulation request")


def _run(args, scene) -> tuple:
    """(model, Trajectory, the outputs asked for) of the scene's [simulation], the command
    line's options first."""
    from nhgait.dynamics import derive, simulate  # functions via the lazy exports
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
    kwargs = {"dae": args.dae} if model.dae_options_apply else {}
    method = args.method or spec.method or "DOP853"
    common = dict(controller=spec.controller, params=spec.parameters or None, method=method, rtol=rtol,
                  atol=atol, outputs=outputs, quantities=scene.quantities or None, **kwargs)
    with _still_integrating(f"{scene.system.name} with {method} to t = {spec.t_final:g} s"):
        compile_s = _estimate_first(simulate, model, spec, common)
        traj = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, t_eval=spec.t_eval, **common)
    through = _chart_singularity(model, traj, spec.parameters)
    if through is None:
        return model, traj, outputs, compile_s
    if args.formulation is not None or spec.formulation is not None:    # pinned: say what runs through
        return model, replace(traj, message=f"{traj.message}; {through}"), outputs, compile_s
    print(f"nhgait simulate: {traj.message}\nnhgait simulate: {through}: integrating again with it "
          "(--formulation reduced keeps the stop)", file=sys.stderr, flush=True)
    model = derive(scene.system, "lagrange", use_cache=not args.no_cache)
    kwargs = {"dae": args.dae} if model.dae_options_apply else {}
    with _still_integrating(f"{scene.system.name} (lagrange) with {method} to t = {spec.t_final:g} s"):
        traj = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, t_eval=spec.t_eval,
                        **{**common, **kwargs})
    return model, traj, outputs, 0.0


def _chart_singularity(model, traj, parameters) -> str | None:
    """The sentence naming the formulation that runs through where the reduced run stopped —
    "--formulation lagrange runs through it …" — when the run stopped at the reduced chart's
    singular set (status SINGULAR) and the robot itself is regular there: ω(q) keeps rank k
    and M(q) stays positive definite at the last configuration (the set is the chart's, the
    pivot block B = ω[:, pivots] or the locked inertia, not the robot's). Else None."""
    import numpy as np

    from nhgait.dynamics.derivation.parameter_checks import numeric_functions
    from nhgait.dynamics.simulation.driver import SINGULAR
    if traj.status != SINGULAR or traj.formulation != "reduced":
        return None
    system = model.system
    q, pv = np.asarray(traj.q[-1], dtype=float), system.param_vector(parameters or None)
    mass, omega, _ = numeric_functions(system)
    M = np.array(mass(q, pv), dtype=float)
    W = (np.array(omega(q, pv), dtype=float).reshape(system.k, system.n) if system.k
         else np.zeros((0, system.n)))
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(W))):
        return None
    sv = np.linalg.svd(W, compute_uv=False) if system.k else np.ones(1)
    if sv.min() <= 1e-8 * max(1.0, sv.max()) or np.linalg.eigvalsh(0.5 * (M + M.T))[0] <= 0:
        return None
    named = {str(x) for e in getattr(model, "singular_set", ()) for x in getattr(e, "free_symbols", ())}
    where = ", ".join(f"{c} = {v:.6g}" for c, v in zip(system.coordinates, q, strict=True)
                      if c in named or not named)
    return (f"--formulation lagrange runs through it: the set is the reduced chart's, not the robot's "
            f"(at {where} the constraints keep rank {system.k}, smallest singular value of ω(q) "
            f"{sv.min():.3g}, and M(q) is positive definite)")


#: seconds between the lines of a run that goes on (:func:`_still_integrating`)
HEARTBEAT_S = 10.0


@contextmanager
def _still_integrating(what: str, every: float = HEARTBEAT_S):
    """A line on stderr every ``every`` seconds while the block runs: a run whose first steps
    did not foresee its cost (forces that switch with the sign of a velocity, chattering
    across it) said nothing for 150 s before max_steps stopped it."""
    stop, start = threading.Event(), time.perf_counter()

    def beat():
        while not stop.wait(every):
            print(f"nhgait simulate: still integrating {what} ({time.perf_counter() - start:.0f} s; "
                  f"max_steps = {MAX_STEPS:,} steps end it at the latest)", file=sys.stderr, flush=True)
    thread = threading.Thread(target=beat, name="simulate-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


#: steps of the first look at a run (methods whose max_steps counts every step: scipy, compiled)
PROBE_STEPS = 2000
#: a run the first steps predict to need more than this many times max_steps is refused
REFUSE_FACTOR = 100
#: a run predicted to take longer than this (seconds) says so first
SAY_AFTER_S = 10.0
#: max_steps of simulate (its default)
MAX_STEPS = 1_000_000
#: more output samples than this say their cost first (about 1.2 kB and 50 µs each)
MANY_SAMPLES = 100_000


def _estimate_first(simulate, model, spec, common) -> float:
    """Look at the first :data:`PROBE_STEPS` steps of the run (every accepted step reported) and
    extrapolate to t_final: a run that would take longer than :data:`SAY_AFTER_S` says its
    estimate on stderr first; one that needs more than :data:`REFUSE_FACTOR` × max_steps (so
    that max_steps would stop it after a small part of its span, minutes later) is refused at
    once (exit 2). SUNDIALS methods count max_steps per output interval: not looked at.
    Returns the seconds the look spent compiling the integrator (the run itself then loads it)."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.simulation.driver import MAX_STEPS as STOPPED_BY_MAX_STEPS
    if spec.samples > MANY_SAMPLES:
        print(f"nhgait simulate: {spec.samples:,} samples: about {spec.samples * 1.2e3 / 1e6:.0f} MB and "
              f"{_duration(spec.samples * 50e-6)} to evaluate and write the outputs (measured for "
              "the unicycle; more for more states)", file=sys.stderr, flush=True)
    if str(common["method"]).upper() in ("CVODES", "IDAS", "AUTO"):
        return 0.0
    span = spec.t_final - spec.t0
    probe = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, t_eval=None,
                     max_steps=PROBE_STEPS, **common)
    compile_s = float(probe.diagnostics.get("compile_time_s") or 0.0)
    if probe.status != STOPPED_BY_MAX_STEPS or not probe.t[-1] > spec.t0:
        return compile_s
    ratio = span / (probe.t[-1] - spec.t0)
    steps = PROBE_STEPS * ratio
    seconds = max(probe.wall_time_s - compile_s, 0.0) * ratio
    first = (f"the first {PROBE_STEPS} steps of {common['method']} reached t = {probe.t[-1]:.4g} s "
             f"of t_final = {spec.t_final:.4g} s")
    if steps > REFUSE_FACTOR * MAX_STEPS:
        raise ModelError([f"{first}: the whole run needs about {steps:.1e} steps and "
                          f"{_duration(seconds)}, far beyond "
                          f"max_steps = {MAX_STEPS:,}, which would stop it near t = "
                          f"{spec.t0 + span * MAX_STEPS / steps:.4g} s; "
                          "shorten t_final (--set t_final=...)"], title="simulation beyond reach")
    if seconds > SAY_AFTER_S:
        stop = (f"; max_steps = {MAX_STEPS:,} will probably stop it near t = "
                f"{spec.t0 + span * MAX_STEPS / steps:.4g} s"
                if steps > MAX_STEPS else "")
        print(f"nhgait simulate: {first}: the whole run needs about {steps:.2g} steps and "
              f"{_duration(seconds)} (an extrapolation){stop}", file=sys.stderr, flush=True)
    return compile_s


def _duration(seconds: float) -> str:
    from nhgait.dynamics.countdown import duration
    return duration(seconds)


def _print_summary(scene, traj, compile_s: float = 0.0) -> None:
    """What ran, how far, at what cost; the end state and the run's own checks."""
    import numpy as np
    used, total = traj.diagnostics["state_count"]
    status = "" if traj.success else " — STOPPED"
    print(f"{scene.system.name}: {traj.formulation} formulation, {traj.method}, {used} of {total} states "
          f"integrated ({', '.join(traj.state_names)}), {len(traj.t)} samples to "
          f"t = {traj.t[-1]:.6g} s ({traj.nfev} evaluations, {_timing(traj, compile_s)}){status}")
    if "fallback" in traj.settings:
        print(f"  note: {traj.settings['fallback']}")
    if "auto" in traj.settings:
        print(f"  auto: {traj.settings['auto']}")
    finite = np.isfinite(traj.q[-1])
    q_end = ", ".join(f"{c}={v:.8g}"
                      for c, v, ok in zip(scene.system.coordinates, traj.q[-1], finite, strict=True) if ok)
    print(f"  q(t_end): {q_end}")
    if traj.constraint_residual.size and np.isfinite(traj.constraint_residual).all():
        print(f"  max |ω(q)q̇| = {np.abs(traj.constraint_residual).max():.3g}, "
              f"max |energy balance| = {np.nanmax(np.abs(traj.energy_balance)):.3g}")
    if traj.holonomic_residual is not None and traj.holonomic_residual.size:
        print(f"  max |h(q)| = {np.nanmax(np.abs(traj.holonomic_residual)):.3g} (drift from the holonomic "
              "constraints kept)")
    if "recommendation" in traj.diagnostics:
        print(f"  {traj.diagnostics['recommendation']}")


def _timing(traj, earlier_compile_s: float = 0.0) -> str:
    """"run 0.087 s" or "run 0.087 s + compiling the integrator 1.07 s (once per model; cached)"
    (``earlier_compile_s``: compiled by the first look at the run, :func:`_estimate_first`)."""
    if earlier_compile_s > 0:        # compiled by the first look: this run loaded it (its loop is shared)
        compile_s, run_s = earlier_compile_s, traj.wall_time_s
    else:
        compile_s = float(traj.diagnostics.get("compile_time_s") or 0.0)
        run_s = traj.wall_time_s - compile_s
    run = f"run {run_s:.3f} s"
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
                   help="write time_series.png (coordinates and inputs with units), checks.png (constraint "
                        "residual, energy balance) and path.png (x-y path "
                        "with the scene's [drawing]) into DIR")
    p.add_argument("--no-cache", action="store_true")
    p.set_defaults(func=cmd_simulate)
    return p
