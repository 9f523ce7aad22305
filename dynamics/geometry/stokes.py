"""The net displacement of a shape loop: the body-velocity integral and Stokes's estimate.

For ξ = −A(r)ṙ (:mod:`.connection_fields`) and ġ = gξ, a closed shape loop r(t) moves the
body from g₀ to g₀·exp(Ω) with, by the Magnus expansion,

    Ω = ∫ξ dt + ½ ∫∫_{s<t} [ξ(s), ξ(t)] ds dt + O(ε³)           (ε: the loop's size)

(:func:`loop_displacement`, the body-velocity integral with its bracket term, on the samples of
the loop), and by Stokes's theorem on a loop in one shape plane (r_a, r_b),

    Ω ≈ ∬ H_ab dr_a dr_b                       (H_ab the height function, :mod:`.heights`)

over the enclosed region, counted with its winding number (:func:`stokes_displacement`:
a fan of triangles from the loop's centroid with signed areas, a 7-point Gauss rule on each).
Both differ from the exact displacement at order ε³: the relative error falls linearly in ε.
For a mixed system these are the displacements with the nonholonomic momentum held at zero;
:func:`stokes_displacement` of the scaled-momentum height H̄ (:mod:`.scaled_momentum`) adds the
momentum's part for an elliptical loop from rest.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .connection_fields import NumericConnection

__all__ = ["LoopDisplacement", "loop_displacement", "stokes_displacement"]

# Dunavant's 7-point rule on a triangle (barycentric weights, exact for degree 5)
_A1, _B1 = 0.797426985353087, 0.101286507323456
_A2, _B2 = 0.059715871789770, 0.470142064105115
_BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [_A1, _B1, _B1], [_B1, _A1, _B1], [_B1, _B1, _A1],
                  [_A2, _B2, _B2], [_B2, _A2, _B2], [_B2, _B2, _A2]])
_W = np.array([0.225, *[0.125939180544827] * 3, *[0.132394159928839] * 3])


@dataclass(frozen=True)
class LoopDisplacement:
    """Ω of a loop in the fibre's Lie algebra (l,), its two parts and the fibre names:
    ``first`` = ∫ξ dt = −∮A dr, ``bracket`` = ½∫∫[ξ(s), ξ(t)]."""

    fiber: tuple
    first: np.ndarray
    bracket: np.ndarray

    @property
    def total(self) -> np.ndarray:
        return self.first + self.bracket


def loop_displacement(connection: NumericConnection, q_samples) -> LoopDisplacement:
    """The body-velocity integral of the configurations ``q_samples`` (n×K, the shape
    coordinates moving along the loop, the fibre held at the start: A depends on r only when
    the fibre is a symmetry group); midpoint rule on each of the K − 1 steps."""
    q = np.asarray(q_samples, float)
    r = q[list(connection.shape_index)]
    mid = 0.5 * (q[:, 1:] + q[:, :-1])
    steps = [-connection.A(mid[:, k]) @ (r[:, k + 1] - r[:, k]) for k in range(q.shape[1] - 1)]
    first = np.sum(steps, axis=0)
    so_far, bracket = np.zeros_like(first), np.zeros_like(first)
    for xi in steps:                                  # ½ Σ_{j<k} [ξ_j, ξ_k] = ½ Σ_k [S_{k−1}, ξ_k]
        bracket += 0.5 * connection.bracket(so_far, xi)
        so_far = so_far + xi
    return LoopDisplacement(connection.fiber, first, bracket)


def stokes_displacement(height, loop_a, loop_b) -> np.ndarray:
    """∬ H over the region a closed loop (``loop_a``, ``loop_b``: its samples, the last equal to
    the first or not) winds around, counter-clockwise positive; ``height(a, b)`` → (l,) is
    the height function of the plane (:func:`~.heights.height_function`, made numeric)."""
    a = np.asarray(loop_a, float)
    b = np.asarray(loop_b, float)
    ca, cb = a.mean(), b.mean()
    total = None
    for k in range(a.size):
        k1 = (k + 1) % a.size
        area = 0.5 * ((a[k] - ca) * (b[k1] - cb) - (a[k1] - ca) * (b[k] - cb))
        pa = _BARY @ np.array([ca, a[k], a[k1]])
        pb = _BARY @ np.array([cb, b[k], b[k1]])
        part = area * sum(w * np.asarray(height(x, y), float).ravel()
                          for w, x, y in zip(_W, pa, pb, strict=True))
        total = part if total is None else total + part
    return total
