"""A CasADi Function called from numpy at the cost of its arithmetic: :class:`BufferedCall`.

An integrator written in Python (scipy's ``solve_ivp``) calls the right-hand side ż = f(t, z, u)
thousands of times per verification, each through ``Function.__call__``: the arguments are
converted to ``DM``, checked and converted back — about 40–70 µs a call, for an expression
that takes a microsecond. CasADi's buffer interface (``Function.buffer()``) binds the inputs
and the output to numpy arrays once; a call then copies the arguments into them and runs the
same evaluation (the same virtual machine on the same expression graph, so the same numbers,
bit for bit) in about 1.5 µs.

    fast = BufferedCall(ode)            # ode: Function (t, z, u) → ż, dense
    zdot = fast(t, z, u)                # a new numpy array of ż (1-D)

A Function whose inputs or first output are not dense is called the ordinary way (the
buffer holds nonzeros only). Not thread-safe: one object per thread (a forked child has its own
copy).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["BufferedCall"]


class BufferedCall:
    """``f(*args)`` → a 1-D numpy array of f's first output, through CasADi's buffer interface
    (module docstring); an evaluation error raises RuntimeError as ``Function.__call__`` does."""

    def __init__(self, f: ca.Function):
        self.function = f
        dense = (all(f.sparsity_in(i).is_dense() for i in range(f.n_in()))
                 and f.sparsity_out(0).is_dense())
        self._inputs = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self._output = np.zeros(f.nnz_out(0))
        self._buffer = self._run = None
        if dense:
            self._buffer, self._run = f.buffer()
            for i, array in enumerate(self._inputs):
                self._buffer.set_arg(i, memoryview(array))
            self._buffer.set_res(0, memoryview(self._output))

    def __call__(self, *args) -> np.ndarray:
        if self._buffer is None:
            out = self.function(*args)
            return np.asarray(out[0] if isinstance(out, (tuple, list)) else out, float).ravel()
        if len(args) != len(self._inputs):
            raise TypeError(f"{self.function.name()} takes {len(self._inputs)} arguments, got {len(args)}")
        for array, value in zip(self._inputs, args, strict=True):   # lengths checked above
            if getattr(value, "ndim", 0) > 1:
                value = np.ravel(value, order="F")    # CasADi stores a matrix column-major
            array[:] = value                          # a scalar, or the n values of a vector
        self._run()
        if self._buffer.ret() != 0:
            raise RuntimeError(f"evaluation of {self.function.name()} failed")
        return self._output.copy()
