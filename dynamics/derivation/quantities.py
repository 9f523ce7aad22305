"""Named quantities of a scene (``[quantities]``): expressions y(q, q̇) such as a forward body
velocity, turned into one CasADi function for the planner, the plots and the simulator.

The expressions are parsed and validated when the scene is loaded (only coordinates,
velocities and parameters may appear); here they become numbers.
"""
from __future__ import annotations

import casadi as ca

from ..numerics.bridge import to_casadi

__all__ = ["quantity_function"]


def quantity_function(system, quantities: dict) -> ca.Function:
    """``f(q, qdot, params) → y`` (len(quantities),) in the order of ``quantities``.

    Parameters
    ----------
    system : System
    quantities : mapping name → sympy expression in ``system.q``, ``system.q_dot`` and
        ``system.param_symbols`` (``Scene.quantities``).
    """
    n, npar = system.n, len(system.param_symbols)
    q, qd, p = ca.SX.sym("q", n), ca.SX.sym("qdot", n), ca.SX.sym("params", npar)
    syms = list(system.q) + list(system.q_dot) + list(system.param_symbols)
    sx = [q[i] for i in range(n)] + [qd[i] for i in range(n)] + [p[i] for i in range(npar)]
    values = to_casadi(list(quantities.values()), syms, sx) if quantities else []
    y = ca.vertcat(*values) if values else ca.SX(0, 1)
    return ca.Function("quantities", [q, qd, p], [y], ["q", "qdot", "params"], [",".join(quantities) or "y"])
