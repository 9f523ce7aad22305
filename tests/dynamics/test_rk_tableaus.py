"""The Runge–Kutta tableaus of the compiled integrator against Butcher's order conditions.

Independent reference: the rooted-tree order conditions Σᵢ bᵢ Φᵢ(τ) = 1/γ(τ) (Butcher 1963;
Hairer, Nørsett & Wanner I, Thm. II.2.13), generated here from scratch for every tree up to
order 8, evaluated in exact rational arithmetic on the published coefficients. For the
continuous extension the condition is Σᵢ bᵢ(θ) Φᵢ(τ) = θ^|τ| / γ(τ) for every θ.
"""
from __future__ import annotations

import functools
from fractions import Fraction as F

import numpy as np
import pytest

from nhgait.dynamics.simulation.rk_tableaus import exact_tableau, tableau


def _trees(order: int) -> list:
    """All rooted trees with ``order`` nodes, each a sorted tuple of its subtrees."""
    if order == 1:
        return [()]
    out = set()
    for children in _forests(order - 1, order - 1):
        out.add(tuple(sorted(children)))
    return sorted(out)


@functools.cache
def _forests(nodes: int, largest: int) -> tuple:
    """Multisets of trees with ``nodes`` nodes in all, each tree at most ``largest`` nodes."""
    if nodes == 0:
        return ((),)
    out = []
    for size in range(min(nodes, largest), 0, -1):
        for tree in _trees_cached(size):
            for rest in _forests(nodes - size, size):
                if all(not (_size(r) == size and r > tree) for r in rest):
                    out.append((tree,) + rest)
    return tuple(out)


@functools.cache
def _trees_cached(order):
    return tuple(_trees(order))


def _size(tree) -> int:
    return 1 + sum(_size(t) for t in tree)


def _gamma(tree) -> int:
    g = _size(tree)
    for t in tree:
        g *= _gamma(t)
    return g


def test_tree_counts():
    """1, 1, 2, 4, 9, 20, 48, 115 rooted trees of orders 1 … 8 (OEIS A000081)."""
    assert [len(_trees_cached(p)) for p in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]


def _stage_weights(a, c):
    s = len(c)

    @functools.cache
    def phi(tree):
        vec = [F(1)] * s
        for child in tree:
            inner = phi(child)
            row = [sum(a[i][j] * inner[j] for j in range(s)) for i in range(s)]
            vec = [vec[i] * row[i] for i in range(s)]
        return tuple(vec)
    return phi


def _max_defect(weights, phi, order):
    worst = F(0)
    for p in range(1, order + 1):
        for tree in _trees_cached(p):
            value = sum(w * v for w, v in zip(weights, phi(tree), strict=True))
            worst = max(worst, abs(value - F(1, _gamma(tree))))
    return float(worst)


@pytest.mark.parametrize("name, order, embedded, exact", [("DOPRI5", 5, 4, True),
                                                          ("DOP853", 8, 5, False)])
def test_order_conditions(name, order, embedded, exact):
    ex = exact_tableau(name)
    phi = _stage_weights(ex["a"], ex["c"])
    # row sums: c_i = Σ_j a_ij (the stages are consistent)
    assert max(abs(sum(r) - ci) for r, ci in zip(ex["a"], ex["c"], strict=True)) < F(1, 10 ** 25)
    tol = 0.0 if exact else 1e-24                       # 30-digit published decimals
    assert _max_defect(ex["b"], phi, order) <= tol
    assert _max_defect(ex["bhat"], phi, embedded) <= tol
    # the pair's orders are sharp: the next order is violated
    assert _max_defect(ex["b"], phi, order + 1) > 1e-6
    assert _max_defect(ex["bhat"], phi, embedded + 1) > 1e-6
    if ex["b3"] is not None:                             # DOP853's 3rd-order estimator
        assert _max_defect(ex["b3"], phi, 3) <= tol


@pytest.mark.parametrize("name, dense_order", [("DOPRI5", 4), ("DOP853", 7)])
@pytest.mark.parametrize("theta", [F(1, 7), F(1, 2), F(5, 6), F(1)])
def test_continuous_extension_order(name, dense_order, theta):
    ex = exact_tableau(name)
    phi = _stage_weights(ex["a"], ex["c"])
    b_theta = [sum(coef * theta ** (d + 1) for d, coef in enumerate(row)) for row in ex["dense"]]
    worst = F(0)
    for p in range(1, dense_order + 1):
        for tree in _trees_cached(p):
            value = sum(w * v for w, v in zip(b_theta, phi(tree), strict=True))
            worst = max(worst, abs(value - theta ** p / _gamma(tree)))
    assert float(worst) < (1e-24 if name == "DOP853" else 1e-30)
    if theta == 1:          # the extension ends on the step's solution y1
        assert max(abs(x - y) for x, y in zip(b_theta, ex["b"], strict=True)) < F(1, 10 ** 24)


def test_float_tableau_matches_exact():
    for name in ("DOPRI5", "DOP853"):
        tab, ex = tableau(name), exact_tableau(name)
        assert np.array_equal(tab.b, [float(x) for x in ex["b"]])
        assert tab.a.shape == (tab.s_ext, tab.s_ext)
        assert np.all(np.triu(tab.a) == 0)
        assert tab.c[tab.i_new] == 1.0
        assert tab.c[tab.i_stiff] == 1.0
        assert np.array_equal(tab.a[tab.i_new], tab.b)
