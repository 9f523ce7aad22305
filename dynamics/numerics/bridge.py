"""The one bridge from sympy to numbers: sympy expressions → CasADi SX graphs.

Every sympy expression that becomes a CasADi graph goes through :func:`to_casadi`. Common
subexpressions are shared through ``sympy.cse`` so the SX graph stays small.
"""
from __future__ import annotations

import casadi as ca
import sympy as sp

from ..errors import ModelError

_UNARY = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan, sp.asin: ca.asin, sp.acos: ca.acos,
    sp.atan: ca.atan, sp.sinh: ca.sinh, sp.cosh: ca.cosh, sp.tanh: ca.tanh, sp.exp: ca.exp,
    sp.log: ca.log, sp.Abs: ca.fabs, sp.sign: ca.sign,
    sp.sec: lambda x: 1 / ca.cos(x), sp.csc: lambda x: 1 / ca.sin(x),
    sp.cot: lambda x: 1 / ca.tan(x),
    sp.Heaviside: lambda x: ca.if_else(x > 0, 1, ca.if_else(x < 0, 0, 0.5)),   # sympy: H(0) = 1/2
}


class BridgeError(ModelError):
    """An expression uses a function the CasADi bridge does not know."""

    def __init__(self, problems):
        super().__init__(problems, title="cannot evaluate the equations numerically")


def to_casadi(exprs, symbols, sx_args):
    """Convert a list of sympy expressions to CasADi SX.

    Parameters
    ----------
    exprs : list of sympy expressions
    symbols : list of sympy Symbols, the inputs
    sx_args : list of SX scalars, the same length as ``symbols``

    Returns
    -------
    list of SX
    """
    reps, reduced = sp.cse(list(exprs), optimizations=None, order="none")
    convert = _Converter({s: x for s, x in zip(symbols, sx_args, strict=True)})
    for sym, sub in reps:
        convert.table[sym] = convert(sub)
    return [convert(e) for e in reduced]


class _Converter:
    """sympy → SX for one :func:`to_casadi` call: ``table`` maps the arguments (and the cse
    symbols, as they are converted) to SX; each converted subexpression is kept once."""

    def __init__(self, table: dict):
        self.table = table
        self.memo: dict = {}

    def __call__(self, e):
        if e in self.table:
            return self.table[e]
        got = self.memo.get(e)
        if got is not None:
            return got
        out = self._convert(e)
        self.memo[e] = out
        return out

    def _convert(self, e):
        if e.is_Integer or e.is_Rational or e.is_Float or e.is_NumberSymbol:
            return float(e)
        if e.is_Add:
            out = 0
            for a in e.args:
                out = out + self(a)
            return out
        if e.is_Mul:
            out = 1
            for a in e.args:
                out = out * self(a)
            return out
        if e.is_Pow:
            return self._power(*e.args)
        if e.is_Symbol:
            raise BridgeError(f"symbol {e} has no numeric value (not an argument of the function)")
        return self._function(e)

    def _power(self, base, exponent):
        """base**exponent: square roots and inverses as such, small integer powers as products."""
        if exponent == sp.Rational(1, 2):
            return ca.sqrt(self(base))
        if exponent == -1:
            return 1 / self(base)
        if exponent.is_Integer and abs(int(exponent)) <= 4:
            factor = self(base)
            out = factor
            for _ in range(abs(int(exponent)) - 1):
                out = out * factor
            return 1 / out if int(exponent) < 0 else out
        return self(base) ** self(exponent)

    def _function(self, e):
        if isinstance(e, sp.DiracDelta):
            # the derivative of a jump (Heaviside, sign) is taken as 0 away from the jump: the
            # equations hold almost everywhere and the integrator steps over the jump itself
            return 0.0
        if e.func in _UNARY:
            return _UNARY[e.func](self(e.args[0]))
        if e.func is sp.atan2:
            return ca.atan2(self(e.args[0]), self(e.args[1]))
        if e.func in (sp.Min, sp.Max):
            pick = ca.fmin if e.func is sp.Min else ca.fmax
            out = self(e.args[0])
            for a in e.args[1:]:
                out = pick(out, self(a))
            return out
        raise BridgeError(f"cannot convert {type(e).__name__} ({e}) to CasADi")
