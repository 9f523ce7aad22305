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

For a mixed system (d > 0) ξ = −A(r)ṙ + Γ(r)p: H_ab is the curvature of A alone, the motion
loops give with the nonholonomic momentum p held at zero. With ``momentum=`` (a
:class:`~.scaled_momentum.ScaledMomentum`, one momentum) the functions below give Shammas's
scaled-momentum height H̄_ab = H_ab − σ̄_ab Γ̄ instead: the displacement, per unit area, of an
elliptical loop traced at a constant rate from rest, the momentum included (what is exact and
what is approximate: :mod:`.scaled_momentum`).

:func:`height_function` gives H_ab (or H̄_ab) as sympy; :func:`evaluate_heights` the arrays over
a grid (:class:`HeightGrid` → :class:`HeightFunctions`), with the connection's fields (rows of
−A) for the figures; :func:`evaluate_heights_numeric` the same from the compiled basis.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import sympy as sp

from ..errors import ModelError
from .connection_fields import LocalConnection

__all__ = ["HeightGrid", "GridAxes", "HeightFunctions", "curvature", "height_function", "evaluate_heights",
           "evaluate_heights_numeric"]

#: the two forms of :attr:`HeightFunctions.form`
CONNECTION, SCALED_MOMENTUM = "connection", "scaled momentum"


def curvature(connection: LocalConnection, a: str, b: str) -> sp.Matrix:
    """DA_ab = ∂A_b/∂r_a − ∂A_a/∂r_b − [A_a, A_b] (l×1 sympy; module docstring)."""
    q = {str(s): s for s in connection.system.q}
    Aa, Ab = connection.column(a), connection.column(b)
    return (Ab.diff(q[a]) - Aa.diff(q[b]) - connection.bracket(Aa, Ab)).applyfunc(sp.cancel)


def height_function(connection: LocalConnection, a: str, b: str, *, momentum=None) -> sp.Matrix:
    """H_ab = −DA_ab, the body displacement per unit area of a counter-clockwise loop in the
    (r_a, r_b) plane (l×1 sympy; module docstring); with ``momentum`` (a
    :class:`~.scaled_momentum.ScaledMomentum` of the same plane) the scaled-momentum height
    H̄_ab = H_ab − σ̄_abΓ̄."""
    H = -curvature(connection, a, b)
    if momentum is None:
        return H
    if tuple(momentum.pair) != (a, b):
        raise ModelError([f"the scaled momentum is of the plane {momentum.pair}, the height of {(a, b)}"],
                         title="invalid height-function request")
    return H + momentum.height()


class GridAxes(NamedTuple):
    """The grid values of a shape plane (a, b): ``a_values`` (na,) and ``b_values`` (nb,)."""

    a_values: np.ndarray
    b_values: np.ndarray


@dataclass(frozen=True)
class HeightGrid:
    """Where to evaluate height functions: ``bounds`` {a: (low, high), b: (low, high)} of the
    two shape coordinates, ``points`` per axis, the other coordinates at ``at`` (default 0),
    the parameters ``params`` (a mapping or a vector in ``system.param_symbols`` order; None:
    the system's — a numeric connection has its own), ``units`` name → text for the figures."""

    bounds: Mapping
    points: int = 41
    at: Mapping = field(default_factory=dict)
    params: object = None
    units: Mapping = field(default_factory=dict)

    def problems(self, shape: tuple, a: str, b: str) -> list:
        """Every problem of the request (a, b) over this grid, for one ModelError."""
        out = [f"{n!r} is not a shape coordinate (shape: {', '.join(shape)})"
               for n in (a, b) if n not in shape]
        out += [f"the pair needs two different shape coordinates, got {a!r} twice"] if a == b else []
        out += [f"bounds of {n!r}: give (low, high) with low < high" for n in (a, b)
                if n in shape and not (n in self.bounds
                                       and float(self.bounds[n][0]) < float(self.bounds[n][1]))]
        out += [f"points: give at least 2 per axis, got {self.points}"] if int(self.points) < 2 else []
        return out

    def axes(self, a: str, b: str) -> GridAxes:
        """The grid values of ``a`` and ``b``: ``points`` evenly spaced over each one's bounds."""
        return GridAxes(*(np.linspace(*map(float, self.bounds[n]), int(self.points)) for n in (a, b)))


@dataclass(frozen=True, eq=False, kw_only=True)
class HeightFunctions:
    """Height functions and connection fields of one shape plane, as arrays.

    Attributes
    ----------
    fiber : names of the l body-velocity components (the fibre coordinates).
    pair : (a, b), the shape coordinates of the horizontal and vertical axes.
    a_values, b_values : grid values (na,), (nb,).
    heights : l×nb×na, H_ab (or H̄_ab) at (b_values[i], a_values[j]) (units of fibre k per rad²
        of shape).
    fields : l×2×nb×na, the rows of −A restricted to (a, b): the shape velocity direction that
        moves fibre k forward fastest (arrows of the figures).
    at : the configuration values held fixed (other shape and fibre coordinates).
    units : name → unit text (the scene's, where given).
    form : ``"connection"`` (H, momentum at zero) or ``"scaled momentum"`` (H̄ = H − σ̄_abΓ̄).
    momentum_part : l×nb×na, −σ̄_abΓ̄ (the scaled-momentum form; None otherwise): ``heights``
        minus it is the connection's H.
    """

    fiber: tuple
    pair: tuple
    a_values: np.ndarray
    b_values: np.ndarray
    heights: np.ndarray
    fields: np.ndarray
    at: dict
    units: dict
    form: str = CONNECTION
    momentum_part: np.ndarray | None = None

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


def _on_grid(function, av, bv, shape) -> np.ndarray:
    """``function(a, b)`` at every grid point, as an array ``shape`` + (nb, na)."""
    out = np.zeros(shape + (bv.size, av.size))
    with np.errstate(all="ignore"):
        for i, vb in enumerate(bv):
            for j, va in enumerate(av):
                out[..., i, j] = np.asarray(function(va, vb), float).reshape(shape)
    return out


def evaluate_heights(connection: LocalConnection, a: str, b: str, grid: HeightGrid, *,
                     momentum=None) -> HeightFunctions:
    """H_ab and the fields of −A over ``grid`` (:class:`HeightGrid`); with ``momentum`` (a
    :class:`~.scaled_momentum.ScaledMomentum` of the plane) the scaled-momentum heights
    H̄_ab = H_ab − σ̄_abΓ̄, the part −σ̄_abΓ̄ kept in ``momentum_part``."""
    problems = grid.problems(connection.shape, a, b)
    if problems:
        raise ModelError(problems, title="invalid height-function request")
    at, system, l = dict(grid.at), connection.system, len(connection.fiber)
    columns = [connection.shape.index(a), connection.shape.index(b)]
    av, bv = grid.axes(a, b)
    H = _numeric(height_function(connection, a, b), system, at, grid.params, a, b)
    heights = _on_grid(H, av, bv, (l,))
    fields = _on_grid(_numeric(-connection.A[:, columns], system, at, grid.params, a, b), av, bv, (l, 2))
    part = None
    if momentum is not None:
        if tuple(momentum.pair) != (a, b):
            raise ModelError([f"the scaled momentum is of the plane {momentum.pair}, "
                              f"the heights of {(a, b)}"],
                             title="invalid height-function request")
        part = _on_grid(_numeric(momentum.height(), system, at, grid.params, a, b), av, bv, (l,))
        heights = heights + part
    return HeightFunctions(fiber=connection.fiber, pair=(a, b), a_values=av, b_values=bv, heights=heights,
                           fields=fields, at=at, units=dict(grid.units),
                           form=CONNECTION if momentum is None else SCALED_MOMENTUM, momentum_part=part)


#: relative step of the central differences of :func:`evaluate_heights_numeric`
DIFFERENCE_STEP = 1e-5


def _momentum_part(equation, connection, a, b):
    """q ↦ −σ_abΓ (l,) from a ReconstructionEquation's numbers at the connection's parameters
    (one momentum, σ_aa = σ_bb = 0: :mod:`.scaled_momentum`); the problems of the request
    otherwise."""
    names, params = connection.names, connection.params
    problems = []
    if len(equation.momenta) != 1:
        problems.append(f"the scaled-momentum heights need one nonholonomic momentum, "
                        f"{equation.system} has {len(equation.momenta)}")
        return None, problems
    ja, jb = equation.shape.index(a), equation.shape.index(b)

    def part(q):
        values = equation.evaluate(q, params)
        rr = values.sigma_rr[0]
        scale = max(abs(rr[ja, jb]), 1.0)
        if max(abs(rr[ja, ja]), abs(rr[jb, jb]), abs(values.sigma_pp[0][0, 0])) > 1e-12 * scale:
            raise ModelError([f"σ_aa, σ_bb or σ_pp is not zero at {dict(zip(names, q, strict=True))}: the "
                              "momentum of a loop does not return to zero (see scaled_momentum)"],
                             title="no scaled-momentum height function")
        return -rr[ja, jb] * values.Gamma[:, 0]
    return part, problems


def _heights_and_fields(connection, q0, rows, columns, axes) -> tuple:
    """(H (l, nb, na), the fields of −A (l, 2, nb, na)) over the grid ``axes`` (a values, b
    values) of the coordinates at positions ``rows`` of q (their columns of A: ``columns``), the
    other coordinates at ``q0``: A at every grid point and its four central-difference
    neighbours in one mapped call of the basis (:meth:`NumericConnection.A_many`). Points where
    A is not finite give non-finite values, as the pointwise evaluation did."""
    (ia, ib), (ja, jb), (av, bv) = rows, columns, axes
    B, Av = np.meshgrid(bv, av, indexing="ij")                  # (nb, na), b the row
    points = np.repeat(q0[:, None], B.size, axis=1)
    points[ia], points[ib] = Av.ravel(), B.ravel()
    steps = {i: DIFFERENCE_STEP * np.maximum(1.0, np.abs(points[i])) for i in (ia, ib)}
    shifted = [points]
    for i in (ia, ib):
        for sign in (1.0, -1.0):
            moved = points.copy()
            moved[i] = points[i] + sign * steps[i]
            shifted.append(moved)
    with np.errstate(all="ignore"):
        A = connection.A_many(np.hstack(shifted)).reshape(5, B.size, len(connection.fiber), -1)
        d_a = (A[1, :, :, jb] - A[2, :, :, jb]) / (2 * steps[ia][:, None])   # ∂A_b/∂r_a
        d_b = (A[3, :, :, ja] - A[4, :, :, ja]) / (2 * steps[ib][:, None])   # ∂A_a/∂r_b
        bracket = np.einsum("kij,pi,pj->pk", connection.structure, A[0, :, :, ja], A[0, :, :, jb])
        H = -(d_a - d_b) + bracket                                             # (points, l)
    shape = B.shape
    heights = np.moveaxis(H.reshape(shape + (H.shape[1],)), -1, 0)
    fields = np.moveaxis(-A[0][:, :, [ja, jb]].reshape(shape + (A.shape[2], 2)), (2, 3), (0, 1))
    return heights, fields


def evaluate_heights_numeric(connection, a: str, b: str, grid: HeightGrid, *,
                             equation=None) -> HeightFunctions:
    """:func:`evaluate_heights` from a
    :class:`~.connection_fields.NumericConnection` (the compiled basis: no symbolic work, for a
    plan's figures and failure report): ∂A/∂r by central differences (step
    :data:`DIFFERENCE_STEP` × max(1, |r|); error about 1e-10 relative), the bracket from the
    structure constants. With ``equation`` (the model's
    :class:`~.reconstruction.ReconstructionEquation`, explicit or implicit form) the
    scaled-momentum heights H̄ = H − σ_abΓ from its numbers (σ̄_abΓ̄ = σ_abΓ). The connection's
    parameters are those it was built with (``grid.params`` must be None)."""
    problems = grid.problems(connection.shape, a, b)
    problems += ["grid.params: a numeric connection's parameters are bound when it is built "
                 "(numeric_connection(model, params))"] if grid.params is not None else []
    part_of = None
    if equation is not None and not problems:
        part_of, more = _momentum_part(equation, connection, a, b)
        problems += more
    if problems:
        raise ModelError(problems, title="invalid height-function request")
    names = connection.names
    q0 = np.array([float(dict(grid.at).get(c, 0.0)) for c in names])
    ia, ib = names.index(a), names.index(b)
    ja, jb = connection.shape.index(a), connection.shape.index(b)
    av, bv = grid.axes(a, b)

    heights, fields = _heights_and_fields(connection, q0, (ia, ib), (ja, jb), (av, bv))

    def at(va, vb):
        q = q0.copy()
        q[ia], q[ib] = va, vb
        return q

    l = len(connection.fiber)
    part = None if part_of is None else _on_grid(lambda va, vb: part_of(at(va, vb)), av, bv, (l,))
    return HeightFunctions(fiber=connection.fiber, pair=(a, b), a_values=av, b_values=bv,
                           heights=heights if part is None else heights + part, fields=fields,
                           at=dict(zip(names, q0, strict=True)), units=dict(grid.units),
                           form=CONNECTION if part is None else SCALED_MOMENTUM, momentum_part=part)
