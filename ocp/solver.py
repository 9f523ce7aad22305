"""Ipopt or FATROP on a transcribed problem, with compiled NLP functions cached on disk.

* **Derivatives from the stage.** For the shooting transcriptions the constraint Jacobian and
  the Lagrangian Hessian are assembled from the stage function's own exact derivatives
  (:mod:`.derivatives`, :mod:`.stage`) and handed to the solver through ``nlpsol``'s function
  cache; CasADi differentiates only the small remaining rows. The NLP's code is the stage
  functions plus O(1) glue: it does not grow with N.
* **Hessians** (``SolverOptions.hessian``): ``"exact"`` (default), ``"gauss-newton"`` (the
  stage curvature dropped; the effort objective's Gauss–Newton matrix) or
  ``"limited-memory"`` (Ipopt's L-BFGS; not for FATROP).
* **Compiled, never waiting for the optimiser** (``jit=None``: when a C compiler is found):
  the oracle ``nlp`` and every function the solver builds from it are generated as one C
  file; :func:`.nlp_code.choose_code` runs it with the optimised library from the cache
  (gcc, flags from its size within :data:`COMPILE_BUDGET`), else with the fast compiler's
  library (tcc, ready in a fraction of a second) while the optimised build runs in the
  background for the next run. ``compile_report`` says which code solved, the size, the
  flags, the seconds and what was started for later. ``jit=True`` without a fast compiler
  builds the optimised library now; ``jit_flags`` forces the optimised flags.
* **Fallback**: without a compiler, when it fails, or without a fast compiler (``jit=None``),
  the solver runs the functions interpreted (``expand=True``, i.e. SX, only for inline
  stages: an expanded structured NLP would inline every call) and ``jit_fallback`` says why.
* **Collocation and MUMPS scaling**: with Ipopt's default ``mumps_scaling`` (77, automatic)
  MUMPS factorises the collocation KKT matrix at a cost that grows super-linearly in N (P2:
  1.3 s per iteration at N = 100, 20 iterations) — the automatic choice scales the matrix in
  a way that defeats the band structure; an explicit scaling (``mumps_scaling = 8``) gives
  ~5 ms per iteration and 10 iterations. Collocation therefore sets it unless the caller does.
* **Progress**: with a :class:`~nhgait.dynamics.progress.Progress`, the build, the compiler
  and (Ipopt) every tenth iteration report on it; ``progress.verbose`` shows the solver's own
  log instead.

An Ipopt/FATROP failure (infeasible, iteration limit, …) is returned as
``Solution(success=False)``; only bad input raises.
"""
from __future__ import annotations

import math
import numbers
import shutil
import time
import weakref
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

import casadi as ca
import numpy as np

from nhgait.dynamics.numerics.compiler import compiler_command
from nhgait.dynamics.numerics.fast_compiler import fast_compiler
from nhgait.dynamics.progress import Progress

from .backends import BACKENDS, SolverBackend
from .coarse import WARM_IPOPT, coarse_intervals, combined, interpolated, resampled
from .derivatives import nlp_functions
from .nlp_code import (
    COMPILE_BUDGET,
    NO_COMPILER,
    CompileBudget,
    CompileReport,
    choose_code,
    external_nlp,
    optimised_ready,
    parallel_maps,
)
from .problem import OptimalControlProblem, ProblemError
from .solution import Solution, node_arrays
from .transcription import Collocation, StageShooting, TranscribedNLP, get_transcription

__all__ = ["SolverOptions", "OCPSolver", "solve", "InitialGuess", "SOLVERS", "HESSIANS", "CompileBudget",
           "COMPILE_BUDGET", "CompileReport"]

SOLVERS = tuple(BACKENDS)
HESSIANS = ("exact", "gauss-newton", "limited-memory")
#: MUMPS settings for collocation KKT matrices (see the module docstring)
COLLOCATION_MUMPS = {"mumps_scaling": 8, "mumps_pivot_order": 0}
#: FATROP's return flags (``stats["fatrop"]["return_flag"]``, fatrop's ``IpSolverReturnFlag``)
#: by the names Ipopt uses for the same outcomes
FATROP_FLAGS = {0: "Solve_Succeeded", 1: "Maximum_Iterations_Exceeded", 2: "Solved_To_Acceptable_Level",
                3: "Infeasible_Problem_Detected", 4: "Line_Search_Failed", 5: "Error_In_Step_Computation",
                6: "Unknown_Error"}
#: the solvers' own names of a solve stopped by its wall-time limit → the name nhgait reports
TIME_LIMIT_STATUSES = {"Maximum_WallTime_Exceeded": "Time_Limit_Exceeded",
                       "Maximum_CpuTime_Exceeded": "Time_Limit_Exceeded"}


@dataclass(frozen=True)
class SolverOptions:
    """Solver settings.

    ``solver``: "ipopt" or "fatrop"; ``hessian``: one of :data:`HESSIANS`; ``jit``: compile
    the NLP functions (None: when a C compiler is found, never waiting for the optimising one;
    "optimised": the optimised library now, built in the foreground if not cached;
    :mod:`.nlp_code`); ``jit_flags``: compiler flags (None:
    chosen by ``budget`` from the C size); ``expand``: None = SX for inline stages when
    interpreted; ``ipopt``/``fatrop``: extra options; ``time_limit``: seconds of wall time per
    solve (None: unbounded) — Ipopt's ``max_wall_time`` and a deadline in its iteration
    callback (:meth:`OCPSolver.with_time_limit` changes the latter only); FATROP has no time
    option: its attempts are bounded by the supervisor that runs them (:mod:`.supervision`). A
    solve stopped by it has status ``"Time_Limit_Exceeded"``. ``iteration_limit``: at most this
    many iterations per solve, below ``max_iter`` (which is fixed when the solver is made), through
    the iteration callback (Ipopt; :meth:`OCPSolver.with_iteration_limit`); a solve stopped by it
    has status ``"Maximum_Iterations_Exceeded"``. FATROP, without the callback, ignores it.
    ``coarse``: each solve starts on a coarse grid (:mod:`.coarse`; Ipopt, problems without
    waypoints or phases, N ≥ 45) — for solves from generic guesses, not from warm starts.
    """

    max_iter: int = 3000
    tol: float = 1e-8
    hessian: str = "exact"
    jit: bool | str | None = None
    jit_flags: tuple | None = None
    expand: bool | None = None
    print_level: int = 0
    linear_solver: str = "mumps"
    solver: str = "ipopt"
    ipopt: dict = field(default_factory=dict)
    fatrop: dict = field(default_factory=dict)
    budget: CompileBudget = COMPILE_BUDGET
    time_limit: float | None = None
    iteration_limit: int | None = None
    coarse: bool = False

    def __post_init__(self):
        problems = []
        if self.jit not in (None, True, False, "optimised"):
            problems.append(f"jit must be None, True, False or 'optimised', got {self.jit!r}")
        if self.time_limit is not None and not (float(self.time_limit) > 0):
            problems.append(f"time_limit must be a positive number of seconds, got {self.time_limit!r}")
        if self.iteration_limit is not None and not (isinstance(self.iteration_limit, numbers.Integral)
                                                     and not isinstance(self.iteration_limit, bool)
                                                     and self.iteration_limit > 0):
            problems.append(f"iteration_limit must be a whole number ≥ 1, got {self.iteration_limit!r}")
        if self.solver not in SOLVERS:
            problems.append(f"unknown solver {self.solver!r} (known: {', '.join(SOLVERS)})")
        if self.hessian not in HESSIANS:
            problems.append(f"unknown Hessian {self.hessian!r} (known: {', '.join(HESSIANS)})")
        elif self.solver in BACKENDS and self.hessian == "limited-memory" and not self.backend.limited_memory:
            problems.append(f"{self.backend.label} has no limited-memory Hessian: use exact or gauss-newton, "
                            "or Ipopt")
        if problems:
            raise ProblemError(problems)

    @property
    def backend(self) -> SolverBackend:
        """The solver named by ``solver`` (:mod:`.backends`)."""
        return BACKENDS[self.solver]

    @property
    def stops_in_time(self) -> bool:
        """Whether the solver itself honours ``time_limit`` (Ipopt: ``max_wall_time``; FATROP has
        no time option)."""
        return self.backend.time_option and self.time_limit is not None

    @property
    def compiled(self) -> bool:
        """Whether compiled functions are asked for (``jit``, or auto with a compiler)."""
        return bool(self.jit) if self.jit is not None else (compiler_command() or fast_compiler()) is not None

    def nlpsol_options(self, *, expand: bool = False) -> dict:
        opts = {"print_time": False, "record_time": True, "expand": bool(expand), "error_on_fail": False}
        return self.backend.nlpsol_options(self, opts)

    def describe(self) -> dict:
        extra = self.backend.own_options(self)
        return {"solver": self.solver, "max_iter": self.max_iter, "tol": self.tol, "hessian": self.hessian,
                "jit": self.jit, "jit_flags": list(self.jit_flags) if self.jit_flags else None,
                "linear_solver": self.linear_solver, "expand": self.expand,
                "time_limit": self.time_limit, "iteration_limit": self.iteration_limit, "coarse": self.coarse,
                **extra}


@dataclass(frozen=True)
class InitialGuess:
    """Node states (nz × (N+1)) and controls (nu × N) on the problem grid, optional T."""

    states: np.ndarray
    controls: np.ndarray
    horizon: float | None = None
    label: str = ""


class _Iterations(ca.Callback):
    """Ipopt's iteration callback: a progress line (iteration, objective, largest constraint
    violation of the iterate) every ``every`` iterations, at most once per ``seconds`` — a fast
    solve prints nothing, a long one talks — and the solve's deadline: past it, Ipopt is asked
    to stop (``timed_out``; reported as ``Time_Limit_Exceeded`` with the iterate reached). An
    exception raised while it runs (a signal's handler) is kept in ``raised`` and the solver
    stopped, to be raised again once the solver has returned (an exception inside a CasADi
    callback would otherwise be lost). :meth:`start` resets it for a new solve."""

    def __init__(self, name, nlp, progress, every=10, seconds=1.0):
        ca.Callback.__init__(self)
        self.nlp, self.progress, self.every, self.seconds = nlp, progress, every, seconds
        self.n_x, self.n_g = int(nlp.w.shape[0]), int(nlp.g.shape[0])
        self.start()
        self.construct(name, {"enable_fd": False})

    def start(self, deadline: float | None = None, cap: int | None = None):
        """A new solve, asked to stop after ``deadline`` (``time.perf_counter()`` seconds) or
        after ``cap`` iterations (``capped``)."""
        self.count, self.last, self.deadline, self.cap = 0, time.perf_counter(), deadline, cap
        self.timed_out, self.capped, self.raised = False, False, None

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        n = ca.nlpsol_out(i)
        size = {"f": 1, "lam_p": 0}.get(n, self.n_x if n in ("x", "lam_x") else self.n_g)
        return ca.Sparsity.dense(size, 1)

    def eval(self, arg):
        try:
            return [self._iteration(arg)]
        except BaseException as exc:  # noqa: BLE001 - kept, the solver stopped, raised after it returns
            self.raised = exc
            return [1]

    def _iteration(self, arg) -> int:
        """1 to stop the solver (past the deadline), else 0."""
        self.count += 1                 # the callback sees iteration 0 too: count − 1 iterations done
        now = time.perf_counter()
        if self.deadline is not None and now > self.deadline:
            self.timed_out = True
            return 1
        if self.cap is not None and self.count > self.cap:
            self.capped = True
            return 1
        if self.progress.enabled and self.count % self.every == 0 and now - self.last >= self.seconds:
            self.last = now
            g = np.asarray(arg[ca.nlpsol_out().index("g")]).ravel()
            viol = max(np.max(self.nlp.lbg - g, initial=0.0), np.max(g - self.nlp.ubg, initial=0.0))
            self.progress.note(f"    iteration {self.count}: objective "
                               f"{float(arg[1]) / self.nlp.objective_scale:.6g}, "
                               f"constraint violation {viol:.2e}")
        return 0


def iteration_history(stats: dict, objective_scale: float = 1.0) -> dict:
    """{"history": {"objective": [...], "violation": [...]}} per iteration from Ipopt's
    ``stats["iterations"]`` (``obj`` unscaled by ``objective_scale``; ``inf_pr``, Ipopt's primal
    infeasibility of the iterate); {} for a solver that keeps none (FATROP). For the convergence
    figure (:mod:`nhgait.gaits.figures.convergence`)."""
    it = stats.get("iterations")
    if not isinstance(it, dict) or "obj" not in it or "inf_pr" not in it:
        return {}
    return {"history": {"objective": [float(v) / objective_scale for v in it["obj"]],
                        "violation": [float(v) for v in it["inf_pr"]]}}


def _refuse_overdetermined(nlp: TranscribedNLP, problem: OptimalControlProblem) -> None:
    """More equality constraints than free unknowns (a task's conditions on too few intervals:
    the unicycle's parallel park on N = 1 or 2) is a ProblemError before any solve — CasADi's
    "NLP is overconstrained" at every attempt, even with --quiet, then a failure."""
    equalities = int(np.sum(np.asarray(nlp.lbg, float) == np.asarray(nlp.ubg, float)))
    free = int(np.sum(np.asarray(nlp.lbx, float) < np.asarray(nlp.ubx, float)))
    if equalities > free:
        raise ProblemError([f"N = {problem.intervals} intervals: {equalities} equality conditions (the "
                            f"dynamics between the nodes and the task's conditions) on {free} free "
                            "unknowns — give the task more intervals"], title="overdetermined problem")


class OCPSolver:
    """A problem transcribed and handed to its solver once; :meth:`solve` may be called many times.

    Attributes
    ----------
    nlp : TranscribedNLP
    setup_time_s : float — transcription + nlpsol construction (+ compile or load)
    compiled : bool — whether the NLP functions are compiled code
    compile_report : CompileReport or None — the C size, flags, seconds and why
    jit_cached : bool or None — whether the compiled functions came from the cache
    jit_fallback : str or None — why compiled functions were asked for but not used
    jit_path : the compiled library (or None)
    """

    def __init__(self, problem: OptimalControlProblem, transcription=None,
                 options: SolverOptions | None = None, *, progress: Progress | None = None):
        t0 = time.perf_counter()
        self.problem = problem
        self.options = options or SolverOptions()
        self.progress = progress or Progress.silent()
        backend = self.options.backend
        if backend.stage_structure and transcription in (None, "multiple-shooting"):
            transcription = StageShooting()
        self.transcription = get_transcription(transcription)
        if backend.stage_structure and self.nlp_structure_missing():
            raise ProblemError([f"FATROP needs a stage-ordered transcription (multiple-shooting-stages), "
                                f"got {self.transcription.name}"])
        if isinstance(self.transcription, Collocation) and backend.mumps:
            self.options = replace(self.options, ipopt={**COLLOCATION_MUMPS, **self.options.ipopt})
        self.nlp: TranscribedNLP = self.transcription.build(problem)
        _refuse_overdetermined(self.nlp, problem)
        self.functions = nlp_functions(self.nlp, hessian=self.options.hessian, solver=self.options.solver,
                                       parallel=parallel_maps(self.options))
        self.jit_cached, self.jit_fallback, self.compiled, self.jit_path = None, None, False, None
        self.compile_report, self.coarse = None, None
        self._capped: dict = {}               # capped copies (:meth:`capped`), shared by this solver's copies
        if self.options.jit is None and compiler_command() is None and fast_compiler() is None:
            self.jit_fallback = NO_COMPILER
            self.progress.note_once("no-compiler", f"{NO_COMPILER}: the NLP functions run interpreted")
        elif self.options.jit is not False:
            self.solver = self._jit_solver()
        if not self.compiled:
            self.solver = self._nlpsol("ocp", *self._source())
        self.setup_time_s = time.perf_counter() - t0
        if self.options.coarse:
            self.coarse = self._coarse_start()
            self.setup_time_s = time.perf_counter() - t0

    def nlp_structure_missing(self) -> bool:
        return not isinstance(self.transcription, StageShooting)

    def _oracle(self) -> dict:
        return {"x": self.nlp.w, "f": self.nlp.f, "g": self.nlp.g}

    def _source(self) -> tuple:
        """(oracle, nlpsol options) the solver is made from: the compiled library's oracle, or
        the symbolic one (expanded to SX for inline stages unless ``options.expand`` says)."""
        if self.compiled:
            return external_nlp(self.jit_path), self.options.nlpsol_options()
        inline = self.nlp.layout is None or self.nlp.layout.stage.mode == "inline"
        expand = inline if self.options.expand is None else self.options.expand
        return self._oracle(), self.options.nlpsol_options(expand=expand)

    def _nlpsol(self, name, nlp, opts, *, talk: bool = True):
        if self.functions and not isinstance(nlp, ca.Function):
            opts = {**opts, "cache": self.functions}
        backend = self.options.backend
        opts = backend.structure_options(self.nlp, opts)
        if talk and backend.iteration_callback:  # progress lines (not with the solver's own log), deadlines
            said = Progress.silent() if self.progress.verbose else self.progress
            self._callback = _Iterations(f"{name}_iterations", self.nlp, said)
            opts = {**opts, "iteration_callback": self._callback}
        if talk and self.progress.verbose:     # the solver's own log (on stdout)
            opts = backend.verbose_options(opts)
        return ca.nlpsol(name, self.options.solver, nlp, opts)

    def _jit_solver(self):
        """The solver on compiled functions, or None (``jit_fallback`` says why).

        Every function the solver plugin builds from its oracle (``nlp_f``, ``nlp_g``,
        ``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l``, …, read off an uncompiled instance) and
        the oracle ``nlp`` itself are generated into one C file; :func:`.nlp_code.choose_code`
        picks the code that runs it now (the optimised library from the cache, else the fast
        compiler's) and starts the optimised build for the next run; the solver is then made
        from the external oracle, whose ``factory`` loads each function from the library by name."""
        opts = self.options.nlpsol_options()
        plain = self._nlpsol("ocp_plain", self._oracle(), opts, talk=False)
        x, p = ca.MX.sym("x", self.nlp.w.shape[0]), ca.MX.sym("p", 0)
        oracle = ca.Function("nlp", [x, p],
                             [plain.get_function("nlp_f")(x, p), plain.get_function("nlp_g")(x, p)],
                             ["x", "p"], ["f", "g"])
        cg = ca.CodeGenerator("nhgait_nlp.c", {"with_header": False})
        for f in [oracle] + [plain.get_function(name) for name in plain.get_function()]:
            cg.add(f)
        code = choose_code(cg.dump(), self.options, self.progress, salt=f"nlp casadi {ca.__version__}",
                           slot=self._build_slot())
        self.compile_report, self.jit_fallback = code.report, code.fallback
        lib = code.library
        if lib is None:
            return None
        if lib.private:   # the library stays loaded; its private folder goes with this solver
            weakref.finalize(self, shutil.rmtree, lib.path.parent, True)
        self.compiled, self.jit_cached, self.jit_path = True, lib.cached, lib.path
        return self._nlpsol("ocp", external_nlp(lib.path), opts)

    def _build_slot(self) -> str:
        """The robot, task, grid and solver this solver's optimised build is asked for (its newest
        request replaces older ones: :mod:`~nhgait.dynamics.numerics.build_queue`); empty for
        a problem without a name (then the build's key alone)."""
        name = self.problem.name.split(" (", 1)[0]     # "robot/task", without its edits "(horizon=2.0)"
        return (f"{name} | {type(self.transcription).__name__} N={self.problem.intervals} | "
                f"{self.options.solver}") if name else ""

    def adopt_optimised(self) -> bool:
        """Switch to the optimised library once the background build this solver started has
        landed in the cache (:func:`.nlp_code.optimised_ready`; issue 25): the solves from now
        on run on it, and their ``settings["compile"]`` says so (``code`` "optimised",
        ``switched_from`` the code before). True when it switched; a library that does not load
        leaves the code as it was. The coarse grid's solver (:mod:`.coarse`) adopts its own
        library the same way, whenever it lands. The search calls it before each batch of
        attempts."""
        switched = self._switch(optimised_ready(self.compile_report))
        if self.coarse is not None:
            n, sub, _ = self.coarse
            sub.adopt_optimised()
            if switched:
                self.coarse = (n, sub, self._warm())
        return switched

    def _switch(self, report: CompileReport | None) -> bool:
        if report is None:
            return False
        try:
            solver = self._nlpsol("ocp", external_nlp(report.path), self.options.nlpsol_options())
        except RuntimeError:
            return False
        self.solver, self.compile_report = solver, report
        self.compiled, self.jit_cached, self.jit_path, self.jit_fallback = True, True, Path(report.path), None
        self.progress.note(f"  the optimised library is ready ({report.compiler} {' '.join(report.flags)}, "
                           "built in the background): the next attempts run on it")
        return True

    def with_problem(self, problem: OptimalControlProblem) -> OCPSolver:
        """This solver for ``problem``, a problem of the same structure whose values (targets,
        bounds) differ: the NLP functions are reused, only the bounds are recomputed."""
        nlp = self.transcription.build(problem)
        if (nlp.n_w != self.nlp.n_w or nlp.lbg.shape != self.nlp.lbg.shape
                or nlp.row_labels != self.nlp.row_labels or nlp.objective_scale != self.nlp.objective_scale):
            raise ProblemError(["with_problem: the new problem has another structure"])
        other = object.__new__(OCPSolver)
        other.__dict__.update(self.__dict__)
        other.problem = problem
        other.nlp = replace(self.nlp, problem=problem, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
        other.coarse = None                     # a problem grown from another: no coarse grid
        other._capped = {}                      # its capped copies solve its own bounds
        return other

    def for_values(self, problem: OptimalControlProblem) -> OCPSolver:
        """This solver for ``problem`` of the same structure whose boundary and bound values
        differ (:meth:`with_problem`), keeping its coarse grid (:mod:`.coarse`), whose solvers
        get the new values too: the solver a cold plan of ``problem`` builds, without building
        it (a long-lived process's memo, :mod:`nhgait.gaits.planning.plan_memo`). ``problem``
        itself when it is this solver's. A problem of another structure is a ProblemError."""
        if problem is self.problem:
            return self
        other = self.with_problem(problem)
        if self.coarse is not None:
            n, sub, warm = self.coarse
            other.coarse = (n, sub.with_problem(problem.replace(intervals=n)),
                            None if warm is None else warm.with_problem(problem))
        return other

    def talk_to(self, progress: Progress | None) -> OCPSolver:
        """This solver (and its capped copies, :meth:`capped`) saying its notes and Ipopt's
        iteration lines on ``progress`` from now on (None: silent) — a solver kept between plans
        talks on each plan's own stream. The solver's own log (``progress.verbose``) is fixed
        when it is made. Returns this solver."""
        self.progress = progress or Progress.silent()
        for solver in (self, *self._capped.values()):
            solver.progress = self.progress
            callback = getattr(solver, "_callback", None)
            if callback is not None:
                callback.progress = Progress.silent() if self.progress.verbose else self.progress
        return self

    def capped(self, iterations: int) -> OCPSolver | None:
        """This solver whose solver plugin stops after ``iterations`` (its own ``max_iter``, for
        a solver without an iteration callback too — FATROP), on the same compiled library; the
        options (and the settings a solution reports) unchanged. Until the cap the iterates are
        those of this solver, so a capped solve that converges is this solver's solve; one that
        reaches the cap reports ``Maximum_Iterations_Exceeded``. None when interpreted (remaking
        an interpreted solver costs as much as making it). Made once per cap and kept."""
        if not self.compiled or self.jit_path is None:
            return None
        key = (int(iterations), repr(self.options), str(self.jit_path))
        if key not in self._capped:      # one dict shared by this solver's copies (direct, time limits)
            other = object.__new__(OCPSolver)
            other.__dict__.update(self.__dict__)
            other.coarse = None
            opts = replace(self.options, max_iter=int(iterations)).nlpsol_options()
            other.solver = other._nlpsol(f"ocp_capped_{int(iterations)}", external_nlp(self.jit_path), opts)
            self._capped[key] = other
        return self._capped[key]

    def settings(self) -> dict:
        stage = self.nlp.layout.stage.describe() if self.nlp.layout is not None else {}
        return {**self.transcription.settings(), **self.options.describe(), **stage,
                "jit": self.compiled, "jit_fallback": self.jit_fallback,
                "intervals": self.problem.intervals, "horizon": float(self.problem.horizon),
                "n_variables": self.nlp.n_w, "n_constraints": int(self.nlp.g.shape[0]),
                "jit_cached": self.jit_cached,
                "compile": self.compile_report.describe() if self.compile_report else None}

    def _non_finite(self, w0) -> str | None:
        """Why the solver must not start at ``w0`` (non-finite constraints: a guess on the
        singular set of the model), or None. A solver started there may not recover (FATROP
        stalls in its first iteration)."""
        g = np.asarray(self.solver.get_function("nlp_g")(w0, [])).ravel()
        rows = np.flatnonzero(~np.isfinite(g))
        if rows.size == 0:
            return None
        where = ""
        if self.nlp.layout is not None:
            stages = np.flatnonzero(np.isin(self.nlp.layout.rows, rows).any(axis=0))
            where = f" at intervals {', '.join(map(str, stages[:8]))}" + (" …" if stages.size > 8 else "")
        return (f"the initial guess gives non-finite values in {rows.size} constraint rows{where} "
                "(a configuration on the model's singular set?)")

    def solve(self, guess: InitialGuess) -> Solution:
        """Run the solver from ``guess`` (projected into the bounds) in this process — on the
        coarse grid first when the solver has one (:mod:`.coarse`); failures are returned as
        ``success=False``, a guess with non-finite dynamics without running the solver. (The
        planner runs each solve in a supervised child: :mod:`.supervision`.)"""
        if self.coarse is not None:
            return self._coarse_first(guess)
        return self._solve(guess)

    def _coarse_start(self) -> tuple | None:
        """(N_c, the coarse grid's solver, this solver with Ipopt's warm-start settings — None
        when interpreted: remaking an interpreted solver costs as much as making it) or None."""
        n = coarse_intervals(self.problem, self.options.solver)
        if n is None:
            return None
        sub = OCPSolver(self.problem.replace(intervals=n), self.transcription,
                        replace(self.options, coarse=False), progress=Progress.silent())
        self.progress.note(f"  coarse grid: each guess solved first on {n} intervals, then on "
                           f"{self.problem.intervals}")
        return n, sub, (self._warm() if self.compiled else None)

    def _warm(self) -> OCPSolver:
        """This solver with :data:`.coarse.WARM_IPOPT`, on the same compiled NLP functions."""
        other = object.__new__(OCPSolver)
        other.__dict__.update(self.__dict__)
        other.options = replace(self.options, ipopt={**WARM_IPOPT, **self.options.ipopt}, coarse=False)
        other.coarse = None
        other.solver = other._nlpsol("ocp_warm", external_nlp(self.jit_path),
                                     other.options.nlpsol_options())
        return other

    def _coarse_first(self, guess: InitialGuess) -> Solution:
        """:mod:`.coarse`, steps 1–3, within this solver's time and iteration limits."""
        n, sub, warm = self.coarse
        t0, limit = time.perf_counter(), self.options.time_limit
        first = sub._with_options(time_limit=limit, iteration_limit=self.options.iteration_limit).solve(
            resampled(guess, self.problem, sub.problem))
        left = None if limit is None else max(limit - (time.perf_counter() - t0), 1e-3)
        if first.success:
            fine = (warm or self)._with_options(time_limit=left)._solve(
                interpolated(first, sub.problem, self.problem, guess))
        else:
            fine = self._with_options(time_limit=left)._solve(guess)
        settings = {**fine.settings, "coarse_intervals": n}
        return combined(replace(fine, settings=settings, setup_time_s=self.setup_time_s), first, n)

    def _solve(self, guess: InitialGuess) -> Solution:
        """:meth:`solve` on this grid only."""
        w0 = self._start(guess)
        callback = getattr(self, "_callback", None)
        if callback is not None:
            limit = self.options.time_limit
            callback.start(None if limit is None else time.perf_counter() + float(limit),
                           self.options.iteration_limit)
        out, error, refused, wall = self._run(w0)
        if callback is not None and callback.raised is not None:
            raise callback.raised
        stats = {} if refused else self.solver.stats()     # a refused guess never ran the solver
        if callback is not None and callback.timed_out:
            stats = {**stats, "return_status": "Time_Limit_Exceeded"}
        elif callback is not None and callback.capped:
            stats = {**stats, "return_status": "Maximum_Iterations_Exceeded"}
        outcome = self._outcome(out, w0)
        fn_time = sum(float(v) for k, v in stats.items() if k.startswith("t_wall_nlp_"))
        total = float(stats.get("t_wall_total", wall))
        verdict = self._verdict(stats, error, refused, outcome.violation)
        message = verdict.status if error is None else f"{verdict.status}: {error}"
        return self._solution(guess, outcome, verdict, message,
                              times=(wall, fn_time, max(total - fn_time, 0.0)))

    def unsolved(self, guess: InitialGuess, status: str, message: str, seconds: float = 0.0) -> Solution:
        """The failed Solution of an attempt from ``guess`` that gave no answer (stopped at its
        time limit, its process died): the guess itself, with its objective and constraint
        violation (NaN where the NLP functions give none)."""
        w0 = self._start(guess)
        try:
            out = {"x": w0, "f": self.solver.get_function("nlp_f")(w0, [])[0],
                   "g": self.solver.get_function("nlp_g")(w0, [])}
            outcome = self._outcome(out, w0)
        except RuntimeError:                   # an evaluation error at the guess
            outcome = _Outcome(w0, math.nan, math.nan, {})
        verdict = _Verdict(False, status, {"solver_status": status, "success": False})
        return self._solution(guess, outcome, verdict, f"{status}: {message}",
                              times=(float(seconds), 0.0, float(seconds)))

    def _solution(self, guess, outcome: _Outcome, verdict: _Verdict, message: str, *, times) -> Solution:
        """A Solution at the decision vector of ``outcome``; ``times``: (wall, in the functions, in
        the solver) [s]."""
        problem, w, stats = self.problem, outcome.w, verdict.stats
        Z, U, T = self.nlp.unpack(w)
        wall, fn_time, solver_time = times
        return Solution(success=verdict.success, status=verdict.status, message=message,
                        iterations=int(stats.get("iter_count", 0)), objective=outcome.objective,
                        t=self.nlp.times(w), z=np.asarray(Z).T, u=np.asarray(U).T,
                        state_names=problem.state_names, control_names=problem.control_names,
                        horizon=T, solve_time_s=wall, setup_time_s=self.setup_time_s,
                        function_time_s=fn_time, solver_time_s=solver_time,
                        stats={**{k: (v if isinstance(v, (int, float, str, bool)) else str(v))
                                  for k, v in stats.items() if not isinstance(v, dict)},
                               **iteration_history(stats, self.nlp.objective_scale)},
                        settings={**self.settings(), "guess": guess.label}, problem=problem,
                        constraint_violation=outcome.violation, violations=outcome.violated)

    def evaluation_seconds(self, guess: InitialGuess | None = None) -> float:
        """Seconds of one evaluation of every NLP function the solver uses (objective,
        constraints, their derivatives, the Hessian of the Lagrangian) at ``guess`` (None: zero
        clipped into the bounds), each called once (a first call also allocates its work
        memory: an over-estimate, never under): the cost of about one iteration, from which
        :mod:`.budget` sets an attempt's default time limit."""
        w0 = (np.clip(np.zeros(self.nlp.n_w), self.nlp.lbx, self.nlp.ubx) if guess is None
              else self._start(guess))
        total = 0.0
        for name in self.solver.get_function():
            f = self.solver.get_function(name)
            args = [w0 if f.name_in(i) == "x" else np.ones(f.size_in(i)) for i in range(f.n_in())]
            total += _seconds(f, args)
        return total

    def with_time_limit(self, seconds: float | None) -> OCPSolver:
        """This solver with ``options.time_limit = seconds``, sharing its NLP functions and
        solver: Ipopt honours it through its iteration callback's deadline (its own
        ``max_wall_time`` is fixed when the solver is made — remaking an interpreted solver costs
        as much as making it); FATROP, which has no time option, through the supervisor that
        runs the attempt (:mod:`.supervision`)."""
        return self._with_options(time_limit=seconds)

    def with_iteration_limit(self, iterations: int | None) -> OCPSolver:
        """This solver with ``options.iteration_limit = iterations`` (honoured by the iteration
        callback), sharing its NLP functions and solver."""
        return self._with_options(iteration_limit=iterations)

    def direct(self) -> OCPSolver:
        """This solver without its coarse grid (:mod:`.coarse`), sharing its NLP functions."""
        other = self._with_options(coarse=False)
        if other is not self:
            other.coarse = None
        return other

    def _with_options(self, **changes) -> OCPSolver:
        if all(getattr(self.options, k) == v for k, v in changes.items()):
            return self
        other = object.__new__(OCPSolver)
        other.__dict__.update(self.__dict__)
        other.options = replace(self.options, **changes)
        return other

    def _start(self, guess: InitialGuess) -> np.ndarray:
        """The guess packed into the decision vector and clipped into its bounds
        (:class:`ProblemError` for arrays of the wrong shape)."""
        problem, N = self.problem, self.problem.intervals
        states, controls = node_arrays(guess)
        problems = []
        if states.shape not in ((problem.n_states, N + 1), (len(problem.model_state_names), N + 1)):
            # the model's states alone: the integral states are completed (TranscribedNLP.complete)
            problems.append(f"guess states have shape {states.shape}, expected {(problem.n_states, N + 1)}")
        if controls.shape != (problem.n_controls, N):
            problems.append(f"guess controls have shape {controls.shape}, expected {(problem.n_controls, N)}")
        if problems:
            raise ProblemError(problems, title="invalid initial guess")
        return np.clip(self.nlp.pack(states, controls, guess.horizon), self.nlp.lbx, self.nlp.ubx)

    def _run(self, w0: np.ndarray) -> tuple:
        """(solver output or None, the error or None, whether the start was refused for
        non-finite dynamics, wall time [s])."""
        nlp = self.nlp
        start = time.perf_counter()
        refused = self._non_finite(w0)
        out, error = None, (RuntimeError(refused) if refused else None)
        if not refused:
            try:
                out = self.solver(x0=w0, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
            except RuntimeError as exc:  # evaluation errors (NaN in the oracle) and the like
                error = exc
        return out, error, bool(refused), time.perf_counter() - start

    def _outcome(self, out, w0: np.ndarray) -> _Outcome:
        """(decision vector, objective, largest bound/constraint violation, the violated
        constraints by name) of a solver output; the start and NaNs without one."""
        nlp = self.nlp
        if out is None:
            return _Outcome(w0, float("nan"), float("nan"), {})
        w = np.asarray(out["x"]).ravel()
        g = np.asarray(out["g"]).ravel()
        viol = float(max(np.max(np.maximum(nlp.lbg - g, 0), initial=0.0),
                         np.max(np.maximum(g - nlp.ubg, 0), initial=0.0),
                         np.max(np.maximum(nlp.lbx - w, 0), initial=0.0),
                         np.max(np.maximum(w - nlp.ubx, 0), initial=0.0)))
        objective = float(out["f"]) / nlp.objective_scale        # the NLP's f is s·J (transcription)
        return _Outcome(w, objective, viol, nlp.violations(g, w, tol=max(1e-6, 10 * self.options.tol)))

    def _verdict(self, stats: dict, error, refused: bool, violation: float) -> _Verdict:
        """(success, status, stats with ``solver_status``): Ipopt's return status; FATROP's
        return flag, or convergence read from its own measures (:func:`_fatrop_converged`)."""
        status = ("Invalid_Initial_Point" if refused else
                  str(stats.get("return_status", "exception" if error else "unknown")))
        status = TIME_LIMIT_STATUSES.get(status, status)
        if not self.options.backend.reports_success and error is None:
            ok = bool(stats.get("success", False)) or _fatrop_converged(stats, violation, self.options.tol)
            flag = ((stats.get("fatrop") or {}).get("return_flag")
                    if isinstance(stats.get("fatrop"), dict) else None)
            stats = {**stats, "success": ok, "fatrop_return_flag": flag}
            status = "Solve_Succeeded" if ok else FATROP_FLAGS.get(flag, f"FATROP return flag {flag}")
        success = bool(stats.get("success", False)) and error is None
        return _Verdict(success, status, {**stats, "solver_status": status})


class _Outcome(NamedTuple):
    """Where a solve ended: the decision vector, J, the largest bound/constraint violation and
    the violated constraints by name."""

    w: np.ndarray
    objective: float
    violation: float
    violated: dict


class _Verdict(NamedTuple):
    """What the solver says of a solve: success, its status, its stats (``solver_status`` added)."""

    success: bool
    status: str
    stats: dict


def _seconds(f, args) -> float:
    """Wall seconds of one call ``f(*args)`` (an evaluation error — NaN at a guess — still counts)."""
    start = time.perf_counter()
    try:
        f(*args)
    except RuntimeError:
        pass
    return time.perf_counter() - start


def _fatrop_converged(stats, violation, tol) -> bool:
    """FATROP reports its return flag (0: converged) in ``stats["fatrop"]``."""
    flag = stats.get("fatrop", {}).get("return_flag") if isinstance(stats.get("fatrop"), dict) else None
    return flag == 0 and violation <= max(1e-6, 10 * tol)


def solve(problem: OptimalControlProblem, guess: InitialGuess, *, transcription=None,
          options: SolverOptions | None = None, **option_kwargs) -> Solution:
    """Transcribe, build and solve in one call (``option_kwargs`` go to :class:`SolverOptions`)."""
    if options is None:
        options = SolverOptions(**option_kwargs)
    elif option_kwargs:
        raise TypeError("give either options or option keywords, not both")
    return OCPSolver(problem, transcription, options).solve(guess)
