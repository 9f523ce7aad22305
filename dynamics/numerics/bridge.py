"""The one bridge from sympy to numbers: sympy expressions → CasADi SX graphs.

Only this module (and :mod:`.numeric`) touches CasADi inside ``nhgait.dynamics``. Common
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
    table = {s: x for s, x in zip(symbols, sx_args)}
    reps, reduced = sp.cse(list(exprs), optimizations=None, order="none")
    memo: dict = {}

    def conv(e):
        if e in table:
            return table[e]
        got = memo.get(e)
        if got is not None:
            return got
        if e.is_Integer or e.is_Rational or e.is_Float:
            out = float(e)
        elif e is sp.pi:
            out = float(sp.pi)
        elif e.is_NumberSymbol:
            out = float(e)
        elif e.is_Add:
            out = 0
            for a in e.args:
                out = out + conv(a)
        elif e.is_Mul:
            out = 1
            for a in e.args:
                out = out * conv(a)
        elif e.is_Pow:
            b, x = e.args
            if x == sp.Rational(1, 2):
                out = ca.sqrt(conv(b))
            elif x == -1:
                out = 1 / conv(b)
            elif x.is_Integer and abs(int(x)) <= 4:
                base = conv(b)
                out = base
                for _ in range(abs(int(x)) - 1):
                    out = out * base
                if int(x) < 0:
                    out = 1 / out
            else:
                out = conv(b) ** conv(x)
        elif isinstance(e, sp.DiracDelta):
            # the derivative of a jump (Heaviside, sign) is taken as 0 away from the jump: the
            # equations hold almost everywhere and the integrator steps over the jump itself
            out = 0.0
        elif e.func in _UNARY:
            out = _UNARY[e.func](conv(e.args[0]))
        elif e.func is sp.atan2:
            out = ca.atan2(conv(e.args[0]), conv(e.args[1]))
        elif e.func is sp.Min:
            out = conv(e.args[0])
            for a in e.args[1:]:
                out = ca.fmin(out, conv(a))
        elif e.func is sp.Max:
            out = conv(e.args[0])
            for a in e.args[1:]:
                out = ca.fmax(out, conv(a))
        elif e.is_Symbol:
            raise BridgeError(f"symbol {e} has no numeric value (not an argument of the function)")
        else:
            raise BridgeError(f"cannot convert {type(e).__name__} ({e}) to CasADi")
        memo[e] = out
        return out

    for sym, sub in reps:
        table[sym] = conv(sub)
    return [conv(e) for e in reduced]
