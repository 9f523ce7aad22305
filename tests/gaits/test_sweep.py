"""Sweeps without the planner: grid parsing, continuation order, store, resume, retries, back
ends, plots — each checked against closed forms of a fake solver (below), never against numbers
the sweep itself produced."""
from __future__ import annotations

import math
import os
import sqlite3

import experiment_scripts
import numpy as np
import pytest

from nhgait.gaits.sweeps.backends import ProcessPool, SerialBackend, WorkerDied, make_backend
from nhgait.gaits.sweeps.driver import Progress, RunOptions, load_sweep, run_sweep
from nhgait.gaits.sweeps.grid import Grid, parse_grid
from nhgait.gaits.sweeps.point import PointJob, SceneData, SweepCase, point_task
from nhgait.gaits.sweeps.store import SweepStore
from nhgait.ocp import ProblemError

CASE = SweepCase(SceneData("fake"), task={"horizon": 4.0, "intervals": 10, "final": {"x": 1.0}},
                 params={"m": 1.0, "J_r": 0.2}, label="fake/task")


# ----------------------------------------------------------------------------- a fake solver
def fake_objective(task, params) -> float:
    """The closed form the fake 'solves': J = (x_f − 1)² / T + m J_r."""
    return (task["final"]["x"] - 1.0) ** 2 / task["horizon"] + params["m"] * params["J_r"]


def fake_solve(job: PointJob) -> dict:
    """Deterministic: J from :func:`fake_objective`; 5 iterations warm, 20 cold; fails for x_f < 0."""
    ok = job.task["final"]["x"] >= 0
    J = fake_objective(job.task, job.params)
    trajectory = {"t": [0.0, 1.0], "q": [[J], [J]], "qdot": [[0.0], [0.0]], "u": [[0.0]]}
    return {"id": job.point_id, "success": ok,
            "status": "Solve_Succeeded" if ok else "Infeasible_Problem_Detected",
            "message": "", "objective": J, "iterations": 5 if job.warm is not None else 20,
            "solve_time_s": 0.0, "wall_time_s": 0.0, "verification_error": 1e-9, "constraint_violation": 0.0,
            "start": "warm" if job.warm is not None else "cold", "worker": str(os.getpid()),
            "solution": {"objective": J, "trajectory": trajectory},
            "warm": {"trajectory": trajectory} if ok else None}


def dying_solve(job: PointJob) -> dict:
    """Kills its own worker process on the point 1-1, once (a marker file records the death)."""
    marker = job.task["marker"]
    if job.point_id == "1-1" and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(9)
    return fake_solve(job)


def always_dying_solve(job: PointJob) -> dict:
    if job.point_id == "0":
        os._exit(9)
    return fake_solve(job)


def raising_solve(job: PointJob) -> dict:
    raise ValueError("a bug in the solve")


# ----------------------------------------------------------------------------- grid
def test_axis_specs_give_the_stated_values():
    g = parse_grid(["final.x=0.2:2.0:10", "horizon=4,6, 8", "initial.theta=pi/2", "params.J_r=0:1/10:2"],
                   parameters=("J_r", "m"))
    assert g.names == ("final.x", "horizon", "initial.theta", "params.J_r")
    np.testing.assert_allclose(g.axis("final.x").values, 0.2 + 0.2 * np.arange(10), rtol=1e-15)
    assert g.axis("horizon").values == (4.0, 6.0, 8.0)
    assert g.axis("initial.theta").values == (math.pi / 2,)
    assert g.axis("params.J_r").values == (0.0, 0.1)
    assert g.shape == (10, 3, 1, 2)
    assert g.size == 60


def test_every_bad_axis_is_listed_in_one_error():
    with pytest.raises(ProblemError) as info:
        parse_grid(["final.x=0:1:one", "speed=1:2:3", "horizon=-1:2:3", "params.k=1,2", "final.x=1",
                    "initial.y=__import__('os')", "intervals=2.5", "nonsense"], parameters=("m",))
    text = str(info.value)
    for fragment in ("whole number ≥ 2, got 'one'", "unknown axis 'speed'", "a horizon must be positive",
                     "unknown parameter 'k'", "'final.x' is given 2 times", "initial.y",
                     "intervals must be whole", "expected NAME=lo:hi:n"):
        assert fragment in text, fragment


def test_point_task_sets_each_axis_on_a_copy():
    g = parse_grid(["final.x=0.5,1.5", "horizon=3,5", "params.J_r=0.3", "objective.time=0.1"])
    base = {"horizon": {"initial": 4.0, "min": 2.0, "max": 8.0}, "final": {"x": 1.0, "theta": 0.0},
            "objective": "effort"}
    task, params = point_task(base, {"J_r": 0.2, "m": 1.0}, g.point((1, 0, 0, 0)))
    assert task["final"] == {"x": 1.5, "theta": 0.0}
    assert task["horizon"] == {"initial": 3.0, "min": 2.0, "max": 8.0}
    assert task["objective"] == {"effort": 1.0, "time": 0.1}
    assert params == {"J_r": 0.3, "m": 1.0}
    assert base["final"] == {"x": 1.0, "theta": 0.0}            # the base is untouched


def test_continuation_tree_reaches_every_point_by_unit_steps():
    g = Grid(parse_grid(["a.x=0:1:5"] if False else ["final.x=0:1:5", "horizon=1:2:3"]).axes)
    assert g.centre == (2, 1)
    assert g.parent((2, 1)) is None
    for p in g.points():
        steps, index = 0, p.index
        while g.parent(index) is not None:
            parent = g.parent(index)
            assert sum(abs(a - b) for a, b in zip(parent, index, strict=True)) == 1      # a grid neighbour
            index, steps = parent, steps + 1
        assert index == g.centre
        assert steps == sum(abs(a - b) for a, b in zip(p.index, g.centre, strict=True))  # shortest path


# ----------------------------------------------------------------------------- sweeps with the fake
def _check_rows(result, grid):
    assert result.complete
    assert len(result.records) == grid.size
    for r in result.records:
        task, params = point_task(CASE.task, CASE.params, grid.point(r.idx))
        assert r.objective == pytest.approx(fake_objective(task, params), rel=1e-15)
        parent = grid.parent(r.idx)
        assert r.warm_from == (None if parent is None else grid.point(parent).id)
        assert r.iterations == (20 if parent is None else 5)


@pytest.mark.parametrize("backend_kind", ["serial", "pool"])
def test_fake_sweep_stores_every_point(tmp_path, backend_kind):
    grid = parse_grid(["final.x=0.5:1.5:3", "params.J_r=0.1,0.3"])
    backend = SerialBackend() if backend_kind == "serial" else ProcessPool(2)
    seen = []
    with backend, SweepStore(tmp_path) as store:
        result = run_sweep(CASE, grid, backend, store, RunOptions(solve=fake_solve, progress=seen.append))
    _check_rows(result, grid)
    assert [p.finished for p in seen] == list(range(1, 7))
    assert isinstance(seen[-1], Progress)
    assert "[6/6] 100%" in seen[-1].line()
    again = load_sweep(tmp_path)
    assert [r.objective for r in again.records] == [r.objective for r in result.records]
    assert (tmp_path / "solutions" / "1-0.json").exists()


def test_resume_solves_only_missing_points(tmp_path):
    grid = parse_grid(["final.x=0.5:1.5:3", "horizon=2:4:3"])
    calls = []

    class Counting(SerialBackend):
        def submit(self, fn, job):
            calls.append(job.point_id)
            return super().submit(fn, job)

    with SweepStore(tmp_path) as store:          # an interrupted run: the first 4 points only
        class Stop(Exception):
            pass

        def stop_after_four(progress):
            if progress.finished == 4:
                raise Stop
        with pytest.raises(Stop):
            run_sweep(CASE, grid, Counting(), store, RunOptions(solve=fake_solve, progress=stop_after_four))
    with SweepStore(tmp_path) as store:
        first = store.done_ids()
    assert len(first) == 4  # a point in flight at the stop is not stored
    assert len(calls) >= 4
    calls.clear()
    with SweepStore(tmp_path) as store:
        with pytest.raises(ProblemError, match="already holds a sweep with 4 finished points"):
            run_sweep(CASE, grid, Counting(), store, RunOptions(solve=fake_solve))
        result = run_sweep(CASE, grid, Counting(), store, RunOptions(solve=fake_solve, resume=True))
    assert sorted(calls) == sorted(set(p.id for p in grid.points()) - set(first))
    _check_rows(result, grid)
    assert result.solved_now == 5


def test_resume_refuses_another_sweep(tmp_path):
    grid = parse_grid(["final.x=0.5:1.5:3"])
    with SweepStore(tmp_path) as store:
        run_sweep(CASE, grid, SerialBackend(), store, RunOptions(solve=fake_solve))
        other = parse_grid(["final.x=0.5:1.5:4"])
        with pytest.raises(ProblemError, match="the grid differs"):
            run_sweep(CASE, other, SerialBackend(), store, RunOptions(solve=fake_solve, resume=True))
        # the entry that differs is named (a task cut at 200 characters hid it behind its prefix)
        changed = SweepCase(CASE.scene, {**CASE.task, "intervals": 60}, CASE.params)
        with pytest.raises(ProblemError) as info:
            run_sweep(changed, grid, SerialBackend(), store, RunOptions(solve=fake_solve, resume=True))
        said = str(info.value)
        assert "the task differs from the stored sweep's (task.intervals: stored 10, now 60)" in said


def test_a_dead_pool_worker_loses_only_its_point(tmp_path):
    grid = parse_grid(["final.x=0.5:1.5:3", "horizon=2:4:3"])
    case = SweepCase(CASE.scene, {**CASE.task, "marker": str(tmp_path / "died")}, CASE.params)
    with ProcessPool(2) as pool, SweepStore(tmp_path / "s") as store:
        result = run_sweep(case, grid, pool, store, RunOptions(solve=dying_solve))
    assert (tmp_path / "died").exists()
    assert result.complete
    assert result.retried == 1
    attempts = {r.id: r.attempts for r in result.records}
    assert attempts.pop("1-1") == 2
    assert set(attempts.values()) == {1}
    assert all(r.success for r in result.records)


def test_a_point_that_kills_its_worker_twice_is_recorded_failed(tmp_path):
    grid = parse_grid(["final.x=0.5:1.5:3"])
    with ProcessPool(2) as pool, SweepStore(tmp_path) as store:
        result = run_sweep(CASE, grid, pool, store, RunOptions(solve=always_dying_solve))
    bad = result.record((0,))
    assert not bad.success
    assert bad.status == "worker-died"
    assert bad.attempts == 2
    assert "died" in bad.message
    assert "exit code" in bad.message
    assert sum(r.success for r in result.records) == 2


def test_a_raising_solve_is_retried_then_recorded(tmp_path):
    grid = parse_grid(["final.x=0.5,1.0"])
    with SweepStore(tmp_path) as store:
        result = run_sweep(CASE, grid, SerialBackend(), store, RunOptions(solve=raising_solve))
    assert [(r.status, r.attempts) for r in result.records] == [("error", 2), ("error", 2)]
    assert "a bug in the solve" in result.records[0].message


class Chaining(SerialBackend):
    """A serial back end asking for chains of 3 points per task, counting its tasks."""

    chain = 3

    def __init__(self):
        self.tasks = []

    def submit(self, fn, *args):
        self.tasks.append(len(args[1]) if fn.__name__ == "solve_chain" else 1)    # points in the task
        return super().submit(fn, *args)


@pytest.mark.parametrize("backend_kind", ["serial", "pool"])
def test_chains_solve_several_points_per_task_each_warm_from_its_parent(tmp_path, backend_kind):
    grid = parse_grid(["final.x=0.5:1.5:7", "horizon=2:4:3"])                  # rays of 3 along final.x
    backend = Chaining() if backend_kind == "serial" else ProcessPool(2)
    with backend, SweepStore(tmp_path) as store:
        result = run_sweep(CASE, grid, backend, store, RunOptions(solve=fake_solve, chain=3))
    _check_rows(result, grid)                  # warm_from: the previous point of the chain = the parent
    if backend_kind == "serial":
        assert sum(backend.tasks) == grid.size
        assert max(backend.tasks) == 3
        assert len(backend.tasks) <= grid.size / 2          # on average at least 2 points per task


def test_a_dead_worker_in_a_chain_costs_its_points_one_retry_each(tmp_path):
    grid = parse_grid(["final.x=0.5:1.5:5", "horizon=2:4:3"])
    case = SweepCase(CASE.scene, {**CASE.task, "marker": str(tmp_path / "died")}, CASE.params)
    with ProcessPool(2) as pool, SweepStore(tmp_path / "s") as store:
        result = run_sweep(case, grid, pool, store, RunOptions(solve=dying_solve, chain=3))
    assert (tmp_path / "died").exists()
    assert result.complete
    assert all(r.success for r in result.records)
    retried = [r for r in result.records if r.attempts == 2]
    assert "1-1" in {r.id for r in retried}
    assert result.retried == len(retried) <= 3


def test_chain_must_be_a_whole_number(tmp_path):
    with SweepStore(tmp_path) as store, pytest.raises(ProblemError, match="chain must be a whole number"):
        run_sweep(CASE, parse_grid(["final.x=0.5,1.0"]), SerialBackend(), store,
                  RunOptions(solve=fake_solve, chain=0))


@pytest.mark.parametrize("chain", [1, 3])
def test_failed_points_do_not_warm_start_their_children(tmp_path, chain):
    grid = parse_grid(["final.x=-1.0:1.0:5"])                        # x < 0 fails in the fake
    with SweepStore(tmp_path) as store:
        result = run_sweep(CASE, grid, SerialBackend(), store, RunOptions(solve=fake_solve, chain=chain))
    rows = {r.idx[0]: r for r in result.records}
    assert [rows[i].success for i in range(5)] == [False, False, True, True, True]
    assert rows[1].warm_from == "2"  # skips the failed neighbour 1
    assert rows[0].warm_from == "2"


def test_store_rows_survive_without_the_driver(tmp_path):
    """Rows are committed one by one: a second connection reads them while the store is open."""
    grid = parse_grid(["final.x=0.5:1.5:3"])
    counts = []
    with SweepStore(tmp_path) as store:
        def look(progress):
            with sqlite3.connect(tmp_path / "sweep.sqlite") as other:
                counts.append(other.execute("SELECT COUNT(*) FROM points").fetchone()[0])
        run_sweep(CASE, grid, SerialBackend(), store, RunOptions(solve=fake_solve, progress=look))
    assert counts == [1, 2, 3]


def test_backend_choices():
    with make_backend(None, 0) as b:
        assert isinstance(b, SerialBackend)
    with pytest.raises(ProblemError, match="either --scheduler or --workers"):
        make_backend("local:2", 2)
    with pytest.raises(ProblemError, match="--workers must be ≥ 0"):
        make_backend(None, -1)


def test_pool_reports_a_dead_worker_as_worker_died():
    with ProcessPool(1) as pool:
        future = pool.submit(os._exit, 3)
        with pytest.raises(WorkerDied, match="exit code 3"):
            future.result(timeout=60)
        assert pool.submit(abs, -2).result(timeout=60) == 2        # replaced, still working


# ----------------------------------------------------------------------------- plots
def test_landscape_shows_the_closed_form_and_marks_failures(tmp_path):
    from nhgait.gaits.sweeps import plots as sweep_plots
    grid = parse_grid(["final.x=-0.5:1.5:5", "horizon=2:4:3", "params.J_r=0.1,0.2"])
    case = SweepCase(CASE.scene, CASE.task, CASE.params, label="fake/task", units={"x": "m", "J_r": "kg*m^2"},
                     inputs=("u",), shape=("q0", "q1"))
    with SweepStore(tmp_path) as store:
        result = run_sweep(case, grid, SerialBackend(), store, RunOptions(solve=fake_solve))
    ax = sweep_plots.plot_landscape(result, "final.x", "horizon", fixed={"params.J_r": 0.2})
    mesh = ax.collections[0].get_array()                 # rows: horizon, columns: final.x
    xs, Ts = np.array(grid.axis("final.x").values), np.array(grid.axis("horizon").values)
    expected = (xs[None, :] - 1) ** 2 / Ts[:, None] + 1.0 * 0.2
    expected[:, xs < 0] = np.nan                         # failed points are not coloured
    np.testing.assert_allclose(np.ma.filled(mesh, np.nan).reshape(3, 5), expected, rtol=1e-14)
    assert ax.get_xlabel() == "final.x [m]"
    assert ax.get_ylabel() == "horizon [s]"
    assert "params.J_r = 0.2" in ax.get_title()
    crosses = [line for line in ax.lines if line.get_marker() == "x"][0]
    assert list(crosses.get_xdata()) == [-0.5] * 3        # the failed column, every horizon
    fax = sweep_plots.plot_feasibility(result, "horizon", "params.J_r")
    assert fax.get_ylabel() == "params.J_r [kg·m²]"
    assert sweep_plots.axis_label("final.theta_dot", {"theta": "rad"}) == "final.theta_dot [rad/s]"
    assert sweep_plots.objective_label(("u",), {"u": "N"}) == "optimal cost J = ∫|u|² dt [(N)²·s]"


def test_plots_reject_unknown_axes(tmp_path):
    from nhgait.gaits.sweeps import plots as sweep_plots
    grid = parse_grid(["final.x=0.5:1.5:3"])
    with SweepStore(tmp_path) as store:
        result = run_sweep(CASE, grid, SerialBackend(), store, RunOptions(solve=fake_solve))
    with pytest.raises(ProblemError, match="no grid axis 'horizon'"):
        sweep_plots.plot_landscape(result, "final.x", "horizon")


def test_bench_sweep_smoke(tmp_path, capsys):
    bench = experiment_scripts.load("bench_sweep")
    assert bench.main(["--quick", "--repeats", "1", "--out", str(tmp_path / "b.json")]) == 0
    text = capsys.readouterr().out
    assert "speed-up 2 workers / 1 worker" in text
    assert "iterations warm / cold" in text
    import json
    report = json.loads((tmp_path / "b.json").read_text())
    assert report["throughput"]["solved"] == {"1": 2, "2": 2}
    assert report["continuation"]["warm"]["solved"] == report["continuation"]["cold"]["solved"] == 2


def test_pool_workers_run_single_threaded_linear_algebra():
    with ProcessPool(1) as pool:
        found = {key: pool.submit(os.getenv, key).result(timeout=60) for key in ("OMP_NUM_THREADS",
                                                                               "OPENBLAS_NUM_THREADS")}
    for key, value in found.items():
        assert value == os.environ.get(key, "1")          # the user's setting wins, else 1


def test_the_continuation_tree_of_a_large_grid_is_built_in_linear_time():
    """Each point's subtree size from one walk down the tree (walking every point's ancestors
    took 182 s for 16 000 points: a 100 000-point sweep never started its first point). Reference: on a line
    of n points warm-started outwards from the centre c, the subtree of point i holds the
    points from i outwards to the end: i + 1 of them below c, n − i above, and n at c."""
    from nhgait.gaits.sweeps.driver import _Tree
    from nhgait.gaits.sweeps.grid import parse_grid
    n = 20_000                          # 0.2 s; the quadratic walk took about 5 minutes
    grid = parse_grid([f"final.y=0:1:{n}"])
    tree = _Tree(grid)
    c = grid.centre[0]
    assert tree.size[(c,)] == n
    assert all(tree.size[(i,)] == i + 1 for i in (0, 1, 17, c - 1))
    assert all(tree.size[(i,)] == n - i for i in (c + 1, n - 2, n - 1))
    square = _Tree(parse_grid(["final.y=0:1:5", "horizon=3:5:7"]))
    assert square.size[(2, 3)] == 35 and sum(len(v) for v in square.children.values()) == 35
