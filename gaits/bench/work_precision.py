"""Work-precision measurements: final-state error against wall time, per formulation, method
and tolerance — the engine of ``experiments/work_precision.py`` and ``nhgait bench precision``.

A :class:`Case` is one simulation (a system's derived formulations, a controller, an initial
state, a horizon); a :class:`Setup` is one way to integrate it (formulation, ``simulate``
method, DAE route, stabilisation). :func:`measure` runs every setup at every tolerance
(atol = rtol·10⁻²) and returns one :class:`Row` each:

* ``error``: max-norm of (q(T), q̇(T)) against a reference state computed by the caller with a
  *different* method at a tighter tolerance (the caller says which in ``Case.reference``);
* ``wall_s``: median wall time of ``repeats`` calls of :func:`~nhgait.dynamics.simulate` that
  report the final state only (after one untimed warm-up call, so a one-time compilation is
  not counted; it is reported as ``compile_s``);
* ``constraint``, ``energy_drift``: max |ω(q)q̇| and max |E − E(0) − W| on an untimed run with
  the same settings on a grid of ``Limits.grid`` points;
* ``nfev``, ``n_steps``, ``status``.

The plots take an optional ``ax`` and never change global matplotlib state.
"""
from __future__ import annotations

import contextlib
import csv
import math
import statistics
import time
from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["Case", "Setup", "Row", "Limits", "measure", "time_call", "write_csv", "read_csv", "plot_case",
           "markdown_table", "time_at_error", "TOLERANCES", "default_setups", "c_integrator_timer"]

#: tolerances of the full report
TOLERANCES = tuple(10.0 ** -k for k in range(4, 13))


@dataclass(frozen=True)
class Setup:
    """One way to integrate a case."""

    formulation: str
    method: str
    dae: str = "index1"
    stabilization: str | None = None
    baumgarte: tuple = (1.0, 0.0)

    @property
    def label(self) -> str:
        route = "IDAS" if self.dae == "idas" else self.method
        extra = f"+{self.stabilization}" if self.stabilization else ""
        return f"{self.formulation}/{route}{extra}"

    def options(self) -> dict:
        from nhgait.dynamics.derivation.formulations import formulation_type
        opts = {"method": self.method}
        if formulation_type(self.formulation).dae_options_apply:   # baumgarte is read only with its law
            opts.update(dae=self.dae, stabilization=self.stabilization, baumgarte=self.baumgarte)
        return opts


@dataclass(frozen=True, eq=False)
class Case:
    """A simulation to measure: ``models`` maps formulation → derived model."""

    name: str
    models: dict
    controller: object
    q0: np.ndarray
    qdot0: np.ndarray
    t_final: float
    reference: tuple = ()          # (q(T), q̇(T)) of the reference solution
    reference_label: str = ""
    params: dict | None = None
    outputs: tuple | None = None
    description: str = ""


@dataclass(frozen=True)
class Row:
    """One measurement (see the module docstring)."""

    case: str
    label: str
    formulation: str
    method: str
    rtol: float
    error: float
    wall_s: float
    wall_all_s: tuple
    nfev: int
    n_steps: int
    constraint: float
    energy_drift: float
    success: bool
    status: int
    states: int
    compile_s: float = 0.0
    note: str = ""

    def as_dict(self) -> dict:
        d = asdict(self)
        d["wall_all_s"] = " ".join(f"{w:.6g}" for w in self.wall_all_s)
        return d


def default_setups(formulations=("reduced", "lagrange", "hamilton"),
                   methods=("RK45", "DOP853", "Radau", "LSODA", "CVODES", "compiled"),
                   idas=True) -> list:
    """Every formulation × method, plus IDAS for the DAE forms."""
    from nhgait.dynamics.derivation.formulations import formulation_type
    setups = [Setup(f, m) for f in formulations for m in methods]
    if idas:
        setups += [Setup(f, "DOP853", dae="idas") for f in formulations
                   if formulation_type(f).dae_options_apply]
    return setups


def time_call(fn, repeats: int):
    """(median wall time, all times, last result) of ``repeats`` calls of ``fn()``."""
    times, result = [], None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), tuple(times), result


@contextlib.contextmanager
def c_integrator_timer():
    """Within the block, every call of the compiled integrator's C core
    (:meth:`~nhgait.dynamics.simulation.compiled.CompiledLoop.run`) is timed: yields the list its
    wall times are appended to (clear it before each ``simulate`` call)."""
    from nhgait.dynamics.simulation import compiled
    original, times = compiled.CompiledLoop.run, []

    def timed(self, *args, **kwargs):
        start = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            times.append(time.perf_counter() - start)
    compiled.CompiledLoop.run = timed
    try:
        yield times
    finally:
        compiled.CompiledLoop.run = original


def _final_error(traj, reference) -> float:
    if not traj.success or not reference:
        return math.nan
    q_ref, qd_ref = reference
    cols = np.isfinite(traj.q[-1])
    err = np.r_[np.abs(traj.q[-1][cols] - np.asarray(q_ref)[cols]),
                np.abs(traj.qdot[-1][cols] - np.asarray(qd_ref)[cols])]
    return float(err.max())


@dataclass(frozen=True)
class Limits:
    """How :func:`measure` spends its time: ``grid`` points of the untimed run that measures the
    constraint and energy drift; a setup whose run took longer than ``max_wall_s`` is not run at
    tighter tolerances."""

    grid: int = 201
    max_wall_s: float = 20.0


def measure(case: Case, setups, tolerances=TOLERANCES, repeats: int = 5, progress=None,
            limits: Limits = Limits()) -> list:
    """Run every setup at every tolerance (loosest first); a setup whose run took longer than
    ``limits.max_wall_s`` is not run at tighter tolerances (noted in the row)."""
    from nhgait.dynamics import simulate
    grid, max_wall_s = limits.grid, limits.max_wall_s
    rows = []
    span = (0.0, float(case.t_final))
    for setup in setups:
        model = case.models[setup.formulation]
        too_slow = None
        for rtol in sorted(tolerances, reverse=True):
            if too_slow is not None:
                rows.append(_skipped(case, setup, rtol, too_slow))
                continue

            def run(t_eval=(span[0], span[1]), model=model, rtol=rtol, setup=setup):
                return simulate(model, span, case.q0, case.qdot0, controller=case.controller,
                                params=case.params, rtol=rtol, atol=rtol * 1e-2, t_eval=t_eval,
                                outputs=case.outputs, **setup.options())
            warm_start = time.perf_counter()
            warm = run()
            warm_s = time.perf_counter() - warm_start
            compile_s = float(warm.diagnostics.get("compile_time_s", 0.0) or 0.0)
            reps = repeats if warm_s < max_wall_s / max(repeats, 1) else max(1, min(repeats, 3))
            wall, walls, traj = time_call(run, reps)
            dense = run(np.linspace(span[0], span[1], grid))
            rows.append(Row(case=case.name, label=setup.label, formulation=setup.formulation,
                            method=traj.method, rtol=rtol, error=_final_error(traj, case.reference),
                            wall_s=wall, wall_all_s=walls, nfev=traj.nfev, n_steps=traj.n_steps,
                            constraint=_max_abs(dense.constraint_residual),
                            energy_drift=_max_abs(dense.energy_balance), success=traj.success,
                            status=traj.status, states=traj.diagnostics["state_count"][0],
                            compile_s=compile_s,
                            note=traj.settings.get("fallback", "") or traj.settings.get("auto", "")
                            or ("" if traj.success else traj.message[:120])))
            if progress is not None:
                progress(rows[-1])
            if wall > max_wall_s:
                too_slow = f"not run: {wall:.1f} s at rtol {rtol:g} already"
    return rows


def _skipped(case, setup, rtol, note) -> Row:
    return Row(case=case.name, label=setup.label, formulation=setup.formulation, method=setup.method,
               rtol=rtol, error=math.nan, wall_s=math.nan, wall_all_s=(), nfev=0, n_steps=0,
               constraint=math.nan, energy_drift=math.nan, success=False, status=0, states=0,
               note=note)


def _max_abs(a) -> float:
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.max(np.abs(a))) if a.size else math.nan


def write_csv(rows, path) -> None:
    """All rows as CSV (one line per run; ``wall_all_s`` space-separated)."""
    rows = list(rows)
    if not rows:
        return
    names = list(rows[0].as_dict())
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=names)
        writer.writeheader()
        for r in rows:
            writer.writerow(r.as_dict())


def read_csv(path) -> list:
    """Rows written by :func:`write_csv` (to redraw figures without re-running)."""
    rows = []
    with open(path, newline="") as fh:
        for d in csv.DictReader(fh):
            rows.append(Row(case=d["case"], label=d["label"], formulation=d["formulation"],
                            method=d["method"], rtol=float(d["rtol"]), error=float(d["error"]),
                            wall_s=float(d["wall_s"]),
                            wall_all_s=tuple(float(v) for v in d["wall_all_s"].split()),
                            nfev=int(d["nfev"]), n_steps=int(d["n_steps"]),
                            constraint=float(d["constraint"]), energy_drift=float(d["energy_drift"]),
                            success=d["success"] == "True", status=int(d["status"]),
                            states=int(d["states"]), compile_s=float(d["compile_s"]), note=d["note"]))
    return rows


class FastestAtError(NamedTuple):
    """What :func:`time_at_error` returns."""

    wall_s: float   #: the fastest median wall time with error ≤ level (nan: none)
    row: object     #: its row, or None


def time_at_error(rows, level: float) -> FastestAtError:
    """(fastest median wall time with error ≤ level, its row) among ``rows``, or (nan, None)."""
    ok = [r for r in rows if r.success and np.isfinite(r.error) and r.error <= level]
    if not ok:
        return FastestAtError(math.nan, None)
    best = min(ok, key=lambda r: r.wall_s)
    return FastestAtError(best.wall_s, best)


def plot_case(rows, ax=None, *, title: str = "", anchor=None):
    """Error against wall time on log-log axes: one curve per setup (label), one marker per
    tolerance (annotated at the loosest and tightest); ``anchor`` rows drawn in black."""
    if ax is None:
        import matplotlib.pyplot as plt
        _, ax = plt.subplots(figsize=(7.5, 5.5))
    from nhgait.gaits.figures.style import series_styles
    labels = list(dict.fromkeys(r.label for r in rows))
    styles = series_styles(len(labels), markers=True)      # distinct colour/marker/line per series
    for i, label in enumerate(labels):
        pts = [r for r in rows if r.label == label and r.success and np.isfinite(r.error) and r.error > 0]
        if not pts:
            continue
        pts.sort(key=lambda r: r.rtol, reverse=True)
        ax.loglog([r.wall_s for r in pts], [r.error for r in pts], ms=4, lw=1, label=label, **styles[i])
    pts = sorted([r for r in anchor or () if r.success and r.error > 0], key=lambda r: r.rtol, reverse=True)
    if pts:
        ax.loglog([r.wall_s for r in pts], [r.error for r in pts], "k--*", ms=9, lw=1,
                  label="anchor: LagrangesMethod + lambdify, scipy DOP853")
        for r in pts:
            ax.annotate(f"{r.rtol:.0e}", (r.wall_s, r.error), fontsize=6, xytext=(3, 3),
                        textcoords="offset points")
    ax.set_xlabel("wall time per run, median [s]")
    ax.set_ylabel("final-state error max|Δq|, |Δq̇| [m, rad, m/s, rad/s]")
    ax.set_title(title or "work-precision (one marker per tolerance, rtol 1e-4 … 1e-12)", fontsize=9)
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=6, loc="upper right", title="formulation/method (one marker per rtol)",
              title_fontsize=6)
    return ax


def markdown_table(rows, *, columns=("label", "rtol", "error", "wall_s", "nfev", "constraint",
                                     "energy_drift", "states", "note")) -> str:
    """A Markdown table of ``rows`` (times in ms)."""
    heads = {"label": "formulation/method", "rtol": "rtol", "error": "error", "wall_s": "wall [ms]",
             "nfev": "nfev", "constraint": "max abs ω q̇", "energy_drift": "max abs energy balance",
             "states": "states", "note": "note"}
    lines = ["| " + " | ".join(heads[c] for c in columns) + " |",
             "|" + "---|" * len(columns)]
    for r in rows:
        cells = []
        for c in columns:
            v = getattr(r, c)
            if c == "wall_s":
                cells.append("—" if not np.isfinite(v) else f"{v * 1e3:.3g}")
            elif c in ("error", "constraint", "energy_drift", "rtol"):
                cells.append("—" if not np.isfinite(v) else f"{v:.2g}")
            else:
                cells.append(str(v).replace("|", "\\|"))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
