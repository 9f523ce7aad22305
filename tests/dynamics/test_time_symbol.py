"""The one time symbol (dynamics/algebra/symbols.py): a real ``t`` that a stated force's ``t``
is (sympy symbols with other assumptions would be different symbols and a time-dependent force
would never see the time), and that evaluates the force at the time given."""
from __future__ import annotations

import sympy as sp

from nhgait.dynamics import System
from nhgait.dynamics.algebra.symbols import TIME


def test_a_forces_t_is_the_time_symbol():
    system = System(["x"], "m*x_dot**2/2", [], forces={"x": "F + sin(2*t)"}, parameters={"m": 1.0},
                    inputs=["F"])
    assert TIME.name == "t" and TIME.is_real and TIME != sp.Symbol("t")
    tau = system.tau[0]
    assert TIME in tau.free_symbols
    assert float(tau.subs({TIME: 0.25, system.input_symbols[0]: 1.0})) == 1.0 + float(sp.sin(0.5))
