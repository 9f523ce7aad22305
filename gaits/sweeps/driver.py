"""Gait landscapes: one optimal control problem per point of a grid over task values and
parameters, solved in parallel, continued from solved neighbours, stored as they finish.

::

    from nhgait.gaits.sweeps.driver import sweep
    result = sweep("unicycle", "parallel-park", ["final.y=0.3:0.7:3", "horizon=3:5:3"], out="out/park")
    result.objectives()          # grid-shaped array of J (nan where the solve failed)

Steps (:func:`run_sweep`)
-------------------------
1. The grid (:mod:`.sweep_grid`) and the case — scene, base task, parameters as data
   (:func:`.sweep_point.describe_case`).
2. The store (:mod:`.sweep_store`): a new sweep records what it is; ``resume=True`` checks it
   is the same sweep and skips every point that already has a row.
3. Points run on a back end (:mod:`.sweep_backends`) as soon as their parent in the
   continuation tree (:meth:`Grid.parent`) has finished: warm-started from the nearest solved
   ancestor's trajectory (the planner's own guesses when there is none, and when a warm start
   fails), each verified by the planner's re-simulation. On a back end with a fixed cost per
   task (Dask: ``chain = 4``) one task solves a *chain* of up to ``chain`` points down the
   tree, each warm-started from the one before (:func:`.sweep_point.solve_chain`); a chain
   passes a branch point only while the other workers have work, so the frontier stays wide.
4. Each finished point is written at once (solution file, then its row). A point whose worker
   died (or whose solve raised) is submitted once more (a chain's points one by one); a second
   failure is recorded as failed with the reason. Input the planner rejects stops the sweep
   with its message.
"""
from __future__ import annotations

import concurrent.futures as cf
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from nhgait.ocp import ProblemError

from .backends import WorkerDied, make_backend
from .grid import Grid, parse_grid
from .options import SweepOptions
from .point import PointJob, SweepCase, point_task, prepare_worker, solve_chain, solve_point
from .store import PointRecord, StoreWriteError, SweepStore

__all__ = ["sweep", "run_sweep", "RunOptions", "SweepOptions", "load_sweep", "SweepResult", "Progress"]

_RESULT_KEYS = ("success", "status", "message", "objective", "iterations", "total_iterations", "solve_time_s",
                "wall_time_s", "verification_error", "constraint_violation", "start", "worker")


@dataclass(frozen=True)
class Progress:
    """Where a running sweep is (handed to the ``progress`` callback after every point)."""

    finished: int          # points with a row (this run and earlier runs)
    total: int
    succeeded: int
    failed: int
    running: int
    retried: int
    elapsed_s: float
    solved_now: int        # points finished in this run
    last: PointRecord | None = None

    @property
    def rate(self) -> float:
        """Points per second in this run."""
        return self.solved_now / self.elapsed_s if self.elapsed_s > 0 else math.nan

    def line(self) -> str:
        left = self.total - self.finished
        eta = f", about {left / self.rate:.0f} s left" if self.rate > 0 and left else ""
        return (f"[{self.finished}/{self.total}] {100 * self.finished / max(self.total, 1):3.0f}%  "
                f"ok {self.succeeded}  failed {self.failed}  running {self.running}  retried {self.retried}  "
                f"{self.rate:.2f} points/s{eta}")


@dataclass(frozen=True, eq=False)
class SweepResult:
    """A sweep's rows (:class:`~.sweep_store.PointRecord`, grid order) with the grid they fill.

    ``solved_now``: points solved by this call (0 for :func:`load_sweep`); ``retried``:
    points submitted twice; ``wall_time_s``: this call's duration; ``backend``: where it ran.
    """

    directory: Any
    grid: Grid
    case: dict
    records: tuple
    solved_now: int = 0
    retried: int = 0
    wall_time_s: float = 0.0
    backend: str = ""
    units: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        from nhgait.dynamics.reprs import sweep_repr
        return sweep_repr(self)

    def record(self, index) -> PointRecord | None:
        key = "-".join(str(int(i)) for i in index)
        return next((r for r in self.records if r.id == key), None)

    def values(self, column: str, *, only_success: bool = True) -> np.ndarray:
        """A grid-shaped array of ``column`` (nan where missing, or failed when ``only_success``)."""
        out = np.full(self.grid.shape, np.nan)
        for r in self.records:
            if r.success or not only_success:
                out[r.idx] = float(getattr(r, column))
        return out

    def objectives(self) -> np.ndarray:
        return self.values("objective")

    def success_mask(self) -> np.ndarray:
        """Grid-shaped: 1 solved and verified, 0 failed, nan not solved."""
        out = np.full(self.grid.shape, np.nan)
        for r in self.records:
            out[r.idx] = 1.0 if r.success else 0.0
        return out

    @property
    def complete(self) -> bool:
        return len(self.records) == self.grid.size

    def summary_lines(self, *, max_rows: int = 40) -> list:
        return summary_lines(self, max_rows=max_rows)


# ----------------------------------------------------------------------------- driver
def _record(point, job: PointJob, answer: dict, attempts: int, solution_path) -> PointRecord:
    values = {k: answer[k] for k in _RESULT_KEYS if k in answer}
    return PointRecord(id=point.id, idx=point.index, axis_values=dict(point.values), task=job.task,
                       params=job.params, attempts=attempts, warm_from=answer.get("warm_from", job.warm_from),
                       solution_path=solution_path, **values)


def _failure(point, job: PointJob, reason: str, status: str, attempts: int) -> PointRecord:
    return PointRecord(id=point.id, idx=point.index, axis_values=dict(point.values), task=job.task,
                       params=job.params, success=False, status=status, message=reason, attempts=attempts,
                       start="warm" if job.warm is not None else "cold", warm_from=job.warm_from)


class _Tree:
    """The continuation tree of a grid: children of each point and the warm data held."""

    def __init__(self, grid: Grid):
        self.grid = grid
        self.children: dict = {}
        for p in grid.points():
            self.children.setdefault(grid.parent(p.index), []).append(p)
        self.warm: dict = {}          # index → warm data of a solved point (or its path)
        self.size: dict = {}          # index → points in its subtree (itself included)
        for index in reversed(self._top_down()):       # children before their parent
            self.size[index] = 1 + sum(self.size[c.index] for c in self.children.get(index, ()))

    def _top_down(self) -> list:
        """Every index, each after its parent (breadth first from the centre): linear in the
        points (walking each point's ancestors was quadratic: 182 s for 16 000 points)."""
        order = [p.index for p in self.children.get(None, ())]
        for index in order:                            # grows while it is walked
            order.extend(c.index for c in self.children.get(index, ()))
        return order

    def warm_source(self, index):
        """(warm data, id) of the nearest solved ancestor of ``index``, or (None, None)."""
        parent = self.grid.parent(index)
        while parent is not None:
            if parent in self.warm:
                return self.warm[parent], self.grid.point(parent).id
            parent = self.grid.parent(parent)
        return None, None


def _load_warm(store: SweepStore, record: PointRecord):
    """Warm data of a point solved in an earlier run (its solution file), or None."""
    from .point import warm_data
    solution = store.load_solution(record)
    try:
        return warm_data(solution)
    except (KeyError, TypeError):
        return None


@dataclass(frozen=True)
class RunOptions:
    """How :func:`run_sweep` runs a sweep.

    ``resume``: continue the stored sweep (solve only its missing points); ``warm_start``:
    continue from solved neighbours; ``solve``: the module-level function a worker calls with a
    :class:`PointJob` (default :func:`.point.solve_point`); ``progress``: called with a
    :class:`Progress` after every finished point; ``max_in_flight``: tasks submitted at once
    (default: twice the back end's workers, so that a worker finds its next point waiting
    instead of a round trip to the driver); ``prepare``: a function submitted with the centre
    point's job to each other worker while the centre is solved (default
    :func:`.point.prepare_worker` with the default ``solve``), its result ignored; ``chain``:
    points per task down the continuation tree (default: the back end's ``chain``, 1 for the
    process pool, 4 for Dask; module docstring).
    """

    resume: bool = False
    warm_start: bool = True
    solve: Callable = solve_point
    progress: Callable | None = None
    max_in_flight: int | None = None
    prepare: Callable | None = None
    chain: int | None = None


class _Run:
    """The driver's state for one call of :func:`run_sweep`: the continuation tree, the stored
    rows, the points ready to run and those in flight (``options.chain`` already chosen)."""

    def __init__(self, case, grid, backend, store, options: RunOptions):
        self.case, self.grid, self.backend, self.store = case, grid, backend, store
        self.chain = max(1, int(options.chain))
        self.second_try: set = set()   # points of a failed chain after its head: alone, attempt 2
        self.warm_start, self.solve, self.progress = options.warm_start, options.solve, options.progress
        self.t_start = time.perf_counter()
        self.tree = _Tree(grid)
        self.done = {r.idx: r for r in store.records()} if options.resume else {}
        for idx, r in self.done.items():
            if r.success and self.warm_start:
                self.tree.warm[idx] = ("file", r)
        self.counts = {"ok": sum(r.success for r in self.done.values()),
                       "failed": sum(not r.success for r in self.done.values()), "now": 0, "retried": 0}
        self.ready: deque = deque()
        self.in_flight: dict = {}
        self.root = grid.point(grid.centre)
        if self.root.index in self.done:
            self.release(self.root.index)
        else:
            self.ready.append(self.root)

    def release(self, index) -> None:
        """Make the children of a finished (or stored) point ready; stored ones release theirs."""
        stack = [index]
        while stack:
            for child in self.tree.children.get(stack.pop(), ()):
                if child.index in self.done:
                    stack.append(child.index)
                else:
                    self.ready.append(child)

    def job_for(self, point) -> PointJob:
        task, params = point_task(self.case.task, self.case.params, point)
        warm, warm_from = self.tree.warm_source(point.index) if self.warm_start else (None, None)
        if isinstance(warm, tuple):                   # stored by an earlier run: read it now
            warm = _load_warm(self.store, warm[1])
            warm_from = warm_from if warm is not None else None
        return PointJob(self.case, point.id, task, params, warm, warm_from)

    def chain_from(self, point) -> list:
        """``point`` and up to ``chain - 1`` descendants, each a child of the one before (the
        largest subtree first); past a point with several children only while the other workers
        have work (``ready`` and in flight), since its other children wait for the whole chain."""
        points = [point]
        while len(points) < self.chain:
            kids = sorted((c for c in self.tree.children.get(points[-1].index, ())
                           if c.index not in self.done),
                          key=lambda c: -self.tree.size[c.index])
            if not kids or (len(kids) > 1 and len(self.ready) + len(self.in_flight) < self.backend.workers):
                break
            if kids[0].index in self.second_try:
                break
            points.append(kids[0])
        return points

    def submit(self, point, job=None, attempt: int = 1) -> PointJob:
        """Submit ``point`` (a first attempt: with its chain) and return its job."""
        if point.index in self.second_try:
            self.second_try.discard(point.index)
            attempt = 2
        points = self.chain_from(point) if attempt == 1 and self.chain > 1 else [point]
        jobs = [job or self.job_for(point)] + [self.job_for(p) for p in points[1:]]
        if len(points) == 1:
            future = self.backend.submit(self.solve, jobs[0])
        else:
            future = self.backend.submit(solve_chain, self.solve, tuple(jobs), self.warm_start)
        self.in_flight[future] = (points, jobs, attempt)
        return jobs[0]

    def finish(self, future) -> None:
        """Store a finished task's points (or resubmit them once, one by one, when the worker
        died or the solve raised)."""
        points, jobs, attempts = self.in_flight.pop(future)
        try:
            answers = future.result()
        except Exception as exc:  # noqa: BLE001 - a dead worker or a bug in the solve: retry once
            status = "worker-died" if isinstance(exc, WorkerDied) else "error"
            if attempts == 1:                   # the head now; the rest when their parents finish
                self.counts["retried"] += len(points)
                self.second_try.update(p.index for p in points[1:])
                self.submit(points[0], jobs[0], 2)
                return
            records = [_failure(p, j, f"{status} twice: {exc}", status, attempts)
                       for p, j in zip(points, jobs, strict=True)]
            answers = [{"failure": r.message} for r in records]
        else:
            answers, records = ([answers] if len(points) == 1 else answers), None
        try:
            if records is None:
                records = [self._record(p, j, a, attempts)
                           for p, j, a in zip(points, jobs, answers, strict=True)]
            for point, record in zip(points, records, strict=True):
                self._store(point, record)
        except StoreWriteError as exc:
            raise StoreWriteError(self._rescued(exc, points, answers)) from None
        self.release(points[0].index)          # through the chain's (now done) points

    def _rescued(self, exc, points, answers) -> str:
        """The message of a store that could not be written: why, what is stored, and where the
        answers of ``points`` (not stored) were saved instead."""
        from ..files.outputs import rescue
        unstored = [{"id": p.id, "axis_values": dict(p.values), "answer": a}
                    for p, a in zip(points, answers, strict=True) if p.index not in self.done]
        where = rescue("unstored_points.json", unstored, f"answer of {len(unstored)} unstored point(s)")
        return (f"{exc}; {len(self.done)} points are stored in {self.store.directory}; {where}; "
                "free the space and continue with --resume")

    def _store(self, point, record) -> None:
        self.store.add(record)
        self.done[point.index] = record
        self.counts["ok" if record.success else "failed"] += 1
        self.counts["now"] += 1
        if self.progress is not None:
            c = self.counts
            self.progress(Progress(finished=len(self.done), total=self.grid.size, succeeded=c["ok"],
                                   failed=c["failed"], running=len(self.in_flight), retried=c["retried"],
                                   elapsed_s=time.perf_counter() - self.t_start, solved_now=c["now"],
                                   last=record))

    def _record(self, point, job, answer, attempts) -> PointRecord:
        if "input_error" in answer:
            raise ProblemError([answer["input_error"]], title=f"grid point {point.id} "
                               f"({', '.join(f'{k} = {v:g}' for k, v in point.values)})")
        path = None
        if answer.get("solution") is not None:
            path = self.store.write_solution(point.id, answer["solution"])
        record = _record(point, job, answer, attempts, path)
        if record.success and self.warm_start and answer.get("warm") is not None:
            self.tree.warm[point.index] = answer["warm"]
        return record


def run_sweep(case: SweepCase, grid: Grid, backend, store: SweepStore,
              options: RunOptions = RunOptions()) -> SweepResult:
    """Run (or resume) a sweep on an open back end and store (see the module docstring and
    :class:`RunOptions`)."""
    store.start({"scene": case.scene.describe(), "task": case.task, "params": case.params,
                 "options": case.options, "grid": grid.to_dict(), "label": case.label, "units": case.units,
                 "shape": list(case.shape), "coordinates": list(case.coordinates),
                 "inputs": list(case.inputs)}, resume=options.resume)
    chain = getattr(backend, "chain", 1) if options.chain is None else options.chain
    if not isinstance(chain, int) or isinstance(chain, bool) or chain < 1:
        raise ProblemError([f"chain must be a whole number ≥ 1 of points per task, got {chain!r}"],
                           title="invalid sweep")
    run = _Run(case, grid, backend, store, replace(options, chain=chain))
    limit = max(1, int(options.max_in_flight or 2 * backend.workers))
    prepare = options.prepare
    if prepare is None and options.solve is solve_point:
        prepare = prepare_worker
    warming = []
    if (prepare is not None and options.warm_start and backend.workers > 1 and run.ready
        and run.ready[0] is run.root):
        job = run.submit(run.ready.popleft())
        warming = [backend.submit(prepare, job) for _ in range(backend.workers - 1)]
    while run.ready or run.in_flight:
        while run.ready and len(run.in_flight) < limit:
            run.submit(run.ready.popleft())
        finished, _ = cf.wait(list(run.in_flight), return_when=cf.FIRST_COMPLETED)
        for future in finished:
            run.finish(future)
    for future in warming:
        future.cancel()
    return SweepResult(directory=store.directory, grid=grid, case=case.describe(),
                       records=tuple(store.records()), solved_now=run.counts["now"],
                       retried=run.counts["retried"], wall_time_s=time.perf_counter() - run.t_start,
                       backend=backend.describe() if hasattr(backend, "describe") else "",
                       units=dict(case.units))


def sweep(system, task=None, grid=(), *, out, options: SweepOptions | None = None, **values) -> SweepResult:
    r"""Sweep ``task`` on ``system`` over ``grid``, storing every point in ``out``.

    Parameters
    ----------
    system : scene file or built-in scene name
    task : None (the scene's ``[task]``), a built-in gait name, or a ``[task]`` dict
    grid : ``NAME=SPEC`` axis texts (``"final.x=0.2:2.0:10"``; :mod:`.sweep_grid`) or a
        mapping name → values
    out : the sweep directory (``sweep.sqlite``, ``solutions/``)
    options : how the sweep runs, a :class:`~.options.SweepOptions` — ``overrides`` and
        ``params`` of the base task, the planner options of every point (``plan``: a
        :class:`~nhgait.gaits.planning.options.PlanOptions` or a mapping of ``transcription``,
        ``solver``, ``jit``, ``time_limit``: seconds per point), ``scheduler``, ``workers``,
        an open ``backend``, ``resume``, ``warm_start``, ``progress``, ``chain``; a mapping
        here is the planner options (as before SweepOptions); None: the defaults
    \*\*values : the same options as keywords, on top of ``options``, e.g.
        ``sweep(..., out=out, workers=0, overrides=["intervals=30"])``

    Notes
    -----
    Every problem of the options is one :class:`~nhgait.ocp.ProblemError` (an unknown name
    among them), raised before any derivation.

    Examples
    --------
    The unicycle's parallel park for two sideways shifts, solved in this process
    (``workers=0``); the longer shift costs more effort:

    >>> import tempfile
    >>> from nhgait.gaits import sweep
    >>> with tempfile.TemporaryDirectory() as out:
    ...     result = sweep("unicycle", "parallel-park", ["final.y=0.3:0.5:2"], out=out, workers=0,
    ...                    options={"jit": False})
    >>> [(r.axis_values["final.y"], r.success) for r in result.records]
    [(0.3, True), (0.5, True)]
    >>> bool(result.records[0].objective < result.records[1].objective)
    True
    """
    from ..files.outputs import output_directory, output_lock
    options = SweepOptions.of(options, **values)    # before any derivation, like the location
    out = output_directory(out)                     # before any derivation: exit 2 for a bad location
    with output_lock(out, f"nhgait sweep {system} --out {out}"):   # one writer: a second run is refused now
        from .point import check_case, describe_case
        case = describe_case(system, task, overrides=options.overrides, params=options.params,
                             options=options.planner())
        the_grid = grid if isinstance(grid, Grid) else parse_grid(grid, parameters=tuple(case.params))
        centre = the_grid.point(the_grid.centre)
        check_case(case, PointJob(case, centre.id, *point_task(case.task, case.params, centre)))
        own = options.backend is None
        backend = make_backend(options.scheduler, options.workers) if own else options.backend
        try:
            with SweepStore(out, lock=False) as store:
                return run_sweep(case, the_grid, backend, store,
                                 RunOptions(resume=options.resume, warm_start=options.warm_start,
                                            progress=options.progress, chain=options.chain))
        finally:
            if own:
                backend.close()


def load_sweep(directory) -> SweepResult:
    """The stored sweep of ``directory`` (complete or not)."""
    with SweepStore(directory, create=False) as store:
        meta = store.meta
        records = tuple(store.records())
    if "grid" not in meta:
        raise ProblemError([f"{directory}: the store has no sweep description"], title="no sweep")
    case = {k: meta.get(k) for k in ("scene", "task", "params", "label", "options", "shape", "coordinates",
                                           "inputs")}
    return SweepResult(directory, Grid.from_dict(meta["grid"]), case, records, units=meta.get("units", {}))


# ----------------------------------------------------------------------------- summary
def _fmt(value, spec=".4g") -> str:
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


def summary_lines(result: SweepResult, *, max_rows: int = 40) -> list:
    """The table printed at the end of ``nhgait sweep``: totals, then one line per point."""
    recs = result.records
    ok = [r for r in recs if r.success]
    J = np.array([r.objective for r in ok]) if ok else np.array([np.nan])
    warm_it = [r.iterations for r in ok if r.start == "warm"]
    cold_it = [r.iterations for r in ok if r.start != "warm"]
    lines = [f"sweep {result.case.get('label', '')}: {len(recs)}/{result.grid.size} points, {len(ok)} solved "
             f"and verified, {len(recs) - len(ok)} failed"
             + (f", {result.retried} retried" if result.retried else ""),
             f"  grid       {' × '.join(f'{a.name} ({len(a)})' for a in result.grid.axes)}",
             f"  objective  min {_fmt(np.nanmin(J))}, median {_fmt(float(np.nanmedian(J)))}, max "
             f"{_fmt(np.nanmax(J))}",
             f"  iterations median {_fmt(float(np.median(warm_it)), '.0f') if warm_it else '—'} warm-started "
             f"({len(warm_it)} points), {_fmt(float(np.median(cold_it)), '.0f') if cold_it else '—'} cold "
             f"({len(cold_it)})",
             "  verification error max "
             f"{_fmt(max((r.verification_error for r in ok), default=math.nan), '.2e')}"]
    if result.solved_now:
        lines.append(f"  this run   {result.solved_now} points in {result.wall_time_s:.1f} s "
                     f"({result.solved_now / max(result.wall_time_s, 1e-9):.2f} points/s) on "
                     f"{result.backend}")
    names = result.grid.names
    head = f"  {'point':>8}  " + "  ".join(f"{n:>12}" for n in names) + \
        f"  {'status':<22} {'J':>11} {'iter':>5} {'start':>5} {'verif.':>8}"
    lines.append(head)
    for r in recs[:max_rows]:
        lines.append(f"  {r.id:>8}  " + "  ".join(f"{r.axis_values[n]:>12.5g}" for n in names)
                     + f"  {r.status[:22]:<22} {_fmt(r.objective, '.5g'):>11} {r.iterations:>5} "
                     f"{(r.start or '—')[:5]:>5} {_fmt(r.verification_error, '.1e'):>8}")
    if len(recs) > max_rows:
        lines.append(f"  … {len(recs) - max_rows} more rows in {result.directory}/sweep.sqlite")
    return lines
