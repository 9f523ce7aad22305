"""Fast smoke run of experiments/bench_scaling.py (the full run is on demand, docs/scaling.md)."""
import json
from pathlib import Path

import experiment_scripts

ROOT = Path(__file__).resolve().parents[2]


def test_bench_scaling_smoke(tmp_path, capsys):
    bench = experiment_scripts.load("bench_scaling")
    assert bench.main(["--repeats", "1", "--members", "unicycle,cart_trailers_0", "--no-cli",
                       "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "bench_scaling.json").read_text())
    assert [r["name"] for r in rows] == ["unicycle", "cart_trailers_0"]
    for r in rows:
        assert r["derive_s"] > 0
        assert r["lagrange_s"] > 0
        assert r["kane_s"] > 0
        assert r["rhs_ops"] > 0
        assert r["oracle_error"] < 1e-10            # against the independent Kane model
    assert (tmp_path / "bench_scaling.png").stat().st_size > 0
    assert "| unicycle | 4 | 2 | explicit |" in capsys.readouterr().out
