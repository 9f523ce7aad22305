"""Smoke runs of the work-precision report (two tolerances, two methods, a short horizon): the
experiment script and ``nhgait bench precision``. The errors are checked against the
independent references the report itself uses (KanesMethod oracle; Lagrangian DAE at 1e-13)."""
from __future__ import annotations

import csv
from pathlib import Path

import experiment_scripts
import pytest

from nhgait.dynamics.numerics.compiler import compiler_command

#: these compile C (the references use CasADi's jit with gcc); CI may have no compiler
needs_cc = pytest.mark.skipif(compiler_command() is None, reason="no C compiler")

ROOT = Path(__file__).resolve().parents[2]


_load = experiment_scripts.load


def _rows(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


@needs_cc
def test_work_precision_smoke(tmp_path, capsys):
    wp = _load("work_precision")
    out = tmp_path / "wp"
    assert wp.main(["--cases", "snakeboard,shape", "--tols", "1e-4,1e-7", "--methods", "DOP853,compiled",
                    "--repeats", "1", "--t-scale", "0.03", "--out", str(out)]) == 0
    rows = _rows(out / "work_precision.csv")
    labels = {r["label"] for r in rows}
    assert {"reduced/DOP853", "reduced/compiled", "lagrange/IDAS", "hamilton/compiled"} <= labels
    assert any(lab.startswith("anchor") for lab in labels)
    for r in rows:
        assert r["success"] == "True", r
        tight = float(r["rtol"]) == 1e-7
        assert float(r["error"]) < (1e-7 if tight and "IDAS" not in r["label"] else 1e-3), r
    shape = [r for r in rows if r["case"] == "shape"]
    assert {r["states"] for r in shape} == {"5"}
    assert {r["states"] for r in rows if r["case"] == "shape (all states)"} == {"8"}
    assert (out / "snakeboard.png").stat().st_size > 10_000
    md = (out / "work_precision.md").read_text()
    assert md.startswith("Machine: ")
    assert "| formulation/method | rtol | error |" in md
    assert "Snakeboard PD 10π targets" in capsys.readouterr().out


def test_bench_precision_cli_smoke(tmp_path, capsys):
    from nhgait.gaits.cli.main import main
    out = tmp_path / "bench"
    assert main(["bench", "precision", "unicycle", "--tols", "1e-4,1e-8", "--methods", "DOP853,compiled",
                 "--formulations", "reduced,hamilton", "--no-idas", "--repeats", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "reference: Lagrangian DAE (index 1) + scipy DOP853, rtol 1e-13" in printed
    rows = _rows(out / "precision.csv")
    assert len(rows) == 2 * 2 * 2
    for r in rows:
        assert float(r["error"]) < (1e-9 if float(r["rtol"]) == 1e-8 else 1e-4), r
    assert (out / "precision.png").exists()
    assert (out / "precision.md").exists()
