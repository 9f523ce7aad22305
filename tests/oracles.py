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
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["KaneOracle", "oracle", "ORACLE_NAMES", "kanes_method", "model_description", "agreement"]

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
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
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


def _board_with_wheels(x, y, th, psi, front_angle, back_angle, m, J, Jr, Jw, r):
    """Frames and bodies of a snakeboard-like robot: a board (mass m, inertia J) at (x, y)
    heading th, a rotor (Jr) at its centre turned by psi, massless wheel assemblies (Jw) on
    axles at ±r along the board heading th + front_angle and th + back_angle; the two
    no-sideslip constraints (back, front). Returns (N, B, R, F, K, bodies, constraints)."""
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, inertia
    N = ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])                   # board
    R = N.orientnew("R", "Axis", [th + psi, N.z])             # rotor
    F = N.orientnew("F", "Axis", [th + front_angle, N.z])     # front wheel assembly
    K = N.orientnew("K", "Axis", [th + back_angle, N.z])      # back wheel assembly
    O = Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", x * N.x + y * N.y)
    C.set_vel(N, C.pos_from(O).dt(N))
    Pf = C.locatenew("Pf", r * B.x)
    Pb = C.locatenew("Pb", -r * B.x)
    Pf.v2pt_theory(C, N, B)                                   # wheel axles are fixed on the board
    Pb.v2pt_theory(C, N, B)
    bodies = [RigidBody("board", C, B, m, (inertia(B, 0, 0, J), C)),
              RigidBody("rotor", C, R, 0, (inertia(R, 0, 0, Jr), C)),
              RigidBody("front", Pf, F, 0, (inertia(F, 0, 0, Jw), Pf)),
              RigidBody("back", Pb, K, 0, (inertia(K, 0, 0, Jw), Pb))]
    constraints = [Pb.vel(N).dot(K.y), Pf.vel(N).dot(F.y)]
    return N, B, R, F, K, bodies, constraints


def _model_snakeboard():
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols
    x, y, th, psi, ph = q = dynamicsymbols("x y theta psi phi")
    m, J, Jr, Jw, r = p = sp.symbols("m J J_r J_w r", positive=True)
    tau_psi, tau_phi = inp = sp.symbols("tau_psi tau_phi")
    N, B, R, F, K, bodies, constraints = _board_with_wheels(x, y, th, psi, ph, -ph, m, J, Jr, Jw, r)
    loads = [(R, tau_psi * N.z), (B, -tau_psi * N.z),        # rotor motor
             (F, tau_phi / 2 * N.z), (K, -tau_phi / 2 * N.z)]  # wheel coupling
    # (the board reaction of the wheel motor, -tau_phi/2 + tau_phi/2, is zero)
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp),
                bodies=bodies, loads=loads, constraints=constraints,
                dependent_sets=[(0, 1), (0, 2), (1, 2)])


def _model_chaplygin_sleigh():
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
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
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
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


def _model_cart_trailers(k, absolute=False):
    """A cart (axle midpoint (x, y), heading theta, centre of mass a ahead of the axle) on one
    driven wheel of radius rho at the axle (spin phi, inertia J_w about the axle), pulling k
    trailers: trailer i hangs on a hitch at the previous axle's midpoint, its axle l_t behind
    the hitch, its centre of mass c_t behind the hitch. Relative hitch angles beta_i, or (k = 1,
    ``absolute``) absolute headings theta0, theta1. Steering torque tau_theta on the cart,
    wheel torque tau_phi between wheel and cart."""
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    if absolute:
        x, y, th, th1, ph = q = dynamicsymbols("x y theta0 theta1 phi")
        headings = [th, th1]
    else:
        x, y, th, ph = dynamicsymbols("x y theta phi")
        betas = dynamicsymbols(" ".join(f"beta{i}" for i in range(1, k + 1))) if k else []
        betas = [betas] if k == 1 else list(betas)
        q = [x, y, th, ph] + betas
        headings = [th]
        for b_ in betas:
            headings.append(headings[-1] + b_)
    m, I, a, rho, Jw = cart = sp.symbols("m I a rho J_w", positive=True)
    mt, It, lt, ct = trailer = sp.symbols("m_t I_t l_t c_t", positive=True)
    params = list(cart) + (list(trailer) if k else [])
    tau_th, tau_ph = inp = sp.symbols("tau_theta tau_phi")
    N = ReferenceFrame("N")
    C = N.orientnew("C", "Axis", [headings[0], N.z])
    W = C.orientnew("W", "Axis", [ph, C.y])
    O = Point("O")
    O.set_vel(N, 0)
    axle = O.locatenew("P0", x * N.x + y * N.y)
    axle.set_vel(N, axle.pos_from(O).dt(N))
    G0 = axle.locatenew("G0", a * C.x)
    G0.v2pt_theory(axle, N, C)
    contact = axle.locatenew("Q", -rho * N.z)          # wheel contact point, fixed in W
    contact.v2pt_theory(axle, N, W)
    bodies = [RigidBody("cart", G0, C, m, (inertia(C, 0, 0, I), G0)),
              RigidBody("wheel", axle, W, 0, (inertia(W, 0, Jw, 0), axle))]
    constraints = [contact.vel(N).dot(C.y), contact.vel(N).dot(C.x)]
    prev_axle = axle
    for i in range(1, k + 1):
        T = N.orientnew(f"T{i}", "Axis", [headings[i], N.z])
        hitch = prev_axle                              # on-axle hitching
        ax = hitch.locatenew(f"P{i}", -lt * T.x)
        ax.v2pt_theory(hitch, N, T)
        G = hitch.locatenew(f"G{i}", -ct * T.x)
        G.v2pt_theory(hitch, N, T)
        bodies.append(RigidBody(f"trailer{i}", G, T, mt, (inertia(T, 0, 0, It), G)))
        constraints.append(ax.vel(N).dot(T.y))
        prev_axle = ax
    loads = [(C, tau_th * N.z), (W, tau_ph * C.y), (C, -tau_ph * C.y)]
    names = [qi.func.__name__ for qi in q]
    ind = (names.index("theta0" if absolute else "theta"), names.index("phi"))
    dep = tuple(i for i in range(len(q)) if i not in ind)
    return dict(N=N, q=list(q), params=params, inputs=list(inp), bodies=bodies, loads=loads,
                constraints=constraints, dependent_sets=[dep])


def _model_snake(n_links, rotor=False):
    """Wheeled snake: n_links links of length 2 l_s (mass m_s, inertia I_s about the centre),
    an axle with no side slip at each link's centre; (x, y) the head link's centre, theta its
    heading, alpha_j the joint angle between links j and j+1 (torque tau_alpha<j> between
    them); optionally a rotor on the head (inertia J_r, angle psi relative to the head,
    torque tau_psi)."""
    import itertools

    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    x, y, th = dynamicsymbols("x y theta")
    psi = dynamicsymbols("psi") if rotor else None
    alphas = [dynamicsymbols(f"alpha{j}") for j in range(1, n_links)]
    q = [x, y, th] + ([psi] if rotor else []) + alphas
    ms, Is, ls = sp.symbols("m_s I_s l_s", positive=True)
    params = [ms, Is, ls]
    if rotor:
        Jr = sp.Symbol("J_r", positive=True)
        params.append(Jr)
    taus = ([sp.Symbol("tau_psi")] if rotor else []) + [sp.Symbol(f"tau_alpha{j}") for j in range(1, n_links)]
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    frames = [N.orientnew("L1", "Axis", [th, N.z])]
    centre = O.locatenew("C1", x * N.x + y * N.y)
    centre.set_vel(N, centre.pos_from(O).dt(N))
    centres = [centre]
    for j in range(1, n_links):
        Lj = N.orientnew(f"L{j + 1}", "Axis", [th + sum(alphas[:j]), N.z])
        joint = centres[-1].locatenew(f"J{j}", -ls * frames[-1].x)
        joint.v2pt_theory(centres[-1], N, frames[-1])
        c = joint.locatenew(f"C{j + 1}", -ls * Lj.x)
        c.v2pt_theory(joint, N, Lj)
        frames.append(Lj)
        centres.append(c)
    bodies = [RigidBody(f"link{i + 1}", c, F, ms, (inertia(F, 0, 0, Is), c))
              for i, (c, F) in enumerate(zip(centres, frames, strict=True))]
    loads = []
    if rotor:
        R = frames[0].orientnew("R", "Axis", [psi, N.z])
        bodies.append(RigidBody("rotor", centres[0], R, 0, (inertia(R, 0, 0, Jr), centres[0])))
        loads += [(R, taus[0] * N.z), (frames[0], -taus[0] * N.z)]
    for j in range(1, n_links):
        tau = taus[j - 1 + (1 if rotor else 0)]
        loads += [(frames[j], tau * N.z), (frames[j - 1], -tau * N.z)]
    constraints = [c.vel(N).dot(F.y) for c, F in zip(centres, frames, strict=True)]
    k, n = n_links, len(q)
    free = [i for i in range(n) if i >= (4 if rotor else 3)]   # the joint angles
    fixed_ind = [3] if rotor else []
    dep_sets = []
    n_ind = n - k - len(fixed_ind)
    for ind in itertools.combinations(free + [2], n_ind):
        dep = tuple(i for i in range(n) if i not in ind and i not in fixed_ind)
        dep_sets.append(dep)
        if len(dep_sets) == 3:
            break
    return dict(N=N, q=q, params=params, inputs=taus, bodies=bodies, loads=loads,
                constraints=constraints, dependent_sets=dep_sets)


def _model_snakeboard_two_steering():
    """The snakeboard with independently steered wheels: front wheel heading theta + phi_f,
    back wheel heading theta + phi_b, torques tau_f, tau_b between each wheel and the board
    and tau_psi between rotor and board (issue 8's 6-coordinate reproduction case)."""
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols
    x, y, th, psi, pf, pb = q = dynamicsymbols("x y theta psi phi_f phi_b")
    m, J, Jr, Jw, r = p = sp.symbols("m J J_r J_w r", positive=True)
    tau_psi, tau_f, tau_b = inp = sp.symbols("tau_psi tau_f tau_b")
    N, B, R, F, K, bodies, constraints = _board_with_wheels(x, y, th, psi, pf, pb, m, J, Jr, Jw, r)
    loads = [(R, tau_psi * N.z), (B, -tau_psi * N.z), (F, tau_f * N.z), (B, -tau_f * N.z),
             (K, tau_b * N.z), (B, -tau_b * N.z)]
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp), bodies=bodies, loads=loads,
                constraints=constraints, dependent_sets=[(0, 1), (0, 2), (1, 2)])


def _family(name):
    """Builders of the scaling families' members by name (see experiments/scaling_systems.py)."""
    if name.startswith("cart_trailers_"):
        return lambda: _model_cart_trailers(int(name.rsplit("_", 1)[1]))
    if name == "cart_trailer_absolute":
        return lambda: _model_cart_trailers(1, absolute=True)
    if name == "snakeboard_two_steering":
        return _model_snakeboard_two_steering
    if name.startswith("snake_") and name[6:7].isdigit():
        parts = name.split("_")
        return lambda: _model_snake(int(parts[1]), rotor=name.endswith("_rotor"))
    return None


def _model_disc_height():
    """A thin disc rolling in 3-D with the height z of its centre kept as a coordinate: q = (x,
    y, z, yaw, lean, spin), (x, y) the point of the ground below the rim's lowest point, C its
    centre. The rim's lowest material point P does not move (three velocity constraints: the
    vertical one is the time derivative of the configuration constraint z = r cos(lean), given
    to KanesMethod as ``configuration_constraints``). A lean torque from the ground."""
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    x, y, z, yaw, lean, spin = q = dynamicsymbols("x y z yaw lean spin")
    m, r, g = p = sp.symbols("m r g", positive=True)
    tau = sp.Symbol("tau_lean")
    N = ReferenceFrame("N")
    I = ReferenceFrame("I")
    I.orient_body_fixed(N, (yaw, lean, 0), "zxy")
    D = I.orientnew("D", "Axis", (spin, I.y))
    O = Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", x * N.x + y * N.y + z * N.z + r * (I.z - I.z.dot(N.z) * N.z))
    C.set_vel(N, C.pos_from(O).dt(N))
    P = C.locatenew("P", -r * I.z)
    P.v2pt_theory(C, N, D)
    disc = RigidBody("disc", C, D, m, (inertia(I, m * r ** 2 / 4, m * r ** 2 / 2, m * r ** 2 / 4), C))
    loads = [(C, -m * g * N.z), (I, tau * I.x)]
    return dict(N=N, q=list(q), params=list(p), inputs=[tau], bodies=[disc], loads=loads,
                constraints=[P.vel(N).dot(N.x), P.vel(N).dot(N.y), P.vel(N).dot(N.z)],
                configuration=[z - r * sp.cos(lean)], dependent_sets=[(0, 1, 2)])


def _model_opty_bicycle():
    """opty's parallel-park car (gallery example plot_parallel_park.py): a bicycle model with the
    mass centre Ao at (x, y), yaw theta, front steer delta; the car A (m, I about Ao), the front
    wheel B at Pf = Ao + a A.x (m/6, I/32); the rear point Pr = Ao − b A.x and Pf do not slip
    sideways; the propulsion F at Pr along A.x and the steering torque T between A and B."""
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    x, y, th, de = q = dynamicsymbols("x y theta delta")
    m, I, a, b = p = sp.symbols("m I a b", positive=True)
    F, T = inp = sp.symbols("F T")
    N = ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [th, N.z])
    B = A.orientnew("B", "Axis", [de, A.z])
    O = Point("O")
    O.set_vel(N, 0)
    Ao = O.locatenew("Ao", x * N.x + y * N.y)
    Ao.set_vel(N, Ao.pos_from(O).dt(N))
    Pr = Ao.locatenew("Pr", -b * A.x)
    Pr.v2pt_theory(Ao, N, A)
    Pf = Ao.locatenew("Pf", a * A.x)
    Pf.v2pt_theory(Ao, N, A)
    bodies = [RigidBody("A", Ao, A, m, (inertia(A, 0, 0, I), Ao)),
              RigidBody("B", Pf, B, m / 6, (inertia(B, 0, 0, I / 32), Pf))]
    loads = [(Pr, F * A.x), (A, -T * B.z), (B, T * B.z)]
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp), bodies=bodies, loads=loads,
                constraints=[Pr.vel(N).dot(A.y), Pf.vel(N).dot(B.y)], dependent_sets=[(1, 2), (0, 2), (0, 1)])


def _model_opty_car3():
    """opty's three-body car (gallery examples plot_car_in_garage.py, plot_car_around_pylons.py):
    front point Pf at (x, y), car angle q0, front axle angle qf relative to the car; the body A0
    (m0, iZZ0 at Dmc = Pf − l/2 A0.y), the rear axle Ab = A0 (mb, iZZb at Pb = Pf − l A0.y), the
    front axle Af (mf, iZZf at Pf); Pb and Pf do not move along their axles (A0.x, Af.x); the
    drive force Fb at Pb along A0.y, the torque Tf on Af alone, friction −reibung·v at Dmc."""
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    x, y, q0, qf = q = dynamicsymbols("x y q0 qf")
    l, m0, mb, mf, i0, ib, i_f, mu = p = sp.symbols("l m0 mb mf iZZ0 iZZb iZZf reibung", positive=True)
    Fb, Tf = inp = sp.symbols("Fb Tf")
    N = ReferenceFrame("N")
    A0 = N.orientnew("A0", "Axis", [q0, N.z])
    Af = A0.orientnew("Af", "Axis", [qf, A0.z])
    O = Point("O")
    O.set_vel(N, 0)
    Pf = O.locatenew("Pf", x * N.x + y * N.y)
    Pf.set_vel(N, Pf.pos_from(O).dt(N))
    Pb = Pf.locatenew("Pb", -l * A0.y)
    Pb.v2pt_theory(Pf, N, A0)
    Dmc = Pf.locatenew("Dmc", -l / 2 * A0.y)
    Dmc.v2pt_theory(Pf, N, A0)
    bodies = [RigidBody("body0", Dmc, A0, m0, (inertia(A0, 0, 0, i0), Dmc)),
              RigidBody("bodyb", Pb, A0, mb, (inertia(A0, 0, 0, ib), Pb)),
              RigidBody("bodyf", Pf, Af, mf, (inertia(Af, 0, 0, i_f), Pf))]
    loads = [(Pb, Fb * A0.y), (Af, Tf * N.z), (Dmc, -mu * Dmc.vel(N))]
    return dict(N=N, q=list(q), params=list(p), inputs=list(inp), bodies=bodies, loads=loads,
                constraints=[Pb.vel(N).dot(A0.x), Pf.vel(N).dot(Af.x)], dependent_sets=[(0, 2), (1, 2)])


_MODELS = {
    "opty_bicycle": _model_opty_bicycle,
    "opty_car3": _model_opty_car3,
    "disc_height": _model_disc_height,
    "unicycle": _model_unicycle,
    "snakeboard": _model_snakeboard,
    "chaplygin_sleigh": _model_chaplygin_sleigh,
    "knife_edge_incline": _model_knife_edge_incline,
}


# --------------------------------------------------------------------------- #
# build
# --------------------------------------------------------------------------- #
def kanes_method(mdl: dict, dependent):
    """sympy's KanesMethod of a model description (``_MODELS[name]()``) with the speeds
    ``dependent`` (indices) dependent; ``kanes_equations`` already formed. Generalized speeds
    u_i = q̇_i. Used by the oracle and by the benchmarks that time KanesMethod."""
    from sympy.physics.mechanics import KanesMethod, dynamicsymbols, msubs
    q = mdl["q"]
    t = dynamicsymbols._t
    u = [dynamicsymbols(f"u_{qi.func.__name__}") for qi in q]
    kd = [qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)]
    cons = [msubs(c, dict(zip([qi.diff(t) for qi in q], u, strict=True))) for c in mdl["constraints"]]
    ind = [i for i in range(len(q)) if i not in dependent]
    configuration = mdl.get("configuration", [])     # with q_dependent: the last len(...) of dependent
    q_dep = [q[i] for i in dependent[len(dependent) - len(configuration):]] if configuration else []
    km = KanesMethod(mdl["N"], q_ind=[qi for qi in q if qi not in q_dep], q_dependent=q_dep,
                     configuration_constraints=configuration, u_ind=[u[i] for i in ind], kd_eqs=kd,
                     u_dependent=[u[i] for i in dependent], velocity_constraints=cons)
    km.kanes_equations(mdl["bodies"], mdl["loads"])
    return km


def model_description(name: str) -> dict:
    """The physical description (frames, bodies, loads, constraints) of oracle ``name``."""
    if name not in _MODELS:
        builder = _family(name)
        if builder is None:
            raise KeyError(f"unknown oracle {name!r}; choose from {ORACLE_NAMES} or a family member "
                           "(cart_trailers_<k>, cart_trailer_absolute, snake_<N>[_rotor])")
        _MODELS[name] = builder
    return _MODELS[name]()


def agreement(system, model, orc, count=100, seed=0) -> float:
    """Worst relative q̈ error of ``model`` against the oracle ``orc`` over ``count`` consistent
    states: of 1.2·count random configurations the 1/6 nearest the singular set (smallest
    singular measure) are dropped. Also checks the round trip q̇ → z → q̇ at each state."""
    num = model.numeric
    pv = system.param_vector()
    po = np.array([system.parameters[p] for p in orc.parameters])
    rng = np.random.default_rng(seed)
    drawn = rng.uniform(-1.2, 1.2, (count + count // 5, system.n))
    measure = np.array([num.call("singular", q, pv) for q in drawn])
    worst = 0.0
    for q in drawn[np.argsort(measure)[::-1][:count]]:   # the count farthest from the singular set
        qd = orc.consistent_qdot(q, rng.uniform(-1.0, 1.0, len(orc.independent)), po)
        u = rng.uniform(-2.0, 2.0, len(system.inputs))
        uo = np.array([u[system.inputs.index(i)] for i in orc.inputs])
        ref = orc.qddot(q, qd, uo, po)
        z = num.call("state", q, qd, pv)
        np.testing.assert_allclose(num.call("qdot", z, pv), qd, rtol=1e-9, atol=1e-9)
        got = num.call("qddot", 0.0, z, u, pv)
        worst = max(worst, float(np.max(np.abs(got - ref)) / max(1.0, np.max(np.abs(ref)))))
    return worst


def _build(name: str) -> KaneOracle:
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols, find_dynamicsymbols, kinetic_energy, msubs

    mdl = _MODELS[name]()
    N, q, params, inputs = mdl["N"], mdl["q"], mdl["params"], mdl["inputs"]
    n = len(q)
    t = dynamicsymbols._t
    qd = [qi.diff(t) for qi in q]
    u = [dynamicsymbols(f"u_{qi.func.__name__}") for qi in q]
    qd_to_u = dict(zip(qd, u, strict=True))

    # plain symbols for lambdify
    qs = sp.symbols([f"q_{i}" for i in range(n)])
    us = sp.symbols([f"v_{i}" for i in range(n)])
    to_plain = dict(zip(q, qs, strict=True))
    to_plain.update(dict(zip(u, us, strict=True)))

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
        km = kanes_method(mdl, dep)
        M = plain(km.mass_matrix)
        f = plain(km.forcing)
        assert M.shape == (n, n)
        assert f.shape == (n, 1)
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


@functools.cache
def oracle(name: str) -> KaneOracle:
    """The (cached, lazily built) Kane oracle for ``name`` (see ORACLE_NAMES)."""
    model_description(name)   # registers a family member
    return _build(name)
