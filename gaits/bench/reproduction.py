"""Reproduction of the thesis's simulations (§3.3): unicycle and snakeboard under PD control,
every formulation, both DAE routes, one JSON summary and the figures 3.8–3.11 and 3.13–3.17.

Cases
-----
* unicycle, t ∈ [0, 2π], controller eqs. 3.52–3.53, initial state Table 3.2;
* snakeboard, t ∈ [0, 10π], controller eqs. 3.95–3.96, initial state Table 3.3.

Initial state (Tables 3.2–3.3, as stated for the Lagrangian form and mapped by the engine to
every formulation's state): all coordinates 0 except the tracked ones at q_d(0); tracked
velocities q̇_d(0); the untracked velocities are the least-norm solution of ω(q)q̇ = 0 (unicycle:
ẋ = r cos θ φ̇, ẏ = r sin θ φ̇; snakeboard: ẋ = ẏ = θ̇ = 0, as in the table).

Runs (labels): ``reduced`` (DOP853 on the reduced ODE), ``lagrange`` and ``hamilton`` (index-1
route, DOP853), ``lagrange/idas`` and ``hamilton/idas`` (CasADi IDAS with λ algebraic). A
``reference`` callable may add an independent run (``experiments/reproduce_thesis.py`` adds
KanesMethod + DOP853); it is then the thick reference line of the figures.

This module uses only the engine (``nhgait.dynamics``); it imports nothing from ``tests``.
"""
from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from nhgait.dynamics.derivation.formulations import FORMULATIONS
from nhgait.dynamics.derivation.states import constraint_residual
from nhgait.dynamics.simulation.controllers import snakeboard_pd, unicycle_pd

#: name → (controller factory, final time, number of output points)
CASES = {
    "unicycle": (unicycle_pd, 2 * math.pi, 1001),
    "snakeboard": (snakeboard_pd, 10 * math.pi, 2001),
}

#: figure files per case: (file stem, kind, argument)
FIGURES = {
    "unicycle": (("fig3_08_unicycle_xy", "path", None), ("fig3_09_unicycle_theta", "q", "theta"),
                 ("fig3_10_unicycle_phi", "q", "phi"), ("fig3_11_unicycle_lambda", "lambda", None)),
    "snakeboard": (("fig3_13_snakeboard_xy", "path", None), ("fig3_14_snakeboard_theta", "q", "theta"),
                   ("fig3_15_snakeboard_psi", "q", "psi"), ("fig3_16_snakeboard_phi", "q", "phi"),
                   ("fig3_17_snakeboard_lambda", "lambda", None)),
}


def thesis_initial_state(model, controller, params=None):
    """(q0, q̇0), each (n,), of Tables 3.2–3.3 for ``controller``'s tracked coordinates."""
    system = model.system
    n = system.n
    q0, qdot0 = np.zeros(n), np.zeros(n)
    qd, vd = controller.initial_state(0.0)
    tracked = [system.coordinates.index(c) for c in controller.coordinates]
    q0[tracked], qdot0[tracked] = qd, vd
    free = [i for i in range(n) if i not in tracked]
    # ω(q0) column by column from the engine's residual ω(q)q̇ (linear in q̇)
    omega = np.column_stack([constraint_residual(model, q0, np.eye(n)[j], params) for j in range(n)])
    rhs = -omega[:, tracked] @ qdot0[tracked]
    qdot0[free] = np.linalg.lstsq(omega[:, free], rhs, rcond=None)[0]
    return q0, qdot0


def run_case(name, *, rtol=1e-10, formulations=FORMULATIONS, idas=True, params=None):
    """All runs of one thesis case.

    Returns
    -------
    dict with ``t_eval`` (N,), ``q0``, ``qdot0`` (n,), ``controller`` and ``runs``
    (label → :class:`~nhgait.dynamics.simulation.driver.Trajectory`).
    """
    from nhgait.dynamics import builtin, derive, simulate  # the derivations: loaded when a case runs
    factory, t_final, n_points = CASES[name]
    controller = factory()
    system = builtin(name)
    t_eval = np.linspace(0.0, t_final, n_points)
    atol = rtol * 1e-2
    runs, q0, qdot0 = {}, None, None
    for formulation in formulations:
        model = derive(system, formulation)
        if q0 is None:
            q0, qdot0 = thesis_initial_state(model, controller, params)
        routes = ("index1", "idas") if idas and model.dae_options_apply else ("index1",)
        for dae in routes:
            label = formulation if dae == "index1" else f"{formulation}/idas"
            runs[label] = simulate(model, (0.0, t_final), q0, qdot0, controller=controller,
                                   params=params, rtol=rtol, atol=atol, t_eval=t_eval, dae=dae)
    return {"t_eval": t_eval, "q0": q0, "qdot0": qdot0, "controller": controller, "runs": runs,
            "system": system}


def _max_abs(a):
    return float(np.max(np.abs(a))) if a is not None and np.size(a) else 0.0


def summarize(case, references=None) -> dict:
    """JSON-ready summary of one case: final states, pairwise max deviations, checks, costs.

    ``references`` maps a label to (t (N,), q (N, n), info dict) on the case's ``t_eval`` grid.
    """
    runs = case["runs"]
    system = case["system"]
    coords = list(system.coordinates)
    q_by_label = {label: run.q for label, run in runs.items() if run.success}
    for label, (_, q_ref, _) in (references or {}).items():
        q_by_label[label] = np.asarray(q_ref)
    out = {
        "t_final": float(case["t_eval"][-1]),
        "n_points": int(case["t_eval"].size),
        "params": runs[next(iter(runs))].settings["params"],
        "q0": dict(zip(coords, case["q0"].tolist(), strict=True)),
        "qdot0": dict(zip(coords, case["qdot0"].tolist(), strict=True)),
        "runs": {},
        "max_deviation_q": {},
        "max_deviation_lambda": {},
    }
    for label, run in runs.items():
        out["runs"][label] = {
            "success": bool(run.success), "message": run.message, "method": run.method,
            "dae": run.settings["dae"],
            "final_q": dict(zip(coords, run.q[-1].tolist(), strict=True)),
            "final_state": dict(zip(run.state_names, run.state[-1].tolist(), strict=True)),
            "final_lambda": None if run.lam is None else run.lam[-1].tolist(),
            "max_abs_constraint_residual": _max_abs(run.constraint_residual),
            "max_abs_energy_balance": _max_abs(run.energy_balance),
            "wall_time_s": run.wall_time_s, "nfev": run.nfev, "njev": run.njev,
            "n_steps": run.n_steps,
        }
    for label, (_, q_ref, info) in (references or {}).items():
        out["runs"][label] = {"final_q": dict(zip(coords, np.asarray(q_ref)[-1].tolist(), strict=True)),
                              **info}
    for a, b in itertools.combinations(q_by_label, 2):
        if q_by_label[a].shape == q_by_label[b].shape:
            out["max_deviation_q"][f"{a} vs {b}"] = _max_abs(q_by_label[a] - q_by_label[b])
    with_lam = [label for label, run in runs.items() if run.lam is not None and run.success]
    for a, b in itertools.combinations(with_lam, 2):
        out["max_deviation_lambda"][f"{a} vs {b}"] = _max_abs(runs[a].lam - runs[b].lam)
    return out


class _Reference:
    """A reference solution shaped like a trajectory for the plots."""

    def __init__(self, t, q, coordinates):
        self.t, self.q, self.coordinates, self.lam = np.asarray(t), np.asarray(q), tuple(coordinates), None


def write_figures(name, case, out_dir, references=None) -> list:
    """The case's thesis figures as PNG files in ``out_dir``; returns their paths."""
    from .thesis_plots import multiplier_figure, plot_coordinate, plot_path, save

    runs = dict(case["runs"])
    coords = case["system"].coordinates
    reference = "reduced" if "reduced" in runs else next(iter(runs))
    for label, (t_ref, q_ref, _) in (references or {}).items():
        runs = {label: _Reference(t_ref, q_ref, coords), **runs}
        reference = label
    title_case = f"{name}, t ∈ [0, {case['t_eval'][-1]:.4g}] s"
    paths = []
    for stem, kind, arg in FIGURES[name]:
        path = Path(out_dir) / f"{stem}.png"
        if kind == "path":
            fig = plot_path(runs, reference=reference, title=f"{title_case}: path").figure
        elif kind == "q":
            fig = plot_coordinate(runs, arg, reference=reference, title=f"{title_case}: {arg}").figure
        else:
            dae_runs = {k: v for k, v in case["runs"].items() if v.lam is not None}
            lam_reference = "lagrange" if "lagrange" in dae_runs else next(iter(dae_runs), None)
            fig = multiplier_figure(dae_runs, reference=lam_reference,
                                    title=f"{title_case}: multipliers")
        save(fig, path)
        paths.append(str(path))
    return paths


def write_csv(name, case, out_dir, columns) -> list:
    """Each run of ``case`` as ``<name>_<run label>.csv`` (``/`` in a label becomes ``-``)."""
    files = []
    for label, trajectory in case["runs"].items():
        path = Path(out_dir) / f"{name}_{label.replace('/', '-')}.csv"
        trajectory.to_csv(path, columns=columns)
        files.append(str(path))
    return files


@dataclass(frozen=True, kw_only=True)
class ReproductionOptions:
    """What :func:`reproduce` runs and writes.

    Attributes
    ----------
    rtol : relative tolerance of every run (atol = rtol·1e-2).
    formulations : subset of ("reduced", "lagrange", "hamilton").
    idas : also integrate the DAE forms with CasADi IDAS.
    figures : write the PNG figures.
    columns : None, or "q" / "qdot" / "all": also write every run as ``<case>_<run>.csv`` with
        those columns (:meth:`~nhgait.dynamics.simulation.driver.Trajectory.to_csv`).
    """

    rtol: float = 1e-10
    formulations: tuple = tuple(FORMULATIONS)
    idas: bool = True
    figures: bool = True
    columns: str | None = None

    @classmethod
    def of(cls, options=None, **values) -> ReproductionOptions:
        """``options`` (None: the defaults) with ``values`` (the fields as keywords) on top; an
        unknown name is one :class:`~nhgait.ocp.ProblemError` naming it."""
        from nhgait.dynamics.suggestions import known_names
        from nhgait.ocp import ProblemError
        names = tuple(f.name for f in fields(cls))
        unknown = [f"unknown option {name!r}" + known_names(name, names, label="options")
                   for name in values if name not in names]
        if unknown:
            raise ProblemError(unknown, title="invalid reproduction options")
        return replace(options or cls(), **values)


def reproduce(out_dir, options: ReproductionOptions | None = None, *, reference=None, progress=None,
              **values) -> dict:
    """Run both thesis cases, write ``summary.json`` and the figures into ``out_dir``.

    Parameters
    ----------
    out_dir : path, created if missing.
    options : what is run and written (:class:`ReproductionOptions`: ``rtol``,
        ``formulations``, ``idas``, ``figures``, ``columns``; None: the defaults)
    reference : callable (name, t_eval (N,), q0 (n,), qdot0 (n,), controller) →
        (label, q (N, n), info dict), optional — an independent solution on the ``t_eval`` grid,
        added to the comparison (``info``, e.g. wall time, goes into the summary) and drawn as
        the figures' reference.
    progress : a text stream (stderr) for one line per finished case with an estimate of the
        time left (:class:`~nhgait.dynamics.countdown.Countdown`); None: silent.
    **values : the options as keywords, on top of ``options`` (``reproduce(out, rtol=1e-8)``)

    Returns
    -------
    dict — the JSON summary (also written to ``out_dir/summary.json``).
    """
    options = ReproductionOptions.of(options, **values)
    rtol, formulations, idas = options.rtol, options.formulations, options.idas
    figures, columns = options.figures, options.columns
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = {"settings": {"rtol": rtol, "atol": rtol * 1e-2, "formulations": list(formulations),
                            "idas": bool(idas), "scipy_method": "DOP853"}}
    from nhgait.dynamics.countdown import Countdown
    countdown = Countdown(len(CASES), stream=progress, what="cases")
    for name in CASES:
        case = run_case(name, rtol=rtol, formulations=formulations, idas=idas)
        references = {}
        if reference is not None:
            label, q_ref, info = reference(name, case["t_eval"], case["q0"], case["qdot0"],
                                           case["controller"])
            references[label] = (case["t_eval"], q_ref, dict(info))
        summary[name] = summarize(case, references)
        try:
            if figures:
                summary[name]["figures"] = write_figures(name, case, out_dir, references)
            if columns is not None:
                summary[name]["csv"] = write_csv(name, case, out_dir, columns)
        except OSError as exc:              # the runs are kept: the summary goes on (and to a fallback)
            from ..files.outputs import write_failure
            summary.setdefault("unwritten", write_failure(exc, out_dir))
        countdown.step(f"{name} ({len(summary[name]['runs'])} runs{', figures' if figures else ''})")
    return _written_summary(summary, out_dir)


def _written_summary(summary: dict, out_dir: Path) -> dict:
    """``summary`` written to ``out_dir/summary.json``; when a write failed, it also goes to a
    fallback and ``summary["unwritten"]`` says what failed and where it is."""
    from ..files.outputs import rescue, write_failure
    try:
        if "unwritten" not in summary:
            with open(out_dir / "summary.json", "w") as fh:
                json.dump(summary, fh, indent=2)
            return summary
    except OSError as exc:
        summary["unwritten"] = write_failure(exc, out_dir / "summary.json")
    summary["unwritten"] += "; " + rescue("summary.json", json.dumps(summary, indent=2), "summary")
    return summary
