"""Smoke test of ``experiments/bench_any_robot.py`` (issue 24, item 3; the full benchmark of at
least 40 pairs is on demand): three seeded robot-and-task pairs nobody tuned the planner for —
a car with one off-axle trailer, a snakeboard with random parameters, a sleigh with two sliding
masses — each planned cold by a real ``nhgait plan`` process (its own session, an empty cache)
at N = 16 under a 90 s budget. Each must be answered: verified (the planner's re-simulation
within 1e-6) or failed with a cause the planner states — not a crash, not a rejection of the
scene, not a hang stopped by the budget — and leave no process behind. The rows must carry
what the table reports, and the table files must be written."""
import json

import experiment_scripts

bench = experiment_scripts.load("bench_any_robot")

SEED, INDICES = 24, "1,3,6"


def test_three_generated_pairs_are_answered(tmp_path):
    out = tmp_path / "bench"
    assert bench.main(["--seed", str(SEED), "--indices", INDICES, "--intervals", "16", "--budget", "90",
                       "--reference", "none", "--out", str(out), "--quiet"]) == 0
    data = json.loads((out / "results.json").read_text())
    rows = data["rows"]
    assert [r["pair"] for r in rows] == ["car1-24-1", "board-24-3", "sleigh2-24-6"]
    for r in rows:
        assert r["outcome"] in ("verified", "failed", "infeasible"), (r["pair"], r["outcome"], r["cause"])
        assert not r["left_processes"]
        assert not r["stopped_by_bench"]
        assert r["N"] == 16
        assert r["n"] >= 5
        assert 1 <= r["k"] < r["n"]
        assert r["time_s"] > 0
        if r["outcome"] == "verified":
            assert r["exit"] == 0
            assert r["verification_error"] <= 1e-6
            assert r["objective"] > 0
        else:
            assert r["exit"] == 1
            assert r["status"]
            assert r["cause"].startswith(r["status"])
    assert (out / "table.csv").read_text().count("\n") == 4
    assert "Failures by cause" in (out / "table.md").read_text()
    assert data["summary"]["pairs"] == 3
