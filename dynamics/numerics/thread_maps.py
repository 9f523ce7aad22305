"""The NLP's stage maps on several threads: CasADi's own threaded map (issue 44).

A planner's NLP function time is almost all the stage Jacobian and Hessian mapped over the N
intervals (``ocp/derivatives.py``), N independent calls. :func:`threaded_map` makes that map
with CasADi's ``Function.map(N, "thread", T)``: T blocks of about N/T consecutive points (a
serial map each; when T does not divide N the last block repeats the last point and the extra
results are dropped), whose generated C (CasADi ≥ 3.8: ``ThreadMap::codegen_body``) starts one
POSIX thread per block through CasADi's macros ``CASADI_THREAD_CREATE`` / ``CASADI_THREAD_JOIN``
and joins them all before the call returns — so no thread outlives a call and a process may
fork after it (GNU OpenMP's pool forbids that), and every compiler runs it: the Tiny C Compiler
of a cold plan (:mod:`.fast_compiler`) as well as gcc. Each block writes its own slices of the
work arrays, so the results are those of the serial map to the last bit. CasADi 3.6–3.7
generate the serial loop for the same map: the same answers on one core.

**The grant.** CasADi's generated C defines those macros only where they are not defined
already (``#ifndef CASADI_THREAD_CREATE``: its documented way to choose the threads). The NLP's
source gets :data:`PRELUDE` in front (:func:`with_grant`: text added, none of CasADi's
rewritten): a block runs on its own thread only while the library's exported ``int``
:data:`~.openmp.THREADS_SYMBOL` is above 1, else in the calling thread — and also when a thread
cannot be started, where CasADi's own macros would join a thread that does not exist.
:func:`.openmp.limit` sets that count to the process's grant, as it sets OpenMP's: one thread
unless the process is a supervised solver child (:func:`.openmp.grant`: its share of the
cores), so attempts running at once do not share cores they were not given.

T is fixed when the map is made (it is part of the generated C, hence of the library's key):
:func:`map_threads`, the usable cores (``$OMP_NUM_THREADS`` caps them, as it caps OpenMP,
:func:`.openmp.share`), at most N.

Measured with ``experiments/bench_thread_maps.py`` (docs/benchmarks.md).
"""
from __future__ import annotations

import contextlib
import io
import sys

from .openmp import THREADS_SYMBOL, share

__all__ = ["threaded_map", "map_threads", "with_grant", "PRELUDE", "CREATE"]

#: the macro CasADi's threaded maps start their threads with (its generated C calls it)
CREATE = "CASADI_THREAD_CREATE("
#: CasADi's warning for a "thread" map from a build without threads (true of its own
#: evaluation, which is then serial, not of the generated C)
_WARNING = "was not compiled with WITH_THREAD"

#: CasADi's thread macros for the stage maps under the process's grant (module docstring)
PRELUDE = r"""/* nhgait (dynamics/numerics/thread_maps.py): CasADi's threaded maps under a thread grant */
int NHGAIT_THREADS = 1;
#if !defined(_WIN32) && !defined(CASADI_THREAD_CREATE)
#include <pthread.h>
typedef struct { pthread_t id; int started; } nhgait_thread;
#define CASADI_THREAD_HANDLE nhgait_thread
#define CASADI_THREAD_CREATE(t, f, a) \
  (((t).started = NHGAIT_THREADS > 1 && pthread_create(&(t).id, 0, f, a) == 0) ? 0 : ((void) f(a), 0))
#define CASADI_THREAD_JOIN(t) ((t).started ? pthread_join((t).id, 0) : 0)
#endif
""".replace("NHGAIT_THREADS", THREADS_SYMBOL)


def map_threads(n: int) -> int:
    """The threads of a map over ``n`` points: the usable cores (:func:`.openmp.share` of one
    worker), at most ``n``, at least 1."""
    return max(1, min(int(n), share(1)))


def threaded_map(function, n: int, threads: int | None = None):
    """``function`` (a CasADi Function) mapped over ``n`` points on ``threads`` threads
    (default :func:`map_threads`) with CasADi's ``map(n, "thread", threads)``; one thread is
    the serial map (no thread started). A CasADi built without threads warns that its own
    evaluation of the map is serial: that line is dropped (the generated C still threads),
    any other message passed on."""
    threads = map_threads(n) if threads is None else max(1, min(int(threads), int(n)))
    if threads == 1:
        return function.map(n, "serial")
    caught = io.StringIO()
    with contextlib.redirect_stderr(caught), contextlib.redirect_stdout(caught):
        mapped = function.map(n, "thread", threads)
    rest = "".join(line for line in caught.getvalue().splitlines(True) if _WARNING not in line)
    if rest:
        sys.stderr.write(rest)
    return mapped


def with_grant(source: str) -> str:
    """``source`` (generated C) with :data:`PRELUDE` in front when it starts threads (its
    threaded maps then follow the process's grant), else as it is."""
    return PRELUDE + source if CREATE in source else source
