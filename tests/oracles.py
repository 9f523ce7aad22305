"""Independent Kane's-method reference ("oracle") equations of motion.

Four nonholonomic systems are modelled here from their *physical* description
(frames, points, bodies, loads; the no-slip conditions are computed from point
velocities) with :class:`sympy.physics.mechanics.KanesMethod` using dependent
generalized speeds (``u_dependent`` + ``velocity_constraints``).  Nothing is
copied from a Lagrangian or a Pfaffian matrix of the main code base, so these
models can be used to cross-check the nhgait engine.

Conventions
-----------
* Generalized speeds are ``u_i = qdot_i`` for every coordinate, so
  ``qddot = udot``.
* ``KanesMethod.mass_matrix`` / ``forcing`` are ``[k_d; k_dnh]`` / ``-[f_d; f_dnh]``:
  the ``n - k`` dynamical equations for the independent speeds stacked on the
  ``k`` time-differentiated velocity constraints, i.e. an ``n x n`` linear
  system for all ``udot``.  These are lambdified once (with CSE) and solved
  numerically with ``numpy.linalg.solve``.
* Each oracle may hold several Kane models ("variants") that differ only in the
  choice of dependent speeds.  ``qddot`` evaluates the variant whose dependent
  block of the constraint Jacobian is best conditioned at the given ``q``
  (they all give the same accelerations where they are regular; the self-test
  checks that).  ``independent`` / ``consistent_qdot`` always refer to the
  first (primary) variant.

Primary independent speeds and singularities of ``consistent_qdot``
-----------------------------------------------------------------
* unicycle          : (theta, phi); never singular.
* snakeboard        : (theta, psi, phi); dependent (x, y), determinant
                      ``sin(2 phi)``: singular at phi = 0 (both wheels parallel,
                      theta_dot is then forced to 0) and phi = +-pi/2 (the two
                      constraints become linearly dependent - a genuine
                      singularity of the system).
* chaplygin_sleigh  : (x, theta); dependent y, ``y_dot = tan(theta) x_dot``;
                      singular at theta = +-pi/2.
* knife_edge_incline: (x, theta); dependent y; singular at theta = +-pi/2.
``qddot`` itself is regular wherever the constraints have full rank (it
switches to a better conditioned variant), i.e. everywhere except the snakeboard
at phi = +-pi/2.

Usage::

    from tests.oracles import oracle        # or ``from oracles import oracle``
    o = oracle("snakeboard")
    qd = o.consistent_qdot(q, qd_ind, params)
    qdd = o.qddot(q, qd, u, params)
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["KaneOracle", "oracle", "ORACLE_NAMES"]

ORACLE_NAMES = ("unicycle", "snakeboard", "chaplygin_sleigh", "knife_edge_incline")


# --------------------------------------------------------------------------- #
# numeric container
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class _Variant:
    independent_idx: tuple[int, ...]
    dependent_idx: tuple[int, ...]
    mass: Callable          # (q, u, inputs, params) -> (n, n), rows/cols in Kane order [ind, dep]
    forcing: Callable       # (q, u, inputs, params) -> (n, 1)


@dataclass(frozen=True)
class KaneOracle:
    name: str
    coordinates: tuple[str, ...]
    parameters: tuple[str, ...]
    inputs: tuple[str, ...]
    independent: tuple[str, ...]
    _variants: tuple = field(default=(), repr=False, compare=False)
    _residual: Callable = field(default=None, repr=False, compare=False)   # (q, u, p) -> (k,)
    _jacobian: Callable = field(default=None, repr=False, compare=False)   # (q, p) -> (k, n)
    _energy: Callable = field(default=None, repr=False, compare=False)     # (q, u, p) -> T

    # -- helpers ----------------------------------------------------------- #
    @property
    def dependent(self) -> tuple[str, ...]:
        """Names of the coordinates whose speeds are dependent (primary variant)."""
        return tuple(c for c in self.coordinates if c not in self.independent)

    def _check(self, q, qdot=None, u=None, params=None):
        n = len(self.coordinates)
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (n,):
            raise ValueError(f"{self.name}: q must have shape ({n},), got {q.shape}")
        out = [q]
        if qdot is not None:
            qdot = np.asarray(qdot, dtype=float).reshape(-1)
            if qdot.shape != (n,):
                raise ValueError(f"{self.name}: qdot must have shape ({n},), got {qdot.shape}")
            out.append(qdot)
        if u is not None:
            u = np.asarray(u, dtype=float).reshape(-1)
            if u.shape != (len(self.inputs),):
                raise ValueError(f"{self.name}: u must have shape ({len(self.inputs)},), got {u.shape}")
            out.append(u)
        if params is not None:
            params = np.asarray(params, dtype=float).reshape(-1)
            if params.shape != (len(self.parameters),):
                raise ValueError(
                    f"{self.name}: params must have shape ({len(self.parameters)},), got {params.shape}")
            out.append(params)
        return out

    def constraint_jacobian(self, q, params) -> np.ndarray:
        """A(q) with constraint_residual(q, qdot) = A(q) @ qdot (k x n)."""
        q, params = self._check(q, params=params)
        return np.asarray(self._jacobian(q, params), dtype=float).reshape(-1, len(self.coordinates))

    def _pick_variant(self, q, params) -> _Variant:
        if len(self._variants) == 1:
            return self._variants[0]
        # the rows of A are shared by all variants, so the smallest singular value
        # of the dependent block is a fair measure (np.linalg.cond is useless for
        # 1x1 blocks)
        A = self.constraint_jacobian(q, params)
        best, best_s = self._variants[0], -1.0
        for v in self._variants:
            s = np.linalg.svd(A[:, list(v.dependent_idx)], compute_uv=False)[-1]
            if s > best_s:
                best, best_s = v, s
        return best

    def _qddot_variant(self, v: _Variant, q, qdot, u, params) -> np.ndarray:
        M = np.asarray(v.mass(q, qdot, u, params), dtype=float)
        f = np.asarray(v.forcing(q, qdot, u, params), dtype=float).reshape(-1)
        udot_kane = np.linalg.solve(M, f)
        out = np.empty(len(self.coordinates))
        out[list(v.independent_idx + v.dependent_idx)] = udot_kane
        return out

    # -- public API -------------------------------------------------------- #
    def qddot(self, q, qdot, u, params) -> np.ndarray:
        """Accelerations of all coordinates, shape (n,), coordinate order.

        ``qdot`` must satisfy the velocity constraints (see consistent_qdot)."""
        q, qdot, u, params = self._check(q, qdot, u, params)
        return self._qddot_variant(self._pick_variant(q, params), q, qdot, u, params)

    def constraint_residual(self, q, qdot, params) -> np.ndarray:
        """The no-slip velocities (k,) exactly as passed to KanesMethod."""
        q, qdot, params = self._check(q, qdot, params=params)
        return np.asarray(self._residual(q, qdot, params), dtype=float).reshape(-1)

    def consistent_qdot(self, q, qdot_independent, params) -> np.ndarray:
        """Full qdot (n,) from the speeds of ``self.independent`` (in that order)."""
        q, params = self._check(q, params=params)
        qi = np.asarray(qdot_independent, dtype=float).reshape(-1)
        v = self._variants[0]
        if qi.shape != (len(v.independent_idx),):
            raise ValueError(f"{self.name}: qdot_independent must have shape "
                             f"({len(v.independent_idx)},), got {qi.shape}")
        A = self.constraint_jacobian(q, params)
        ind, dep = list(v.independent_idx), list(v.dependent_idx)
        qdot = np.zeros(len(self.coordinates))
        qdot[ind] = qi
        qdot[dep] = np.linalg.solve(A[:, dep], -A[:, ind] @ qi)
        return qdot

    def kinetic_energy(self, q, qdot, params) -> float:
        """Kinetic energy of the Kane model's bodies (sympy ``kinetic_energy``)."""
        q, qdot, params = self._check(q, qdot, params=params)
        return float(self._energy(q, qdot, params))


# --------------------------------------------------------------------------- #
# symbolic models
# --------------------------------------------------------------------------- #
def _model_unicycle():
    import sympy as sp
    from sympy.physics.mechanics import (Point, ReferenceFrame, RigidBody, dynamicsymbols,
                                         inertia)
    x, y, th, ph = q = dynamicsymbols("x y theta phi")
    m, r, Jphi, Jth = p = sp.symbols("m r J_phi J_theta", positive=True)
    tau_th, tau_ph = inp = sp.symbols("tau_theta tau_phi")

    N = ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [th, N.z])          # heading / yoke frame
    B = A.orientnew("B", "Axis", [ph, A.y])          # disc, spins about +A.y
    O = Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", x * N.x + y * N.y + r * N.z)   # disc centre, height r
    C.set_vel(N, C.pos_from(O).dt(N))
    P = C.locatenew("P", -r * A.z)                    # contact point, fixed in disc B
    P.v2pt_theory(C, N, B)
    disc = RigidBody("disc", C, B, m, (inertia(A, Jth, Jphi, Jth), C))
    constraints = [P.vel(N).dot(N.x), P.vel(N).dot(N.y)]
    loads = [(B, tau_th * N.z),      # heading torque from the ground
             (B, tau_ph * A.y),      # spin motor on the disc ...
             (A, -tau_ph * A.y)]     # ... reacting on the massless yoke
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp), bodies=[disc],
                loads=loads, constraints=constraints,
                dependent_sets=[(0, 1)])


def _model_snakeboard():
    import sympy as sp
    from sympy.physics.mechanics import (Point, ReferenceFrame, RigidBody, dynamicsymbols,
                                         inertia)
    x, y, th, psi, ph = q = dynamicsymbols("x y theta psi phi")
    m, J, Jr, Jw, r = p = sp.symbols("m J J_r J_w r", positive=True)
    tau_psi, tau_phi = inp = sp.symbols("tau_psi tau_phi")

    N = ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])          # board
    R = N.orientnew("R", "Axis", [th + psi, N.z])    # rotor
    F = N.orientnew("F", "Axis", [th + ph, N.z])     # front wheel assembly
    K = N.orientnew("K", "Axis", [th - ph, N.z])     # back wheel assembly
    O = Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", x * N.x + y * N.y)
    C.set_vel(N, C.pos_from(O).dt(N))
    Pf = C.locatenew("Pf", r * B.x)
    Pb = C.locatenew("Pb", -r * B.x)
    Pf.v2pt_theory(C, N, B)                          # wheel axles are fixed on the board
    Pb.v2pt_theory(C, N, B)
    board = RigidBody("board", C, B, m, (inertia(B, 0, 0, J), C))
    rotor = RigidBody("rotor", C, R, 0, (inertia(R, 0, 0, Jr), C))
    front = RigidBody("front", Pf, F, 0, (inertia(F, 0, 0, Jw), Pf))
    back = RigidBody("back", Pb, K, 0, (inertia(K, 0, 0, Jw), Pb))
    constraints = [Pb.vel(N).dot(K.y), Pf.vel(N).dot(F.y)]
    loads = [(R, tau_psi * N.z), (B, -tau_psi * N.z),        # rotor motor
             (F, tau_phi / 2 * N.z), (K, -tau_phi / 2 * N.z)]  # wheel coupling
    # (the board reaction of the wheel motor, -tau_phi/2 + tau_phi/2, is zero)
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp),
                bodies=[board, rotor, front, back], loads=loads, constraints=constraints,
                dependent_sets=[(0, 1), (0, 2), (1, 2)])


def _model_chaplygin_sleigh():
    import sympy as sp
    from sympy.physics.mechanics import (Point, ReferenceFrame, RigidBody, dynamicsymbols,
                                         inertia)
    x, y, th = q = dynamicsymbols("x y theta")
    m, Ic, a = p = sp.symbols("m I_c a", positive=True)
    Fin, tau = inp = sp.symbols("F tau")

    N = ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])
    O = Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)          # knife-edge contact point (in B)
    P.set_vel(N, P.pos_from(O).dt(N))
    G = P.locatenew("G", a * B.x)                    # centre of mass
    G.v2pt_theory(P, N, B)
    body = RigidBody("sleigh", G, B, m, (inertia(B, 0, 0, Ic), G))
    constraints = [P.vel(N).dot(B.y)]
    loads = [(P, Fin * B.x), (B, tau * N.z)]
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp), bodies=[body],
                loads=loads, constraints=constraints, dependent_sets=[(1,), (0,)])


def _model_knife_edge_incline():
    import sympy as sp
    from sympy.physics.mechanics import (Point, ReferenceFrame, RigidBody, dynamicsymbols,
                                         inertia)
    x, y, th = q = dynamicsymbols("x y theta")
    m, I, g, alpha = p = sp.symbols("m I g alpha", positive=True)
    tau = sp.Symbol("tau")
    inp = [tau]

    N = ReferenceFrame("N")                          # N.x down the slope, N.z plane normal
    B = N.orientnew("B", "Axis", [th, N.z])
    O = Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, P.pos_from(O).dt(N))
    body = RigidBody("skate", P, B, m, (inertia(B, 0, 0, I), P))
    constraints = [P.vel(N).dot(B.y)]                # -sin(th) xd + cos(th) yd
    loads = [(P, m * g * sp.sin(alpha) * N.x), (B, tau * N.z)]
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp), bodies=[body],
                loads=loads, constraints=constraints, dependent_sets=[(1,), (0,)])


_MODELS = {
    "unicycle": _model_unicycle,
    "snakeboard": _model_snakeboard,
    "chaplygin_sleigh": _model_chaplygin_sleigh,
    "knife_edge_incline": _model_knife_edge_incline,
}


# --------------------------------------------------------------------------- #
# build
# --------------------------------------------------------------------------- #
def _build(name: str) -> KaneOracle:
    import sympy as sp
    from sympy.physics.mechanics import KanesMethod, dynamicsymbols, kinetic_energy, msubs
    from sympy.physics.mechanics import find_dynamicsymbols

    mdl = _MODELS[name]()
    N, q, params, inputs = mdl["N"], mdl["q"], mdl["params"], mdl["inputs"]
    n = len(q)
    t = dynamicsymbols._t
    qd = [qi.diff(t) for qi in q]
    u = [dynamicsymbols(f"u_{qi.func.__name__}") for qi in q]
    qd_to_u = dict(zip(qd, u))
    kd = [qdi - ui for qdi, ui in zip(qd, u)]

    # plain symbols for lambdify
    qs = sp.symbols([f"q_{i}" for i in range(n)])
    us = sp.symbols([f"v_{i}" for i in range(n)])
    to_plain = dict(zip(q, qs))
    to_plain.update(dict(zip(u, us)))

    def plain(expr):
        e = msubs(sp.Matrix(expr), qd_to_u).xreplace(to_plain)
        left = find_dynamicsymbols(e) if hasattr(e, "free_symbols") else set()
        if left:
            raise RuntimeError(f"{name}: unresolved dynamicsymbols {left}")
        return e

    cons_u = [msubs(c, qd_to_u) for c in mdl["constraints"]]
    k = len(cons_u)
    cons_plain = plain(cons_u)
    jac_plain = cons_plain.jacobian(us)
    if sp.simplify(cons_plain - jac_plain * sp.Matrix(us)) != sp.zeros(k, 1):
        raise RuntimeError(f"{name}: constraints are not homogeneous-linear in the speeds")

    lam = functools.partial(sp.lambdify, modules="numpy", cse=True)
    residual = lam([qs, us, params], cons_plain)
    jacobian = lam([qs, params], jac_plain)
    T = kinetic_energy(N, *mdl["bodies"])
    energy = lam([qs, us, params], plain([T])[0])

    variants = []
    for dep in mdl["dependent_sets"]:
        ind = tuple(i for i in range(n) if i not in dep)
        km = KanesMethod(N, q_ind=q, u_ind=[u[i] for i in ind], kd_eqs=kd,
                         u_dependent=[u[i] for i in dep], velocity_constraints=cons_u)
        km.kanes_equations(mdl["bodies"], mdl["loads"])
        M = plain(km.mass_matrix)
        f = plain(km.forcing)
        assert M.shape == (n, n) and f.shape == (n, 1)
        variants.append(_Variant(
            independent_idx=ind, dependent_idx=tuple(dep),
            mass=lam([qs, us, inputs, params], M),
            forcing=lam([qs, us, inputs, params], f)))

    names = tuple(qi.func.__name__ for qi in q)
    return KaneOracle(
        name=name,
        coordinates=names,
        parameters=tuple(str(s) for s in params),
        inputs=tuple(str(s) for s in inputs),
        independent=tuple(names[i] for i in variants[0].independent_idx),
        _variants=tuple(variants),
        _residual=residual,
        _jacobian=jacobian,
        _energy=energy,
    )


@functools.lru_cache(maxsize=None)
def oracle(name: str) -> KaneOracle:
    """The (cached, lazily built) Kane oracle for ``name`` (see ORACLE_NAMES)."""
    if name not in _MODELS:
        raise KeyError(f"unknown oracle {name!r}; choose from {ORACLE_NAMES}")
    return _build(name)
