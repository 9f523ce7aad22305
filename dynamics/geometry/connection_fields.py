"""The local connection of a reduced model, symbolic and numeric (thesis step 5, eq. 2.47, Table 2.1).

The reconstruction equation ξ = −A(r)ṙ + Γ(r)p gives the body velocity ξ = g⁻¹ṡ of the fibre
s (l coordinates, ``model.fiber``) from the shape velocities ṙ (m, ``model.shape``) and the
nonholonomic momenta p (d). Column α of A, A_α, is the fibre velocity the unit shape velocity
ṙ_α gives (negated); row k of A, as a field over the shape space, is the 1-form whose line
integral over a shape path is (minus) the k-th body displacement.

:func:`local_connection` returns A, Γ and the bracket of the fibre group as sympy
(:class:`LocalConnection`); :func:`numeric_connection` the same A from the model's compiled
basis X (A = −g⁻¹X_s, the shape columns; :class:`NumericConnection`), a second route that
works for the implicit form and costs no symbolic work.

The bracket: the fibre's left-invariant fields X_i(s) = g(s)e_i (the columns of g) have
[X_i, X_j] = Σ_k c^k_ij X_k with constant c^k_ij = (g⁻¹((∂X_j/∂s)X_i − (∂X_i/∂s)X_j))_k; the
Lie algebra bracket is [u, v]^k = Σ_ij c^k_ij u^i v^j (for SE(2), fibre (x, y, θ) in the
version-B frame: [u, v] = (u_y v_θ − u_θ v_y, u_θ v_x − u_x v_θ, 0)). With g = identity
(version A) the bracket vanishes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ..errors import ModelError

__all__ = ["LocalConnection", "NumericConnection", "local_connection", "numeric_connection",
           "structure_constants", "numeric_structure_constants"]


@dataclass(frozen=True, eq=False)
class LocalConnection:
    """ξ = −A(r)ṙ + Γ(r)p of a reduced model (sympy).

    Attributes
    ----------
    fiber, shape : names of the fibre s (l) and of the shape r (m) coordinates.
    A : sympy Matrix l×m, the local connection (column α: shape coordinate ``shape[α]``).
    Gamma : sympy Matrix l×d (d = 0: principally kinematic).
    structure : numpy array l×l×l of the bracket's constants, ``structure[k, i, j]`` = c^k_ij.
    classification : the Table 2.1 class of the model.
    system : the model's System (parameters, units).
    """

    fiber: tuple
    shape: tuple
    A: sp.Matrix
    Gamma: sp.Matrix
    structure: np.ndarray
    classification: str
    system: Any

    def column(self, name: str) -> sp.Matrix:
        """A_α, the column of A of the shape coordinate ``name`` (l×1)."""
        return self.A[:, self._index(name)]

    def bracket(self, u, v) -> sp.Matrix:
        """[u, v] of two Lie algebra elements (l×1 sympy), by :attr:`structure`."""
        c = self.structure
        l = len(self.fiber)
        return sp.Matrix([sum(sp.nsimplify(c[k, i, j]) * u[i] * v[j]
                              for i in range(l) for j in range(l) if c[k, i, j] != 0) for k in range(l)])

    def _index(self, name: str) -> int:
        if name not in self.shape:
            raise ModelError([f"{name!r} is not a shape coordinate of {self.system.name} "
                              f"(shape: {', '.join(self.shape) or 'none'})"],
                             title="invalid shape coordinate")
        return self.shape.index(name)


def structure_constants(g: sp.Matrix, s: list) -> np.ndarray:
    """c^k_ij of the group whose left-invariant fields are the columns of ``g`` (l×l, in the
    fibre coordinates ``s``); a ModelError when they are not constant (g is no group frame)."""
    l = g.shape[0]
    c = np.zeros((l, l, l))
    ginv = g.inv() if g != sp.eye(l) else g
    J = [g[:, i].jacobian(s) for i in range(l)]      # a frame turning with the shape: constant in s
    for i in range(l):
        for j in range(i + 1, l):
            vec = sp.simplify(ginv * (J[j] * g[:, i] - J[i] * g[:, j]))
            if vec.free_symbols:
                raise ModelError([f"the fibre frame's bracket [e_{i}, e_{j}] = {list(vec)} is not constant"],
                                 title="fibre is not a group")
            c[:, i, j] = np.array([float(x) for x in vec])
            c[:, j, i] = -c[:, i, j]
    return c


#: the fibre configurations (one row each, the first l entries) where
#: :func:`numeric_structure_constants` evaluates the bracket, and the spread between them
#: (relative to max |c|) it accepts as constant
_SAMPLES = np.array([[0.31, -0.72, 1.13, 0.57, -1.41, 0.88], [-1.07, 0.46, -0.29, 1.62, 0.21, -0.64],
                     [0.83, 1.37, -0.95, -0.18, 0.74, 1.26]])
_CONSTANT_RTOL = 1e-9


def numeric_structure_constants(g: sp.Matrix, s: list) -> np.ndarray:
    """:func:`structure_constants` by numbers: c^k_ij = (g⁻¹((∂X_j/∂s)X_i − (∂X_i/∂s)X_j))_k at
    three fibre configurations, the same to :data:`_CONSTANT_RTOL` (relative to max |c|) — no
    symbolic inverse or simplification (a plan's figures and checks). Where g has symbols
    other than ``s``, is singular at a sample, has more than six fibre coordinates or gives
    different constants, the symbolic :func:`structure_constants` decides (and names the problem)."""
    l = g.shape[0]
    if g == sp.eye(l):
        return np.zeros((l, l, l))
    if not g.free_symbols <= set(s) or len(s) > _SAMPLES.shape[1]:
        return structure_constants(g, s)
    frame = sp.lambdify(s, [g, *(g[:, i].jacobian(s) for i in range(l))], "numpy")
    found = []
    for point in _SAMPLES[:, :len(s)]:
        G, *J = (np.asarray(m, float) for m in frame(*point))
        c = np.zeros((l, l, l))
        try:
            for i in range(l):
                for j in range(i + 1, l):
                    c[:, i, j] = np.linalg.solve(G, J[j] @ G[:, i] - J[i] @ G[:, j])
                    c[:, j, i] = -c[:, i, j]
        except np.linalg.LinAlgError:
            return structure_constants(g, s)
        found.append(c)
    spread = max(float(np.max(np.abs(c - found[0]))) for c in found)
    if spread > _CONSTANT_RTOL * max(1.0, float(np.max(np.abs(found[0])))):
        return structure_constants(g, s)
    return found[0]


def local_connection(model) -> LocalConnection:
    """A(r), Γ(r) and the bracket of a :class:`~nhgait.dynamics.derivation.reduction.ReducedODE`:
    the explicit form's step 5 as it stands, the implicit form's step 5 run again on sympy."""
    layout = model.layout
    step5 = next(s for s in model.steps if s.number == 5)
    A, Gamma = step5.items.get("A"), step5.items.get("Gamma")
    if not isinstance(A, sp.MatrixBase) or not isinstance(Gamma, sp.MatrixBase):
        A, Gamma = _step5_in_sympy(layout)
    s = [layout.system.q[i] for i in layout.si]
    l, m = len(layout.si), len(layout.free)
    A = sp.Matrix(A) if m else sp.zeros(l, 0)
    Gamma = sp.Matrix(Gamma) if layout.d else sp.zeros(l, 0)
    shape = tuple(model.system.coordinates[i] for i in layout.free)
    return LocalConnection(fiber=tuple(layout.fiber), shape=shape,
                           A=A, Gamma=Gamma, structure=structure_constants(sp.Matrix(layout.g), s),
                           classification=model.classification, system=model.system)


def _step5_in_sympy(layout):
    """Step 5 (eq. 2.47) run on the sympy back end: (A, Γ = e K_Ω⁻¹) as sympy matrices."""
    from ..derivation.reduction import connection as steps_4_8
    from ..derivation.reduction.pipeline import arithmetic_for
    arith = arithmetic_for("sympy", layout)
    _, rec = steps_4_8.reconstruction(arith, layout, layout.symbols())
    l, m, d = len(layout.si), len(layout.free), layout.d
    A = arith.show(rec.A, l, m) if m else sp.zeros(l, 0)
    Gamma = (arith.show(rec.e, l, d) * arith.show(rec.K_nh_inv, d, d)) if d else sp.zeros(l, 0)
    return sp.Matrix(A).applyfunc(sp.cancel), sp.Matrix(Gamma).applyfunc(sp.cancel)


@dataclass(frozen=True, eq=False)
class NumericConnection:
    """A(q) from a model's compiled basis, parameters bound (module docstring).

    ``names``: the coordinates q; ``fiber_index``, ``shape_index``: positions of s and r in q;
    ``structure`` as in
    :class:`LocalConnection`; ``frame(q)`` is g(s) (l×l), ``A(q)`` the l×m local connection."""

    fiber: tuple
    shape: tuple
    names: tuple
    fiber_index: tuple
    shape_index: tuple
    structure: np.ndarray
    basis: Any
    g_function: Any
    params: np.ndarray
    n_momenta: int

    def A(self, q) -> np.ndarray:
        """A at the configuration ``q`` (n), from X = basis(q): A = −g⁻¹ X[s rows, shape columns]."""
        q = np.asarray(q, float)
        z = np.concatenate([q, np.zeros(self.n_momenta + len(self.shape))])
        X = np.asarray(self.basis(z, self.params))
        Xs = X[np.ix_(self.fiber_index, range(X.shape[1] - len(self.shape), X.shape[1]))]
        return -np.linalg.solve(self.frame(q), Xs)

    def A_many(self, q_samples) -> np.ndarray:
        """A at each column of ``q_samples`` (n×K), as a (K, l, m) array, in one mapped call of
        the basis (:meth:`A` at each column, to rounding): A = −g(s)⁻¹ X[s rows, shape columns],
        g evaluated once per distinct fibre configuration s (it depends on s only)."""
        q = np.asarray(q_samples, float)
        K, m, l = q.shape[1], len(self.shape), len(self.fiber)
        Z = np.vstack([q, np.zeros((self.n_momenta + m, K))])
        X = np.asarray(self.basis.map(K)(Z, self.params))          # n × (K·columns), sample by sample
        cols = X.shape[1] // K
        Xs = X[list(self.fiber_index)].reshape(l, K, cols)[:, :, cols - m:].transpose(1, 0, 2)
        _, first, which = np.unique(q[list(self.fiber_index)].T, axis=0, return_index=True,
                                    return_inverse=True)
        frames = np.stack([self.frame(q[:, k]) for k in first])[which.ravel()]
        return -np.linalg.solve(frames, Xs)

    def lift_sizes(self, q_samples) -> np.ndarray:
        """‖gA‖ (Frobenius) at each column of ``q_samples`` (n×K), in one mapped call of the
        basis: the size of the fibre velocity per unit shape velocity (= ‖A‖ when g is a rotation)."""
        q = np.asarray(q_samples, float)
        K, m = q.shape[1], len(self.shape)
        Z = np.vstack([q, np.zeros((self.n_momenta + m, K))])
        X = np.asarray(self.basis.map(K)(Z, self.params))          # n × (K·columns), sample by sample
        cols = X.shape[1] // K
        blocks = X[list(self.fiber_index)].reshape(len(self.fiber_index), K, cols)[:, :, cols - m:]
        return np.sqrt(np.sum(blocks ** 2, axis=(0, 2)))

    def frame(self, q) -> np.ndarray:
        return np.asarray(self.g_function(*np.asarray(q, float), *self.params), float).reshape(
            len(self.fiber), len(self.fiber))

    def bracket(self, u, v) -> np.ndarray:
        return np.einsum("kij,i,j->k", self.structure, u, v)


def numeric_connection(model, params=None) -> NumericConnection:
    """:class:`NumericConnection` of a ReducedODE (or a specialised model's ``base``), with the
    parameter values ``params`` (default: the model's)."""
    layout = model.layout
    s = [layout.system.q[i] for i in layout.si]
    g = sp.Matrix(layout.g)
    values = np.asarray(model.numeric.params(params), float)
    nP = len(model.momenta)
    shape = tuple(model.system.coordinates[i] for i in layout.free)
    return NumericConnection(fiber=tuple(layout.fiber), shape=shape, names=tuple(model.system.coordinates),
                             fiber_index=tuple(layout.si), shape_index=tuple(layout.free),
                             structure=numeric_structure_constants(g, s), basis=model.numeric["basis"],
                             g_function=sp.lambdify([*layout.system.q, *layout.system.param_symbols], g,
                                                    "numpy"), params=values,
                             n_momenta=nP - len(layout.free))
