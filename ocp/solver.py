"""Ipopt or FATROP on a transcribed problem, with compiled NLP functions cached on disk.

* **Compiled by default** (``SolverOptions(jit=None)``: compile when a C compiler is found —
  ``$CC``, else ``gcc``/``cc``): the NLP is *not* expanded (the MX graph keeps ``F.map(N)`` as
  a loop over one RK4 kernel); the oracle ``nlp`` = (f, g) and every function the solver
  builds from it (``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l``, …) are generated as one C
  file, compiled once to
  ``$NHGAIT_CACHE_DIR/jit/<sha256 of the C source, compiler, flags, CasADi version>.so`` and
  loaded with ``casadi.external`` (the solver's ``factory`` calls find each function in the
  library by name). The library's SHA-256 is recorded beside it
  (``<key>.so.sha256``) and a cached library is loaded only through
  :func:`nhgait.dynamics.cache.trusted_file` (directory 0700, not group/world-writable, owned
  by the user, content hash unchanged); otherwise it is rebuilt. Boundary values live in the
  bounds, not in the compiled code, so changing a target does not recompile.
* **Fallback**: without a compiler, or when compiling fails, the solver is built the
  interpreted way (``expand=True``: the MX graph expanded to SX, the fastest interpreted
  evaluation) and ``settings["jit_fallback"]`` says why. ``jit=False`` asks for that directly.
* **Solvers**: ``solver="ipopt"`` (MUMPS, exact Hessian; default) or ``solver="fatrop"``, the
  structure-exploiting interior-point solver inside the CasADi wheel, on the stage-ordered
  transcription (:class:`~nhgait.ocp.transcription.StageShooting`, chosen automatically).
* **Collocation and MUMPS scaling**: with Ipopt's default ``mumps_scaling`` (77, automatic)
  MUMPS factorises the collocation KKT matrix at a cost that grows super-linearly in N (P2:
  1.3 s per iteration at N = 100, 20 iterations) — the automatic choice scales the matrix in
  a way that defeats the band structure; an explicit scaling (``mumps_scaling = 8``) gives
  ~5 ms per iteration and 10 iterations. Collocation therefore sets it unless the caller does.

An Ipopt/FATROP failure (infeasible, iteration limit, …) is returned as
``Solution(success=False)``; only bad input raises.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import time
import weakref
from dataclasses import dataclass, field, replace
from pathlib import Path

import casadi as ca
import numpy as np

from .problem import OptimalControlProblem, ProblemError
from .solution import Solution
from .transcription import Collocation, StageShooting, TranscribedNLP, get_transcription

__all__ = ["SolverOptions", "OCPSolver", "solve", "InitialGuess", "jit_cache_dir", "find_compiler", "SOLVERS"]

SOLVERS = ("ipopt", "fatrop")
#: MUMPS settings for collocation KKT matrices (see the module docstring)
COLLOCATION_MUMPS = {"mumps_scaling": 8, "mumps_pivot_order": 0}


def find_compiler() -> str | None:
    """The C compiler used for compiled functions: ``$CC`` if set (None when it does not
    exist), else ``gcc`` or ``cc`` on the PATH."""
    env = os.environ.get("CC")
    if env:
        return shutil.which(env)
    for name in ("gcc", "cc"):
        found = shutil.which(name)
        if found:
            return found
    return None


@dataclass(frozen=True)
class SolverOptions:
    """Solver settings.

    ``solver``: "ipopt" or "fatrop"; ``hessian``: "exact" or "limited-memory" (Ipopt);
    ``jit``: compile the NLP functions (None: when a C compiler is found); ``jit_flags``:
    compiler flags; ``expand``: None = ``not jit``; ``ipopt``/``fatrop``: extra options.
    """

    max_iter: int = 3000
    tol: float = 1e-8
    hessian: str = "exact"
    jit: bool | None = None
    jit_flags: tuple = ("-O1",)
    expand: bool | None = None
    print_level: int = 0
    linear_solver: str = "mumps"
    solver: str = "ipopt"
    ipopt: dict = field(default_factory=dict)
    fatrop: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.solver not in SOLVERS:
            raise ProblemError([f"unknown solver {self.solver!r} (known: {', '.join(SOLVERS)})"])

    @property
    def compiled(self) -> bool:
        """Whether compiled functions are asked for (``jit``, or auto with a compiler)."""
        return bool(self.jit) if self.jit is not None else find_compiler() is not None

    def nlpsol_options(self, compiled: bool | None = None) -> dict:
        compiled = self.compiled if compiled is None else compiled
        expand = (not compiled) if self.expand is None else self.expand
        opts = {"print_time": False, "record_time": True, "expand": bool(expand) and not compiled,
                "error_on_fail": False}
        if self.solver == "fatrop":
            fopts = {"print_level": self.print_level, "max_iter": int(self.max_iter), "tol": float(self.tol)}
            fopts.update(self.fatrop)
            opts["fatrop"] = fopts
            return opts
        opts.update({"ipopt.print_level": self.print_level, "ipopt.sb": "yes",
                     "ipopt.max_iter": int(self.max_iter), "ipopt.tol": float(self.tol),
                     "ipopt.hessian_approximation": self.hessian, "ipopt.linear_solver": self.linear_solver})
        opts.update({f"ipopt.{k}" if not k.startswith("ipopt.") else k: v for k, v in self.ipopt.items()})
        return opts

    def describe(self) -> dict:
        extra = dict(self.ipopt) if self.solver == "ipopt" else dict(self.fatrop)
        return {"solver": self.solver, "max_iter": self.max_iter, "tol": self.tol, "hessian": self.hessian,
                "jit": self.jit, "jit_flags": list(self.jit_flags), "linear_solver": self.linear_solver,
                "expand": self.expand, **extra}


@dataclass(frozen=True)
class InitialGuess:
    """Node states (nz × (N+1)) and controls (nu × N) on the problem grid, optional T."""

    states: np.ndarray
    controls: np.ndarray
    horizon: float | None = None
    label: str = ""


def jit_cache_dir() -> Path:
    from nhgait.dynamics.cache import cache_dir
    return cache_dir() / "jit"


class CompileError(RuntimeError):
    """The C compiler is missing or failed (the solver falls back to interpreted functions)."""


def _no_compiler() -> str:
    cc = os.environ.get("CC")
    return f"no C compiler found ({'$CC = ' + repr(cc) if cc else 'looked for gcc and cc'})"


def _compile(source: str, compiler: str, flags: tuple, folder: Path, key: str) -> Path:
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        c_file = Path(tmp) / f"{key}.c"
        c_file.write_text(source)
        tmp_so = Path(tmp) / f"{key}.so"
        cmd = [compiler, *flags, "-fPIC", "-shared", str(c_file), "-o", str(tmp_so), "-lm"]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise CompileError(f"cannot run the C compiler {compiler!r} ({exc.strerror})") from None
        if proc.returncode != 0:
            raise CompileError(f"compiling failed ({' '.join(cmd)}): {proc.stderr[-500:]}")
        os.chmod(tmp_so, 0o700)
        so = folder / f"{key}.so"
        os.replace(tmp_so, so)  # atomic: a concurrent process sees all or nothing
    return so


def _compile_cached(functions: list, flags: tuple) -> tuple[Path, bool, bool]:
    """C code of ``functions`` compiled to ``jit/<sha256>.so``; returns (path, was_cached,
    private).

    The library is loaded from the cache only when :func:`~nhgait.dynamics.cache.trusted_file`
    accepts it with the SHA-256 recorded when it was written; an untrusted cache directory
    means a private temporary directory (``private`` True: the caller removes it).
    """
    from nhgait.dynamics import cache
    cg = ca.CodeGenerator("nhgait_nlp.c", {"with_header": False})
    for f in functions:
        cg.add(f)
    source = cg.dump()
    compiler = find_compiler()
    if compiler is None:
        raise CompileError(_no_compiler())
    key = hashlib.sha256("\0".join([source, os.path.basename(compiler), *flags, ca.__version__]).encode()).hexdigest()
    folder = cache.trusted_dir(jit_cache_dir())
    private = folder is None
    if private:   # untrusted or unwritable cache: compile privately, do not share
        folder = Path(tempfile.mkdtemp(prefix="nhgait-jit-"))
    so, record = folder / f"{key}.so", folder / f"{key}.so.sha256"
    if so.exists() and record.exists() and cache.trusted_file(so, record.read_text().strip()):
        return so, True, private
    so = _compile(source, compiler, flags, folder, key)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=".sha256")
    with os.fdopen(fd, "w") as fh:
        fh.write(cache.file_sha256(so))
    os.replace(tmp, record)
    return so, False, private


class OCPSolver:
    """A problem transcribed and handed to its solver once; :meth:`solve` may be called many times.

    Attributes
    ----------
    nlp : TranscribedNLP
    setup_time_s : float — transcription + nlpsol construction (+ compile or load)
    compiled : bool — whether the NLP functions are compiled code
    jit_cached : bool or None — whether the compiled functions came from the cache
    jit_fallback : str or None — why compiled functions were asked for but not used
    """

    def __init__(self, problem: OptimalControlProblem, transcription=None, options: SolverOptions | None = None):
        t0 = time.perf_counter()
        self.problem = problem
        self.options = options or SolverOptions()
        if self.options.solver == "fatrop" and transcription in (None, "multiple-shooting"):
            transcription = StageShooting()
        self.transcription = get_transcription(transcription)
        if self.options.solver == "fatrop" and self.nlp_structure_missing():
            raise ProblemError([f"FATROP needs a stage-ordered transcription (multiple-shooting-stages), "
                                f"got {self.transcription.name}"])
        if isinstance(self.transcription, Collocation) and self.options.solver == "ipopt":
            self.options = replace(self.options, ipopt={**COLLOCATION_MUMPS, **self.options.ipopt})
        self.nlp: TranscribedNLP = self.transcription.build(problem)
        self.jit_cached, self.jit_fallback, self.compiled = None, None, False
        if self.options.jit is None and find_compiler() is None:
            self.jit_fallback = _no_compiler()
        elif self.options.jit is not False:
            try:
                self.solver, self.jit_cached, self.jit_path = self._jit_solver()
                self.compiled = True
            except CompileError as exc:
                self.jit_fallback = str(exc)
        if not self.compiled:
            self.solver = self._nlpsol("ocp", {"x": self.nlp.w, "f": self.nlp.f, "g": self.nlp.g},
                                       self.options.nlpsol_options(compiled=False))
        self.setup_time_s = time.perf_counter() - t0

    def nlp_structure_missing(self) -> bool:
        return not isinstance(self.transcription, StageShooting)

    def _nlpsol(self, name, nlp, opts):
        if self.options.solver == "fatrop":
            st = self.nlp.structure
            opts = {**opts, "structure_detection": "manual", "N": st["N"], "nx": st["nx"], "nu": st["nu"],
                    "ng": st["ng"]}
        return ca.nlpsol(name, self.options.solver, nlp, opts)

    def _jit_solver(self):
        """The solver on compiled functions: every function the solver plugin builds from its
        oracle (``nlp_f``, ``nlp_g``, ``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l``, …, read off
        an uncompiled instance) and the oracle ``nlp`` itself are generated into one library;
        the solver is then made from the external oracle, whose ``factory`` loads each
        function from the library by name (Ipopt and FATROP alike)."""
        opts = self.options.nlpsol_options(compiled=True)
        plain = self._nlpsol("ocp_plain", {"x": self.nlp.w, "f": self.nlp.f, "g": self.nlp.g},
                             {**opts, "expand": False})
        x, p = ca.MX.sym("x", self.nlp.w.shape[0]), ca.MX.sym("p", 0)
        oracle = ca.Function("nlp", [x, p], [plain.get_function("nlp_f")(x, p), plain.get_function("nlp_g")(x, p)],
                             ["x", "p"], ["f", "g"])
        functions = [oracle] + [plain.get_function(name) for name in plain.get_function()]
        so, cached, private = _compile_cached(functions, tuple(self.options.jit_flags))
        if private:   # the library stays loaded; its private folder goes with this solver
            weakref.finalize(self, shutil.rmtree, so.parent, True)
        return self._nlpsol("ocp", ca.external("nlp", str(so)), {**opts, "expand": False}), cached, so

    def with_problem(self, problem: OptimalControlProblem) -> "OCPSolver":
        """This solver for ``problem``, a problem of the same structure whose values (targets,
        bounds) differ: the NLP functions are reused, only the bounds are recomputed."""
        nlp = self.transcription.build(problem)
        if nlp.n_w != self.nlp.n_w or nlp.lbg.shape != self.nlp.lbg.shape:
            raise ProblemError(["with_problem: the new problem has another structure"])
        other = object.__new__(OCPSolver)
        other.__dict__.update(self.__dict__)
        other.problem = problem
        other.nlp = replace(self.nlp, problem=problem, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
        return other

    def settings(self) -> dict:
        return {**self.transcription.settings(), **self.options.describe(),
                "jit": self.compiled, "jit_fallback": self.jit_fallback,
                "intervals": self.problem.intervals, "horizon": float(self.problem.horizon),
                "n_variables": self.nlp.n_w, "n_constraints": int(self.nlp.g.shape[0]),
                "jit_cached": self.jit_cached}

    def solve(self, guess: InitialGuess) -> Solution:
        """Run Ipopt from ``guess``; failures are returned as ``success=False``."""
        nlp, problem = self.nlp, self.problem
        states = np.asarray(guess.states, dtype=float)
        controls = np.asarray(guess.controls, dtype=float)
        N = problem.intervals
        problems = []
        if states.shape != (problem.n_states, N + 1):
            problems.append(f"guess states have shape {states.shape}, expected {(problem.n_states, N + 1)}")
        if controls.shape != (problem.n_controls, N):
            problems.append(f"guess controls have shape {controls.shape}, expected {(problem.n_controls, N)}")
        if problems:
            raise ProblemError(problems, title="invalid initial guess")
        w0 = nlp.pack(states, controls, guess.horizon)
        t0 = time.perf_counter()
        try:
            out = self.solver(x0=w0, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
            error = None
        except RuntimeError as exc:  # evaluation errors (NaN in the oracle) and the like
            out, error = None, exc
        wall = time.perf_counter() - t0
        stats = self.solver.stats()
        if out is not None:
            w = np.asarray(out["x"]).ravel()
            objective = float(out["f"])
            g = np.asarray(out["g"]).ravel()
            viol = float(max(np.max(np.maximum(nlp.lbg - g, 0), initial=0.0),
                             np.max(np.maximum(g - nlp.ubg, 0), initial=0.0)))
        else:
            w, objective, viol = w0, float("nan"), float("nan")
        Z, U, T = nlp.unpack(w)
        fn_time = sum(float(v) for k, v in stats.items() if k.startswith("t_wall_nlp_"))
        total = float(stats.get("t_wall_total", wall))
        status = str(stats.get("return_status", "exception" if error else "unknown"))
        if self.options.solver == "fatrop" and error is None:
            ok = bool(stats.get("success", False)) or _fatrop_converged(stats, viol, self.options.tol)
            stats = {**stats, "success": ok}
            status = "Solve_Succeeded" if ok else f"fatrop_return_flag_{status}"
        success = bool(stats.get("success", False)) and error is None
        message = status if error is None else f"{status}: {error}"
        return Solution(success=success, status=status, message=message,
                        iterations=int(stats.get("iter_count", 0)), objective=objective,
                        t=np.linspace(0.0, T, N + 1), states=Z, controls=U,
                        state_names=problem.state_names, control_names=problem.control_names,
                        horizon=T, solve_time_s=wall, setup_time_s=self.setup_time_s,
                        function_time_s=fn_time, solver_time_s=max(total - fn_time, 0.0),
                        stats={k: (v if isinstance(v, (int, float, str, bool)) else str(v))
                               for k, v in stats.items() if not isinstance(v, dict)},
                        settings={**self.settings(), "guess": guess.label}, problem=problem,
                        constraint_violation=viol)


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
