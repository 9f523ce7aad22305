"""The thesis's simulations (§3.3) over their full horizons: every formulation against each
other and against KanesMethod + DOP853 at rtol 1e-12 (experiments/reproduce_thesis.py).

Known values (independent KanesMethod + DOP853, rtol 1e-12): unicycle x(2π) = 0.4767982,
θ(2π) = −0.00363117; snakeboard x(10π) = 2.2990248, y(10π) = −0.00906814.
"""
from __future__ import annotations

import json
from pathlib import Path

import experiment_scripts
import numpy as np
import pytest

from nhgait.gaits.bench.reproduction import reproduce

REPO = Path(__file__).resolve().parents[2]


def _experiment():
    return experiment_scripts.load("reproduce_thesis")


@pytest.fixture(scope="module")
def reproduction(tmp_path_factory, models):
    models["unicycle"]["reduced"], models["snakeboard"]["reduced"]   # derive once, session cache
    out = tmp_path_factory.mktemp("reproduce")
    summary = reproduce(out, rtol=1e-10, reference=_experiment().kane_reference, columns="all")
    return out, summary


@pytest.mark.slow
def test_known_final_values(reproduction):
    _, s = reproduction
    for label in ("reduced", "lagrange", "hamilton", "lagrange/idas", "hamilton/idas", "kane"):
        uq, sq = s["unicycle"]["runs"][label]["final_q"], s["snakeboard"]["runs"][label]["final_q"]
        assert uq["x"] == pytest.approx(0.4767982, abs=1e-6), label
        assert uq["theta"] == pytest.approx(-0.00363117, abs=1e-6), label
        assert sq["x"] == pytest.approx(2.2990248, abs=1e-6), label
        assert sq["y"] == pytest.approx(-0.00906814, abs=1e-6), label


@pytest.mark.slow
@pytest.mark.parametrize("case", ["unicycle", "snakeboard"])
def test_formulations_agree_over_horizon(reproduction, case):
    _, s = reproduction
    data = s[case]
    assert all(run.get("success", True) for run in data["runs"].values())
    dev = data["max_deviation_q"]
    for pair, value in dev.items():            # all pairs, incl. vs kane and the IDAS runs
        assert value < 1e-7, (pair, value)
    for a in ("reduced", "lagrange", "hamilton"):   # index-1 runs agree far tighter
        assert dev[f"{a} vs kane"] < 1e-10
    for pair, value in data["max_deviation_lambda"].items():
        assert value < 1e-6, (pair, value)


@pytest.mark.slow
@pytest.mark.parametrize("case", ["unicycle", "snakeboard"])
def test_constraints_and_energy(reproduction, case):
    runs = reproduction[1][case]["runs"]
    # the reduced ODE carries the constraints in its equations: machine precision
    assert runs["reduced"]["max_abs_constraint_residual"] < 1e-13
    for label in ("lagrange", "hamilton"):         # index-1 route at rtol 1e-10: drift only
        assert runs[label]["max_abs_constraint_residual"] < 1e-11
    for label in ("lagrange/idas", "hamilton/idas"):
        assert runs[label]["max_abs_constraint_residual"] < 1e-8
    for label in ("reduced", "lagrange", "hamilton", "lagrange/idas", "hamilton/idas"):
        assert runs[label]["max_abs_energy_balance"] < 1e-8, label


@pytest.mark.slow
def test_outputs_written(reproduction):
    out, s = reproduction
    on_disk = json.loads((out / "summary.json").read_text())
    assert (on_disk["snakeboard"]["runs"]["kane"]["final_q"]["x"]
            == s["snakeboard"]["runs"]["kane"]["final_q"]["x"])
    names = sorted(p.name for p in out.glob("*.png"))
    assert names == sorted(["fig3_08_unicycle_xy.png", "fig3_09_unicycle_theta.png",
                            "fig3_10_unicycle_phi.png", "fig3_11_unicycle_lambda.png",
                            "fig3_13_snakeboard_xy.png", "fig3_14_snakeboard_theta.png",
                            "fig3_15_snakeboard_psi.png", "fig3_16_snakeboard_phi.png",
                            "fig3_17_snakeboard_lambda.png"])
    assert all((out / n).stat().st_size > 10_000 for n in names)
    # Table 3.2: ẋ(0) = r cos θ(0) φ̇_d(0) = 0.1 from the constraints
    assert s["unicycle"]["qdot0"] == pytest.approx({"x": 0.1, "y": 0.0, "theta": 1.0, "phi": 1.0})
    assert s["snakeboard"]["q0"]["phi"] == pytest.approx(1.0)


@pytest.mark.slow
def test_csv_columns(reproduction):
    """``--columns all``: every run as CSV; its last row agrees with the summary and the
    unicycle's rolling constraint ẋ = r cos θ φ̇ (r = 0.1) holds in the written columns."""
    out, s = reproduction
    path = out / "unicycle_lagrange-idas.csv"
    header = path.read_text().splitlines()[0]
    columns = [c.strip().split(" ")[0].split("[")[0] for c in header.lstrip("# ").split(",")]
    for name in ("t", "x", "theta", "x_dot", "phi_dot", "tau_theta", "lambda1", "energy"):
        assert name in columns, name
    table = np.loadtxt(path, delimiter=",", comments="#", skiprows=1)
    col = {c: table[:, i] for i, c in enumerate(columns)}
    assert col["x"][-1] == pytest.approx(s["unicycle"]["runs"]["lagrange/idas"]["final_q"]["x"], abs=1e-12)
    assert np.max(np.abs(col["x_dot"] - 0.1 * np.cos(col["theta"]) * col["phi_dot"])) < 1e-7
    assert len(s["snakeboard"]["csv"]) == len(s["snakeboard"]["runs"]) - 1       # all but the Kane reference


def test_cli_parser_registers_reproduce():
    import argparse

    from nhgait.gaits.cli.reproduce import add_reproduce_parser, run
    parser = argparse.ArgumentParser()
    add_reproduce_parser(parser.add_subparsers())
    args = parser.parse_args(["reproduce", "--out", "x", "--rtol", "1e-8", "--no-idas", "--columns", "qdot"])
    assert args.func is run
    assert args.rtol == 1e-8
    assert args.no_idas
    assert args.out == "x"
    assert args.columns == "qdot"
