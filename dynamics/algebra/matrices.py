"""Symbolic matrices the derivations need: a division-free null-space basis
(:func:`null_basis_adjugate`), determinants and adjugates without simplification for large
entries (:func:`plain_det`, :func:`plain_adjugate`, :func:`is_large`), common factors removed
from basis columns (:func:`strip_factors`) and independent columns chosen numerically
(:func:`numeric_pivots`).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from .trig import tidy, tree_size

__all__ = ["null_basis_adjugate", "LARGE_MATRIX_NODES", "is_large", "plain_det", "plain_adjugate",
           "strip_factors", "numeric_pivots"]


def null_basis_adjugate(A: sp.Matrix, pivots: list[int]) -> sp.Matrix:
    """Basis of the right null space of the k×l matrix ``A`` (rank k) without divisions.

    With B = A[:, pivots] (k×k, invertible at generic points) each free column j gives the
    null vector v = det(B)·e_j − (adj(B)·A[:, j]) placed on the pivot rows. Its entries are
    k×k minors of A, so no vector vanishes through a division; the vectors do become
    dependent where det B = 0, which may happen where rank A = k (a singular point of the
    basis, listed in the reduction's singular set). Returns an l×(l−k) matrix.
    """
    k, l = A.shape
    free = [j for j in range(l) if j not in pivots]
    if k == 0:
        return sp.eye(l)
    if not free:
        return sp.zeros(l, 0)
    B = A.extract(list(range(k)), pivots)
    large = is_large(A)
    if large:                      # entries from bodies: plain products, no intermediate simplification
        detB, adjB = plain_det(B), plain_adjugate(B)
    else:
        detB, adjB = B.det(method="berkowitz"), B.adjugate(method="berkowitz")
    cols = []
    for j in free:
        v = sp.zeros(l, 1)
        v[j] = detB
        w = adjB * A[:, j]
        for i, p in enumerate(pivots):
            v[p] = -w[i]
        v = tidy(v)
        # remove a common constant/polynomial factor, fix the sign of the free entry
        try:
            g = None if large else sp.gcd(list(v))
        except (sp.PolynomialError, sp.GeneratorsNeeded, TypeError):
            g = None          # no gcd of these entries: v is a basis vector as it is
        if g is not None and g not in (0, 1) and g.is_Number:
            v = tidy(v / g)
        if v[j].could_extract_minus_sign():
            v = -v
        cols.append(v)
    return sp.Matrix.hstack(*cols) if cols else sp.zeros(l, 0)


#: a matrix whose entries have more tree nodes together than this is "large": its minors and
#: their gcd are formed without simplification (the wheeled 8-link snake's ω_s has 329 nodes,
#: the Whipple bicycle's 912, whose 4×4 minors then take seconds instead of a minute)
LARGE_MATRIX_NODES = 600


def is_large(A: sp.Matrix) -> bool:
    """More than :data:`LARGE_MATRIX_NODES` tree nodes in the entries of ``A`` together."""
    total = 0
    for e in A:
        total += tree_size(e, LARGE_MATRIX_NODES)
        if total > LARGE_MATRIX_NODES:
            return True
    return False


def plain_det(B: sp.Matrix):
    """det B by expansion along the first row, without simplification (for large entries,
    where sympy's methods spend minutes simplifying intermediate products)."""
    n = B.shape[0]
    if n == 0:
        return sp.Integer(1)
    if n == 1:
        return B[0, 0]
    terms = []
    for j in range(n):
        if B[0, j] != 0:
            minor = B.extract(list(range(1, n)), [c for c in range(n) if c != j])
            terms.append((-1) ** j * B[0, j] * plain_det(minor))
    return sp.Add(*terms)


def plain_adjugate(B: sp.Matrix) -> sp.Matrix:
    """adj B (the transposed cofactor matrix) by :func:`plain_det` of the minors."""
    n = B.shape[0]
    if n == 1:
        return sp.Matrix([[1]])
    out = sp.zeros(n, n)
    for i in range(n):
        for j in range(n):
            minor = B.extract([r for r in range(n) if r != i], [c for c in range(n) if c != j])
            out[j, i] = (-1) ** (i + j) * plain_det(minor)
    return out


def strip_factors(N: sp.Matrix, symbols) -> sp.Matrix:
    """Divide each column of ``N`` by the common factor of its entries that depends on
    ``symbols`` (e.g. a sin θ common to a null vector when θ is a group variable), so a basis
    vector does not vanish at a spurious point. Factors of other symbols are kept. A large
    ``N`` (:func:`is_large`) is returned as it is (its gcd alone would take minutes)."""
    if is_large(N):
        return N
    symbols = set(symbols)
    cols = []
    for j in range(N.shape[1]):
        v = N[:, j]
        try:
            g = sp.factor(sp.gcd([e for e in v if e != 0]))
        except (sp.PolynomialError, sp.GeneratorsNeeded, TypeError):
            cols.append(v)
            continue
        keep = sp.Integer(1)
        for f in sp.Mul.make_args(g):
            if f.free_symbols & symbols:
                keep *= f
        if keep != 1:
            v = tidy(v / keep)
            nz = [e for e in v if e != 0]
            if nz and nz[-1].could_extract_minus_sign():
                v = -v
        cols.append(v)
    return sp.Matrix.hstack(*cols) if cols else N


def numeric_pivots(A_num: np.ndarray, order=None, tol=1e-9) -> list[int]:
    """Greedy choice of linearly independent columns of a numeric matrix (in ``order``)."""
    k, l = A_num.shape
    order = list(range(l)) if order is None else list(order)
    chosen: list[int] = []
    for j in order:
        trial = chosen + [j]
        sub = A_num[:, trial]
        if np.linalg.matrix_rank(sub, tol=tol * max(1.0, np.abs(A_num).max())) == len(trial):
            chosen.append(j)
        if len(chosen) == k:
            break
    return sorted(chosen)
