"""Linearisation of the reduced ODE ż = f(z, u) about an equilibrium or a steady motion.

Coordinates: the reduced state z = (q, P) of the 20-step method (2n − k entries, no
multipliers, the constraints built in), linearised by automatic differentiation of
``model.numeric["jacobian"]`` (exact to rounding, no finite differences).

1. **Cyclic coordinates are left out.** A coordinate on which no right-hand side of the
   remaining states depends (the fibre coordinates x, y, heading, wheel angles — and a
   heading in the shape when the reduced equations do not read it) drifts along a steady
   motion; the states kept, K, are the smallest set containing the momenta and every
   coordinate their right-hand sides read (fixpoint over the dependence pattern of ∂f/∂z at
   z* and at random states around it). A = ∂f_K/∂z_K, B = ∂f_K/∂u at (z*, u*); the
   reference must be at rest in K: f_K(z*, u*) = 0 (else an error names the rates).
2. **Holonomic constraints** h(q) = 0 kept as coordinates: h is constant along every
   solution (ḣ = ∇h·q̇ is a constraint row), so ∇h_K A = 0 at z*: A maps into the tangent
   space ker ∇h_K and is restricted to it (one zero eigenvalue, "leaving the constraint
   surface", removed per constraint).
3. **The family of steady motions**: f(z*(V)) = 0 for every speed V, so A ∂z*/∂V = 0 — a zero
   eigenvalue that only says that a neighbouring speed is another steady motion. It is
   removed by passing to the quotient by ∂z*/∂V (A is block-triangular in a basis whose first
   vector is ∂z*/∂V).

The eigenvalues of what remains are the motion's: for the Whipple bicycle the four of the
benchmark's (lean, steer and their rates), for the rolling disc the lean–yaw pair and the
zero of the neighbouring steady turns. A mode is stable when Re λ < −τ, unstable when
Re λ > τ, neutral otherwise, with τ = 10⁻⁸·max(1, max |λ|) (rounding of the eigenvalues of
a non-normal A is far below).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .reference import STEADY, ReferenceMotion, reference_motion

__all__ = ["Linearisation", "Mode", "linearise", "STABLE", "UNSTABLE", "NEUTRAL", "verdict"]

STABLE, UNSTABLE, NEUTRAL = "stable", "unstable", "neutral"
#: |Re λ| ≤ TOLERANCE · max(1, max |λ|): neutral
TOLERANCE = 1e-8
#: a column of ∂f/∂z counts as a dependence when some entry exceeds this relative size
DEPENDENCE = 1e-11
#: random states around z* at which the dependence pattern is sampled
DEPENDENCE_SAMPLES = 3
#: states whose eigenvector entry is at least this fraction of the largest name a mode
MODE_SHARE = 0.3
#: a reference is at rest when |f_K(z*)| ≤ REST · (1 + |z*|) · max(1, |A|)
REST = 1e-9


@dataclass(frozen=True)
class Mode:
    """One eigenvalue λ of the linearisation and the states its eigenvector lives on
    (``states``: the coordinates, or else the momenta, whose entries are at least
    MODE_SHARE of the largest), its eigenvector in the order of ``Linearisation.states`` and
    its verdict (stable, unstable, neutral)."""

    eigenvalue: complex
    states: tuple
    vector: np.ndarray = field(repr=False)
    verdict: str

    def label(self) -> str:
        lam = self.eigenvalue
        value = f"{lam.real:+.14g}" if lam.imag == 0 else f"{lam.real:+.14g} {lam.imag:+.14g}i"
        return f"{value}  ({self.verdict}; {', '.join(self.states)})"


@dataclass(frozen=True)
class Linearisation:
    """ż_K ≈ A (z_K − z*_K) + B (u − u*) about a reference motion.

    Attributes
    ----------
    reference : :class:`~.reference.ReferenceMotion`.
    states : names of the states kept (K, in ``model.state_names`` order).
    inputs : input names (columns of B).
    A : (|K|, |K|); B : (|K|, m).
    cyclic : coordinates left out (they drift along the motion and no kept rate reads them).
    eigenvalues : eigenvalues after the restrictions of the module docstring, sorted by real
        part then imaginary part.
    modes : one :class:`Mode` per eigenvalue.
    removed : sentences saying which zero eigenvalues were taken out and why.
    tolerance : τ of the verdicts.
    """

    reference: ReferenceMotion
    coordinates: tuple
    states: tuple
    inputs: tuple
    A: np.ndarray = field(repr=False)
    B: np.ndarray = field(repr=False)
    cyclic: tuple
    eigenvalues: np.ndarray
    modes: tuple = field(repr=False)
    removed: tuple = ()
    tolerance: float = 0.0

    @property
    def stability(self) -> str:
        """unstable when a mode is, stable when every mode is, neutral otherwise."""
        return verdict(self.eigenvalues, self.tolerance)

    def to_text(self, *, matrices: bool = True) -> str:
        """A, B (when ``matrices``), the eigenvalues with their modes and the verdict."""
        lines = [f"linearised about the {self.reference.describe(self.coordinates)}",
                 f"  states kept: {', '.join(self.states)}"
                 + (f"; cyclic (drifting, left out): {', '.join(self.cyclic)}" if self.cyclic else "")]
        if matrices:
            lines += ["  A =", _matrix_text(self.A, self.states, self.states)]
            if self.inputs:
                lines += ["  B =", _matrix_text(self.B, self.states, self.inputs)]
        lines += [f"  {sentence}" for sentence in self.removed]
        lines.append(f"  eigenvalues ({len(self.eigenvalues)}; {self.stability}):")
        lines += [f"    {mode.label()}" for mode in self.modes]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready: ``eigenvalues`` as [re, im] pairs, A and B as nested lists."""
        ref = self.reference
        return {"reference": {"kind": ref.kind, "speed": ref.speed,
                              "q": dict(zip(self.coordinates, ref.q.tolist(), strict=True)),
                              "qdot": dict(zip(self.coordinates, ref.qdot.tolist(), strict=True))},
                "states": list(self.states), "inputs": list(self.inputs), "cyclic": list(self.cyclic),
                "A": self.A.tolist(), "B": self.B.tolist(),
                "eigenvalues": [[float(v.real), float(v.imag)] for v in self.eigenvalues],
                "modes": [{"eigenvalue": [float(m.eigenvalue.real), float(m.eigenvalue.imag)],
                           "states": list(m.states), "verdict": m.verdict} for m in self.modes],
                "removed": list(self.removed), "stability": self.stability}


def verdict(eigenvalues, tolerance: float) -> str:
    """unstable / stable / neutral of a set of eigenvalues (see the module docstring)."""
    if not len(eigenvalues):
        return NEUTRAL
    top = float(np.max(np.real(eigenvalues)))
    return UNSTABLE if top > tolerance else STABLE if top < -tolerance else NEUTRAL


def linearise(model, *, speed=None, configuration=None, inputs=None, params=None,
              reference: ReferenceMotion | None = None) -> Linearisation:
    """Linearise a reduced ODE about an equilibrium (``speed`` None) or the straight steady
    motion at forward ``speed`` (see :func:`~.reference.reference_motion` for
    ``configuration``, ``inputs`` and ``params``; or pass a ``reference`` made before).

    Raises :class:`ModelError` when the model is not a reduced ODE or the reference is not at
    rest in the kept states.

    Examples
    --------
    The Chaplygin sleigh sliding straight at v = 1 m/s: its position and heading are cyclic,
    and a turning rate decays at λ = −m a v / (I_c + m a²) (centre of mass a ahead of the
    knife edge), the one eigenvalue left once the family of straight motions is removed:

    >>> from nhgait.dynamics import derive
    >>> from nhgait.dynamics.linearisation.linearised import linearise
    >>> lin = linearise(derive("chaplygin_sleigh"), speed=1.0)
    >>> lin.cyclic, lin.states
    (('x', 'y', 'theta'), ('p1', 'p2'))
    >>> m, I_c, a = 1.0, 0.2, 0.3                               # the scene's parameters
    >>> float(abs(lin.eigenvalues[0] - (-m * a * 1.0 / (I_c + m * a ** 2)))) < 1e-12
    True
    >>> lin.modes[0].verdict
    'stable'
    """
    if getattr(model, "formulation", None) != "reduced":
        raise ModelError(["linearisation works on the reduced ODE: derive(system, 'reduced') "
                          f"(got {getattr(model, 'formulation', type(model).__name__)})"],
                         title="invalid linearisation request")
    ref = reference or reference_motion(model, speed=speed, configuration=configuration,
                                        inputs=inputs, params=params)
    num = model.numeric
    J, Ju = _jacobians(num, ref.z, ref.u, ref.params)
    keep = kept_states(num, ref, model.system.n, J)
    names = tuple(model.state_names[i] for i in keep)
    A, B = J[np.ix_(keep, keep)], Ju[keep, :]
    _check_at_rest(num, ref, keep, names, A)
    basis, family, removed = _restriction(model, ref, keep, A)
    eigenvalues, vectors = _reduced_eigen(A, basis, family)
    tolerance = TOLERANCE * max(1.0, float(np.max(np.abs(eigenvalues), initial=0.0)))
    modes = tuple(_mode(lam, vec, names, model.system.n, keep, tolerance)
                  for lam, vec in zip(eigenvalues, vectors.T, strict=True))
    cyclic = tuple(model.state_names[i] for i in range(model.system.n) if i not in keep)
    return Linearisation(reference=ref, coordinates=tuple(model.system.coordinates), states=names,
                         inputs=tuple(model.system.inputs), A=A, B=B, cyclic=cyclic,
                         eigenvalues=eigenvalues, modes=modes, removed=tuple(removed), tolerance=tolerance)


def _jacobians(num, z, u, pv) -> tuple:
    J, Ju = num["jacobian"](0.0, z, u, pv)
    return np.asarray(J, dtype=float), np.asarray(Ju, dtype=float).reshape(len(z), -1)


def kept_states(num, ref: ReferenceMotion, n: int, J: np.ndarray) -> list:
    """Indices of K (module docstring, item 1), in state order."""
    rng = np.random.default_rng(0)
    pattern = _pattern(J)
    for _ in range(DEPENDENCE_SAMPLES):
        z = ref.z + 0.3 * rng.standard_normal(ref.z.size)
        with np.errstate(all="ignore"):
            sample = _jacobians(num, z, ref.u, ref.params)[0]
        if np.all(np.isfinite(sample)):
            pattern |= _pattern(sample)
    keep = set(range(n, ref.z.size))
    while True:
        reads = {j for i in keep for j in range(n) if pattern[i, j]}
        if reads <= keep:
            return sorted(keep)
        keep |= reads


def _pattern(J: np.ndarray) -> np.ndarray:
    """Which entries of ∂f/∂z are not rounding noise (relative to their row)."""
    scale = np.maximum(1.0, np.max(np.abs(J), axis=1, keepdims=True))
    return np.abs(J) > DEPENDENCE * scale


def _check_at_rest(num, ref, keep, names, A) -> None:
    """f_K(z*, u*) = 0, or one error naming the rates that are not."""
    f = np.asarray(num["rhs"](0.0, ref.z, ref.u, ref.params), dtype=float).ravel()[keep]
    limit = REST * (1.0 + float(np.max(np.abs(ref.z)))) * max(1.0, float(np.max(np.abs(A), initial=0.0)))
    moving = [f"d{name}/dt = {value:.6g}" for name, value in zip(names, f, strict=True)
              if not abs(value) <= limit]
    if moving:
        what = "a steady motion" if ref.kind == STEADY else "an equilibrium"
        raise ModelError([f"the reference is not {what}: {', '.join(moving)} (should be 0; tolerance "
                          f"{limit:.3g}); choose the configuration (--set q.<coordinate>=...) or the "
                          "inputs (--set inputs.<name>=...) that hold it"],
                         title="invalid linearisation request")


def _restriction(model, ref, keep, A) -> tuple:
    """(orthonormal basis (|K| × r) of the tangent space of the holonomic constraints in the
    kept states — item 2, the identity without them —, the family direction ∂z*/∂V in the kept
    states or None — item 3 —, the sentences saying what was removed)."""
    removed = []
    basis = np.eye(len(keep))
    system = model.system
    if system.holonomic:
        basis = _tangent_basis(system, ref, keep)
        removed.append(f"removed: λ = 0 of leaving the holonomic constraint surface "
                       f"({'; '.join(f'{h} = 0' for h in system.holonomic)}; {', '.join(system.dependent)} "
                       "follows the other coordinates)")
    family = None
    if ref.family is not None:
        d = ref.family[keep]
        scale = max(1.0, float(np.max(np.abs(A), initial=0.0))) * float(np.linalg.norm(d))
        if np.linalg.norm(d) > 0 and np.linalg.norm(A @ d) <= 1e-9 * scale:
            family = d
            removed.append("removed: λ = 0 along the family of straight steady motions (a "
                           "neighbouring speed)")
        else:
            removed.append("kept: the direction of a neighbouring speed is not a null vector of A here")
    return basis, family, removed


def _tangent_basis(system, ref, keep) -> np.ndarray:
    """Orthonormal basis of ker ∇h in the kept states (the momenta are free). ∇h reads only
    kept coordinates: h is a function of the shape, which the kept rates read."""
    from ..derivation.holonomic import constraint_gradient
    G = constraint_gradient(system, ref.q, ref.params)             # (c, n)
    n = system.n
    outside = [j for j in range(n) if j not in keep and np.any(G[:, j] != 0)]
    if outside:
        raise ModelError([f"the holonomic constraints read the cyclic coordinates "
                          f"{', '.join(system.coordinates[j] for j in outside)}"],
                         title="invalid linearisation request")
    G_K = np.zeros((G.shape[0], len(keep)))
    for col, state in enumerate(keep):
        if state < n:
            G_K[:, col] = G[:, state]
    _, sv, vt = np.linalg.svd(G_K)
    rank = int(np.sum(sv > 1e-12 * max(1.0, sv.max(initial=0.0))))
    if rank < G.shape[0]:
        raise ModelError(["the holonomic constraints are dependent at the reference configuration "
                          f"(rank {rank} of {G.shape[0]})"], title="invalid linearisation request")
    return vt[rank:].T


def _reduced_eigen(A: np.ndarray, basis: np.ndarray, family) -> tuple:
    """Eigenvalues and eigenvectors (in the kept states) of A restricted to span(basis), with
    the family direction quotiented out (items 2–3)."""
    Q = basis if family is None else _family_first(basis, family)
    R = Q.T @ A @ Q
    start = 0 if family is None else 1
    lam, W = np.linalg.eig(R[start:, start:])
    vectors = np.empty((Q.shape[0], lam.size), dtype=complex)
    for j in range(lam.size):
        w = W[:, j]
        if start:
            alpha = (R[0, 1:] @ w) / lam[j] if abs(lam[j]) > 0 else 0.0
            w = np.concatenate(([alpha], w))
        vectors[:, j] = Q @ w
    order = np.lexsort((lam.imag, lam.real))
    return lam[order], vectors[:, order]


def _family_first(basis: np.ndarray, d: np.ndarray) -> np.ndarray:
    """An orthonormal basis of span(basis) (orthonormal columns) whose first vector is the
    family direction ``d`` (which lies in it: a neighbouring speed keeps the configuration):
    d/|d|, then an orthonormal basis of the rest of span(basis) orthogonal to it."""
    d = basis @ (basis.T @ d)
    d = d / np.linalg.norm(d)
    rest = basis - np.outer(d, d @ basis)
    u, sv, _ = np.linalg.svd(rest, full_matrices=False)
    return np.column_stack([d, u[:, :basis.shape[1] - 1]])


def _mode(lam, vector, names, n, keep, tolerance) -> Mode:
    """The :class:`Mode` of one eigenpair."""
    v = np.abs(vector)
    coords = [i for i, state in enumerate(keep) if state < n]
    pick = coords if coords and v[coords].max() > 1e-9 * max(v.max(), 1e-300) else list(range(len(keep)))
    top = v[pick].max()
    states = tuple(names[i] for i in pick if v[i] >= MODE_SHARE * top)
    return Mode(complex(lam), states, vector, verdict([lam], tolerance))


def _matrix_text(M: np.ndarray, rows, columns) -> str:
    """A labelled matrix, 12 significant digits."""
    width = max(14, *(len(c) + 1 for c in columns))
    head = " " * 16 + "".join(f"{c:>{width}}" for c in columns)
    body = [f"    {r:<12}" + "".join(f"{v:>{width}.6g}" for v in row) for r, row in zip(rows, M, strict=True)]
    return "\n".join([head] + body)
