"""Smoke test of ``experiments/bench_scale.py`` (issue 19's benchmark; the full run is on
demand): one member, N = 20 (at N = 10 the RK4 error, 1.4e-6, fails the verification:
correctly), interpreted, one repeat. The cold run is a real ``nhgait plan`` in a fresh process
with an empty cache, then the same plan warm; the row must carry what the benchmark table
reports (peak memory, the longest silent gap, phases) and the planner's objective must equal the
independent hand-written reference's at the same N."""
import json

import experiment_scripts
import pytest

bench = experiment_scripts.load("bench_scale")


def test_one_member_cold_and_warm(tmp_path, monkeypatch):
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))      # main() moves it per member
    out = tmp_path / "bench.json"
    assert bench.main(["--members", "cart_trailers_1", "--repeats", "1", "--intervals", "20", "--no-jit",
                       "--out", str(out)]) == 0
    (row,) = json.loads(out.read_text())["rows"]
    assert row["success"], row.get("stderr_tail")
    assert row["exit"] == 0, row.get("stderr_tail")
    assert row["peak_mb"] > 50
    assert 0 < row["max_silent_s"] <= row["cold_s"]
    assert row["c_bytes"] == 0 or row["flags"] is None                        # --no-jit: nothing compiled
    assert row["code"] == "interpreted"
    assert row["background"]["state"] == "none"
    assert row["warm"]["success"]
    assert row["cold_over_warm"] == pytest.approx(row["cold_s"] / row["warm_s"])
    assert row["reference"]["success"]
    assert row["objective"] == pytest.approx(row["reference"]["objective"], rel=1e-6)
    assert row["verification_error"] <= 1e-6
