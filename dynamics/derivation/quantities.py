"""Named quantities of a scene (``[quantities]``): expressions y(q, q̇) such as a forward body
velocity, turned into one CasADi function for the planner, the plots and the simulator; and
quantities of the motion y(q, q̇, q̈, u) (an axle's acceleration, an input's square) for the
planner's path bounds and integrals.

The expressions are parsed and validated when the scene is loaded (coordinates, velocities,
accelerations ``<q>_ddot``, inputs and parameters may appear); here they become numbers.
"""
from __future__ import annotations

import casadi as ca

from ..numerics.bridge import to_casadi

__all__ = ["quantity_function", "motion_quantity_function", "acceleration_symbols"]


def acceleration_symbols(system) -> tuple:  # of sympy Symbols
    """The accelerations ``<q>_ddot`` of the coordinates, as real sympy symbols."""
    import sympy as sp
    return tuple(sp.Symbol(f"{c}_ddot", real=True) for c in system.coordinates)


def motion_quantity_function(system, quantities: dict) -> ca.Function:
    """``f(q, qdot, qddot, u, params) → y`` (len(quantities),) of expressions in the
    coordinates, velocities, accelerations, inputs and parameters (``Scene.motion_quantities``)."""
    n, m, npar = system.n, len(system.inputs), len(system.param_symbols)
    q, qd, qdd = ca.SX.sym("q", n), ca.SX.sym("qdot", n), ca.SX.sym("qddot", n)
    u, p = ca.SX.sym("u", m), ca.SX.sym("params", npar)
    syms = (list(system.q) + list(system.q_dot) + list(acceleration_symbols(system))
            + list(system.input_symbols)
            + list(system.param_symbols))
    sx = ([q[i] for i in range(n)] + [qd[i] for i in range(n)] + [qdd[i] for i in range(n)]
          + [u[i] for i in range(m)])
    sx += [p[i] for i in range(npar)]
    values = to_casadi(list(quantities.values()), syms, sx) if quantities else []
    y = ca.vertcat(*values) if values else ca.SX(0, 1)
    return ca.Function("motion_quantities", [q, qd, qdd, u, p], [y], ["q", "qdot", "qddot", "u", "params"],
                       [",".join(quantities) or "y"])


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
