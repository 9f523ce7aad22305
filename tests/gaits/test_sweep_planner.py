"""Sweeps with the real planner (unicycle parallel park, N = 50): each stored objective checked
against the same point planned directly, once, outside the sweep (``plan``, cold guesses); the
CLI; an interrupted sweep (a killed process) resumed."""
from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from nhgait.gaits.cli.main import main
from nhgait.gaits.sweeps.driver import load_sweep, sweep
from nhgait.ocp import ProblemError

GRID = ["final.y=0.4:0.6:3", "horizon=3.5:4.5:3"]
SET = ["intervals=50"]


def direct_objective(y: float, T: float) -> float:
    """The same task planned on its own with the planner's cold guesses (no sweep involved)."""
    from nhgait.gaits.planner import plan
    result = plan("unicycle", "parallel-park", overrides=[*SET, f"final.y={y!r}", f"horizon={T!r}"],
                  animate=False, jit=False)
    assert result.success
    return result.solution.objective


@pytest.fixture(scope="module")
def pool_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("pool")
    return sweep("unicycle", "parallel-park", GRID, out=out, overrides=SET, workers=2)


def test_pool_sweep_matches_direct_plans(pool_sweep):
    r = pool_sweep
    assert r.complete
    assert all(x.success for x in r.records)
    for index in [(1, 1), (0, 2), (2, 0)]:       # the cold centre and two corners reached by continuation
        rec = r.record(index)
        y, T = rec.axis_values["final.y"], rec.axis_values["horizon"]
        assert rec.objective == pytest.approx(direct_objective(y, T), rel=1e-6)
    # the store holds what the result says; warm starts came from grid neighbours
    again = load_sweep(r.directory)
    assert [x.objective for x in again.records] == [x.objective for x in r.records]
    centre = r.record((1, 1))
    assert centre.start == "cold"
    assert centre.warm_from is None
    neighbours = [x for x in r.records if x.id != "1-1"]
    assert all(x.start == "warm" for x in neighbours), [x.start for x in neighbours]
    assert all(x.warm_from for x in neighbours), [x.warm_from for x in neighbours]
    assert max(x.verification_error for x in r.records) < 1e-6


def test_warm_starts_need_fewer_iterations(pool_sweep):
    """Continuation: every warm point converges in fewer Ipopt iterations than the cold centre."""
    cold = pool_sweep.record((1, 1)).total_iterations
    assert all(x.total_iterations < cold for x in pool_sweep.records if x.start == "warm")


def test_bad_axis_names_stop_before_any_solve(tmp_path):
    with pytest.raises(ProblemError, match="unknown name 'zeta'"):
        sweep("unicycle", "parallel-park", ["final.zeta=0:1:2"], out=tmp_path, workers=0)
    with pytest.raises(ProblemError, match="unknown parameter 'mass'"):
        sweep("unicycle", "parallel-park", ["params.mass=1:2:2"], out=tmp_path, workers=0)
    assert not (tmp_path / "sweep.sqlite").exists() or not load_sweep(tmp_path).records


def _rows(path) -> int:
    try:
        with sqlite3.connect(path) as db:
            return db.execute("SELECT COUNT(*) FROM points").fetchone()[0]
    except sqlite3.Error:
        return 0


def test_killed_sweep_resumes_where_it_stopped(tmp_path, capsys):
    """Kill the sweep process mid-run; the rows it wrote survive and --resume solves the rest."""
    out = tmp_path / "sweep"
    args = ["sweep", "unicycle", "--gait", "parallel-park", "--grid", GRID[0], "--grid", GRID[1],
            "--set", SET[0], "--out", str(out), "--workers", "1", "--no-plots"]
    proc = subprocess.Popen([sys.executable, "-m", "nhgait.gaits.cli.main", *args], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240
        while _rows(out / "sweep.sqlite") < 3 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    before = load_sweep(out)
    assert 3 <= len(before.records) < 9, "the kill should land mid-sweep"
    code = main([*args, "--resume"])
    printed = capsys.readouterr().out
    after = load_sweep(out)
    assert code == 0
    assert after.complete
    assert f"this run   {9 - len(before.records)} points" in printed
    kept = {r.id: r for r in after.records}
    for r in before.records:                     # rows of the killed run are kept, not re-solved
        assert kept[r.id].finished_at == r.finished_at
        assert kept[r.id].objective == r.objective
    rec = after.record((2, 2))
    assert rec.objective == pytest.approx(direct_objective(0.6, 4.5), rel=1e-6)


def test_cli_writes_store_table_and_plots(tmp_path, capsys):
    out = tmp_path / "cli"
    code = main(["sweep", "unicycle", "--gait", "parallel-park", "--grid", "final.y=0.45,0.55",
                 "--grid", "horizon=4", "--set", SET[0], "--out", str(out), "--workers", "0", "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0
    assert "2/2 points, 2 solved and verified, 0 failed" in printed
    assert (out / "loops.png").exists()
    assert (out / "sweep.sqlite").exists()
    assert main(["sweep", "unicycle", "--gait", "parallel-park", "--grid", "final.y=0.45,0.55", "--out",
                 str(out), "--workers", "0"]) == 2       # the directory holds a sweep: bad input
    assert "use --resume" in capsys.readouterr().err
    assert main(["sweep", "unicycle", "--gait", "parallel-park", "--grid", "horizon=-1:2:3", "--out",
                 str(tmp_path / "bad"), "--workers", "0"]) == 2
    assert "a horizon must be positive" in capsys.readouterr().err
    # a --plot axis that is not on the grid: refused before any point is solved (it was after all)
    assert main(["sweep", "unicycle", "--gait", "parallel-park", "--grid", "final.y=0.45,0.55", "--out",
                 str(tmp_path / "plot"), "--workers", "0", "--plot", "horizon,final.y"]) == 2
    assert "--plot: no grid axis 'horizon' (axes: final.y)" in capsys.readouterr().err
    assert not (tmp_path / "plot").exists()


# ----------------------------------------------------------------------------- Dask
@pytest.fixture(scope="module")
def dask_backend():
    pytest.importorskip("distributed",
                        reason="Dask distributed is not installed (pip install 'nhgait[dask]')")
    from nhgait.gaits.sweeps.backends import DaskBackend
    backend = DaskBackend("local:2")
    yield backend
    backend.close()


def test_dask_sweep_gives_the_pool_objectives(pool_sweep, dask_backend, tmp_path):
    r = sweep("unicycle", "parallel-park", GRID, out=tmp_path, overrides=SET, backend=dask_backend)
    assert r.complete
    assert "Dask distributed (LocalCluster on 127.0.0.1" in r.backend
    assert len({x.worker for x in r.records}) == 2                       # both Dask workers solved points
    for a, b in zip(r.records, pool_sweep.records, strict=True):
        assert a.id == b.id
        assert a.success
        assert a.objective == pytest.approx(b.objective, rel=1e-8, abs=0)


def test_killing_a_dask_worker_loses_no_row(dask_backend, tmp_path):
    """A worker killed while solving: its point is retried once, every row is there."""
    import threading
    pids = dask_backend.worker_pids()
    killed = []

    def kill_first_busy_worker():
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline:
            busy = [a for a, keys in dask_backend.client.processing().items() if keys]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])
                return
            time.sleep(0.01)

    watcher = threading.Thread(target=kill_first_busy_worker)
    watcher.start()
    # new parameter values: each point specialises its model (seconds), so the kill lands mid-point
    r = sweep("unicycle", "parallel-park", ["params.m=0.47:0.53:3", "final.y=0.45,0.55"], out=tmp_path,
              overrides=SET, backend=dask_backend)
    watcher.join()
    assert killed
    assert r.complete
    assert all(x.success for x in r.records)
    assert r.retried == 1
    assert [x.attempts for x in r.records].count(2) == 1
    again = next(x for x in r.records if x.attempts == 2)
    from nhgait.gaits.planner import plan
    direct = plan("unicycle", "parallel-park", overrides=[*SET, f"final.y={again.axis_values['final.y']!r}"],
                  params={"m": again.axis_values["params.m"]}, animate=False, jit=False)
    assert again.objective == pytest.approx(direct.solution.objective, rel=1e-6)


def test_a_local_cluster_leaves_no_scratch_space():
    """A LocalCluster's workers keep their scratch space (the lock files of
    /tmp/dask-scratch-space by default, left behind by ``nhgait track --scheduler local:1``) in
    a private folder that closing the back end removes."""
    pytest.importorskip("distributed",
                        reason="Dask distributed is not installed (pip install 'nhgait[dask]')")
    from nhgait.gaits.sweeps.backends import DaskBackend
    backend = DaskBackend("local:1")
    try:
        scratch = backend.scratch
        assert os.path.isdir(scratch) and os.listdir(scratch)          # the workers' own, in use
        where = backend.client.run(lambda dask_worker: dask_worker.local_directory)
        assert all(path.startswith(scratch) for path in where.values())
    finally:
        backend.close()
    assert not os.path.exists(scratch)
