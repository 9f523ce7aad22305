"""Fast smoke runs of the on-demand benchmarks (the full runs live in experiments/)."""
import json
from pathlib import Path

import experiment_scripts
import pytest

from nhgait.dynamics.numerics.compiler import compiler_command

#: these compile C (the references use CasADi's jit with gcc); CI may have no compiler
needs_cc = pytest.mark.skipif(compiler_command() is None, reason="no C compiler")

ROOT = Path(__file__).resolve().parents[2]


_load = experiment_scripts.load


def test_bench_derivation_smoke(tmp_path, capsys):
    bench = _load("bench_derivation")
    out = tmp_path / "bench.json"
    assert bench.main(["--repeats", "1", "--systems", "unicycle", "--json", str(out)]) == 0
    data = json.loads(out.read_text())["unicycle"]
    for label in ("KanesMethod", "LagrangesMethod", "nhgait reduced (20 steps)",
                  "cached reload (derive call)"):
        assert data[label]["median_s"] > 0
    assert "ratio = time / KanesMethod" in capsys.readouterr().out


@needs_cc
def test_bench_ocp_smoke(tmp_path, capsys):
    bench = _load("bench_ocp")
    out = tmp_path / "ocp.json"
    assert bench.main(["--problems", "P1", "--N", "25", "--repeats", "1", "--out", str(out),
                       "--sections", "default,fatrop,collocation"]) == 0    # cold: bench_scale's smoke test
    text = capsys.readouterr().out
    assert "P1" in text
    assert "1.543703" in text
    assert "FATROP" in text
    assert "collocation" in text
    rows = json.loads(out.read_text())["rows"]
    assert {r["section"] for r in rows} == {"default", "fatrop", "collocation"}
    fatrop = next(r for r in rows if r["section"] == "fatrop")
    assert fatrop["rel_diff"] < 1e-6
    assert fatrop["fatrop"]["success"]


def test_thesis_printed_equations_script(capsys):
    script = _load("thesis_printed_equations")
    assert script.main() == 0
    out = capsys.readouterr().out
    assert "x(10pi)=4.8299458" in out
    assert "x(10pi)=2.2990248" in out


def test_bench_bicycle_smoke(tmp_path, capsys):
    bench = _load("bench_bicycle")
    assert bench.main(["--out", str(tmp_path), "--speeds", "4:7:4", "--repeats", "1", "--no-cold",
                       "--no-commands"]) == 0
    data = json.loads((tmp_path / "bicycle.json").read_text())
    assert data["table2_max_abs_error"] < 1e-10
    assert data["basu_mandal_max_abs_error"] < 1e-11
    assert data["weave_error"] < 1e-10
    assert data["capsize_error"] < 1e-10
    assert (tmp_path / "eigenvalues.png").stat().st_size > 10_000
    assert "linearise_median_s" in capsys.readouterr().out


def test_bench_tracking_smoke(tmp_path, capsys):
    bench = _load("bench_tracking")
    out = tmp_path / "tracking.json"
    assert bench.main(["--quick", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["snakeboard"]["ratio"] < 0.2
    assert data["six_coordinates"]["samples"] == 8
    assert data["floquet"]["closed_loop"]["max_multiplier_difference"] < 1e-6
    # planned for m ×1.1 among others
    robust, nominal = data["robust"]["robust"], data["robust"]["nominal"]
    assert robust["noise_free_open"] < 0.8 * nominal["noise_free_open"]
    assert robust["robust"]["copies"] == 4
    assert nominal["robust"] is None
    printed = capsys.readouterr().out
    assert "Floquet (snakeboard forward gait)" in printed
    assert "robust / nominal open loop" in printed


def test_bench_loop_smoke(tmp_path, capsys):
    """experiments/bench_loop.py at its smallest: the floor and one warm `nhgait derive`, one
    run each; the table has both rows with their wall and CPU ratios."""
    bench = _load("bench_loop")
    out = tmp_path / "loop.json"
    assert bench.main(["--sections", "process", "--commands", "derive", "--repeats", "1",
                       "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "(the floor)" in text
    assert "nhgait derive snakeboard, warm" in text
    rows = json.loads(out.read_text())["rows"]
    assert [r["ratio"] for r in rows][0] == 1.0
    assert all(r["median_s"] > 0 and r["cpu_s"] > 0 for r in rows)
