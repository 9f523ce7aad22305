"""Steps 2–3 of the 20-step method (thesis §3.2.2, Fig. 3.5, Table 3.1): the constraint
distribution D_q = null ω(q) and the full-symmetry-group test.

For every candidate set of fiber coordinates s ⊂ q (the rest r are shape coordinates):

* T_q Orb(q) = span{∂/∂s};
* S_q = D_q ∩ T_q Orb(q) = {v : v_r = 0, ω_s v_s = 0} (ω_s = the columns of ω for s);
* ξ = a basis of S_q written in the s-components (the Lie algebra element of eq. 3.8/3.68);
* the candidate is a symmetry if L and ω are invariant under the group acting on s: translations
  of s (identity g), or SE(2) on a planar frame (x, y, heading) ⊂ s times translations of the
  other fiber coordinates; checked exactly (identity) or numerically at random points (SE(2));
* rank ω_s = k in the thesis (D_q + T_q Orb = T_q Q); with rank ω_s < k the other constraints
  restrict the shape velocities (an extension: such candidates rank after those with rank k);
* verdict "full" when S_q ≠ 0 and every fiber coordinate moves in S_q (thesis: "a Lie algebra
  element made of a zero in one of the basis means that no motion is allowed in that
  direction", Remark 3.2). With S_q = 0 and l = k the candidate is principally kinematic
  (Table 2.1), accepted only when no full candidate exists.

Selection rule (documented in docs/reduction.md): fewest shape constraints k − rank ω_s first,
then a full candidate before a principally kinematic one, then smallest dimension l; ties go to the
candidate with fewer forced fiber coordinates, then to coordinate order.

How many candidates are tested
------------------------------
Up to :data:`FULL_TABLE_MAX_N` coordinates every one of the 2ⁿ − 1 subsets is a row of the
table (the thesis's Table 3.1, 255 rows at n = 8, a fraction of a second). Beyond, 2ⁿ grows out
of reach (n = 20: a million subsets), so:

* a ``fiber`` the user gives is tested alone (one row) — any n;
* otherwise only the subsets that can be symmetries are tested — translations of coordinates
  L and ω do not depend on, or SE(2) on the planar frame times such translations — by
  increasing size, stopping after the first size that holds a full candidate of the largest
  rank ω_s those coordinates allow (no larger set can come before it in the selection rule),
  and after :data:`MAX_CANDIDATES` candidates at most: past that budget the search says so and
  asks for the fiber (``fiber = [...]`` in ``[system]``) unless it already found an admissible
  one, which it then takes with a note.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import sympy as sp

from ..algebra.matrices import null_basis_adjugate, numeric_pivots
from ..errors import ModelError
from .system import System

#: verdict labels
FULL = "full"
KINEMATIC = "principally kinematic (S_q = 0)"


@dataclass(frozen=True, eq=False)
class Candidate:
    """One row of the symmetry table (thesis Table 3.1).

    The verdict comes from exact invariance checks and the numeric rank structure of ω_s;
    the symbolic columns ``xi`` (S_q in s-components) and ``S_q`` are computed on first access.
    """

    fiber: tuple[str, ...]          # s
    group: str                      # G, e.g. "R^3 (x, y, phi)" or "SE(2) (x, y, theta)"
    orbit_tangent: tuple[str, ...]  # T_q Orb = span{∂/∂s}
    rank: int                       # generic rank of ω_s
    invariant: bool
    verdict: str
    reason: str
    omega_s: sp.Matrix | None = field(default=None, repr=False)   # k×l columns of ω for s
    pivots: tuple = field(default=(), repr=False)
    indices: tuple = field(default=(), repr=False)
    n: int = 0
    rows: tuple | None = field(default=None, repr=False)   # independent rows of ω_s (rank < k)

    @property
    def admissible(self) -> bool:
        return self.verdict in (FULL, KINEMATIC)

    @cached_property
    def xi(self) -> sp.Matrix | None:
        """l×d basis of S_q in the s-components (None when rank ω_s < k)."""
        if self.omega_s is None:
            return None
        Ws = self.omega_s if self.rows is None else self.omega_s.extract(list(self.rows),
                                                                         list(range(len(self.fiber))))
        if Ws.shape[0] == 0:
            return sp.eye(len(self.fiber))
        return null_basis_adjugate(Ws, list(self.pivots))

    @cached_property
    def S_q(self) -> sp.Matrix | None:
        """n×d basis of S_q = D_q ∩ T_q Orb(q) (None when rank ω_s < k)."""
        xi = self.xi
        if xi is None:
            return None
        out = sp.zeros(self.n, xi.shape[1])
        for a, i in enumerate(self.indices):
            out[i, :] = xi[a, :]
        return out


#: largest k for which step 2 writes out a basis of D_q (k×k minors); larger: described only
DISTRIBUTION_MAX_K = 3
#: up to this many coordinates the symmetry table holds every subset (2ⁿ − 1 rows)
FULL_TABLE_MAX_N = 8
#: most candidate fibre sets the pruned search tests (about 1 ms each) before it asks for the fiber
MAX_CANDIDATES = 4000


@dataclass(frozen=True)
class SymmetryTest:
    """Result of steps 2–3: the candidate table, the chosen fiber and D_q (on first access)."""

    system: System = field(repr=False)
    candidates: tuple[Candidate, ...]
    chosen: Candidate
    chosen_by: str                   # "user" or "test"
    search: str = ""                 # how the candidates were found, when not all subsets were tested

    @cached_property
    def distribution(self):
        """n×(n−k) basis of D_q (entries k×k minors of ω) for k ≤ DISTRIBUTION_MAX_K; for
        larger k a sentence (the basis X of step 8 spans D_q)."""
        if self.system.k > DISTRIBUTION_MAX_K:
            return (f"null ω(q), dimension {self.system.n - self.system.k}: spanned by the columns "
                    f"of X (step 8); minors not expanded (k = {self.system.k})")
        return constraint_distribution(self.system)

    def __str__(self) -> str:
        return self.table_markdown()

    def table_markdown(self) -> str:
        """The table as Markdown (thesis Table 3.1 generated for this system)."""
        rows = ["| fibre coordinates | group G | T_q Orb(q) | rank ω_fibre | invariant | S_q | ξ | verdict |",
                "|---|---|---|---|---|---|---|---|"]
        for c in self.candidates:
            sq = "—" if c.S_q is None else ("{0}" if c.S_q.shape[1] == 0 else
                                            "span{" + ", ".join(_vec(c.S_q[:, j])
                                                                for j in range(c.S_q.shape[1])) + "}")
            xi = "—" if c.xi is None else ("0" if c.xi.shape[1] == 0 else
                                          "; ".join(_vec(c.xi[:, j]) for j in range(c.xi.shape[1])))
            mark = " **(chosen)**" if c is self.chosen else ""
            rows.append(f"| ({', '.join(c.fiber)}) | {c.group} | "
                        f"span{{{', '.join('∂/∂' + s for s in c.orbit_tangent)}}}"
                        f" | {c.rank} | {'yes' if c.invariant else 'no'} | {sq} | {xi} | {c.verdict}{mark}: "
                        f"{c.reason} |")
        if self.search:
            rows.append(f"\n{self.search}")
        return "\n".join(rows)


def _vec(v) -> str:
    return "(" + ", ".join(sp.sstr(e) for e in v) + ")"


def constraint_distribution(system: System) -> sp.Matrix:
    """Step 2: a basis (columns) of D_q = null ω(q), computed without divisions (entries are
    k×k minors of ω)."""
    W = system.omega()
    if system.k == 0:
        return sp.eye(system.n)
    piv = numeric_pivots(omega_samples(system, 1)[0])
    return null_basis_adjugate(W, piv)


def omega_samples(system: System, count: int, seed: int = 3) -> list:
    """ω(q) (k×n numpy arrays) at ``count`` random configurations, default parameters."""
    f = system.numeric_functions().omega
    pv = system.param_vector()
    out = []
    for qv in system.sample_configurations(count, seed):
        with np.errstate(all="ignore"):
            out.append(np.array(f(qv, pv), dtype=float).reshape(system.k, system.n))
    return out


def group_transform(system: System, fiber: tuple[str, ...], version: str) -> sp.Matrix:
    """The matrix g(q) (l×l) of the reconstruction ξ = g⁻¹ṡ.

    ``version`` "A": identity. "B": rotation by the planar heading on the (x, y) rows of s
    (thesis eqs. 3.34, 3.70); requires x and y in s.
    """
    l = len(fiber)
    g = sp.eye(l)
    if version == "A":
        return g
    pf = system.planar_frame
    if pf is None or pf[0] not in fiber or pf[1] not in fiber:
        raise ModelError([f"version B of the reconstruction needs a planar frame (x, y, heading) "
                          f"with x and y among the fiber coordinates {fiber}"])
    th = system.q[system.coordinates.index(pf[2])]
    i, j = fiber.index(pf[0]), fiber.index(pf[1])
    c, s = sp.cos(th), sp.sin(th)
    g[i, i], g[i, j], g[j, i], g[j, j] = c, -s, s, c
    return g


def _invariance(system: System, fiber: tuple[str, ...], free: set) -> tuple[bool, str, str]:
    """Is (L, ω) invariant under the group acting on the fiber? Returns (ok, group label, why).
    ``free``: the free symbols of M, ω and V."""
    s_syms = {system.q[system.coordinates.index(c)] for c in fiber}
    dep = sorted(s.name for s in s_syms & free)
    label = f"R^{len(fiber)} ({', '.join(fiber)})"
    if not dep:
        return True, label, f"L and ω do not depend on {', '.join(fiber)}"
    pf = system.planar_frame
    if pf is None or not set(pf) <= set(fiber):
        return False, label, f"L or ω depends on {', '.join(dep)}"
    others = [c for c in fiber if c not in pf]
    label = "SE(2) (" + ", ".join(pf) + ")" + (f" × R^{len(others)} ({', '.join(others)})" if others else "")
    # numeric SE(2) invariance: T(q) = blockdiag(R(heading) on x, y; identity elsewhere)
    n = system.n
    ix, iy, ih = (system.coordinates.index(c) for c in pf)
    M_f, W_f, V_f = system.numeric_functions()
    pv = system.param_vector()
    rng = np.random.default_rng(7)
    fib_idx = [system.coordinates.index(c) for c in fiber]

    def T(qv):
        Tm = np.eye(n)
        c, s = np.cos(qv[ih]), np.sin(qv[ih])
        Tm[np.ix_([ix, iy], [ix, iy])] = [[c, -s], [s, c]]
        return Tm

    for qv in system.sample_configurations(4, seed=11):
        q2 = qv.copy()
        q2[fib_idx] += rng.uniform(-2, 2, len(fib_idx))
        T1, T2 = T(qv), T(q2)
        A1 = T1.T @ np.array(M_f(qv, pv), float) @ T1
        A2 = T2.T @ np.array(M_f(q2, pv), float) @ T2
        if not np.allclose(A1, A2, rtol=1e-9, atol=1e-12):
            return False, label, "the kinetic energy is not SE(2)-invariant"
        if not np.isclose(float(V_f(qv, pv)), float(V_f(q2, pv)), rtol=1e-9, atol=1e-12):
            return False, label, "the potential is not SE(2)-invariant"
        if W_f is not None:
            B1 = np.array(W_f(qv, pv), float).reshape(system.k, n) @ T1
            B2 = np.array(W_f(q2, pv), float).reshape(system.k, n) @ T2
            r = np.linalg.matrix_rank(np.vstack([B1, B2]), tol=1e-9 * max(1, np.abs(B1).max()))
            if r != np.linalg.matrix_rank(B1, tol=1e-9 * max(1, np.abs(B1).max())):
                return False, label, "the constraint distribution is not SE(2)-invariant"
    return True, label, "L and ω are SE(2)-invariant (checked at random points)"


@dataclass(frozen=True, eq=False)
class _TestInputs:
    """What every candidate fiber set is tested against: the system, ω (sympy), ω at three
    sample configurations (numeric, ``omega_samples``) and the free symbols of M, ω and V."""

    system: System
    W: sp.Matrix
    W_samples: list
    free: set


def _locked(inputs: _TestInputs, idx, fiber, rank) -> list:
    """The fiber coordinates that never move within S_q (numeric null spaces of ω_s at the
    three sample configurations)."""
    k, size = inputs.system.k, len(idx)
    locked = list(fiber)
    if size == rank:
        return locked
    for w in inputs.W_samples:
        ws = w[:, idx] if k else np.zeros((0, size))
        _, sv, vt = np.linalg.svd(ws) if k else (None, np.zeros(0), np.eye(size))
        nullv = vt[rank:].T if k else np.eye(size)
        moving = np.abs(nullv).max(axis=1) > 1e-10 if nullv.size else np.zeros(size, bool)
        locked = [f for a, f in enumerate(fiber) if f in locked and not moving[a]]
    return locked


def _candidate(inputs: _TestInputs, idx) -> Candidate:
    """The candidate of the fiber coordinates with indices ``idx``: its rank, invariance,
    pivots and verdict (step 2's table row)."""
    system, W, Wn = inputs.system, inputs.W, inputs.W_samples
    n, k, size = system.n, system.k, len(idx)
    fiber = tuple(system.coordinates[i] for i in idx)
    rank = min(np.linalg.matrix_rank(w[:, idx], tol=1e-9 * max(1, np.abs(w).max())) if k else 0
               for w in Wn)
    inv, group, why_inv = _invariance(system, fiber, inputs.free)
    Ws = W[:, list(idx)] if k else sp.zeros(0, size)
    rows = None
    if k and rank < k:   # the other k − rank constraints restrict the shape velocities
        rows = tuple(numeric_pivots(Wn[0][:, idx].T))
    piv = (numeric_pivots(Wn[0][np.ix_(list(rows), list(idx))] if rows is not None else Wn[0][:, idx]) if k
           and rank else [])
    d = size - rank
    locked = _locked(inputs, idx, fiber, rank)
    if not inv:
        verdict, reason = "not a symmetry", why_inv
    elif d == 0:
        verdict, reason = KINEMATIC, f"l = rank ω_s = {rank}: no nonholonomic momentum, ξ = −A(r)ṙ"
    elif locked:
        verdict = "not full"
        reason = f"ξ vanishes along {', '.join(locked)}: no motion allowed there"
    else:
        verdict, reason = FULL, why_inv
    if verdict in (FULL, KINEMATIC) and rank < k:
        reason += f"; {k - rank} constraint(s) restrict the shape velocities"
    return Candidate(fiber=fiber, group=group, orbit_tangent=fiber, rank=rank, invariant=inv, verdict=verdict,
                     reason=reason, omega_s=Ws, pivots=tuple(piv), indices=tuple(idx), n=n, rows=rows)


def _choose(system: System, candidates: list, search: str = "") -> SymmetryTest:
    """Step 3: the user's fiber (refused when not admissible) or the best admissible candidate:
    most constraints in the fiber, full before kinematic, fewest fiber coordinates, fewest
    forced fiber coordinates, then the coordinates' order."""
    names = system.coordinates
    if system.fiber is not None:
        want = tuple(sorted(system.fiber, key=names.index))
        chosen = next(c for c in candidates if c.fiber == want)
        if not chosen.admissible:
            table = SymmetryTest(system, tuple(candidates), chosen, "user", search).table_markdown()
            raise ModelError([f"the fiber coordinates ({', '.join(want)}) do not give a full symmetry "
                              f"group: {chosen.verdict}: {chosen.reason}\n{table}"],
                             title="no full symmetry group")
        return SymmetryTest(system, tuple(candidates), chosen, "user", search)
    full = sorted((c for c in candidates if c.admissible), key=lambda c: _rank_key(system, c))
    if not full:
        table = (SymmetryTest(system, tuple(candidates), candidates[0], "test", search).table_markdown()
                 if candidates
                 else f"(no subset can be a symmetry: L or ω depends on every coordinate) {search}")
        raise ModelError(["no candidate group of fiber coordinates gives a full Lie algebra element "
                          "(and none is principally kinematic); the symmetry table:\n" + table],
                         title="no full symmetry group")
    return SymmetryTest(system, tuple(candidates), full[0], "test", search)


def _rank_key(system: System, c: Candidate) -> tuple:
    """The selection rule as a sort key (smallest first; see the module docstring)."""
    names = system.coordinates
    forced = {name for name, f in zip(names, system.tau, strict=True) if f != 0}
    return (system.k - c.rank, c.verdict != FULL, len(c.fiber), len(set(c.fiber) & forced),
            [names.index(f) for f in c.fiber])


def symmetry_test(system: System, M: sp.Matrix | None = None, *,
                  max_candidates: int = MAX_CANDIDATES) -> SymmetryTest:
    """Steps 2–3: D_q, the candidate table, and the chosen fiber (which candidates are tested:
    the module docstring; ``max_candidates`` bounds the pruned search).

    Raises :class:`ModelError` (with the table) when no candidate is admissible or when the
    user's fiber choice is not.
    """
    n, k = system.n, system.k
    W = system.omega()
    M = system.mass_matrix() if M is None else M
    V = system.potential()
    inputs = _TestInputs(system, W, omega_samples(system, 3, seed=5) if k else [np.zeros((0, n))] * 3,
                         set().union(M.free_symbols, W.free_symbols, V.free_symbols))
    if n <= FULL_TABLE_MAX_N:
        return _choose(system, [_candidate(inputs, idx) for size in range(1, n + 1)
                                for idx in itertools.combinations(range(n), size)])
    if system.fiber is not None:
        idx = tuple(sorted(system.coordinates.index(c) for c in system.fiber))
        return _choose(system, [_candidate(inputs, idx)],
                       f"n = {n} > {FULL_TABLE_MAX_N}: the given fiber is tested alone (no table of the "
                       f"2^{n} − 1 subsets)")
    candidates, search = _pruned_candidates(inputs, max_candidates)
    return _choose(system, candidates, search)


def _symmetry_sets(inputs: _TestInputs, size: int, plain: list) -> list:
    """The index sets of ``size`` coordinates that can be symmetries: subsets of ``plain`` (the
    coordinates L and ω do not depend on), or the planar frame with such a subset."""
    system = inputs.system
    sets = set(itertools.combinations(plain, size))
    if system.planar_frame is not None:
        frame = {system.coordinates.index(c) for c in system.planar_frame}
        others = [i for i in plain if i not in frame]
        if size >= len(frame):
            sets.update(tuple(sorted(frame | set(rest)))
                        for rest in itertools.combinations(others, size - len(frame)))
    return sorted(sets)


def _pruned_candidates(inputs: _TestInputs, budget: int) -> tuple[list, str]:
    """(the candidates tested, a sentence saying how) for n > FULL_TABLE_MAX_N without a given
    fiber: the module docstring's pruned search."""
    system = inputs.system
    n, k = system.n, system.k
    plain = [i for i, q in enumerate(system.q) if q not in inputs.free]
    columns = sorted(set(plain) | {system.coordinates.index(c) for c in (system.planar_frame or ())})
    best_rank = min((np.linalg.matrix_rank(w[:, columns], tol=1e-9 * max(1, np.abs(w).max())) if k
                     and columns else 0)
                    for w in inputs.W_samples)
    candidates, tested = [], 0
    for size in range(1, n + 1):
        level = _symmetry_sets(inputs, size, plain)
        if tested + len(level) > budget:
            return _over_budget(system, candidates, tested, size, budget)
        candidates += [_candidate(inputs, idx) for idx in level]
        tested += len(level)
        admissible = [c for c in candidates if c.admissible]
        if any(c.verdict == FULL and c.rank == best_rank for c in admissible):
            break
    return candidates, (f"n = {n} > {FULL_TABLE_MAX_N}: {tested} of the 2^{n} − 1 subsets tested (those "
                        f"that can be symmetries, up to {size} coordinates; no larger set comes first "
                        "in the rule)")


def _over_budget(system: System, candidates: list, tested: int, size: int, budget: int) -> tuple[list, str]:
    """The search stopped at ``budget``: the best admissible candidate so far, with a note, or
    an error asking for the fiber."""
    admissible = sorted((c for c in candidates if c.admissible), key=lambda c: _rank_key(system, c))
    if not admissible:
        raise ModelError([f"the symmetry search over {system.n} coordinates found no admissible "
                          "fibre among the "
                          f"{tested} candidate sets of up to {size - 1} coordinates, and testing "
                          f"sets of {size} would exceed {budget} candidates: name the fibre coordinates "
                          "in [system] (fiber = [...]; System(fiber=...))"],
                         title="symmetry search too large")
    return candidates, (f"n = {system.n} > {FULL_TABLE_MAX_N}: the search stopped after {tested} "
                        "candidate sets of up "
                        f"to {size - 1} coordinates (budget {budget}); the best found is taken — "
                        "name another fibre in [system] (fiber = [...]) to choose")
