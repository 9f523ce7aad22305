"""A compiled adaptive integrator: the closed loop as C, integrated by Dormand–Prince pairs.

:func:`build` turns the CasADi functions of a closed loop (:mod:`.closed_loop`) into one shared
library: CasADi's C code generator writes the right-hand side, the output map and the event
measure; the template ``explicit_rk.c`` (package data) adds an embedded explicit Runge–Kutta integrator
(DOP853, Dormand–Prince 8(5,3) with its 7th-order dense output, or DOPRI5, the 5(4) pair with
Shampine's dense output; tableaus in :mod:`.rk_tableaus`), with step-size control, output on a
grid, a singular-set event located by bisection, stiffness detection and a stop at the first
non-finite value. The whole run is one C call per interval; Python only sets it up.

Compilation and trust
---------------------
The library is built by :func:`.compiler.build_library`, the one compiler path of nhgait
(compiler ``$NHGAIT_CC``, else ``$CC``, else gcc, else cc; flags :data:`CFLAGS`): cached in
``<cache dir>/jit`` under the SHA-256 of the generated C source, the compiler command and the
flags, with a record of the library's SHA-256; a cached library is loaded only if that hash
matches and neither the directory nor the files are writable by group/others, links or owned
by another user (:func:`~.cache.trusted_dir`, :func:`~.cache.trusted_file`) — otherwise it is
refused with a warning and rebuilt. An interrupted build kills the compiler and removes its
build folder. Within a process, loaded libraries are kept by key. Without a working compiler
:func:`build` raises :class:`CompilerUnavailable` (the caller falls back to scipy).
"""
from __future__ import annotations

import ctypes
import shutil
from dataclasses import dataclass
from importlib import resources

import casadi as ca
import numpy as np

from ..memo import LruMemo
from ..numerics.compiler import CompilerUnavailable, Library, Toolchain, build_library, library_key
from .rk_tableaus import tableau

__all__ = ["CompiledLoop", "CompilerUnavailable", "build", "CFLAGS", "DIAGNOSTIC_OUTPUTS",
           "METHODS", "OutputBuffers", "RunState", "STATUS"]

#: compiler flags (:func:`.compiler.build_library` adds ``-fPIC -shared``; no -march=native: a
#: cached library must run on any machine sharing the cache)
CFLAGS = ("-O2", "-std=c99")
#: the key's salt: these libraries apart from other C nhgait compiles
_SALT = "compiled closed loop"
#: seconds after which the compiler is stopped (the route then falls back to scipy)
_COMPILE_TIMEOUT_S = 300.0
#: the blocks of the closed loop's outputs (``ClosedLoop.outputs``) that only a run's diagnostics
#: read: compiled into their own C function, evaluated when a diagnostic is first read
DIAGNOSTIC_OUTPUTS = ("measure", "metric", "gram")
#: method name → index in the C template
METHODS = {"DOP853": 0, "DOPRI5": 1}
#: return codes of ``nhg_run``
STATUS = {0: "done", 1: "paused", -1: "step size too small", -2: "max_steps reached",
          -3: "non-finite right-hand side", -4: "non-finite stages", -5: "event", -6: "stiff"}
_ABI = 2
_NCTL, _NCNT = 12, 9
_C = dict(t=0, h=1, rtol=2, atol=3, hmax=4, evtol=5, err_old=6, t_stiff=7, t_fail=8, g_last=9,
          stop_stiff=10, h_lambda=11)
_N = dict(nfev=0, accepted=1, rejected=2, max_steps=3, i_eval=4, n_out=5, stiff=6, nonstiff=7,
          bad=8)

#: library key → loaded ctypes library, for the life of the process (a loaded library is never
#: unloaded; the memo only spares the cache lookup and the ctypes declarations)
LOADED_LIBRARIES = LruMemo("compiled closed loops loaded in this process, by library key", size=1024)


# --------------------------------------------------------------------------------------------
# C source
# --------------------------------------------------------------------------------------------
def _c_array(name: str, values) -> str:
    flat = np.asarray(values, dtype=float).ravel()
    body = ", ".join(float(v).hex() for v in flat) or "0"
    return f"static const double {name}[{max(flat.size, 1)}] = {{{body}}};\n"


def _tableau_source() -> str:
    parts = []
    for name in METHODS:
        tab = tableau(name)
        parts.append(f"#define {name}_DEGREE {tab.dense.shape[1]}\n")
        parts.append(_c_array(f"{name}_C", tab.c))
        parts.append(_c_array(f"{name}_A", tab.a))
        parts.append(_c_array(f"{name}_B", tab.b))
        parts.append(_c_array(f"{name}_E", tab.e))
        if tab.e3 is not None:
            parts.append(_c_array(f"{name}_E3", tab.e3))
        parts.append(_c_array(f"{name}_DENSE", tab.dense))
    return "".join(parts)


def _renamed(function: ca.Function, name: str) -> ca.Function:
    args = function.mx_in() if function.is_a("MXFunction") else function.sx_in()
    return ca.Function(name, args, function.call(args), function.name_in(), function.name_out())


def _shared(expr):
    """``expr`` with equal subexpressions evaluated once (SX; an MX expression as it is)."""
    return ca.cse(expr) if isinstance(expr, ca.SX) else expr


def c_source(rhs: ca.Function, outputs: ca.Function, event: ca.Function | None,
             project: ca.Function | None = None) -> str:
    """The complete C translation unit for one closed loop (with ``project``: projection of
    every accepted step onto the constraints)."""
    args = outputs.mx_in() if outputs.is_a("MXFunction") else outputs.sx_in()
    blocks = outputs.call(args)
    main = [ca.vec(o) for o, name in zip(blocks, outputs.name_out(), strict=True)
            if name not in DIAGNOSTIC_OUTPUTS]
    diag = [ca.vec(o) for o, name in zip(blocks, outputs.name_out(), strict=True)
            if name in DIAGNOSTIC_OUTPUTS]
    out = ca.Function("nhg_out", args, [_shared(ca.vertcat(*main))])
    functions = [_renamed(rhs, "nhg_rhs"), out, ca.Function("nhg_diag", args, [_shared(ca.vertcat(*diag))])]
    if event is not None:
        functions.append(_renamed(event, "nhg_event"))
    if project is not None:
        functions.append(_renamed(project, "nhg_project"))
    gen = ca.CodeGenerator("nhgait_loop.c", {"with_header": False, "casadi_real": "double",
                                             "casadi_int": "long long int"})
    for f in functions:
        gen.add(f)
    sizes = [max(f.sz_arg() for f in functions), max(f.sz_res() for f in functions),
             max(f.sz_iw() for f in functions), max(f.sz_w() for f in functions)]
    ny = rhs.nnz_in(2)
    header = (f"/* generated by nhgait.dynamics.simulation.compiled (ABI {_ABI}) */\n"
              f"#define NHG_NY {ny}\n#define NHG_NP {rhs.nnz_in(rhs.n_in() - 1)}\n"
              f"#define NHG_NOUT {out.nnz_out(0)}\n#define NHG_NDIAG {functions[2].nnz_out(0)}\n#define "
              f"NHG_HAS_EVENT {int(event is not None)}\n"
              f"#define NHG_HAS_PROJECT {int(project is not None)}\n"
              f"#define NHG_SZ_ARG {sizes[0]}\n#define NHG_SZ_RES {sizes[1]}\n"
              f"#define NHG_SZ_IW {sizes[2]}\n#define NHG_SZ_W {sizes[3]}\n")
    template = resources.files("nhgait.dynamics.simulation").joinpath("explicit_rk.c").read_text()
    return header + gen.dump() + "\n" + _tableau_source() + "\n" + template


# --------------------------------------------------------------------------------------------
# building and loading (nhgait.dynamics.numerics.compiler)
# --------------------------------------------------------------------------------------------
def build(rhs: ca.Function, outputs: ca.Function, event: ca.Function | None = None,
          project: ca.Function | None = None) -> CompiledLoop:
    """Compile (or load from the cache) the closed loop ``rhs(t, t_c, y, p)``,
    ``outputs(t, t_c, y, p)``, ``event(y, ydot, p) → (s, ṡ)`` and ``project(y, params)``
    (optional). Raises :class:`CompilerUnavailable`.

    The library lives in ``<cache dir>/jit``; if that directory is refused by the trust rules,
    it is compiled into a private temporary directory instead, removed once it is loaded."""
    source = c_source(rhs, outputs, event, project)
    key = library_key(source, flags=CFLAGS, salt=_SALT)
    compile_time = 0.0

    def build_and_load():
        nonlocal compile_time
        built = build_library(source, Toolchain(flags=CFLAGS), salt=_SALT, label="compiling the closed loop",
                              timeout=_COMPILE_TIMEOUT_S)
        compile_time = built.compile_s
        return _load(built)
    lib = LOADED_LIBRARIES.get(key, build_and_load)
    dims = [lib.nhg_dims(i) for i in range(5)]
    sizes = {name: outputs.nnz_out(i) for i, name in enumerate(outputs.name_out())}
    return CompiledLoop(key=key, library=lib, ny=dims[0], np=dims[1], nout=dims[2],
                        has_event=bool(dims[3]), compile_time_s=compile_time,
                        out_sizes=tuple(v for k, v in sizes.items() if k not in DIAGNOSTIC_OUTPUTS),
                        n_diag=dims[4], diag_sizes=tuple(sizes[k] for k in DIAGNOSTIC_OUTPUTS))


def _load(built: Library):
    """The library loaded with ctypes, its functions declared and its ABI checked; a private
    build folder is removed once the library is loaded (its mapping stays valid)."""
    try:
        lib = ctypes.CDLL(str(built.path))
    except OSError as exc:
        raise CompilerUnavailable(f"cannot load the compiled library {built.path} ({exc})") from exc
    finally:
        if built.private:
            shutil.rmtree(built.path.parent, ignore_errors=True)
    _declare(lib)
    if lib.nhg_abi_version() != _ABI:
        raise CompilerUnavailable("compiled library has a different ABI version")
    return lib


def _declare(lib) -> None:
    vp, ll, dbl = ctypes.c_void_p, ctypes.c_longlong, ctypes.c_double
    lib.nhg_run.argtypes = [ctypes.c_int, dbl, dbl, vp, vp, vp, vp, vp, ll, vp, vp, vp, ll]
    lib.nhg_run.restype = ctypes.c_int
    lib.nhg_outputs.argtypes = [ll, vp, vp, vp, vp, vp, vp]
    lib.nhg_outputs.restype = None
    lib.nhg_diagnostics.argtypes = [ll, vp, vp, vp, vp, vp, vp]
    lib.nhg_diagnostics.restype = None
    lib.nhg_eval_rhs.argtypes = [dbl, dbl, vp, vp, vp, ll]
    lib.nhg_eval_rhs.restype = None
    lib.nhg_dims.argtypes = [ctypes.c_int]
    lib.nhg_abi_version.restype = ctypes.c_int


# --------------------------------------------------------------------------------------------
# running
# --------------------------------------------------------------------------------------------
@dataclass
class RunState:
    """What carries over between calls of the C integrator: time, next step, counters."""

    ctl: np.ndarray
    cnt: np.ndarray

    @classmethod
    def start(cls, t0, tolerances, step_limits, event_tol, stop_on_stiff=False) -> RunState:
        """From ``t0`` with ``tolerances`` = (rtol, atol), ``step_limits`` = (largest step,
        max_steps), the event threshold (0: none) and whether stiffness stops the run."""
        (rtol, atol), (h_max, max_steps) = tolerances, step_limits
        ctl = np.zeros(_NCTL)
        for name, value in (("t", t0), ("rtol", rtol), ("atol", atol), ("hmax", h_max), ("evtol", event_tol),
                            ("err_old", 1e-4), ("t_stiff", np.nan), ("stop_stiff", float(stop_on_stiff))):
            ctl[_C[name]] = value
        cnt = np.zeros(_NCNT, dtype=np.longlong)
        cnt[_N["max_steps"]] = max_steps
        return cls(ctl=ctl, cnt=cnt)

    def __getitem__(self, name):
        return self.ctl[_C[name]] if name in _C else int(self.cnt[_N[name]])

    def values(self) -> dict:
        """Every entry by name, as Python numbers (floats and ints)."""
        ctl, cnt = self.ctl.tolist(), self.cnt.tolist()
        return {**{name: ctl[i] for name, i in _C.items()}, **{name: cnt[i] for name, i in _N.items()}}

    def set(self, name, value):
        if name in _C:
            self.ctl[_C[name]] = value
        else:
            self.cnt[_N[name]] = value


@dataclass(frozen=True, eq=False)
class OutputBuffers:
    """Where ``nhg_run`` writes its outputs: on the grid ``t_eval`` into the rows of ``y_eval``
    (``RunState["i_eval"]`` is the next grid index), or — without a grid — every accepted step
    into ``t_steps``/``y_steps`` (``RunState["n_out"]`` rows; the call pauses when they are
    full and :meth:`grown` gives room for twice as many). The arrays are written in place."""

    t_eval: np.ndarray | None = None
    y_eval: np.ndarray | None = None
    t_steps: np.ndarray | None = None
    y_steps: np.ndarray | None = None

    @classmethod
    def for_grid(cls, t_eval: np.ndarray, ny: int) -> OutputBuffers:
        return cls(t_eval=t_eval, y_eval=np.empty((t_eval.size, ny)))      # rows written before read

    @classmethod
    def for_steps(cls, ny: int, rows: int = 4097) -> OutputBuffers:
        return cls(t_steps=np.empty(rows), y_steps=np.empty((rows, ny)))    # rows written before read

    def grown(self) -> OutputBuffers:
        """Empty step buffers with room for about twice as many rows."""
        return OutputBuffers.for_steps(self.y_steps.shape[1], 2 * self.t_steps.size - 1)

    def fresh(self) -> OutputBuffers:
        """Empty step buffers of the same size."""
        return OutputBuffers.for_steps(self.y_steps.shape[1], self.t_steps.size)


def _ptr(a):
    return None if a is None else a.ctypes.data


@dataclass(frozen=True, eq=False)
class CompiledLoop:
    """A loaded library of one closed loop. ``out_sizes``: sizes of the output blocks of
    :meth:`outputs` (the blocks of ``ClosedLoop.outputs`` but the diagnostic ones);
    ``diag_sizes``: sizes of the blocks of :meth:`diagnostic_outputs`
    (:data:`DIAGNOSTIC_OUTPUTS`), ``n_diag`` their total."""

    key: str
    library: object
    ny: int
    np: int
    nout: int
    has_event: bool
    compile_time_s: float
    out_sizes: tuple
    n_diag: int = 0
    diag_sizes: tuple = ()

    def run(self, method: str, state: RunState, span: tuple, y: np.ndarray, p: np.ndarray,
            buffers: OutputBuffers | None = None) -> int:
        """One call of the C integrator from ``state['t']`` towards ``span`` = (t_end, t_hi):
        the end of the call and the last time of its segment (the controller's and the forces'
        clamp); ``y`` is updated in place, outputs go to ``buffers`` (None: only the final
        state). Returns the C status (see :data:`STATUS`)."""
        t_end, t_hi = span
        out = buffers or OutputBuffers()
        cap = 0 if out.t_steps is None else out.t_steps.size - 1
        n_eval = 0 if out.t_eval is None else out.t_eval.size
        return self.library.nhg_run(METHODS[method], float(t_end), float(t_hi), _ptr(y), _ptr(p),
                                    _ptr(state.ctl), _ptr(state.cnt), _ptr(out.t_eval), n_eval,
                                    _ptr(out.y_eval), _ptr(out.t_steps), _ptr(out.y_steps), cap)

    def outputs(self, t, t_c, Y, P, seg=None) -> list:
        """The output blocks at N points (each (N, size)); t, t_c (N,), Y (N, ny); P (N, np) the
        parameter vector at each point, or with ``seg`` (N,) the rows of P each point takes (the
        points' segment indices, non-decreasing)."""
        return self.blocks(self.output_table(t, t_c, Y, P, seg))

    def output_table(self, t, t_c, Y, P, seg=None) -> np.ndarray:
        """The outputs at N points as one (N, nout) table, the blocks side by side (:meth:`blocks`)."""
        return self._evaluate(self.library.nhg_outputs, (t, t_c, Y, P, seg), self.nout)

    def blocks(self, table: np.ndarray, sizes: tuple | None = None) -> list:
        """The column blocks of ``table`` (views) of ``sizes`` (default: :attr:`out_sizes`)."""
        blocks, start = [], 0
        for size in self.out_sizes if sizes is None else sizes:
            blocks.append(table[:, start:start + size])
            start += size
        return blocks

    def diagnostic_outputs(self, t, t_c, Y, P, seg=None) -> list:
        """The blocks :data:`DIAGNOSTIC_OUTPUTS` at N points (arguments as
        :meth:`outputs`): only what the diagnostics read, evaluated when they are read."""
        table = self._evaluate(self.library.nhg_diagnostics, (t, t_c, Y, P, seg), self.n_diag)
        return self.blocks(table, self.diag_sizes)

    def _evaluate(self, c_function, points: tuple, width: int) -> np.ndarray:
        t, t_c, Y, P, seg = points
        N = len(t)
        out = np.empty((N, width))          # the C function writes every entry
        T, TC = np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(t_c, dtype=float)
        Y = np.ascontiguousarray(Y, dtype=float).reshape(N, self.ny)
        P = np.ascontiguousarray(P, dtype=float).reshape(-1, self.np)
        seg = np.arange(N, dtype=np.longlong) if seg is None else np.ascontiguousarray(seg, dtype=np.longlong)
        if seg.shape != (N,) or (N and not 0 <= seg[0] <= seg[-1] < len(P)):     # seg is non-decreasing
            raise ValueError(f"seg must hold N = {N} non-decreasing row indices of P ({len(P)} rows)")
        if N:
            c_function(N, T.ctypes.data, TC.ctypes.data, Y.ctypes.data, seg.ctypes.data, P.ctypes.data,
                       out.ctypes.data)
        return out

    def rhs(self, t, t_hi, y, p, repeat: int = 1) -> np.ndarray:
        """ẏ at one point (evaluated ``repeat`` times, for timing)."""
        y = np.ascontiguousarray(y, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        dy = np.zeros(self.ny)
        self.library.nhg_eval_rhs(float(t), float(t_hi), _ptr(y), _ptr(p), _ptr(dy), int(repeat))
        return dy
