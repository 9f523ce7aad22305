"""Structural checks of a reduced model: the Jacobi identity of the reduced bracket and the
holonomy (Frobenius integrability) of the constraints.

The thesis (§2.2.2, after eq. 2.31) states, after van der Schaft and Maschke, that the bracket
on the constraint submanifold satisfies the Jacobi identity iff the constraints are holonomic.
:func:`jacobi_test` evaluates both sides independently at random states:

* Jacobiator of J(z): Σ_l J_il ∂_l J_jk + J_jl ∂_l J_ki + J_kl ∂_l J_ij for all i < j < k;
* involutivity of D_q: ω [X_a, X_b] for all pairs of the basis columns X_a.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..numerics.bridge import to_casadi


@dataclass(frozen=True)
class JacobiTest:
    """Outcome of :func:`jacobi_test`.

    Attributes
    ----------
    jacobiator : float
        Max |Jacobiator| relative to max|J|·max|∂J| over the samples.
    holonomy : float
        Max |ω[X_a, X_b]| relative to max|X|·max|∂X|·max|ω| over the samples.
    jacobi_holds, holonomic : bool
        Each below ``tol``.
    samples : int
    """

    jacobiator: float
    holonomy: float
    jacobi_holds: bool
    holonomic: bool
    samples: int
    tol: float

    @property
    def consistent(self) -> bool:
        """The thesis's statement for this system: Jacobi holds ⇔ holonomic."""
        return self.jacobi_holds == self.holonomic


def jacobi_test(model, samples: int = 20, seed: int = 0, tol: float = 1e-9) -> JacobiTest:
    """Check the Jacobi identity of the structure J_z and the holonomy of the constraints.

    Works on ``model.numeric``'s ``structure`` and ``basis`` functions (either form of the
    reduced ODE), differentiated by CasADi's AD."""
    system = model.system
    n, nz = system.n, len(model.state)
    num = model.numeric
    z = ca.SX.sym("z", nz)
    p = ca.SX.sym("p", len(system.param_symbols))
    J = num["structure"](z, p)
    dJ = ca.jacobian(ca.vec(J), z)                        # (nz*nz) × nz, column-major vec
    X = num["basis"](z, p)
    syms = list(system.q) + list(system.param_symbols)
    sx = [z[i] for i in range(n)] + [p[i] for i in range(p.shape[0])]
    W = (ca.reshape(ca.vertcat(*to_casadi(list(system.omega().T), syms, sx)), system.k, n) if system.k
         else ca.SX(0, n))
    q = z[:n]
    cols = X.shape[1]
    brackets = []
    for a in range(cols):
        for b in range(a + 1, cols):
            lie = ca.mtimes(ca.jacobian(X[:, b], q), X[:, a]) - ca.mtimes(ca.jacobian(X[:, a], q), X[:, b])
            brackets.append(ca.mtimes(W, lie))
    hol = ca.vertcat(*brackets) if brackets else ca.SX(0, 1)
    f = ca.Function("jacobi", [z, p], [J, dJ, hol, X, W])
    rng = np.random.default_rng(seed)
    pv = np.array(system.param_values, dtype=float)
    worst_j, worst_h = 0.0, 0.0
    for _ in range(samples):
        zv = rng.uniform(-1.0, 1.0, nz)
        Jn, dJn, hn, Xn, Wn = (np.array(o.full()) for o in f(zv, pv))
        dJn = dJn.reshape(nz, nz, nz, order="F")          # dJn[i, j, l] = ∂J_ij/∂z_l
        jac = (np.einsum("il,jkl->ijk", Jn, dJn) + np.einsum("jl,kil->ijk", Jn, dJn)
               + np.einsum("kl,ijl->ijk", Jn, dJn))
        scale = max(1e-300, np.abs(Jn).max() * max(1.0, np.abs(dJn).max()))
        worst_j = max(worst_j, float(np.abs(jac).max()) / scale)
        if hn.size:
            hscale = max(1e-300, max(1.0, np.abs(Xn).max()) ** 2 * max(1.0, np.abs(Wn).max()))
            worst_h = max(worst_h, float(np.abs(hn).max()) / hscale)
    return JacobiTest(jacobiator=worst_j, holonomy=worst_h, jacobi_holds=worst_j < tol,
                      holonomic=worst_h < tol, samples=samples, tol=tol)
