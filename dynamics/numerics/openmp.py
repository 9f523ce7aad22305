"""The threads a process may use for the NLP's stage maps (its grant), and OpenMP's maps.

An iteration's function time is almost all the stage Jacobian and Hessian mapped over the N
intervals (``ocp/derivatives.py``), N independent calls. The planner makes those maps CasADi's
threaded maps (:mod:`.thread_maps`: any compiler runs them on several threads, their library's
count :data:`THREADS_SYMBOL` set by :func:`limit`). This module holds the grant they follow and
CasADi's other parallel map, ``"openmp"`` (:func:`parallel_map`): a loop under ``#pragma omp
parallel for`` (each call with its own work arrays), compiled with :data:`FLAG` the calls share
the cores, and without it (a compiler without OpenMP: the build retries without the flag,
:mod:`.compiler`) the pragma is ignored and the loop is the serial map's. No compiler runs to
find out beforehand: that would put one on a cold plan's critical path. Measured on the 2-core
machine (the cart with six trailers, gcc -O2 -march=native, best of 7 calls, OpenMP maps):
``nlp_hess_l`` 10.6 → 5.4 ms and ``nlp_jac_g`` 2.8 → 2.1 ms on two threads, the same numbers to
the last bit; on one thread the OpenMP source is 3–4 % slower than the serial one (the per-call
work arrays).

**Fork safety.** GNU OpenMP does not survive ``fork``: a child forked after its parent ran a
parallel region on several threads hangs in its own first region (measured: every time). So a
process runs the NLP functions on **one** thread unless it was **granted** more, and only the
supervised solver children are (:mod:`nhgait.ocp.supervision`: they fork nothing): :func:`limit`
after loading a library applies the process's grant (1 by default), :func:`grant` in a child sets
it to its share of the cores (:func:`share`: the cores over the attempts running at once;
``$OMP_NUM_THREADS`` caps it).

**Idle threads sleep** (``$OMP_WAIT_POLICY`` = :data:`WAIT_POLICY` unless set, :func:`before_load`):
each attempt is a fresh child whose first solve pays for its threads, and spinning ones made a
short solve slower on two threads than on one.

The CasADi wheel is built without OpenMP, so making an ``"openmp"`` map prints a warning that it
will evaluate serially (true of the interpreted map, not of its generated C):
:func:`parallel_map` makes the map without it.
"""
from __future__ import annotations

import contextlib
import ctypes
import io
import os
import sys

__all__ = ["FLAG", "parallel_map", "share", "grant", "limit", "threads", "before_load", "WAIT_POLICY",
           "THREADS_SYMBOL"]

#: the compiler flag (compile and link) of OpenMP's pragmas and runtime
FLAG = "-fopenmp"
#: the runtimes a library built with FLAG loads (GNU, LLVM, Intel)
RUNTIMES = ("libgomp.so.1", "libomp.so", "libomp.so.5", "libiomp5.so", "libomp.dylib", "libgomp.1.dylib")
#: the runtime's wait policy unless the user set one: idle threads sleep at once instead of
#: spinning. Measured (a forked child's solves, as the planner's attempts, medians of 2 children):
#: the cart with two trailers' first solve in a child 24 ms passive against 31–43 ms spinning (one
#: thread: 31 ms), the cart with six trailers' 93–97 against 118–121 ms (one thread: 144 ms); later
#: solves in the same child 20 against 18 ms and 85 against 81 ms
WAIT_POLICY = "PASSIVE"
#: CasADi's warning for an "openmp" map (this wheel has no OpenMP: its own evaluation is serial)
_WARNING = "was not compiled with WITH_OPENMP"

#: the exported ``int`` of a library whose stage maps are CasADi's threaded maps (:mod:`.thread_maps`):
#: its blocks run on threads when it is above 1, else in the calling thread (:func:`limit` sets it)
THREADS_SYMBOL = "nhgait_threads"

_granted = 1      # threads this process may use (grant); 1 unless it is a supervised child
_threaded: set = set()   # paths of the loaded libraries with THREADS_SYMBOL (limit)


def parallel_map(function, n: int):
    """``function.map(n, "openmp")`` without CasADi's warning that its own evaluation is serial
    (module docstring); any other message it prints is passed on."""
    caught = io.StringIO()
    with contextlib.redirect_stderr(caught), contextlib.redirect_stdout(caught):
        mapped = function.map(n, "openmp")
    rest = "".join(line for line in caught.getvalue().splitlines(True) if _WARNING not in line)
    if rest:
        sys.stderr.write(rest)
    return mapped


def before_load() -> None:
    """Set ``$OMP_WAIT_POLICY`` to :data:`WAIT_POLICY` unless it is set (the runtime reads it
    when it is first loaded: call before loading a library built with :data:`FLAG`)."""
    os.environ.setdefault("OMP_WAIT_POLICY", WAIT_POLICY)


def share(workers: int) -> int:
    """Threads for each of ``workers`` attempts running at once: the usable cores over them (at
    least 1), at most ``$OMP_NUM_THREADS`` when set."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    n = max(1, cores // max(1, int(workers)))
    cap = os.environ.get("OMP_NUM_THREADS", "").split(",")[0].strip()
    return min(n, int(cap)) if cap.isdigit() and int(cap) > 0 else n


def grant(n: int) -> None:
    """Let this process — a supervised child, which forks nothing — run on ``n`` threads."""
    global _granted
    _granted = max(1, int(n))
    limit()


def threads() -> int:
    """The threads this process's parallel regions use (its grant)."""
    return _granted


def limit(library=None) -> None:
    """Apply this process's grant to every OpenMP runtime loaded in it and to every loaded
    library with threaded maps (:data:`THREADS_SYMBOL`, :mod:`.thread_maps`; ``library``: the
    path of one just loaded, remembered if it is one): one thread unless :func:`grant` said
    more. Call after loading a library."""
    loaded = getattr(os, "RTLD_NOLOAD", 0)
    for name in RUNTIMES:
        try:
            runtime = ctypes.CDLL(name, mode=loaded | ctypes.RTLD_GLOBAL)
        except OSError:
            continue                  # not loaded here
        runtime.omp_set_num_threads(ctypes.c_int(_granted))
    if library is not None:
        _threaded.add(str(library))
    for path in sorted(_threaded):
        try:
            count = ctypes.c_int.in_dll(ctypes.CDLL(path, mode=loaded), THREADS_SYMBOL)
        except (OSError, ValueError):     # unloaded since, or without threaded maps
            _threaded.discard(path)
            continue
        count.value = _granted
