"""Which code runs a planner's NLP functions: ready at once now, optimised for the next run.

The NLP functions (the oracle and every function the solver builds from it) are generated as
one C file by :class:`~.solver.OCPSolver`; :func:`choose_code` decides what runs them
(issue 25: no compiler on the critical path of a cold plan)::

    code = choose_code(source, options, progress)
    code.library, code.report.code, code.report.later

1. **The optimised library from the cache** when an earlier run (or its background build)
   made it: gcc (``$NHGAIT_CC``, ``$CC``, gcc, cc) with the flags :class:`CompileBudget` picks
   from the C size (``SolverOptions.jit_flags`` forces them), and ``-fopenmp`` when the source has
   OpenMP pragmas (dropped by a compiler without OpenMP, :mod:`~nhgait.dynamics.numerics.openmp`);
   the stage maps themselves are CasADi's threaded maps (:func:`parallel_maps`), which run the
   intervals on the cores with any compiler, a solver child on its share of them
   (:mod:`~nhgait.dynamics.numerics.thread_maps`: the source gets its thread macros in front).
2. Otherwise **code ready at once**: the fast compiler (:mod:`~nhgait.dynamics.numerics.fast_compiler`,
   the Tiny C Compiler: 0.02–0.25 s for 0.4–7 MB of C, code 1.2–2.6× slower than gcc -O1; its
   stage maps on POSIX threads too),
   cached like any library; without one, the functions run **interpreted** (one line says
   so) — measured slower than the fast compiler's code at every size of the scale benchmark
   (the 6-link snake: 33 s against 8.6 s per solve), so a fast compiler present is always used.
   ``jit=True`` without a fast compiler builds the optimised library now, in the foreground;
   ``jit="optimised"`` always does (benchmarks, and users who want the fastest code at once).
3. **The optimised build for later**, when the optimised library was not in the cache: started
   in the background (:mod:`~nhgait.dynamics.numerics.background`: detached, nice 19, one
   compiler at a time, memory-bounded, finished atomically into the cache) — the plan never
   waits for it; the next run takes step 1.

:class:`CompileReport` (``settings.compile`` of solution.json, the summary's compile line) says
which code solved (``code``: optimised, fast or interpreted; ``compiler``; ``flags``; seconds;
``cached``) and what was built for later (``later``: started with the builder's pid, or why not).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

from nhgait.dynamics.numerics import openmp
from nhgait.dynamics.numerics.background import PENDING, BackgroundBuild, start_build
from nhgait.dynamics.numerics.compiler import (
    SAME_BITS_FLAGS,
    CompilerUnavailable,
    Library,
    Toolchain,
    build_library,
    builds_for_cpu,
    cached_library,
    compiler_command,
    known_compiler,
    library_by_key,
)
from nhgait.dynamics.numerics.fast_compiler import MISSING, fast_compiler
from nhgait.dynamics.numerics.thread_maps import with_grant

__all__ = ["CompileBudget", "COMPILE_BUDGET", "CompileReport", "NlpCode", "choose_code", "CODES",
           "NO_COMPILER", "optimised_ready", "parallel_maps", "external_nlp"]

#: what can run the NLP functions
CODES = ("optimised", "fast", "interpreted")
#: why the functions run interpreted when no compiler at all is found
NO_COMPILER = "no C compiler found (looked for $NHGAIT_CC, $CC, gcc and cc, and a fast compiler)"


class BuildChoice(NamedTuple):
    """What :meth:`CompileBudget.choose` returns."""

    flags: tuple | None   #: compiler flags, None for no optimised build
    seconds: float        #: the estimated compile time
    reason: str           #: why


@dataclass(frozen=True)
class CompileBudget:
    """Generated C size → optimisation level, from ``experiments/bench_scale.py`` on the 2-core
    machine (loaded): gcc -O1 took 34.7 s for 2.56 MB, 63.4 s for 4.07 MB and 250 s for 7.02 MB of
    CasADi's straight-line code (superlinear: register allocation in huge functions; 0.47 GB of
    memory for 2.56 MB, 1.1 GB for 7 MB; -Og no better: 127 s, 1.08 GB); -O0 takes 1.5–5 s per MB
    but its code runs 3–4× slower (the 8-link snake's NLP solved in 4.3 s compiled at -O1, 16.7 s at
    -O0). -O2 (issue 25, measured on a quiet machine, 2026-11-26): 1.4–1.8× the seconds of -O1 and ≤
    1.2× its memory for 0.4–2.9 MB of the scale benchmark's C (the cart with six trailers, 2.90 MB:
    45.7 s and 594 MB against 31.6 s and 577 MB), and solves in 0.78–0.95× the time of -O1's code
    (the two-steering snakeboard 0.78, the 5-link snake 0.90). With ``native`` (when
    :func:`~nhgait.dynamics.numerics.compiler.builds_for_cpu`: a CPU it can read — Linux x86_64 and
    aarch64 — and gcc, clang or cc) -O2 builds for this machine's CPU (``-march=native``, the
    library keyed by that CPU): another 0.87–0.93× (the 3–5-link snakes, the two-steering
    snakeboard, the cart with three trailers). -O2 is kept up to 3 MB, -O1 up to 4.2 MB (gcc's memory
    follows the largest function: the 8-link snake's 4.14 MB, 2.6 MB of it its stage Hessian g_hess,
    took 56–71 s and 0.99 GB on a quiet machine — the same function alone in its own translation unit
    1.03 GB, so splitting the file does not lower it), -O0 up to 20 MB, then there is no optimised
    build. The optimised build runs in the background
    (:func:`choose_code`); its estimate is said beside it. Every level keeps the fast compiler's
    bits (:data:`~nhgait.dynamics.numerics.compiler.SAME_BITS_FLAGS`, for gcc, clang and cc), for
    1.06–1.13× the function time of fused multiply-adds (-O2 -march=native, ``nlp_hess_l`` +
    ``nlp_jac_g``, medians of 21: the cart with six trailers 18.7 → 19.8 ms, the 3-link snake
    3.27 → 3.68 ms)."""

    o1_bytes: float = 4.2e6
    o0_bytes: float = 20e6
    o1_s_per_mb: float = 15.0
    o0_s_per_mb: float = 1.5
    o2_bytes: float = 3e6
    o2_s_per_mb: float = 22.0
    native: bool = True

    def choose(self, c_bytes: int) -> BuildChoice:
        """(flags or None for no optimised build, estimated seconds, reason); a
        :func:`~nhgait.dynamics.numerics.compiler.known_compiler` also gets
        :data:`~nhgait.dynamics.numerics.compiler.SAME_BITS_FLAGS` (the fast compiler's bits)."""
        flags, seconds, reason = self._level(c_bytes)
        if flags is not None and known_compiler():
            flags = (*flags, *SAME_BITS_FLAGS)
        return BuildChoice(flags, seconds, reason)

    def _level(self, c_bytes: int) -> tuple:
        mb = c_bytes / 1e6
        if c_bytes <= min(self.o2_bytes, self.o1_bytes):
            flags = ("-O2", "-march=native") if self.native and builds_for_cpu() else ("-O2",)
            reason = f"{mb:.2f} MB ≤ {self.o2_bytes / 1e6:g} MB: {' '.join(flags)}"
            return flags, mb * self.o2_s_per_mb, reason
        if c_bytes <= self.o1_bytes:
            return ("-O1",), mb * self.o1_s_per_mb, (f"{mb:.2f} MB > {self.o2_bytes / 1e6:g} MB: -O1 "
                                                      f"(-O2 would take about {mb * self.o2_s_per_mb:.0f} s)")
        if c_bytes <= self.o0_bytes:
            return ("-O0",), mb * self.o0_s_per_mb, (f"{mb:.2f} MB > {self.o1_bytes / 1e6:g} MB: -O0 "
                                                      f"(-O1 would take about {mb * self.o1_s_per_mb:.0f} s)")
        return None, 0.0, f"{mb:.1f} MB > {self.o0_bytes / 1e6:g} MB: no optimised build"


COMPILE_BUDGET = CompileBudget()


@dataclass(kw_only=True, frozen=True)
class CompileReport:
    """What runs the NLP functions and why: the C size; ``flags`` of that code (None:
    interpreted); the compiler's seconds (0 when the library came from the cache); the
    optimised build's estimate; ``cached``; the ``reason`` for the optimised flags; the library
    path; ``code`` (one of :data:`CODES`), ``compiler`` (its name) and ``later`` (the
    :class:`~nhgait.dynamics.numerics.background.BackgroundBuild` for the next run, or None)."""

    c_bytes: int
    flags: tuple | None
    compile_s: float
    estimate_s: float
    cached: bool
    reason: str
    path: str | None = None
    code: str = "optimised"
    compiler: str = ""
    later: BackgroundBuild | None = None
    switched_from: str = ""

    def describe(self) -> dict:
        return {"c_bytes": self.c_bytes, "flags": list(self.flags) if self.flags else None,
                "compile_s": round(self.compile_s, 3), "estimate_s": round(self.estimate_s, 1),
                "cached": self.cached, "reason": self.reason, "code": self.code, "compiler": self.compiler,
                "later": self.later.describe() if self.later is not None else None,
                "switched_from": self.switched_from}


@dataclass(frozen=True)
class NlpCode:
    """The outcome of :func:`choose_code`: the ``library`` to solve with (None: interpreted),
    the ``report``, and ``fallback`` — why the functions run interpreted (None otherwise)."""

    library: Library | None
    report: CompileReport
    fallback: str | None = None


def choose_code(source: str, options, progress, *, salt: str, slot: str = "") -> NlpCode:
    """The code that runs the NLP functions of ``source`` now, and the optimised build started
    for later (module docstring); ``options`` a :class:`~.solver.SolverOptions` (``jit``,
    ``jit_flags``, ``budget``); ``salt`` separates the keys (the CasADi version); ``slot`` names
    the robot and task, whose newest build request replaces the older ones (issue 40)."""
    source = with_grant(source)     # threaded stage maps follow the process's grant
    size = len(source)
    flags, estimate, reason = ((tuple(options.jit_flags), 0.0, "flags given") if options.jit_flags
                               else options.budget.choose(size))
    command = compiler_command()
    if flags is not None and "#pragma omp" in source:
        flags = (*flags, openmp.FLAG)        # the stage maps on the cores (dropped where unsupported)
    optimiser = Path(command[0]).name if command else ""
    if flags is not None and command is not None:
        found = cached_library(source, Toolchain(flags=flags), salt=salt)
        if found is not None:
            progress.note(f"  optimised library ({optimiser} {' '.join(flags)}) from the cache")
            return NlpCode(found, CompileReport(c_bytes=size, flags=flags, compile_s=0.0,
                                                estimate_s=estimate, cached=True, reason=reason,
                                                path=str(found.path), code="optimised", compiler=optimiser))
    if options.jit == "optimised" and flags is not None and command is not None:
        lib, kind, compiler, fallback = _optimised_now(source, progress, salt, (flags, estimate, command))
    else:
        lib, kind, compiler, fallback = _ready_now(source, options, progress, salt,
                                                   (flags, estimate, command))
    later = None
    if kind != "optimised":
        later = (start_build(source, Toolchain(flags=flags), salt=salt, slot=slot, estimate_s=estimate)
                 if flags is not None else
                 BackgroundBuild(state="unavailable", flags=(), compiler=optimiser, reason=reason))
        progress.note(f"  {later.text()}")
    report = CompileReport(c_bytes=size, flags=None if lib is None else lib.flags,
                           compile_s=0.0 if lib is None else lib.compile_s, estimate_s=estimate,
                           cached=bool(lib is not None and lib.cached), reason=reason,
                           path=None if lib is None else str(lib.path), code=kind, compiler=compiler,
                           later=later)
    return NlpCode(lib, report, fallback)


def parallel_maps(options) -> bool:
    """Whether to build the NLP's stage maps on threads (CasADi's threaded map,
    :mod:`~nhgait.dynamics.numerics.thread_maps`): when compiled code is asked for (its C starts
    the threads; both the fast compiler and the optimising one build it)."""
    return options.compiled


def external_nlp(path):
    """The NLP oracle of the library at ``path``, this process's OpenMP grant applied (one
    thread unless it is a solver child: a process that forks must not have run a team)."""
    import casadi as ca
    openmp.before_load()
    oracle = ca.external("nlp", str(path))
    openmp.limit(path)
    return oracle


def optimised_ready(report: CompileReport | None) -> CompileReport | None:
    """The report of the optimised library once the background build ``report`` started has
    landed in the cache (found by its key, trusted), else None: a plan adopts it between its
    attempts (:meth:`~.solver.OCPSolver.adopt_optimised`) instead of waiting for the next run.
    ``switched_from`` keeps the code it replaces; ``later`` is then done."""
    later = None if report is None or report.code == "optimised" else report.later
    if later is None or later.state not in PENDING:
        return None
    path = library_by_key(later.key)
    if path is None:
        return None
    return replace(report, flags=later.flags, compile_s=0.0, cached=True, path=str(path), code="optimised",
                   compiler=later.compiler, later=None, switched_from=report.code)


def _ready_now(source, options, progress, salt, optimised) -> tuple:
    """(library or None, code, compiler name, fallback reason): the fast compiler's library,
    else — ``jit=True`` only — the optimised one built now, else interpreted."""
    flags, estimate, command = optimised
    mb = len(source) / 1e6
    fast = fast_compiler()
    failed = None
    if fast is not None:
        try:
            lib = build_library(source, fast.toolchain, salt=salt, progress=progress,
                                label=f"compile {mb:.2f} MB of C with {fast.name}")
        except CompilerUnavailable as exc:
            failed = f"the fast C compiler failed: {exc}"
        else:
            progress.note(f"  NLP functions: {mb:.2f} MB of C, " + ("fast library from the cache"
                                                                    if lib.cached else
                          f"compiled with {fast.name} in {lib.compile_s:.2f} s"))
            return lib, "fast", fast.name, None
        progress.note_once("fast-compiler-failed", f"{failed}; the NLP functions run interpreted")
    else:
        progress.note_once("fast-compiler", MISSING)
    if options.jit is True and flags is not None and command is not None:
        return _optimised_now(source, progress, salt, optimised)
    return None, "interpreted", "", failed or (MISSING if command is not None else NO_COMPILER)


def _optimised_now(source, progress, salt, optimised) -> tuple:
    """(library or None, code, compiler name, fallback reason): the optimised library built now,
    in the foreground (``jit="optimised"``, or ``jit=True`` without a fast compiler)."""
    flags, estimate, command = optimised
    label = f"compile {len(source) / 1e6:.2f} MB of C with {' '.join(flags)}"
    progress.note(f"{label} (about {estimate:.0f} s unless cached) …")
    try:
        lib = build_library(source, Toolchain(flags=flags), salt=salt, progress=progress, label=label)
    except CompilerUnavailable as exc:
        return None, "interpreted", "", str(exc)
    progress.note(f"  compiled in {lib.compile_s:.1f} s (cached for the next run)")
    return lib, "optimised", Path(command[0]).name, None
