"""The NLP's stage maps on several threads: CasADi's own threaded map (issue 44).

A planner's NLP function time is almost all the stage Jacobian and Hessian mapped over the N
intervals (``ocp/derivatives.py``), N independent calls. :func:`threaded_map` makes that map
with CasADi's ``Function.map(N, "thread", T)``: T blocks of about N/T consecutive points (a
serial map each; when T does not divide N the last block repeats the last point and the extra
results are dropped), whose generated C (CasADi ≥ 3.8: ``ThreadMap::codegen_body``) starts one
POSIX thread per block and joins them all before the call returns — so no thread outlives a
call and a process may fork after it (GNU OpenMP's pool forbids that), and every compiler runs
it, the Tiny C Compiler of a cold plan (:mod:`.fast_compiler`) as well as gcc. Each block
writes its own slices of the work arrays, so the results are those of the serial map to the
last bit. Older CasADi (3.6, 3.7) generates the serial loop for the same map: the same answers
on one core.

T is fixed when the map is made (it is part of the generated C and hence of the library's
key): :func:`map_threads`, the usable cores (``$OMP_NUM_THREADS`` caps them, as it caps
OpenMP, :func:`.openmp.share`), at most N. Attempts running at once each start their T
threads; idle ones block in ``pthread_join`` (no spinning).

Measured with ``experiments/bench_thread_maps.py`` (the numbers are in ``docs/benchmarks.md``).
"""
from __future__ import annotations

from .openmp import share

__all__ = ["threaded_map", "map_threads"]


def map_threads(n: int) -> int:
    """The threads of a map over ``n`` points: the usable cores (:func:`.openmp.share` of one
    worker), at most ``n``, at least 1."""
    return max(1, min(int(n), share(1)))


def threaded_map(function, n: int, threads: int | None = None):
    """``function`` (a CasADi Function) mapped over ``n`` points on ``threads`` threads
    (default :func:`map_threads`) with CasADi's ``map(n, "thread", threads)``; one thread is
    the serial map (no thread started)."""
    threads = map_threads(n) if threads is None else max(1, min(int(threads), int(n)))
    if threads == 1:
        return function.map(n, "serial")
    return function.map(n, "thread", threads)
