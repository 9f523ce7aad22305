"""The planner's ODE with the parameter vector as an argument, for scenario (robust) planning.

:func:`~.specialisation.specialise` binds the parameter values into the functions a plan is
solved with; a scenario problem (:mod:`nhgait.ocp.scenarios`) integrates copies of the same
state under other parameter values with *one* function, so it needs ż = f(t, z, u, θ) with θ
free — in the same coordinates as the specialised model. In velocity coordinates z = (q, y),
y = Y(q, θ) q̇ (:mod:`.velocity_coordinates`), with the reduced model's q̇ = Q(q, θ) P
(q̇ is linear in the momenta P, so Q = ∂q̇/∂P at P = 0) and B = Y Q::

    P = B⁻¹ y,   q̇ = q̇(q, P, θ),   ẏ = ∂(Y q̇)/∂z_P · ż_P(t, z_P, u, θ),   z_P = (q, P),

the numeric route of the specialisation with θ a symbol (no sympy, any model form). In the
momentum coordinates (no velocity states) it is the derived model's own ``rhs``. Parameters
listed in ``fixed`` keep their values (folded into constants by CasADi): only the varied ones
cost operations.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .velocity_coordinates import row_function

__all__ = ["parametric_rhs"]


def parametric_rhs(specialised, quantities=None, *, varied=None) -> ca.Function:
    """ż = f(t, z, u, θ) of ``specialised`` (a :class:`~.specialisation.SpecialisedModel`) with
    the whole parameter vector θ (the model's ``param_names`` order) as the last argument.

    ``quantities``: the scene's quantity expressions (velocity states named by them);
    ``varied``: the indices of θ that may differ from the specialised model's values (None:
    every one); the others are bound to those values.
    """
    model = specialised.base
    n, nz = model.system.n, len(model.state_names)
    nu = len(model.numeric.input_names)
    values = np.asarray(specialised.numeric.params(), dtype=float)
    t, z, u, theta = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("params", len(values))
    free = range(len(values)) if varied is None else sorted(set(varied))
    bound = [theta[i] if i in free else ca.SX(values[i]) for i in range(len(values))]
    p = ca.vertcat(*bound) if len(values) else theta
    velocities = tuple(specialised.velocities)
    if not velocities:
        rhs = model.numeric["rhs"](t, z, u, p)
    else:
        Y = row_function(model, velocities, dict(quantities or {}))
        q, y, P0 = z[:n], z[n:], ca.SX.sym("P", nz - n)
        qdot = model.numeric["qdot"]
        Q = ca.substitute(ca.jacobian(qdot(ca.vertcat(q, P0), p), P0), P0, ca.DM.zeros(nz - n))
        zP = ca.vertcat(q, ca.solve(ca.mtimes(Y(q, p), Q), y))
        zs = ca.SX.sym("zP", nz)
        ydot = ca.jtimes(ca.mtimes(Y(zs[:n], p), qdot(zs, p)), zs, model.numeric["rhs"](t, zs, u, p))
        rhs = ca.vertcat(qdot(zP, p), ca.substitute(ydot, zs, zP))
    return ca.Function("rhs_params", [t, z, u, theta], [ca.cse(rhs)], ["t", "z", "u", "params"], ["zdot"])
