"""The NLP's constraint Jacobian and Lagrangian Hessian assembled from the stage derivatives.

A shooting transcription records where its mapped terms sit
(:class:`~nhgait.ocp.transcription.StageLayout`: the stage function F, and the path bounds on
derived quantities c, each a function applied at K points)::

    g(w) = g_lin(w) + Σ_terms σ Σ_k E_k F(x_k),   x_k = P_k w   (P_k, E_k selections, σ = ±1).

Hence, with λ the multipliers of g and λ_f that of the objective f,

    ∂g/∂w      = ∂g_lin/∂w + Σ_terms σ Σ_k E_k J_k P_k,            J_k = ∂F/∂x (x_k)
    ∇²_w L     = ∇²_w (λ_f f + λᵀ g_lin) + Σ_terms Σ_k P_kᵀ H_k P_k,  H_k = ∇²_x (σ E_kᵀλ)ᵀ F (x_k)

The terms come from their functions mapped over their points (one call of ``jacobian`` /
``hessian`` per point, code independent of N; with ``parallel`` CasADi's threaded map, whose C
shares the points among the usable cores, :mod:`nhgait.dynamics.numerics.thread_maps`);
CasADi differentiates only g_lin and f (conditions at single nodes, periodicity, the
objective), which are small. The blocks are
placed by a constant sparse scatter of the structural nonzeros of one point's J and H.

Hessians (``hessian``):

* ``"exact"`` — as above;
* ``"gauss-newton"`` — the stage terms dropped: ∇²(λ_f f + λᵀ g_lin) only. For an effort
  objective Σ h w u² this is the Gauss–Newton matrix of the residuals √(h w) u, plus the exact
  curvature of the (cheap) boundary rows;
* ``"limited-memory"`` — no Hessian function (Ipopt's L-BFGS); the Jacobian as above (left
  to CasADi's AD of the whole graph, it cost ~60× more per evaluation on the scale benchmark).

:func:`nlp_functions` returns the functions in the form each solver's plugin asks for:
Ipopt ``nlp_hess_l(x, p, lam_f, lam_g) -> triu(H)``, FATROP
``nlp_hess_l(x, p, lam_f, lam_g) -> (∇_w L, H)``; both ``nlp_jac_g(x, p) -> (g, ∂g/∂w)``.
They are handed to ``casadi.nlpsol`` through its function cache (option ``cache``).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from nhgait.dynamics.numerics.thread_maps import threaded_map

__all__ = ["nlp_functions", "HESSIANS"]

HESSIANS = ("exact", "gauss-newton", "limited-memory")


def _scatter(n_rows: int, n_cols: int, rows: np.ndarray, cols: np.ndarray, values: ca.MX) -> ca.MX:
    """The sparse n_rows × n_cols matrix with ``values[t]`` added at (rows[t], cols[t])
    (repeated positions are summed), as one constant sparse product."""
    rows, cols = np.asarray(rows, dtype=np.int64).ravel(), np.asarray(cols, dtype=np.int64).ravel()
    linear = rows + cols * n_rows
    unique, position = np.unique(linear, return_inverse=True)
    sp = ca.Sparsity.triplet(n_rows, n_cols, (unique % n_rows).tolist(), (unique // n_rows).tolist())
    nz_of = np.array(sp.get_nz(unique.tolist()), dtype=np.int64)
    gather = ca.DM(ca.Sparsity.triplet(sp.nnz(), len(rows), nz_of[position].tolist(), list(range(len(rows)))),
                   1.0)
    return ca.MX(sp, ca.mtimes(gather, values))


def _mapped(function, K: int, parallel: bool):
    """``function`` over K points: CasADi's threaded map when ``parallel`` (its C runs the points
    on the usable cores, :mod:`~nhgait.dynamics.numerics.thread_maps`), else serial."""
    return threaded_map(function, K) if parallel else function.map(K, "serial")


def _jacobian(nlp, w, parallel: bool) -> tuple:
    """(g, ∂g/∂w), each term evaluated once by its mapped Jacobian."""
    lay = nlp.layout
    n_g = int(nlp.g.shape[0])
    g, jac = lay.g_linear, ca.jacobian(lay.g_linear, w)
    for term in lay.terms:
        (m, K), fn = term.rows.shape, term.functions
        # m × K, m × (nx K) (K blocks of one sparsity)
        F, J = _mapped(fn.jacobian, K, parallel)(*term.arguments)
        place = ca.DM(ca.Sparsity.triplet(n_g, m * K, term.rows.T.ravel().tolist(),
                                          list(range(m * K))), term.sign)
        g = g + ca.mtimes(place, ca.vec(F))
        r, c = (np.array(v, dtype=np.int64) for v in fn.jacobian.sparsity_out(1).get_triplet())
        if r.size == 0:
            continue
        k = np.repeat(np.arange(K), r.size)                         # nonzero e of point k: k nnz + e
        e = np.tile(np.arange(r.size), K)
        values = ca.vec(J.nz[(k * r.size + e).tolist()])
        jac = jac + _scatter(n_g, nlp.n_w, term.rows[r[e], k], term.columns[c[e], k], term.sign * values)
    return g, jac


def _stage_hessian(nlp, lam_g, upper: bool, parallel: bool) -> ca.MX:
    """Σ_terms Σ_k P_kᵀ H_k P_k (upper triangle for Ipopt)."""
    total = ca.MX(nlp.n_w, nlp.n_w)
    for term in nlp.layout.terms:
        (m, K), fn = term.rows.shape, term.functions
        Lam = term.sign * ca.reshape(lam_g[term.rows.T.ravel().tolist()], m, K)
        H = _mapped(fn.hessian, K, parallel)(*term.arguments, Lam)       # nx × (nx K)
        a, b = (np.array(v, dtype=np.int64) for v in fn.hessian.sparsity_out(0).get_triplet())
        if a.size == 0:
            continue
        k = np.repeat(np.arange(K), a.size)
        e = np.tile(np.arange(a.size), K)
        ra, rb = term.columns[a[e], k], term.columns[b[e], k]
        keep = (ra <= rb) if upper else np.ones_like(ra, dtype=bool)
        values = ca.vec(H.nz[(k * a.size + e)[keep].tolist()])
        total = total + _scatter(nlp.n_w, nlp.n_w, ra[keep], rb[keep], values)
    return total


def nlp_functions(nlp, *, hessian: str = "exact", solver: str = "ipopt", parallel: bool = False) -> dict:
    """``nlp_jac_g`` and ``nlp_hess_l`` of a shooting NLP (see the module docstring), or {}
    when ``nlp`` has no stage layout (collocation: CasADi differentiates the whole graph);
    ``parallel``: the stage terms mapped on threads (for compiled C)."""
    if nlp.layout is None:
        return {}
    if hessian not in HESSIANS:
        from .problem import ProblemError
        raise ProblemError([f"unknown Hessian {hessian!r} (known: {', '.join(HESSIANS)})"])
    w, p = nlp.w, ca.MX.sym("p", 0)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", nlp.g.shape[0])
    g, jac = _jacobian(nlp, w, parallel)
    out = {"nlp_jac_g": ca.Function("nlp_jac_g", [w, p], [g, jac], ["x", "p"], ["g", "jac_g_x"])}
    if hessian == "limited-memory":
        return out
    rest = lam_f * nlp.f + ca.dot(lam_g, nlp.layout.g_linear)
    upper = solver == "ipopt"
    H = ca.hessian(rest, w)[0]
    H = ca.triu(H) if upper else H
    if hessian == "exact":
        H = H + _stage_hessian(nlp, lam_g, upper, parallel)
    ins, names = [w, p, lam_f, lam_g], ["x", "p", "lam_f", "lam_g"]
    if upper:
        out["nlp_hess_l"] = ca.Function("nlp_hess_l", ins, [H], names, ["triu_hess_gamma_x_x"])
    else:
        grad = ca.gradient(lam_f * nlp.f, w) + ca.mtimes(jac.T, lam_g)
        out["nlp_hess_l"] = ca.Function("nlp_hess_l", ins, [grad, H], names,
                                        ["grad_gamma_x", "hess_gamma_x_x"])
    return out
