"""Height functions: the curvature of the local connection over a plane of two shape coordinates.

For shape coordinates (r_a, r_b) (the others fixed) and ξ = −A(r)ṙ (:mod:`.connection_fields`),
the curvature in the chosen fibre coordinates, with the Lie-bracket term, is

    DA_ab = ∂A_b/∂r_a − ∂A_a/∂r_b − [A_a, A_b]          (l×1; A_α the column of r_α)

and the height function is H_ab = −DA_ab = −(∂A_b/∂r_a − ∂A_a/∂r_b) + [A_a, A_b]: a small
counter-clockwise loop in the (r_a, r_b) plane (r_a on the horizontal axis) of enclosed area S
moves the body by exp(S·H_ab) to second order (Stokes's theorem on −∮A dr plus the Magnus
term ½∫∫[ξ(s), ξ(t)]; Hatton & Choset's "total Lie bracket", Shammas's height functions). A
clockwise loop moves it by −S·H_ab. The sign of H_k over a region therefore says which way a
loop there can move the fibre coordinate k.

For a mixed system (d > 0) ξ = −A(r)ṙ + Γ(r)p: H here is the curvature of A alone, the motion
shape loops give with the nonholonomic momentum p held at zero; the momentum's drift Γp is not
in it (Shammas's scaled-momentum height functions are not computed here; the motion with the
momentum equation along a given loop is :func:`~.prescribed.fibre_motion`).

:func:`height_function` gives H_ab as sympy; :func:`evaluate_heights` the arrays over a grid
(:class:`HeightFunctions`), with the connection's fields (rows of −A) for the figures.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..errors import ModelError
from .connection_fields import LocalConnection

__all__ = ["HeightFunctions", "curvature", "height_function", "evaluate_heights", "evaluate_heights_numeric"]


def curvature(connection: LocalConnection, a: str, b: str) -> sp.Matrix:
    """DA_ab = ∂A_b/∂r_a − ∂A_a/∂r_b − [A_a, A_b] (l×1 sympy; module docstring)."""
    q = {str(s): s for s in connection.system.q}
    Aa, Ab = connection.column(a), connection.column(b)
    return (Ab.diff(q[a]) - Aa.diff(q[b]) - connection.bracket(Aa, Ab)).applyfunc(sp.cancel)


def height_function(connection: LocalConnection, a: str, b: str) -> sp.Matrix:
    """H_ab = −DA_ab, the body displacement per unit area of a counter-clockwise loop in the
    (r_a, r_b) plane (l×1 sympy; module docstring)."""
    return -curvature(connection, a, b)


@dataclass(frozen=True, eq=False, kw_only=True)
class HeightFunctions:
    """Height functions and connection fields of one shape plane, as arrays.

    Attributes
    ----------
    fiber : names of the l body-velocity components (the fibre coordinates).
    pair : (a, b), the shape coordinates of the horizontal and vertical axes.
    a_values, b_values : grid values (na,), (nb,).
    heights : l×nb×na, H_ab at (b_values[i], a_values[j]) (units of fibre k per rad² of shape).
    fields : l×2×nb×na, the rows of −A restricted to (a, b): the shape velocity direction that
        moves fibre k forward fastest (arrows of the figures).
    at : the configuration values held fixed (other shape and fibre coordinates).
    units : name → unit text (the scene's, where given).
    """

    fiber: tuple
    pair: tuple
    a_values: np.ndarray
    b_values: np.ndarray
    heights: np.ndarray
    fields: np.ndarray
    at: dict
    units: dict

    def component(self, name: str) -> int:
        if name not in self.fiber:
            raise ModelError([f"{name!r} is not a fibre coordinate (fibre: {', '.join(self.fiber)})"],
                             title="invalid height function")
        return self.fiber.index(name)


def _numeric(expr: sp.Matrix, system, at: dict, params, a, b):
    """``expr`` as a numpy function of (a, b) with every other coordinate at ``at`` and the
    parameters bound."""
    vector = (system.param_vector(params) if params is None or isinstance(params, dict)
              else np.asarray(params, float))
    sub = dict(zip(system.param_symbols, vector, strict=True))
    sub.update({s: at.get(str(s), 0.0) for s in system.q if str(s) not in (a, b)})
    qa, qb = (next(s for s in system.q if str(s) == n) for n in (a, b))
    return sp.lambdify((qa, qb), expr.subs(sub), "numpy")


def evaluate_heights(connection: LocalConnection, a: str, b: str, *, bounds: dict, at=None, params=None,
                     points: int = 41, units=None) -> HeightFunctions:
    """H_ab and the fields of −A over the grid ``bounds[a] × bounds[b]`` (``points`` each way),
    the other coordinates at ``at`` (default 0), the parameters ``params`` (a mapping or a vector
    in ``system.param_symbols`` order; default the system's); ``units``: the scene's units
    (name → text) for the figures."""
    problems = [f"{n!r} is not a shape coordinate (shape: {', '.join(connection.shape)})"
                for n in (a, b) if n not in connection.shape]
    problems += [f"the pair needs two different shape coordinates, got {a!r} twice"] if a == b else []
    problems += [f"bounds of {n!r}: give (low, high) with low < high" for n in (a, b)
                 if n in connection.shape and not (n in bounds and float(bounds[n][0]) < float(bounds[n][1]))]
    if problems:
        raise ModelError(problems, title="invalid height-function request")
    at = dict(at or {})
    system = connection.system
    H = _numeric(height_function(connection, a, b), system, at, params, a, b)
    columns = [connection.shape.index(a), connection.shape.index(b)]
    F = _numeric(-connection.A[:, columns], system, at, params, a, b)
    av = np.linspace(*map(float, bounds[a]), points)
    bv = np.linspace(*map(float, bounds[b]), points)
    AA, BB = np.meshgrid(av, bv)
    l = len(connection.fiber)
    heights = np.zeros((l, points, points))
    fields = np.zeros((l, 2, points, points))
    with np.errstate(all="ignore"):
        for i in range(points):
            for j in range(points):
                heights[:, i, j] = np.asarray(H(AA[i, j], BB[i, j]), float).ravel()
                fields[:, :, i, j] = np.asarray(F(AA[i, j], BB[i, j]), float)
    units = dict(units or {})
    return HeightFunctions(fiber=connection.fiber, pair=(a, b), a_values=av, b_values=bv, heights=heights,
                           fields=fields, at=at, units=units)


#: relative step of the central differences of :func:`evaluate_heights_numeric`
DIFFERENCE_STEP = 1e-5


def evaluate_heights_numeric(connection, a: str, b: str, *, bounds: dict, at=None, points: int = 41,
                             units=None) -> HeightFunctions:
    """:func:`evaluate_heights` from a
    :class:`~.connection_fields.NumericConnection` (the compiled basis: no symbolic work, for a
    plan's figures and failure report): ∂A/∂r by central differences (step
    :data:`DIFFERENCE_STEP` × max(1, |r|); error about 1e-10 relative), the bracket from the
    structure constants."""
    problems = [f"{n!r} is not a shape coordinate (shape: {', '.join(connection.shape)})"
                for n in (a, b) if n not in connection.shape]
    problems += [f"bounds of {n!r}: give (low, high) with low < high" for n in (a, b)
                 if n in connection.shape and not (n in bounds and float(bounds[n][0]) < float(bounds[n][1]))]
    if problems:
        raise ModelError(problems, title="invalid height-function request")
    names = connection.names
    q0 = np.array([float(dict(at or {}).get(c, 0.0)) for c in names])
    ia, ib = names.index(a), names.index(b)
    ja, jb = connection.shape.index(a), connection.shape.index(b)
    av = np.linspace(*map(float, bounds[a]), points)
    bv = np.linspace(*map(float, bounds[b]), points)
    l = len(connection.fiber)
    heights, fields = np.zeros((l, points, points)), np.zeros((l, 2, points, points))

    def column(q, i, j):
        h = DIFFERENCE_STEP * max(1.0, abs(q[i]))
        up, down = q.copy(), q.copy()
        up[i] += h
        down[i] -= h
        return (connection.A(up)[:, j] - connection.A(down)[:, j]) / (2 * h)

    with np.errstate(all="ignore"):
        for i, vb in enumerate(bv):
            for j, va in enumerate(av):
                q = q0.copy()
                q[ia], q[ib] = va, vb
                A = connection.A(q)
                curl = column(q, ia, jb) - column(q, ib, ja)
                heights[:, i, j] = -curl + connection.bracket(A[:, ja], A[:, jb])
                fields[:, :, i, j] = -A[:, [ja, jb]]
    return HeightFunctions(fiber=connection.fiber, pair=(a, b), a_values=av, b_values=bv, heights=heights,
                           fields=fields, at=dict(zip(names, q0, strict=True)), units=dict(units or {}))
