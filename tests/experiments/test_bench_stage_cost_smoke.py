"""Smoke test of ``experiments/bench_stage_cost.py`` (the full run, compiled, is on demand): a
small structured member, interpreted, five calls per map. The row must carry every NLP function
and stage piece the benchmark prints, each a positive time; the stage has 4 M = 16 RK points per
interval (M = 4 RK4 sub-steps, the transcription's default), and the weighted Hessian of the
scaled ODE takes more operations than its value and Jacobian."""
import json
import math

import experiment_scripts

bench = experiment_scripts.load("bench_stage_cost")


def test_one_member_interpreted(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "cost.json"
    assert bench.main(["--member", "cart_trailers_2", "--calls", "5", "--repeats", "1", "--interpreted",
                       "--out", str(out)]) == 0
    row = json.loads(out.read_text())
    assert row["flags"] is None and row["rk_points"] == 16
    for name in bench.NLP_FUNCTIONS:
        assert math.isfinite(row[f"{name}_ms"]) and row[f"{name}_ms"] > 0, name
    for name in bench.STAGE_PIECES:
        assert math.isfinite(row[f"{name}_us"]) and row[f"{name}_us"] > 0, name
    assert row["g_hess_instructions"] > row["g_jac_instructions"] > row["ode_operations"]
    assert "stage_hess = 16 × g_hess" in capsys.readouterr().out
