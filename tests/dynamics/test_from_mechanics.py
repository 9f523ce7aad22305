"""``System.from_mechanics`` against sympy.physics.mechanics' own objects (issue 43).

The reference of each test is the sympy object itself: its ``mass_matrix_full`` and
``forcing_full`` (KanesMethod, mechanics System) evaluated at 40 digits by mpmath, so the
reference's own round-off (2e-9 at some rolling-disc states in double precision) does not
count against nhgait. nhgait's reduced ODE, mapped to (q̇, q̈), must give the same state
derivatives to 1e-12 relative to max(1, |ref|) at random constraint-consistent states
(u_ind random, u_dep from the model's own velocity constraints).
"""
from __future__ import annotations

import mpmath
import numpy as np
import pytest
import sympy as sp
from oracles import kanes_method, model_description
from sympy.physics import mechanics as me
from sympy.physics.mechanics.tests.test_kane5 import _create_rolling_disc

from nhgait.dynamics import System, derive
from nhgait.dynamics.errors import ModelError

RTOL = 1e-12
DISC_VALUES = {"g": 9.81, "r": 0.26, "m": 3.43}     # sympy's test_kane5.py values


def _disc_kane():
    props = _create_rolling_disc()
    return KanesReference(me.KanesMethod(
        props["frame"], props["q_ind"], props["u_ind"], props["kdes"], u_dependent=props["u_dep"],
        velocity_constraints=props["fnh"], bodies=props["bodies"], forcelist=props["loads"]))


class KanesReference:
    """A KanesMethod (or mechanics System) evaluated at 40 digits: the state derivative
    (q̇, u̇) from its mass_matrix_full and forcing_full, q̈ = ∂q̇/∂q q̇ + ∂q̇/∂u u̇ from its
    kinematic differential equations, u_dep from its velocity constraints."""

    def __init__(self, method, inputs=()):
        self.method = method
        method._form_eoms() if isinstance(method, me.System) else method.kanes_equations()
        kane = method.eom_method if isinstance(method, me.System) else method
        self.q, self.u = list(kane.q), list(kane.u)
        free = kane.mass_matrix_full.free_symbols | kane.forcing_full.free_symbols
        self.params = sorted(free - {me.dynamicsymbols._t} - set(inputs), key=lambda s: s.name)
        self.inputs = list(inputs)
        qd = sp.Matrix([kane.kindiffdict()[qi.diff()] for qi in self.q])
        args = (self.q, self.u, self.inputs, self.params)
        lam = {"modules": "mpmath"}
        self.full = sp.lambdify(args, (kane.mass_matrix_full, kane.forcing_full), **lam)
        self.kin = sp.lambdify(args, (qd, qd.jacobian(self.q), qd.jacobian(self.u)), **lam)
        self.nh = sp.lambdify([self.q, self.params], kane._k_nh, **lam)
        self.n_dep = len(kane._udep)

    def state(self, rng, values):
        """(q, u) at random: q in [−1.2, 1.2], u_ind in [−1, 1], u_dep on the constraints."""
        p = [values[s.name] for s in self.params]
        q = rng.uniform(-1.2, 1.2, len(self.q))
        ui = rng.uniform(-1.0, 1.0, len(self.u) - self.n_dep)
        if not self.n_dep:
            return q, ui
        K = np.array(self.nh(q, p).tolist(), dtype=float)
        m = len(ui)
        return q, np.r_[ui, np.linalg.solve(K[:, m:], -K[:, :m] @ ui)]

    def derivatives(self, q, u, inputs, values):
        """(q̇, q̈) of the model at (q, u) (40 digits, returned as floats)."""
        p = [values[s.name] for s in self.params]
        with mpmath.workdps(40):
            M, F = self.full(q, u, inputs, p)
            xdot = mpmath.lu_solve(M, F)
            qd, Jq, Ju = self.kin(q, u, inputs, p)
            udot = mpmath.matrix([xdot[len(self.q) + i] for i in range(len(self.u))])
            qdd = Jq * qd + Ju * udot
        as_float = lambda m: np.array([float(x) for x in m])   # noqa: E731
        return as_float(qd), as_float(qdd)


def _worst(system, reference, values, count=40, seed=0):
    """Largest relative difference of q̇ and q̈ between nhgait's reduced ODE and the reference."""
    num = derive(system, "reduced").numeric
    pv = system.param_vector()
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(count):
        q, u = reference.state(rng, values)
        inputs = rng.uniform(-2.0, 2.0, len(reference.inputs))
        qd, qdd = reference.derivatives(q, u, inputs, values)
        ours = np.array([inputs[[s.name for s in reference.inputs].index(n)] for n in system.inputs])
        z = num.call("state", q, qd, pv)
        got_qd = np.asarray(num.call("qdot", z, pv), float).ravel()
        got_qdd = np.asarray(num.call("qddot", 0.0, z, ours, pv), float).ravel()
        worst = max(worst, np.abs(got_qd - qd).max() / max(1.0, np.abs(qd).max()),
                    np.abs(got_qdd - qdd).max() / max(1.0, np.abs(qdd).max()))
    return worst


def test_rolling_disc_kanes_method_through_from_mechanics():
    """sympy's rolling disc (test_kane5.py: speeds u1..u3 the body-frame angular velocity, not
    q̇; the centre's velocity stated as ω × r): nhgait's reduced ODE = KanesMethod's, 1e-12."""
    reference = _disc_kane()
    system = System.from_mechanics(reference.method, DISC_VALUES, name="disc")
    assert system.coordinates == ("q1", "q2", "q3", "q4", "q5") and system.k == 2
    assert system.inputs == ()
    worst = _worst(system, reference, DISC_VALUES)
    assert worst < RTOL, f"max relative (q̇, q̈) error {worst:.3g}"


def test_rolling_disc_as_a_mechanics_system():
    """The same disc as a sympy.physics.mechanics.System (its fixed point is the origin)."""
    props = _create_rolling_disc()
    sys_ = me.System(props["frame"], _fixed_point(props))
    sys_.add_coordinates(*props["q_ind"])
    sys_.add_speeds(*props["u_ind"])
    sys_.add_speeds(*props["u_dep"], independent=False)
    sys_.add_kdes(*props["kdes"])
    sys_.add_nonholonomic_constraints(*props["fnh"])
    sys_.add_bodies(*props["bodies"])
    sys_.add_loads(*props["loads"])
    system = System.from_mechanics(sys_, DISC_VALUES)
    reference = KanesReference(sys_)
    assert _worst(system, reference, DISC_VALUES, count=15, seed=1) < RTOL


def _fixed_point(props):
    """The ground's mass centre of the disc model: the point whose velocity was set to 0."""
    todo, seen = [props["bodies"][0].masscenter], set()
    while todo:
        point = todo.pop()
        if point not in seen:
            seen.add(point)
            if point._vel_dict.get(props["frame"]) == 0:
                return point
            todo.extend(point._pos_dict)
    raise AssertionError("the disc model has no fixed point")


SNAKEBOARD = {"m": 1.0, "J": 0.5, "J_r": 0.3, "J_w": 0.05, "r": 1.2}


def test_snakeboard_written_with_kanes_method():
    """A snakeboard written with KanesMethod (tests/oracles.py's physical description: board,
    rotor, two wheel assemblies, the no-sideslip velocities of the axles; inputs τ_ψ, τ_φ):
    through from_mechanics, nhgait's reduced ODE = the KanesMethod's, 1e-12."""
    km = kanes_method(model_description("snakeboard"), (0, 1))
    system = System.from_mechanics(km, SNAKEBOARD, name="board")
    assert system.inputs == ("tau_phi", "tau_psi")
    assert system.k == 2 and set(system.planar_frame) == {"x", "y", "theta"}
    tau = [sp.Symbol("tau_psi"), sp.Symbol("tau_phi")]
    reference = KanesReference(km, inputs=tau)        # |φ| ≤ 1.2: off the singular set φ = ±π/2
    assert _worst(system, reference, SNAKEBOARD, count=30) < RTOL


def test_lagranges_method_with_nonholonomic_constraints():
    """A Chaplygin sleigh as LagrangesMethod (L and the knife-edge constraint given): its
    System has that L and constraint, and its reduced ODE equals LagrangesMethod's q̈."""
    x, y, th = q = me.dynamicsymbols("x y theta")
    m, I, a = sp.symbols("m I a")
    F = sp.Symbol("F")
    t = me.dynamicsymbols._t
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])
    O = me.Point("O")
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, P.pos_from(O).dt(N))
    G = P.locatenew("G", a * B.x)
    G.v2pt_theory(P, N, B)
    L = m / 2 * G.vel(N).dot(G.vel(N)) + I / 2 * th.diff(t) ** 2
    lm = me.LagrangesMethod(L, q, forcelist=[(P, F * B.x)], frame=N,
                            nonhol_coneqs=[P.vel(N).dot(B.y)])
    values = {"m": 2.0, "I": 0.3, "a": 0.4}
    system = System.from_mechanics(lm, values)
    assert system.inputs == ("F",) and system.k == 1
    lm.form_lagranges_equations()
    subs = {m: 2.0, I: 0.3, a: 0.4}
    rhs = sp.lambdify([q, [qi.diff(t) for qi in q], [F]], lm.rhs().xreplace(subs), "numpy")
    num = derive(system, "reduced").numeric
    pv = system.param_vector()
    rng = np.random.default_rng(2)
    for _ in range(10):
        qq = rng.uniform(-1.2, 1.2, 3)
        v = rng.uniform(-1, 1)
        qd = np.array([v * np.cos(qq[2]), v * np.sin(qq[2]), rng.uniform(-1, 1)])
        f = rng.uniform(-2, 2)
        ref = np.asarray(rhs(qq, qd, [f]), float).ravel()[3:6]
        z = num.call("state", qq, qd, pv)
        got = np.asarray(num.call("qddot", 0.0, z, [f], pv), float).ravel()
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)


def test_a_point_set_fixed_that_moves_is_refused():
    """sympy's other rolling disc (test_kane.py) is written from the contact point up with the
    contact point's velocity set to 0 and no coordinates for where it is: its configuration
    does not determine the centre's velocity; refused, not converted into a wrong system."""
    q1, q2, q3, u1, u2, u3 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3")
    r, m, g = sp.symbols("r m g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, 0)
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    kd = [me.dot(R.ang_vel_in(N) - w_R_N_qd, uv) for uv in L]
    body = me.RigidBody("BodyD", Dmc, R, m, (me.inertia(L, m / 4 * r**2, m / 2 * r**2, m / 4 * r**2), Dmc))
    km = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd)
    km.kanes_equations([body], [(Dmc, -m * g * Y.z)])
    with pytest.raises(ModelError, match=r"velocity of Dmc stated in the model is not the time derivative"):
        System.from_mechanics(km, {"r": 1.0, "m": 1.0, "g": 9.81})


def test_missing_values_and_wrong_objects_are_one_clear_error():
    reference = _disc_kane()
    with pytest.raises(ModelError, match=r"m, r appear in the kinetic energy.*give them in parameters"):
        System.from_mechanics(reference.method, {"g": 9.81})
    with pytest.raises(ModelError, match=r"expected a KanesMethod, a LagrangesMethod or a "
                                         r"sympy.physics.mechanics.System, got str"):
        System.from_mechanics("disc", DISC_VALUES)


def test_dynamicsymbols_as_coordinates():
    """System(coordinates=[x(t), …]) with x(t)' in L, the constraint and the forces is the
    System stated with names and strings (the string parser is the reference)."""
    x, y, th = me.dynamicsymbols("x y theta")
    t = me.dynamicsymbols._t
    m, I = sp.symbols("m I")
    F = sp.Symbol("F")
    xd, yd, thd = (c.diff(t) for c in (x, y, th))
    ours = System(coordinates=[x, y, th], lagrangian=m / 2 * (xd**2 + yd**2) + I / 2 * thd**2,
                  constraints=[-sp.sin(th) * xd + sp.cos(th) * yd],
                  forces={x: F * sp.cos(th), y: F * sp.sin(th)},
                  parameters={"m": 1.0, "I": 0.5}, name="sleigh")
    text = System(coordinates=["x", "y", "theta"], lagrangian="m/2*(x_dot**2 + y_dot**2) + I/2*theta_dot**2",
                  constraints=["-sin(theta)*x_dot + cos(theta)*y_dot"],
                  forces={"x": "F*cos(theta)", "y": "F*sin(theta)"}, parameters={"m": 1.0, "I": 0.5},
                  name="sleigh")
    assert ours.canonical_text() == text.canonical_text()


def test_a_dynamicsymbol_expression_is_named_once_in_the_refusal():
    x = me.dynamicsymbols("x")
    with pytest.raises(ModelError) as exc:
        System(coordinates=[x**2], lagrangian="0")
    message = str(exc.value)
    assert "got the sympy expression x(t)**2" in message and "x x(t)" not in message
