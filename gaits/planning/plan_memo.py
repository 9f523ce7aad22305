"""What a long-lived process keeps between plans (issue 40): the built NLP solver of each plan
structure and the last optimum of each task.

A designer iterates — plan, look, change a value, plan again — and in a notebook or a sweep
worker every turn used to rebuild the NLP and its solver, build and screen every initial guess
and explore further guesses after the first success, for a solve of a few hundredths of a
second. A :class:`PlanMemo` keeps, per process:

* **prepared** — the derived model, its specialisation and the problem of each plan
  (:func:`prepared_key`: the system's canonical text, every value of the task, the parameter
  values and the scene's extra quantities), so that a repeated plan neither loads nor
  specialises the model again;
* **solvers** — the :class:`~nhgait.ocp.solver.OCPSolver` (NLP functions, compiled code, the
  solver plugin, its coarse grid and time limit) of each *structure*: :func:`structure_key`,
  the SHA-256 of the derived model's cache key and chart, the velocity coordinates, the
  parameter values, the scene's extra quantities, the task with the values that only enter the
  NLP's bounds (initial, final and path bounds) replaced by their names, and the solver
  settings. A plan of the same structure reuses it; one whose boundary values changed
  (``overrides=["final.y=0.61"]``) reuses it with the new bounds
  (:meth:`~nhgait.ocp.solver.OCPSolver.for_values`, which checks that the new problem has the
  same NLP — else the solver is built anew);
* **derived** — what is computed from a converged solution alone (its momentum coordinates,
  its verification, the feedback along it and its Floquet multipliers), by the solution's content
  (:func:`solution_key`: the task key and the exact bytes of its grid, states and inputs): the
  same solution again gets the same values without computing them. A warm start from the last
  optimum (below) starts every repetition at the same point, so it returns the same solution,
  bit for bit, and these are reused;
* **optima** — the last converged solution of each *task* (:func:`task_key`: the structure and
  every value of the task), as an initial guess on the task's grid, with whether the planner's
  exploration of further guesses had been run for it. A repeated plan starts from it; when it
  had been explored, no exploration runs again (the progress line says so); the planner's own
  guesses are built only when that start fails.

**Across processes** (``nhgait plan`` run again): the last *verified* optimum of each task is
also kept in the disk cache next to the derived model (:func:`store_optimum`, under the task
key, with the cache's trust rules and checksums), and a new process's first plan of that task
starts from it (:func:`stored_optimum`), building the planner's own guesses only when it fails.
``NHGAIT_WARM_OPTIMA=0`` turns this off (the test suite does, so that no test starts from
another's answer).

A memo serves the thread that used it first (:meth:`PlanMemo.serves_this_thread`): a plan in
another thread runs without it (a built solver must not run in two threads at once).

Neither is a source of results: the solver is the one a cold plan builds, and a warm start from
the last optimum converges to that optimum (tests/gaits/test_plan_memo.py checks both against a
cold plan). Both are bounded (least recently used entries dropped: :data:`SOLVER_ENTRIES`,
:data:`OPTIMUM_ENTRIES`) and :meth:`PlanMemo.clear` empties them.

:data:`PLAN_MEMO` is the memo :func:`~nhgait.gaits.planner.plan` uses unless given another
(``plan(..., memo=PlanMemo())`` for a private one, ``memo=False`` for none); it is the only
module-level one, documented here, bounded and clearable like a ``functools`` cache.
"""
from __future__ import annotations

import hashlib
import json
import os
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

from nhgait.dynamics.memo import LruMemo

__all__ = ["PlanMemo", "Kept", "Optimum", "PLAN_MEMO", "prepared_key", "structure_key", "solution_key",
           "task_key", "stored_optimum", "store_optimum", "SOLVER_ENTRIES", "OPTIMUM_ENTRIES"]

#: built solvers kept (each holds its NLP functions and loaded library: a few MB)
SOLVER_ENTRIES = 8
#: last optima kept (each one trajectory on its grid)
OPTIMUM_ENTRIES = 32
#: the label of a warm start from the last optimum
LAST_OPTIMUM = "last optimum"
#: the disk cache's suffix of a task's last verified optimum
OPTIMUM_SUFFIX = ".optimum"
#: the environment variable that turns the disk cache's optima off ("0")
WARM_OPTIMA_ENV = "NHGAIT_WARM_OPTIMA"


class Kept(NamedTuple):
    """What a :class:`PlanMemo` hands out: the ``value`` (kept or just made) and whether it
    was ``reused`` (kept from an earlier plan: nothing was built or computed)."""

    value: Any
    reused: bool


@dataclass(frozen=True)
class Optimum:
    """The last converged solution of a task: ``guess`` (an
    :class:`~nhgait.ocp.solver.InitialGuess` on the task's grid, labelled :data:`LAST_OPTIMUM`),
    its ``objective`` J, ``explored``: whether it is the optimum the planner's exploration
    kept (the further guesses were tried), so that a repeated plan need not explore again, and
    ``iteration_s``: the seconds per iteration of the solve that found it."""

    guess: Any
    objective: float
    explored: bool
    #: seconds per iteration of the solve that found it (a warm start from it may then be solved
    #: in the planner's own process: :func:`~nhgait.gaits.planning.search._in_process`)
    iteration_s: float = float("inf")


class _Newest:
    """The one entry of a task in :attr:`PlanMemo.optima`: its newest optimum (``replaced``)."""

    def __init__(self, optimum: Optimum):
        self.replaced = optimum


def _kept(store: LruMemo, key: str | None, make: Callable[[], Any]) -> Kept:
    """``store``'s value for ``key`` (reused), else ``make()``, kept under ``key`` unless it is None."""
    if key is not None and key in store:
        return Kept(value=store.get(key), reused=True)
    value = make()
    if key is not None:
        store.get(key, lambda: value)
    return Kept(value=value, reused=False)


class PlanMemo:
    """A process's built solvers by structure and last optima by task (module docstring).

    Attributes
    ----------
    solvers, optima : :class:`~nhgait.dynamics.memo.LruMemo` — the entries
    builds : solvers built through :meth:`solver` (a memo hit builds none)
    reuses : solvers handed out again
    """

    def __init__(self, solvers: int = SOLVER_ENTRIES, optima: int = OPTIMUM_ENTRIES):
        self.prepared = LruMemo("prepared models and problems by plan", solvers)
        self.solvers = LruMemo("built NLP solvers by plan structure", solvers)
        self.optima = LruMemo("last optimum by task", optima)
        self.derived = LruMemo("values derived from a converged solution, by its content", optima)
        self.builds = 0
        self.reuses = 0
        self._thread: int | None = None

    def serves_this_thread(self) -> bool:
        """Whether plans in the calling thread may use this memo: a memo serves the one thread
        that used it first (a solver must not run in two threads at once); a plan in another
        thread runs without it."""
        ident = threading.get_ident()
        if self._thread is None:
            self._thread = ident
        return self._thread == ident

    def solver(self, key: str | None, build: Callable[[], Any]) -> Kept:
        """The solver kept for ``key`` (reused), else ``build()`` kept (``key`` None: built and
        not kept); counted in :attr:`builds` and :attr:`reuses`."""
        kept = _kept(self.solvers, key, build)
        if kept.reused:
            self.reuses += 1
        else:
            self.builds += 1
        return kept

    def prepare(self, key: str | None, make: Callable[[], Any]) -> Kept:
        """The :class:`~nhgait.gaits.planner.Prepared` kept for ``key`` (reused), else
        ``make()`` kept (``key`` None: made and not kept)."""
        return _kept(self.prepared, key, make)

    def of_solution(self, key: str | None, make: Callable[[], Any]) -> Kept:
        """The value kept for the solution key ``key`` (:func:`solution_key`; reused), else
        ``make()`` kept (``key`` None: made and not kept)."""
        return _kept(self.derived, key, make)

    def optimum(self, key: str | None) -> Optimum | None:
        """The last optimum of the task ``key`` (None: none kept)."""
        return self.optima.get(key).replaced if key is not None and key in self.optima else None

    def remember(self, key: str | None, optimum: Optimum) -> None:
        """Keep ``optimum`` as the last of the task ``key`` (replacing the one before)."""
        if key is not None:
            if key in self.optima:
                self.optima.get(key).replaced = optimum        # one entry per task, the newest
            else:
                self.optima.get(key, lambda: _Newest(optimum))

    def clear(self) -> None:
        """Forget every prepared plan, solver and optimum (the counters too)."""
        self.prepared.clear()
        self.solvers.clear()
        self.derived.clear()
        self.optima.clear()
        self.builds = self.reuses = 0
        self._thread = None

    def __repr__(self) -> str:
        return (f"PlanMemo({len(self.solvers)}/{self.solvers.size} solvers, {len(self.optima)}/"
                f"{self.optima.size} optima; {self.builds} built, {self.reuses} reused)")


#: the memo :func:`~nhgait.gaits.planner.plan` uses by default (module docstring)
PLAN_MEMO = PlanMemo()


def _digest(data) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=repr).encode()).hexdigest()


def _floats(values) -> list:
    """Exact floats (hex), so that equal keys mean equal numbers, never rounded ones."""
    return [float(v).hex() for v in values]


def _quantities(scene) -> list | None:
    """The scene's extra quantities as text, or None when they have no stable text (then no key)."""
    items = []
    for name, q in sorted(dict(getattr(scene, "quantities", {}) or {}).items()):
        text = repr(q)
        if " at 0x" in text:
            return None
        items.append((name, text))
    return items


def _task_structure(task: Mapping) -> dict:
    """The task with the values that only enter the NLP's bounds (initial, final, path bounds)
    replaced by their names (whether each is fixed or a range kept)."""
    shape = {}
    for key, value in task.items():
        if key in ("initial", "final", "bounds") and isinstance(value, Mapping):
            shape[key] = sorted((k, isinstance(v, (list, tuple))) for k, v in value.items())
        elif key not in ("name", "description"):
            shape[key] = value
    return shape


def prepared_key(to_plan, params) -> str | None:
    """The SHA-256 of what :func:`~nhgait.gaits.planner.prepare` makes a plan from: the
    system's canonical text, the plan's label, every value of its task, the parameter values
    and the scene's extra quantities (None when these have no stable text)."""
    quantities = _quantities(to_plan.scene)
    canonical = getattr(to_plan.scene.system, "canonical_text", None)
    if quantities is None or canonical is None:
        return None
    values = None if params is None else sorted((str(k), repr(v)) for k, v in dict(params).items())
    return _digest({"system": canonical(), "label": to_plan.label, "task": to_plan.task.to_dict(),
                    "params": values, "quantities": quantities})


def structure_key(prepared, scene, task, settings, solver_name: str) -> str | None:
    """The SHA-256 of what the NLP of ``prepared.problem`` is built from (module docstring), or
    None when the derived model has no cache key (then nothing is kept)."""
    model, specialised = prepared.model, prepared.specialised
    provenance = getattr(model, "provenance", None)
    quantities = _quantities(scene)
    if provenance is None or not getattr(provenance, "key", "") or quantities is None:
        return None
    return _digest({"model": provenance.key, "fiber": list(getattr(model, "fiber", ()) or ()),
                    "shape": list(getattr(model, "shape", ()) or ()),
                    "velocities": list(specialised.velocities), "route": str(specialised.route),
                    "params": _floats(prepared.problem.params), "quantities": quantities,
                    "task": _task_structure(task.to_dict()), "solver": solver_name,
                    "transcription": repr(settings.transcription), "jit": repr(settings.jit),
                    "hessian": settings.hessian, "max_iter": settings.max_iter})


def task_key(structure: str | None, task) -> str | None:
    """The SHA-256 of a structure and every value of ``task`` (None without a structure)."""
    if structure is None:
        return None
    values = {k: v for k, v in task.to_dict().items() if k not in ("name", "description")}
    return _digest({"structure": structure, "task": values})


def _disk_optima() -> bool:
    return os.environ.get(WARM_OPTIMA_ENV, "1").strip() != "0"


def stored_optimum(key: str | None) -> Optimum | None:
    """The last verified optimum of the task ``key`` in the disk cache (None: none, turned off
    by ``NHGAIT_WARM_OPTIMA=0``, or an entry the cache refuses)."""
    if key is None or not _disk_optima():
        return None
    import numpy as np

    from nhgait.dynamics.numerics import cache
    from nhgait.ocp import InitialGuess
    data = cache.load(key, dict, suffix=OPTIMUM_SUFFIX)
    try:
        guess = InitialGuess(np.asarray(data["states"], dtype=float),
                             np.asarray(data["controls"], dtype=float), float(data["horizon"]), LAST_OPTIMUM)
        return Optimum(guess, float(data["objective"]), bool(data["explored"]),
                       float(data.get("iteration_s", float("inf"))))
    except (TypeError, KeyError, ValueError):
        return None


def store_optimum(key: str | None, optimum: Optimum) -> None:
    """Keep ``optimum`` (verified) as the last of the task ``key`` in the disk cache (nothing
    when turned off, or when the cache cannot be written)."""
    if key is None or not _disk_optima():
        return
    import numpy as np

    from nhgait.dynamics.numerics import cache
    g = optimum.guess
    cache.store(key, {"states": np.asarray(g.states, dtype=float),
                      "controls": np.asarray(g.controls, dtype=float), "horizon": float(g.horizon),
                      "objective": float(optimum.objective), "iteration_s": float(optimum.iteration_s),
                      "explored": bool(optimum.explored)}, suffix=OPTIMUM_SUFFIX)


def solution_key(task: str | None, solution, what: str) -> str | None:
    """The SHA-256 of ``what`` is derived (a name), the task key and the exact content of a
    converged ``solution`` (its grid, states, inputs, horizon and RK4 sub-steps); None without a
    task key or a converged solution."""
    if task is None or solution is None or not solution.success:
        return None
    import numpy as np
    h = hashlib.sha256(f"{what}\0{task}\0{float(solution.horizon).hex()}\0"
                       f"{solution.settings.get('rk4_steps')}\0".encode())
    for array in (solution.t, solution.z, solution.u):
        a = np.ascontiguousarray(array, dtype=float)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()
