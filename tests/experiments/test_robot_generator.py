"""The robot-and-task generator of issue 24 (experiments/robot_generator.py): its physics against
the independent KanesMethod oracle, its tasks, and the determinism of its seed.

The oracle of a generated robot is built here from the robot's description alone — frames
oriented about N.z by their headings, points located with ``Point.locatenew`` and moved by
``pos_from(O).dt(N)`` (sympy.physics.vector's own kinematics), rigid bodies, the wheels'
no-side-slip speeds ``P.vel(N).dot(F.y)``, the loads as torques on frames and forces on points (a
slider's force on the slider and, reversed, on the body point it slides past, whose velocity is
``v2pt_theory``) — and handed to ``KanesMethod`` (as tests/oracles.py builds its models), the
contact-point speeds kept as rows with multipliers (see ``_KaneMultiplierOracle``). The
scene text (Lagrangian written from positions by hand-rolled differentiation, constraints as
n(h)·v_P) goes through nhgait's parser and the 20-step reduction. At random consistent states
off the singular set, q̈ of the reduced ODE equals the oracle's to 1e-9 relative; so does q̈ of
the benchmark's independent transcription (experiments/reference_dae_ocp.py: the Lagrange DAE
built in CasADi from the same description).
"""
from functools import cache

import experiment_scripts
import numpy as np
import pytest

gen = experiment_scripts.load("robot_generator")

RTOL = 1e-9
#: (family, seed, index): two or three robots of each family, of a size the oracle builds in seconds;
#: between them every convention of the family (base link, angle sign or absolute headings,
#: rotor, number of trailers / sliders, base point) — the three chains of 5–6 coordinates hold
#: the three base links, the three angle conventions and the rotor
CASES = [("chain", 11, 0), ("chain", 27, 0), ("chain", 38, 0),
         ("car", 11, 0), ("car", 9, 0), ("car", 6, 0),
         ("sleigh", 1, 0), ("sleigh", 8, 0), ("snakeboard", 2, 0), ("snakeboard", 3, 0)]


def _kane_description(robot):
    """Frames, points, bodies, loads and contact-point speeds of ``robot`` (module docstring)."""
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    q = {c: dynamicsymbols(c) for c in robot.coordinates}
    par = {name: sp.Symbol(name, real=True) for name in robot.parameters}
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    frames = {f.name: N.orientnew(f"F_{f.name}", "Axis", [sum(c * q[v] for v, c in f.heading), N.z])
              for f in robot.frames}
    points, rails = {}, {}
    for p in robot.points:
        F = frames[p.frame]
        length = [sum((c * par[name] for c, name in comp), sp.Integer(0)) for comp in p.offset]
        if p.parent is None:
            P = O.locatenew(p.name, q[robot.base[0]] * N.x + q[robot.base[1]] * N.y)
        else:
            offset = length[0] * F.x + length[1] * F.y
            if p.slide is not None:
                rail = sp.cos(par[p.slide[1]]) * F.x + sp.sin(par[p.slide[1]]) * F.y
                offset += q[p.slide[0]] * rail
                rails[p.name] = (rail, points[p.parent], offset)
            P = points[p.parent].locatenew(p.name, offset)
        P.set_vel(N, P.pos_from(O).dt(N))
        points[p.name] = P
    bodies = [RigidBody(b.name, points[b.point], frames[b.frame], par[b.mass] if b.mass else 0,
                        (inertia(frames[b.frame], 0, 0, par[b.inertia] if b.inertia else 0), points[b.point]))
              for b in robot.bodies]
    inputs = {u: sp.Symbol(u, real=True) for u in robot.inputs}
    loads = []
    for t in robot.torques:
        loads.append((frames[t.on], t.gain * inputs[t.input] * N.z))
        if t.against:
            loads.append((frames[t.against], -t.gain * inputs[t.input] * N.z))
    for push in robot.pushes:
        F = frames[push.frame]
        if push.reaction:
            rail, parent, offset = rails[push.point]
            fixed = parent.locatenew(f"{push.point}_on_body", offset)
            fixed.v2pt_theory(parent, N, F)                  # the body's point under the slider
            loads += [(points[push.point], inputs[push.input] * rail), (fixed, -inputs[push.input] * rail)]
        else:
            direction = sp.cos(push.angle) * F.x + sp.sin(push.angle) * F.y
            loads.append((points[push.point], inputs[push.input] * direction))
    constraints = [points[pt].vel(N).dot(frames[fr].y) for pt, fr in robot.wheels]
    return N, [q[c] for c in robot.coordinates], par, inputs, bodies, loads, constraints


class _KaneMultiplierOracle:
    """q̈ of ``robot`` from ``KanesMethod`` of its unconstrained bodies (speeds u = q̇, all
    independent: M u̇ = F) and the contact-point speeds A(q) u = 0 enforced by multipliers:
    [M −Aᵀ; A 0] [u̇; λ] = [F; −Ȧu], solved numerically. (KanesMethod with *dependent* speeds
    eliminates A_dep by a symbolic LU without pivoting, which loses every digit where a pivot
    of the chosen block passes near zero — on a car pulled by its last trailer, at most random
    states — so the oracle here keeps the constraints as rows.)"""

    def __init__(self, robot):
        import sympy as sp
        from sympy.physics.mechanics import KanesMethod, dynamicsymbols, msubs
        N, q, par, inputs, bodies, loads, constraints = _kane_description(robot)
        t = dynamicsymbols._t
        u = [dynamicsymbols(f"u_{i}") for i in range(len(q))]
        km = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)])
        km.kanes_equations(bodies, loads)
        to_u = {qi.diff(t): ui for qi, ui in zip(q, u, strict=True)}
        cons = sp.Matrix([msubs(c, to_u) for c in constraints])
        A = cons.jacobian(u)
        Adot_u = sp.Matrix([sum(sp.diff(ci, qi) * ui for qi, ui in zip(q, u, strict=True)) for ci in cons])
        qs, us = sp.symbols(f"q0:{len(q)}"), sp.symbols(f"v0:{len(q)}")
        plain = {**dict(zip(q, qs, strict=True)), **dict(zip(u, us, strict=True))}

        def lam(expr):
            return sp.lambdify([qs, us, list(inputs.values()), list(par.values())],
                               msubs(expr, to_u).xreplace(plain), "numpy", cse=True)
        self.mass, self.forcing = lam(km.mass_matrix), lam(km.forcing)
        self.A, self.Adot_u = lam(A), lam(Adot_u)
        self.params = np.array(list(robot.parameters.values()))
        self.inputs = tuple(inputs)
        self.n, self.k = len(q), len(constraints)

    def constraint_jacobian(self, q):
        return np.asarray(self.A(q, np.zeros(self.n), np.zeros(len(self.inputs)), self.params), float)

    def qddot(self, q, qd, u):
        args = (q, qd, u, self.params)
        M, F = np.asarray(self.mass(*args), float), np.asarray(self.forcing(*args), float).ravel()
        A = self.constraint_jacobian(q)
        kkt = np.block([[M, -A.T], [A, np.zeros((self.k, self.k))]])
        rhs = np.concatenate([F, -np.asarray(self.Adot_u(*args), float).ravel()])
        return np.linalg.solve(kkt, rhs)[:self.n]


def _worst_qddot_error(pair, count=30, seed=0) -> tuple:
    """Worst relative q̈ errors of nhgait's reduced ODE and of the benchmark's reference DAE
    (experiments/reference_dae_ocp.py, built in CasADi from the same description) against the
    Kane oracle over ``count`` consistent states (random q in ±1.2, q̇ a random combination of
    the null space of A(q), random inputs), drawn off nhgait's singular set (measure ≥ 1e-3)."""
    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    robot = pair.robot
    orc = _KaneMultiplierOracle(robot)
    system = scene_from_text(pair.scene, pair.name).system
    assert list(system.coordinates) == list(robot.coordinates)
    model = derive(system, "reduced")
    num, pv = model.numeric, system.param_vector()
    accel = experiment_scripts.load("reference_dae_ocp").dae(robot)["accel"]
    rng = np.random.default_rng(seed)
    worst, worst_ref, used = 0.0, 0.0, 0
    while used < count:
        qv = rng.uniform(-1.2, 1.2, system.n)
        if num.call("singular", qv, pv) < 1e-3:
            continue
        basis = np.linalg.svd(orc.constraint_jacobian(qv))[2][robot.k:].T          # null space of A(q)
        qd = basis @ rng.uniform(-1.0, 1.0, basis.shape[1])
        u = rng.uniform(-2.0, 2.0, len(system.inputs))
        ref = orc.qddot(qv, qd, np.array([u[system.inputs.index(i)] for i in orc.inputs]))
        z = num.call("state", qv, qd, pv)
        got = np.asarray(num.call("qddot", 0.0, z, u, pv), float).ravel()
        dae = np.asarray(accel(qv, qd, [u[system.inputs.index(i)] for i in robot.inputs])[0], float).ravel()
        scale = max(1.0, np.max(np.abs(ref)))
        worst = max(worst, float(np.max(np.abs(got - ref)) / scale))
        worst_ref = max(worst_ref, float(np.max(np.abs(dae - ref)) / scale))
        used += 1
    return worst, worst_ref


@cache
def _case(family, seed, index):
    """The pair of an oracle case, generated once per run (its sympy scene text costs ~0.5 s)."""
    return gen.pair(seed, index, family, intervals=20)


@pytest.mark.parametrize("family,seed,index", CASES)
def test_generated_robot_equals_kane(family, seed, index):
    pair = _case(family, seed, index)
    worst, worst_reference = _worst_qddot_error(pair)
    assert worst < RTOL, f"{pair.name} ({pair.robot.comment}): max relative q̈ error {worst:.3g}"
    assert worst_reference < RTOL, f"{pair.name}: the reference DAE's q̈ is off by {worst_reference:.3g}"


def test_the_cases_cover_every_convention():
    """The oracle cases above include each family's conventions: the head, middle and tail
    link of a chain as the base, relative angles of both signs and absolute headings, a rotor,
    a car based on its rear axle, centre of mass or last trailer, a sleigh with two sliders and
    one based on its blade, a snakeboard based on its back axle."""
    robots = [_case(f, s, i).robot for f, s, i in CASES]
    comments = " ".join(r.comment for r in robots)
    for phrase in ("the head link", "the middle link", "the tail link", "absolute", "rear minus front",
                   "front minus rear", "rotor", "rear axle", "centre of mass", "last trailer", "2 sliding",
                   "the blade and", "back axle"):
        assert phrase in comments, phrase


def test_same_seed_same_pairs_other_seed_other_pairs():
    a = [p.scene for p in gen.pairs(7, 4, intervals=20)]
    assert a == [p.scene for p in gen.pairs(7, 4, intervals=20)]
    assert all(x != y for x, y in zip(a, [p.scene for p in gen.pairs(8, 4, intervals=20)], strict=True))
    assert gen.pair(7, 3, intervals=20).scene == a[3]            # a pair depends on (seed, index) only


def test_every_task_is_meaningful_and_loads():
    """The benchmark's first 8 pairs: each task passes the generator's checks and nhgait's own
    task checks (the scene parses, the task binds to the system), every end value lies inside
    its path bounds, and the pairs cover every family and every kind of task."""
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    from nhgait.gaits.tasks.sources import resolve
    pairs = gen.pairs(24, 8)
    labels = set()
    for p in pairs:
        assert gen.check_task(p.robot, p.task) == []
        resolve(scene_from_text(p.scene, p.name))
        for end in ("initial", "final"):
            for name, v in p.task[end].items():
                lo, hi = p.task.get("bounds", {}).get(name, (-np.inf, np.inf))
                assert lo <= v <= hi
        labels |= {p.family, *p.labels.values()}
    assert set(gen.FAMILIES) | {"forward", "sideways", "turning", "rest", "periodic", "fixed", "free",
                                "near", "far", "tight", "loose"} <= labels


def test_check_task_names_what_is_wrong():
    p = gen.pair(1, 0)
    bad = dict(p.task, initial={**p.task["initial"], **{c: 9.0 for c in p.task.get("bounds", {})}},
               final=dict(p.task["initial"]))
    problems = " ".join(gen.check_task(p.robot, bad))
    assert "outside its bound" in problems
    assert "the target is the start" in problems
