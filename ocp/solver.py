"""Ipopt on a transcribed problem, with optional compiled (jit) NLP functions cached on disk.

* Default: ``nlpsol`` with ``expand=True`` — the MX graph (``F.map(N)``) expanded to SX, the
  fastest interpreted evaluation; exact Hessian.
* ``jit=True``: the NLP is *not* expanded (the MX graph keeps ``F.map(N)`` as a loop over one
  RK4 kernel); its functions ``nlp`` (f, g), ``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l`` are
  generated as one C file, compiled once with gcc to
  ``$NHGAIT_CACHE_DIR/jit/<sha256 of the C source and compiler flags>.so`` and loaded with
  ``casadi.external``; a later solve of the same problem (same model, N, T, transcription)
  finds the shared object and pays no compile. Boundary values live in the bounds, not in the
  compiled functions, so changing a target (distance, angle) does not recompile.

An Ipopt failure (infeasible, iteration limit, …) is returned as ``Solution(success=False)``;
only bad input raises.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from .problem import OptimalControlProblem, ProblemError
from .solution import Solution
from .transcription import TranscribedNLP, get_transcription

__all__ = ["SolverOptions", "OCPSolver", "solve", "InitialGuess", "jit_cache_dir"]


@dataclass(frozen=True)
class SolverOptions:
    """Ipopt settings.

    ``hessian``: "exact" or "limited-memory"; ``jit``: compile the NLP functions (gcc, cached);
    ``jit_flags``: compiler flags; ``expand``: None = ``not jit``; ``ipopt``: extra Ipopt options.
    """

    max_iter: int = 3000
    tol: float = 1e-8
    hessian: str = "exact"
    jit: bool = False
    jit_flags: tuple = ("-O1",)
    expand: bool | None = None
    print_level: int = 0
    linear_solver: str = "mumps"
    ipopt: dict = field(default_factory=dict)

    def nlpsol_options(self) -> dict:
        expand = (not self.jit) if self.expand is None else self.expand
        opts = {"print_time": False, "record_time": True, "expand": bool(expand) and not self.jit,
                "ipopt.print_level": self.print_level, "ipopt.sb": "yes",
                "ipopt.max_iter": int(self.max_iter), "ipopt.tol": float(self.tol),
                "ipopt.hessian_approximation": self.hessian, "ipopt.linear_solver": self.linear_solver,
                "error_on_fail": False}
        opts.update({f"ipopt.{k}" if not k.startswith("ipopt.") else k: v for k, v in self.ipopt.items()})
        return opts

    def describe(self) -> dict:
        return {"solver": "ipopt", "max_iter": self.max_iter, "tol": self.tol, "hessian": self.hessian,
                "jit": self.jit, "jit_flags": list(self.jit_flags), "linear_solver": self.linear_solver,
                "expand": (not self.jit) if self.expand is None else self.expand, **dict(self.ipopt)}


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


_JIT_FUNCTIONS = ("nlp_grad_f", "nlp_jac_g", "nlp_hess_l")


def _compile_cached(functions: list, flags: tuple) -> tuple[Path, bool]:
    """C code of ``functions`` compiled to ``jit/<sha256>.so``; returns (path, was_cached)."""
    cg = ca.CodeGenerator("nhgait_nlp.c", {"with_header": False})
    for f in functions:
        cg.add(f)
    source = cg.dump()
    compiler = os.environ.get("CC", "gcc")
    key = hashlib.sha256("\0".join([source, compiler, *flags, ca.__version__]).encode()).hexdigest()
    directory = jit_cache_dir()
    so = directory / f"{key}.so"
    if so.exists():
        return so, True
    directory.mkdir(parents=True, exist_ok=True)
    if shutil.which(compiler) is None:
        raise ProblemError([f"jit: C compiler {compiler!r} not found (set $CC or use jit=False)"])
    with tempfile.TemporaryDirectory(dir=directory) as tmp:
        c_file = Path(tmp) / f"{key}.c"
        c_file.write_text(source)
        tmp_so = Path(tmp) / f"{key}.so"
        cmd = [compiler, *flags, "-fPIC", "-shared", str(c_file), "-o", str(tmp_so), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"jit compile failed ({' '.join(cmd)}):\n{proc.stderr[-2000:]}")
        shutil.copy(c_file, directory / f"{key}.c")
        os.replace(tmp_so, so)  # atomic: a concurrent process sees all or nothing
    return so, False


class OCPSolver:
    """A problem transcribed and handed to Ipopt once; :meth:`solve` may be called many times.

    Attributes
    ----------
    nlp : TranscribedNLP
    setup_time_s : float — transcription + nlpsol construction (+ jit compile or load)
    jit_cached : bool or None — whether the compiled functions came from the cache
    """

    def __init__(self, problem: OptimalControlProblem, transcription=None, options: SolverOptions | None = None):
        t0 = time.perf_counter()
        self.problem = problem
        self.transcription = get_transcription(transcription)
        self.options = options or SolverOptions()
        self.nlp: TranscribedNLP = self.transcription.build(problem)
        nlp = {"x": self.nlp.w, "f": self.nlp.f, "g": self.nlp.g}
        opts = self.options.nlpsol_options()
        self.jit_cached = None
        if self.options.jit:
            self.solver, self.jit_cached, self.jit_path = self._jit_solver(nlp, opts)
        else:
            self.solver = ca.nlpsol("ocp", "ipopt", nlp, opts)
        self.setup_time_s = time.perf_counter() - t0

    def _jit_solver(self, nlp: dict, opts: dict):
        plain = ca.nlpsol("ocp_plain", "ipopt", nlp, {**opts, "expand": False})
        x, p = ca.MX.sym("x", self.nlp.w.shape[0]), ca.MX.sym("p", 0)
        oracle = ca.Function("nlp", [x, p], [plain.get_function("nlp_f")(x, p), plain.get_function("nlp_g")(x, p)],
                             ["x", "p"], ["f", "g"])
        functions = [oracle] + [plain.get_function(name) for name in _JIT_FUNCTIONS]
        so, cached = _compile_cached(functions, tuple(self.options.jit_flags))
        ext = {f.name(): ca.external(f.name(), str(so)) for f in functions}
        jit_opts = {**opts, "expand": False, "grad_f": ext["nlp_grad_f"], "jac_g": ext["nlp_jac_g"],
                    "hess_lag": ext["nlp_hess_l"], "calc_lam_p": False, "no_nlp_grad": True}
        if self.options.hessian != "exact":
            jit_opts.pop("hess_lag")
        return ca.nlpsol("ocp", "ipopt", ext["nlp"], jit_opts), cached, so

    def settings(self) -> dict:
        return {**self.transcription.settings(), **self.options.describe(),
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


def solve(problem: OptimalControlProblem, guess: InitialGuess, *, transcription=None,
          options: SolverOptions | None = None, **option_kwargs) -> Solution:
    """Transcribe, build and solve in one call (``option_kwargs`` go to :class:`SolverOptions`)."""
    if options is None:
        options = SolverOptions(**option_kwargs)
    elif option_kwargs:
        raise TypeError("give either options or option keywords, not both")
    return OCPSolver(problem, transcription, options).solve(guess)
