"""The stage maps on POSIX threads, for C compiled without OpenMP (the fast compiler).

A planner's NLP functions map the stage Jacobian and Hessian over the N intervals
(``ocp/derivatives.py``); with OpenMP maps CasADi generates each as a loop under
``#pragma omp parallel for``, which gcc's ``-fopenmp`` runs on the cores (:mod:`.openmp`) and
the Tiny C Compiler ignores: a cold plan's code (:mod:`.fast_compiler`) ran its intervals on
one core. :func:`threaded_maps` rewrites each such loop into a function of one point,

    static int casadi_fK_point(arg, res, iw, w, i) { <the loop's body for point i> }
    static int casadi_fK(arg, res, iw, w, mem) { return nhgait_parallel_for(N, casadi_fK_point, …); }

and adds :data:`RUNTIME`, which splits the N points into contiguous blocks, one per thread —
threads started and joined within the call, so none outlives it (a process may fork after it,
which GNU OpenMP's pool forbids). The points write disjoint slices of ``arg``, ``res``, ``iw``
and ``w`` (CasADi gives each its own, as it does for OpenMP), so the results are those of the
serial loop to the last bit. The library's thread count is its exported ``int``
:data:`THREADS_SYMBOL` (1 until set: :func:`.openmp.limit` gives it the process's grant).

Measured (the 2-core machine, the Tiny C Compiler, ``nlp_hess_l`` + ``nlp_jac_g``, median of 7,
a nice-19 busy loop on the other core as a background build): the 8-link snake 244 ms serial,
243 ms on one thread, 129 ms on two; the cart with six trailers 65.7, 65.9 and 35.8 ms.

The rewrite recognises the loop CasADi writes (:data:`MAP`; CasADi 3.8, checked by the tests on
the installed version); for any other shape it returns None and the caller compiles the source
as it is (serial, as before).
"""
from __future__ import annotations

import re

__all__ = ["threaded_maps", "THREADS_SYMBOL", "RUNTIME", "MAP", "MAX_THREADS"]

#: the library's exported thread count (an ``int``; 1 until set)
THREADS_SYMBOL = "nhgait_threads"
#: at most this many threads per map call
MAX_THREADS = 64

#: the parallel loop over one map's points, inserted before the first rewritten map
RUNTIME = r"""
/* nhgait (dynamics/numerics/thread_maps.py): the maps' points on POSIX threads */
#include <pthread.h>
int nhgait_threads = 1;
typedef int (*nhgait_point)(const casadi_real**, casadi_real**, casadi_int*, casadi_real*, casadi_int);
struct nhgait_block { nhgait_point point; const casadi_real** arg; casadi_real** res; casadi_int* iw;
                      casadi_real* w; casadi_int lo, hi; int flag; };
static void* nhgait_run(void* p) {
  struct nhgait_block* b = (struct nhgait_block*) p;
  casadi_int i;
  for (i = b->lo; i < b->hi; ++i) b->flag = b->point(b->arg, b->res, b->iw, b->w, i) || b->flag;
  return 0;
}
static int nhgait_parallel_for(casadi_int n, nhgait_point point, const casadi_real** arg,
                               casadi_real** res, casadi_int* iw, casadi_real* w) {
  struct nhgait_block block[MAX_THREADS];
  pthread_t thread[MAX_THREADS];
  int started[MAX_THREADS], t, flag, T = nhgait_threads;
  if (T > MAX_THREADS) T = MAX_THREADS;
  if (T > n) T = (int) n;
  if (T < 1) T = 1;
  for (t = 0; t < T; ++t) {
    block[t].point = point; block[t].arg = arg; block[t].res = res; block[t].iw = iw; block[t].w = w;
    block[t].lo = n * t / T; block[t].hi = n * (t + 1) / T; block[t].flag = 0;
  }
  for (t = 1; t < T; ++t) started[t] = pthread_create(&thread[t], 0, nhgait_run, &block[t]) == 0;
  nhgait_run(&block[0]);
  flag = block[0].flag;
  for (t = 1; t < T; ++t) {
    if (started[t]) pthread_join(thread[t], 0); else nhgait_run(&block[t]);
    flag = flag || block[t].flag;
  }
  return flag;
}
""".replace("MAX_THREADS", str(MAX_THREADS))

#: one OpenMP map as CasADi generates it: its declarations, its count and its loop's body
MAP = re.compile(
    r"static int (?P<name>casadi_f\d+)\(const casadi_real\*\* arg, casadi_real\*\* res, casadi_int\* iw, "
    r"casadi_real\* w, int mem\) \{\n"
    r"  casadi_int cflag=0, i;\n"
    r"(?P<declarations>(?:  [^\n]*;\n)*?)"
    r"  #pragma omp parallel for private\(i,arg1,res1\) reduction\(\|\|:cflag\)\n"
    r"  for \(i=0; i<(?P<n>\d+); \+\+i\) \{\n"
    r"(?P<body>(?:    [^\n]*\n)+)"
    r"  \}\n"
    r"  if \(cflag\) return 1;\n"
    r"  return 0;\n"
    r"\}\n")


def _point_and_map(m: re.Match) -> str:
    name, signature = m["name"], "const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w"
    return (f"static int {name}_point({signature}, casadi_int i) {{\n"
            f"  casadi_int cflag=0;\n{m['declarations']}{m['body']}  return cflag;\n}}\n"
            f"static int {name}({signature}, int mem) {{\n"
            f"  return nhgait_parallel_for({m['n']}, {name}_point, arg, res, iw, w);\n}}\n")


def threaded_maps(source: str) -> str | None:
    """``source`` with every OpenMP map's loop on POSIX threads (module docstring), or None when
    it has none or one that :data:`MAP` does not recognise (then nothing is rewritten)."""
    maps = list(MAP.finditer(source))
    if not maps or source.count("#pragma omp") != len(maps):
        return None
    first = maps[0].start()
    return source[:first] + RUNTIME + MAP.sub(_point_and_map, source[first:])
