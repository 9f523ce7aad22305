"""Seeded robot-and-task pairs nobody tuned the planner for (issue 24, item 3).

``pair(seed, index)`` draws one robot and one gait task and returns them as the text of a scene
file (TOML with ``[system]`` and ``[task]``, docs/scene-format.md and docs/gait-planning.md) written
the way a user writes it: a Lagrangian T = Σ ½ m |v_G|² + ½ I ω² as sums of squared velocity
components, each no-side-slip constraint as n(h)·v_P (the axle's normal dotted with the contact
point's velocity, not simplified), generalized forces per coordinate, parameters by name.
``pairs(seed, count)`` gives ``count`` pairs, the four families in turn.

Every robot is first a *physical description* (:class:`Robot`): rigid frames whose headings are
linear in the coordinates, points located from a base point (x, y) through offsets in those
frames (and slides along rails), bodies (mass at a point, inertia about the vertical), wheels
(the point's velocity along its frame's y axis is zero) and the inputs' loads (torques between
two frames, forces along a frame's axis). :func:`walk` places every point and heading with any
math namespace (sympy for the scene text, CasADi for ``experiments/reference_dae_ocp.py``);
``tests/experiments/test_robot_generator.py`` builds the same description independently with frames and
points of ``sympy.physics.mechanics`` and checks nhgait's q̈ against ``KanesMethod``.

Families (sizes, parameters and conventions drawn from the seed)
------------------------------------------------------------------
* ``chain``: a wheeled chain of 3–6 links (half-lengths 0.1–0.3 m, masses 0.5–2 kg, inertias
  about the centre), an axle with no side slip on 2 … all links at a random point of each
  (±0.5 of the half-length from the centre), optionally a rotor on the base link; joint torques.
  (x, y, θ) is the centre and heading of the head, middle or tail link; joint angles relative
  (either sign) or every link's absolute heading; joint and input names vary.
* ``car``: a car (rear axle, front axle steered by φ, drive force F along the heading at the
  rear axle, steering torque) pulling 1–3 trailers hitched 0.05–0.25 m *behind* the axle of the
  body ahead (off-axle). (x, y, θ) is the car's rear axle, its centre of mass, or the last
  trailer's axle and heading; hitch angles relative (either sign) or absolute headings.
* ``sleigh``: a Chaplygin sleigh (knife edge, centre of mass ahead of it) carrying one or two
  masses that slide on rails at random positions and angles (forces along the rails), with or
  without a rotor; (x, y) the blade or the centre of mass. At least two inputs.
* ``snakeboard``: the snakeboard with random m, J, J_r, J_w, r (not the thesis's m r² = J + J_r +
  2 J_w); (x, y) the board's centre or its back axle; front/back steering θ ± φ or θ ∓ φ.

Tasks
-----
``forward`` / ``sideways`` / ``turning`` (for cars: a lane change and a quarter turn on a
radius), ``rest`` (every velocity zero at both ends, written as ``<q>_dot = 0`` for every
coordinate) or ``periodic`` (the shape variables and their rates periodic, the fibre from rest at
the start), initial shape ``fixed`` (values inside the bounds, sometimes the straight posture)
or ``free``, ``near`` or ``far`` targets (a fraction of the robot's length, or a multiple; a far
target gets a longer horizon), loose (or no) or ``tight`` control bounds (a small multiple of the
robot's own torque scale m L² (2π/T)²). The start is the origin or a random pose.
:func:`check_task` states what makes a task meaningful (every end value inside its path bound,
a fixed initial shape inside the bounds, the target away from the start) and every pair is
checked when it is made. Whether a target is *reachable* within the bounds is decided by the
independent transcription (``experiments/reference_dae_ocp.py``), not here.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

import numpy as np
import sibling  # experiments/sibling.py: the other scripts, loaded by file path

FAMILIES = ("chain", "car", "sleigh", "snakeboard")
"""The families, in the order :func:`pairs` cycles through them."""

KINDS = ("forward", "sideways", "turning")


# --------------------------------------------------------------------------- #
# the physical description
# --------------------------------------------------------------------------- #
Length = tuple  # ((coefficient, parameter name), ...): Σ coefficient · parameter, in m


@dataclass(frozen=True)
class Frame:
    """A rigid part's x axis at the absolute angle Σ coef·q (``heading``: ((coordinate, coef), …))."""

    name: str
    heading: tuple


@dataclass(frozen=True)
class Point:
    """A point at ``parent`` + offset (in ``frame``'s axes) + s·(cos γ, sin γ) (``slide`` = (s, γ):
    a coordinate and the rail's angle in ``frame``'s axes, a parameter name); ``parent`` None: the
    base point (x, y)."""

    name: str
    parent: str | None
    frame: str
    offset: tuple = ((), ())          # (Length along the frame's x, Length along its y)
    slide: tuple | None = None


@dataclass(frozen=True)
class Body:
    """Mass ``mass`` at ``point``, inertia ``inertia`` about the vertical turning with ``frame``
    (parameter names; None: massless / no inertia)."""

    name: str
    point: str
    frame: str
    mass: str | None
    inertia: str | None


@dataclass(frozen=True)
class Torque:
    """Input ``input`` × ``gain`` turns ``on`` about +z and ``against`` (None: the ground) about −z."""

    input: str
    on: str
    against: str | None
    gain: float = 1.0


@dataclass(frozen=True)
class Push:
    """Input ``input`` pushes ``point`` along ``frame``'s x axis turned by ``angle``, the ground
    pushing back; ``reaction``: a slider's motor — the force acts along the point's rail (its
    ``slide`` direction; ``angle`` unused) and, reversed, on the point of ``frame`` where the
    slider is, so its generalized force is F on the slide coordinate alone."""

    input: str
    point: str
    frame: str
    angle: float = 0.0
    reaction: bool = False


@dataclass(frozen=True)
class Robot:
    """A planar robot. ``coordinates`` (the order of q), ``base`` the names of (x, y, heading),
    ``shape`` the coordinates that are not the base's, ``wheels`` ((point, frame), …): the point's
    velocity along the frame's y axis is zero (one constraint each, in this order)."""

    name: str
    family: str
    comment: str
    coordinates: tuple
    base: tuple
    shape: tuple
    frames: tuple
    points: tuple
    bodies: tuple
    wheels: tuple
    torques: tuple = ()
    pushes: tuple = ()
    parameters: dict = field(default_factory=dict)
    length: float = 1.0               # a characteristic length (m) for the task's distances

    @property
    def inputs(self) -> tuple:
        return tuple(dict.fromkeys([t.input for t in self.torques] + [p.input for p in self.pushes]))

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def k(self) -> int:
        return len(self.wheels)

    @property
    def mass(self) -> float:
        return sum(self.parameters[b.mass] for b in self.bodies if b.mass)


def walk(robot: Robot, q: dict, sin, cos, param):
    """Headings of every frame and positions of every point (``q``: coordinate name → value or
    symbol; ``param``: parameter name → value or symbol; ``sin``/``cos`` of the namespace).
    Returns ({frame: h}, {point: (px, py)})."""
    heads = {f.name: sum((c * q[name] for name, c in f.heading), 0) for f in robot.frames}
    pos = {}

    def length(spec):
        return sum((c * param(p) for c, p in spec), 0)

    for p in robot.points:
        h = heads[p.frame]
        ex, ey = (cos(h), sin(h)), (-sin(h), cos(h))
        if p.parent is None:
            px, py = q[robot.base[0]], q[robot.base[1]]
        else:
            px, py = pos[p.parent]
        a, b = length(p.offset[0]), length(p.offset[1])
        px, py = px + a * ex[0] + b * ey[0], py + a * ex[1] + b * ey[1]
        if p.slide is not None:
            s, gam = q[p.slide[0]], param(p.slide[1])
            px = px + s * (cos(gam) * ex[0] + sin(gam) * ey[0])
            py = py + s * (cos(gam) * ex[1] + sin(gam) * ey[1])
        pos[p.name] = (px, py)
    return heads, pos


# --------------------------------------------------------------------------- #
# random numbers as a user writes them
# --------------------------------------------------------------------------- #
def _r(rng, lo, hi, digits=3) -> float:
    """A uniform draw in [lo, hi] rounded to ``digits`` significant digits."""
    v = float(rng.uniform(lo, hi))
    return float(f"{v:.{digits}g}")


def _L(*terms) -> Length:
    """A length Σ coef·parameter from (coef, name) pairs or bare names (coef 1)."""
    return tuple((1, t) if isinstance(t, str) else t for t in terms)


def _chain_headings(count, b, theta, joints, convention):
    """Heading of each part of a chain (tuples ((coord, coef), …)). ``convention``: +1 / −1 for
    relative angles α_j = ±(h_{j+1} − h_j) (joint j between parts j and j+1), 0 for absolute
    headings (``joints`` are then the headings of the parts other than b)."""
    if convention == 0:
        others = iter(joints)
        return [((theta, 1),) if i == b else ((next(others), 1),) for i in range(count)]
    heads = [None] * count
    heads[b] = {theta: 1}
    for i in range(b + 1, count):                 # h_i = h_{i-1} + s α_{i-1}
        heads[i] = {**heads[i - 1], joints[i - 1]: convention}
    for i in range(b - 1, -1, -1):                # h_i = h_{i+1} − s α_i
        heads[i] = {**heads[i + 1], joints[i]: -convention}
    return [tuple(h.items()) for h in heads]


_JOINT_NAMES = (("alpha{}", "tau{}"), ("q{}", "u{}"), ("phi{}", "T{}"), ("joint{}", "tau_j{}"))


def chain(rng, name: str) -> Robot:
    """A wheeled chain (module docstring)."""
    L = int(rng.integers(3, 7))
    b = int(rng.choice([0, L // 2, L - 1]))
    rotor = bool(rng.random() < 0.3)
    convention = int(rng.choice([1, -1, 1, 0]))
    jn, un = _JOINT_NAMES[int(rng.integers(len(_JOINT_NAMES)))]
    if convention == 0:
        joints = [f"theta{i + 1}" for i in range(L) if i != b]
        theta = f"theta{b + 1}"
    else:
        joints = [jn.format(j) for j in range(1, L)]
        theta = "theta"
    wheeled = sorted(int(i) for i in rng.choice(L, size=int(rng.integers(2, L + 1)), replace=False))
    params = {}
    for i in range(1, L + 1):
        params[f"l{i}"] = _r(rng, 0.1, 0.3, 2)
        params[f"m{i}"] = _r(rng, 0.5, 2.0, 2)
        params[f"I{i}"] = _r(rng, 0.7, 1.5) * params[f"m{i}"] * (2 * params[f"l{i}"]) ** 2 / 12
        params[f"I{i}"] = float(f"{params[f'I{i}']:.3g}")
    for i in wheeled:
        params[f"w{i + 1}"] = _r(rng, -0.5, 0.5, 2) * params[f"l{i + 1}"]
        params[f"w{i + 1}"] = float(f"{params[f'w{i + 1}']:.3g}")
    heads = _chain_headings(L, b, theta, joints, convention)
    frames = [Frame(f"link{i + 1}", heads[i]) for i in range(L)]
    points = [Point(f"C{b + 1}", None, f"link{b + 1}")]
    for i in range(b + 1, L):        # behind the base: joint at the rear end of link i-1
        points.append(Point(f"J{i}", f"C{i}", f"link{i}", (_L((-1, f"l{i}")), ())))
        points.append(Point(f"C{i + 1}", f"J{i}", f"link{i + 1}", (_L((-1, f"l{i + 1}")), ())))
    for i in range(b - 1, -1, -1):   # ahead of the base: joint at the front end of link i+2
        points.append(Point(f"J{i + 1}", f"C{i + 2}", f"link{i + 2}", (_L(f"l{i + 2}"), ())))
        points.append(Point(f"C{i + 1}", f"J{i + 1}", f"link{i + 1}", (_L(f"l{i + 1}"), ())))
    points += [Point(f"W{i + 1}", f"C{i + 1}", f"link{i + 1}", (_L(f"w{i + 1}"), ())) for i in wheeled]
    bodies = [Body(f"link{i + 1}", f"C{i + 1}", f"link{i + 1}", f"m{i + 1}", f"I{i + 1}") for i in range(L)]
    inputs = [un.format(j) for j in range(1, L)]
    torques = [Torque(inputs[j], f"link{j + 2}", f"link{j + 1}", 1.0) for j in range(L - 1)]
    coords = ["x", "y", theta]
    shape = list(joints)
    if rotor:
        params["J_r"] = _r(rng, 0.01, 0.1, 2)
        frames.append(Frame("rotor", heads[b] + (("psi", 1),)))
        bodies.append(Body("rotor", f"C{b + 1}", "rotor", None, "J_r"))
        torques.insert(0, Torque("tau_psi", "rotor", f"link{b + 1}"))
        shape.insert(0, "psi")
    coords += shape
    where = {0: "head", L - 1: "tail"}.get(b, "middle")
    conv = {1: "relative joint angles (rear minus front)", -1: "relative joint angles (front minus rear)",
            0: "absolute link headings"}[convention]
    comment = (f"Wheeled {L}-link chain{' with a rotor on the base link' if rotor else ''}: (x, y, "
               f"{theta}) the {where} link's centre and heading, {conv}; wheel axles (no side slip) on links "
               f"{', '.join(str(i + 1) for i in wheeled)}; torques on the joints.")
    return Robot(name, "chain", comment, tuple(coords), ("x", "y", theta), tuple(shape), tuple(frames),
                 tuple(points), tuple(bodies), tuple((f"W{i + 1}", f"link{i + 1}") for i in wheeled),
                 tuple(torques), (), params, length=2 * sum(params[f"l{i}"] for i in range(1, L + 1)))


def car(rng, name: str) -> Robot:
    """A car with 1–3 off-axle trailers (module docstring)."""
    K = int(rng.integers(1, 4))
    base = str(rng.choice(["rear axle", "centre of mass", "last trailer"]))
    convention = int(rng.choice([1, -1, 0]))
    params = {"b": _r(rng, 0.2, 0.5, 2)}
    params.update(a=float(f"{_r(rng, 0.3, 0.7, 2) * params['b']:.3g}"), m=_r(rng, 1.0, 3.0, 2))
    params["I"] = float(f"{params['m'] * params['b'] ** 2 / 8 * _r(rng, 0.7, 1.5):.3g}")
    params["J_s"] = _r(rng, 0.005, 0.02, 2)
    for i in range(1, K + 1):
        params[f"d{i}"] = _r(rng, 0.05, 0.25, 2)
        params[f"l{i}"] = _r(rng, 0.2, 0.5, 2)
        params[f"c{i}"] = float(f"{_r(rng, 0.3, 1.0, 2) * params[f'l{i}']:.3g}")
        params[f"m{i}"] = _r(rng, 0.5, 2.0, 2)
        params[f"I{i}"] = float(f"{params[f'm{i}'] * params[f'l{i}'] ** 2 / 12 * _r(rng, 0.7, 1.5):.3g}")
    b = K if base == "last trailer" else 0
    theta = "theta"
    if convention == 0:
        hitch = [f"theta{i}" for i in range(K + 1) if i != b]
        theta = f"theta{b}"
    else:
        hitch = [f"beta{i}" for i in range(1, K + 1)]
    heads = _chain_headings(K + 1, b, theta, hitch, convention)
    steer = "delta" if rng.random() < 0.5 else "phi"
    frames = [Frame("car", heads[0])] + [Frame(f"trailer{i}", heads[i]) for i in range(1, K + 1)]
    frames.append(Frame("steer", heads[0] + ((steer, 1),)))
    # points: P0 the car's rear axle, H_i the hitch of trailer i, P_i its axle
    if b == 0:
        first = Point("P0", None, "car") if base == "rear axle" else None
        points = [first] if first else [Point("G0", None, "car"),
                                        Point("P0", "G0", "car", (_L((-1, "a")), ()))]
        for i in range(1, K + 1):
            prev = "car" if i == 1 else f"trailer{i - 1}"
            points.append(Point(f"H{i}", f"P{i - 1}", prev, (_L((-1, f"d{i}")), ())))
            points.append(Point(f"P{i}", f"H{i}", f"trailer{i}", (_L((-1, f"l{i}")), ())))
    else:
        points = [Point(f"P{K}", None, f"trailer{K}")]
        for i in range(K, 0, -1):
            prev = "car" if i == 1 else f"trailer{i - 1}"
            points.append(Point(f"H{i}", f"P{i}", f"trailer{i}", (_L(f"l{i}"), ())))
            points.append(Point(f"P{i - 1}", f"H{i}", prev, (_L(f"d{i}"), ())))
    if base != "centre of mass":
        points.append(Point("G0", "P0", "car", (_L("a"), ())))
    points.append(Point("F0", "P0", "car", (_L("b"), ())))
    points += [Point(f"G{i}", f"H{i}", f"trailer{i}", (_L((-1, f"c{i}")), ())) for i in range(1, K + 1)]
    bodies = [Body("car", "G0", "car", "m", "I"), Body("steering", "F0", "steer", None, "J_s")]
    bodies += [Body(f"trailer{i}", f"G{i}", f"trailer{i}", f"m{i}", f"I{i}") for i in range(1, K + 1)]
    wheels = [("P0", "car"), ("F0", "steer")] + [(f"P{i}", f"trailer{i}") for i in range(1, K + 1)]
    coords = ["x", "y", theta, steer] + hitch
    conv = {1: "hitch angles relative (trailer minus the body ahead)",
            -1: "hitch angles relative (the body ahead minus the trailer)",
            0: "absolute headings"}[convention]
    comment = (f"Car with {K} trailer(s) hitched behind the axle of the body ahead (off-axle): (x, "
               f"y, {theta}) "
               f"the {'car' if b == 0 else 'last trailer'}'s {base if b == 0 else 'axle'} and "
               f"heading, {conv}; front axle steered by {steer}; drive force F along the car at "
               "its rear axle, steering torque tau_s.")
    return Robot(name, "car", comment, tuple(coords), ("x", "y", theta), tuple([steer] + hitch),
                 tuple(frames), tuple(points), tuple(bodies), tuple(wheels),
                 (Torque("tau_s", "steer", "car"),), (Push("F", "P0", "car"),), params,
                 length=params["b"] + sum(params[f"d{i}"] + params[f"l{i}"] for i in range(1, K + 1)))


def sleigh(rng, name: str) -> Robot:
    """A Chaplygin sleigh with sliding masses (module docstring)."""
    sliders = int(rng.integers(1, 3))
    rotor = sliders == 1 or bool(rng.random() < 0.4)
    at_blade = bool(rng.random() < 0.5)
    heading = str(rng.choice(["theta", "phi"]))
    params = {"a": _r(rng, 0.05, 0.3, 2), "m": _r(rng, 1.0, 3.0, 2)}
    params["I"] = float(f"{params['m'] * _r(rng, 0.01, 0.05, 2):.3g}")
    frames = [Frame("body", ((heading, 1),))]
    points = ([Point("B", None, "body"), Point("G", "B", "body", (_L("a"), ()))] if at_blade else
              [Point("G", None, "body"), Point("B", "G", "body", (_L((-1, "a")), ()))])
    bodies = [Body("sleigh", "G", "body", "m", "I")]
    coords, shape, pushes, torques = ["x", "y", heading], [], [], []
    for j in range(1, sliders + 1):
        params[f"p{j}"] = _r(rng, -0.1, 0.3, 2)
        params[f"e{j}"] = _r(rng, -0.15, 0.15, 2)
        params[f"m_s{j}"] = _r(rng, 0.2, 1.0, 2)
        params[f"gamma{j}"] = _r(rng, 0.3, math.pi - 0.3)     # the rail's angle, not along the body
        s = f"s{j}" if sliders > 1 else "s"
        points.append(Point(f"S{j}", "B", "body", (_L(f"p{j}"), _L(f"e{j}")), (s, f"gamma{j}")))
        bodies.append(Body(f"slider{j}", f"S{j}", "body", f"m_s{j}", None))
        pushes.append(Push(f"F{j}" if sliders > 1 else "F", f"S{j}", "body", reaction=True))
        shape.append(s)
    if rotor:
        params["J_r"] = _r(rng, 0.01, 0.08, 2)
        frames.append(Frame("rotor", ((heading, 1), ("psi", 1))))
        bodies.append(Body("rotor", "G", "rotor", None, "J_r"))
        torques.append(Torque("tau", "rotor", "body"))
        shape.append("psi")
    coords += shape
    comment = (f"Chaplygin sleigh with {sliders} sliding mass(es) on rails{' and a rotor' if rotor else ''}: "
               f"(x, y, {heading}) the {'blade' if at_blade else 'centre of mass'} and heading; the blade "
               "does not slip sideways; forces along the rails"
               f"{', rotor torque tau' if rotor else ''}.")
    return Robot(name, "sleigh", comment, tuple(coords), ("x", "y", heading), tuple(shape), tuple(frames),
                 tuple(points), tuple(bodies), (("B", "body"),), tuple(torques), tuple(pushes), params,
                 length=2 * params["a"] + 0.3)


def snakeboard(rng, name: str) -> Robot:
    """The snakeboard with random parameters (module docstring)."""
    params = {"m": _r(rng, 0.5, 3.0, 2), "r": _r(rng, 0.2, 0.6, 2)}
    params["J"] = float(f"{params['m'] * params['r'] ** 2 * _r(rng, 0.2, 0.5, 2):.3g}")
    params["J_r"] = float(f"{params['J'] * _r(rng, 0.3, 1.0, 2):.3g}")
    params["J_w"] = float(f"{params['J'] * _r(rng, 0.05, 0.3, 2):.3g}")
    sign = int(rng.choice([1, -1]))
    at_back = bool(rng.random() < 0.4)
    frames = [Frame("board", (("theta", 1),)), Frame("rotor", (("theta", 1), ("psi", 1))),
              Frame("front", (("theta", 1), ("phi", sign))), Frame("back", (("theta", 1), ("phi", -sign)))]
    points = ([Point("K", None, "board"), Point("C", "K", "board", (_L("r"), ()))] if at_back else
              [Point("C", None, "board"), Point("K", "C", "board", (_L((-1, "r")), ()))])
    points.append(Point("F", "C", "board", (_L("r"), ())))
    bodies = [Body("board", "C", "board", "m", "J"), Body("rotor", "C", "rotor", None, "J_r"),
              Body("front", "F", "front", None, "J_w"), Body("back", "K", "back", None, "J_w")]
    torques = (Torque("tau_psi", "rotor", "board"), Torque("tau_phi", "front", "back", 0.5 * sign))
    where = "back axle" if at_back else "centre"
    comment = (f"Snakeboard with random parameters: (x, y, theta) the board's {where} "
               f"and heading; the front wheels steer by theta {'+' if sign > 0 else '-'} phi, the "
               f"back wheels by theta {'-' if sign > 0 else '+'} phi; rotor torque tau_psi, steering "
               "torque tau_phi.")
    return Robot(name, "snakeboard", comment, ("x", "y", "theta", "psi", "phi"), ("x", "y", "theta"),
                 ("psi", "phi"), tuple(frames), tuple(points), tuple(bodies), (("K", "back"), ("F", "front")),
                 torques, (), params, length=2 * params["r"])


BUILDERS = {"chain": chain, "car": car, "sleigh": sleigh, "snakeboard": snakeboard}


# --------------------------------------------------------------------------- #
# the scene text (sympy)
# --------------------------------------------------------------------------- #
def _symbols(robot: Robot):
    import sympy as sp
    q = {c: sp.Symbol(c, real=True) for c in robot.coordinates}
    qd = {c: sp.Symbol(f"{c}_dot", real=True) for c in robot.coordinates}

    def d(expr):
        """Time derivative along q̇ of an expression of q."""
        return sum((sp.diff(expr, q[c]) * qd[c] for c in robot.coordinates), sp.Integer(0))
    return q, qd, d


def _compact(e):
    """A velocity expression grouped by its sines and cosines (short scene text)."""
    import sympy as sp
    e = sp.expand(e)
    return sp.collect(e, sorted(e.atoms(sp.sin, sp.cos), key=sp.default_sort_key), func=sp.factor)


def kinematics(robot: Robot):
    """Sympy headings, point positions and velocities of ``robot`` (parameters as symbols):
    (q, qd, heads, pos, vel) with vel[point] = (v_x, v_y) compact."""
    import sympy as sp
    q, qd, d = _symbols(robot)
    heads, pos = walk(robot, q, sp.sin, sp.cos, lambda name: sp.Symbol(name, real=True))
    vel = {p: (_compact(d(px)), _compact(d(py))) for p, (px, py) in pos.items()}
    return q, qd, d, heads, pos, vel


def generalized_forces(robot: Robot) -> dict:
    """Q_j (sympy) of every input's loads: a torque τ·g on frame `on` against `against` gives
    τ g ∂(h_on − h_against)/∂q_j; a push F along direction u at point P gives F u·∂P/∂q_j, or,
    with the reaction on the rail, F on the slide coordinate only (the relative motion)."""
    import sympy as sp
    q, qd, d, heads, pos, vel = kinematics(robot)
    Q = {c: sp.Integer(0) for c in robot.coordinates}
    for t in robot.torques:
        tau = sp.Symbol(t.input, real=True)
        rel = heads[t.on] - (heads[t.against] if t.against else 0)
        for c in robot.coordinates:
            Q[c] += sp.nsimplify(t.gain) * tau * sp.diff(rel, q[c])
    points = {p.name: p for p in robot.points}
    for push in robot.pushes:
        F = sp.Symbol(push.input, real=True)
        if push.reaction:
            Q[points[push.point].slide[0]] += F
            continue
        h = heads[push.frame] + push.angle
        for c in robot.coordinates:
            px, py = pos[push.point]
            Q[c] += F * sp.trigsimp(sp.cos(h) * sp.diff(px, q[c]) + sp.sin(h) * sp.diff(py, q[c]))
    return {c: sp.simplify(v) for c, v in Q.items() if v != 0}


def system_toml(robot: Robot) -> str:
    """The ``[system]`` table of ``robot``: a user's Lagrangian, constraints and forces."""
    import sympy as sp
    q, qd, d, heads, pos, vel = kinematics(robot)
    terms = []
    for b in robot.bodies:
        if b.mass:
            vx, vy = vel[b.point]
            terms.append(f"{b.mass}/2*(({sp.sstr(vx)})**2 + ({sp.sstr(vy)})**2)")
        if b.inertia:
            terms.append(f"{b.inertia}/2*({sp.sstr(d(heads[b.frame]))})**2")
    cons = []
    for point, frame in robot.wheels:
        h = sp.sstr(heads[frame])
        vx, vy = vel[point]
        cons.append(f'  "-sin({h})*({sp.sstr(vx)}) + cos({h})*({sp.sstr(vy)})",')
    lines = [f"# {robot.comment}", "# (experiments/robot_generator.py)", "[system]", f'name = "{robot.name}"',
             "coordinates = [" + ", ".join(f'"{c}"' for c in robot.coordinates) + "]",
             'lagrangian = """\n' + "\n+ ".join(terms) + '\n"""', "constraints = [", *cons, "]",
             "inputs = [" + ", ".join(f'"{u}"' for u in robot.inputs) + "]", "", "[system.forces]"]
    lines += [f'{c} = "{sp.sstr(f)}"' for c, f in generalized_forces(robot).items()]
    lines += ["", "[system.parameters]"] + [f"{k} = {v!r}" for k, v in robot.parameters.items()]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- #
# tasks
# --------------------------------------------------------------------------- #
def _shape_bounds(rng, robot: Robot) -> dict:
    """Path bounds a user puts on the shape variables (none on rotors and absolute headings)."""
    bounds = {}
    fam = robot.family
    for c in robot.shape:
        if c == "psi" or c.startswith("theta"):
            continue
        if fam == "chain":
            lim = _r(rng, 0.8, 1.5, 2)
        elif fam == "car":
            lim = _r(rng, 0.4, 0.7, 2) if c == robot.shape[0] else _r(rng, 0.8, 1.2, 2)
        elif fam == "sleigh":
            lim = _r(rng, 0.1, 0.25, 2)
        else:
            lim = _r(rng, 0.6, 1.0, 2)
        bounds[c] = [-lim, lim]
    return bounds


def _target(rng, robot: Robot, kind: str, reach: str):
    """(Δx, Δy, Δθ) in the start's frame (module docstring: Tasks)."""
    Lr, far = robot.length, reach == "far"
    if robot.family == "car":
        if kind == "forward":
            return _r(rng, 2.0, 4.0) * Lr if far else _r(rng, 0.5, 1.0) * Lr, 0.0, 0.0
        if kind == "sideways":
            return (_r(rng, 4.0, 6.0) if far else _r(rng, 2.0, 4.0)) * Lr, (
                _r(rng, 0.5, 1.0) if far else _r(rng, 0.2, 0.5)) * Lr, 0.0
        turn, R = (math.pi / 2 if far else math.pi / 4), _r(rng, 1.5, 3.0) * Lr
        return R * math.sin(turn), R * (1 - math.cos(turn)), turn
    if kind == "forward":
        return (_r(rng, 0.8, 1.5) if far else _r(rng, 0.1, 0.3)) * Lr, 0.0, 0.0
    if kind == "sideways":
        return 0.0, (_r(rng, 0.3, 0.6) if far else _r(rng, 0.05, 0.15)) * Lr, 0.0
    return 0.0, 0.0, _r(rng, math.pi / 2, 3 * math.pi / 4) if far else _r(rng, math.pi / 8, math.pi / 4)


_HORIZON = {"chain": (4.0, 7.0), "car": (6.0, 9.0), "sleigh": (3.0, 6.0), "snakeboard": (4.0, 7.0)}


def _control_bounds(rng, robot: Robot, T: float, tight: bool):
    """A number (every input) or {input: [lo, hi]}, from the robot's torque and force scales
    M (L/2)² (2π/T)²/4 and M (L/2) (2π/T)²/4; ``tight``: 1–3 times the scale, else 20–50
    times, or no bound (half of the loose draws)."""
    if not tight and rng.random() < 0.5:
        return None
    w2 = (2 * math.pi / T) ** 2
    factor = _r(rng, 1.0, 3.0, 2) if tight else _r(rng, 20.0, 50.0, 2)
    torque = float(f"{factor * robot.mass * (robot.length / 2) ** 2 * w2 / 4:.2g}")
    force = float(f"{factor * robot.mass * (robot.length / 2) * w2 / 4:.2g}")
    if not robot.pushes:
        return torque
    pushed = {p.input for p in robot.pushes}
    return {u: [-(force if u in pushed else torque), force if u in pushed else torque] for u in robot.inputs}


def _start_shape(rng, robot: Robot, bounds: dict, start_heading: float) -> dict:
    """Initial shape values inside the bounds: the straight posture (40 %) or random; absolute
    headings near the base's, rotors at 0."""
    straight = rng.random() < 0.4
    out = {}
    for c in robot.shape:
        if c == "psi":
            out[c] = 0.0
        elif c.startswith("theta"):
            out[c] = start_heading if straight else float(f"{start_heading + rng.uniform(-0.4, 0.4):.3g}")
        else:
            lo, hi = bounds.get(c, (-0.5, 0.5))
            out[c] = 0.0 if straight else float(f"{rng.uniform(0.5 * lo, 0.5 * hi):.3g}")
    return out


def make_task(rng, robot: Robot, intervals: int = 40) -> tuple:
    """A random ``[task]`` table of ``robot`` (a dict) and its labels (module docstring: Tasks)."""
    labels = {"kind": str(rng.choice(KINDS)), "mode": str(rng.choice(["rest", "periodic"])),
              "shape": str(rng.choice(["fixed", "free"])), "reach": str(rng.choice(["near", "far"])),
              "bounds": str(rng.choice(["tight", "loose"]))}
    x, y, th = robot.base
    origin = rng.random() < 0.7
    x0, y0, h0 = (0.0, 0.0, 0.0) if origin else (_r(rng, -1, 1), _r(rng, -1, 1), _r(rng, -math.pi, math.pi))
    dx, dy, dh = _target(rng, robot, labels["kind"], labels["reach"])
    final = {x: float(f"{x0 + dx * math.cos(h0) - dy * math.sin(h0):.4g}"),
             y: float(f"{y0 + dx * math.sin(h0) + dy * math.cos(h0):.4g}"), th: float(f"{h0 + dh:.4g}")}
    lo, hi = _HORIZON[robot.family]
    T = _r(rng, lo, hi, 2) * (1.5 if labels["reach"] == "far" else 1.0)
    bounds = _shape_bounds(rng, robot)
    initial = {x: x0, y: y0, th: h0}
    if labels["shape"] == "fixed":
        initial.update(_start_shape(rng, robot, bounds, h0))
    rest = {f"{c}_dot": 0.0 for c in robot.coordinates}
    task = {"name": f"{labels['kind']}-{labels['mode']}",
            "description": f"{robot.family} {labels['kind']}, {labels['mode']}, initial shape "
                           f"{labels['shape']}, "
                           f"{labels['reach']} target, {labels['bounds']} control bounds "
                           "(robot_generator.py)",
            "horizon": float(f"{T:.3g}"), "intervals": int(intervals), "initial": {**initial, **rest},
            "final": dict(final)}
    if labels["mode"] == "rest":
        task["final"].update(rest)
    else:
        task["periodic"] = list(robot.shape) + [f"{c}_dot" for c in robot.shape]
    if bounds:
        task["bounds"] = bounds
    cb = _control_bounds(rng, robot, task["horizon"], labels["bounds"] == "tight")
    if cb is not None:
        task["control_bounds"] = cb
    task["objective"] = "effort"
    return task, labels


def check_task(robot: Robot, task: dict) -> list:
    """What would make ``task`` meaningless, as sentences (empty when it is fine): an end value
    outside its path bound, a periodic name fixed to different values at the two ends, a target
    at the start, an unknown name."""
    problems = []
    names = set(robot.coordinates) | {f"{c}_dot" for c in robot.coordinates}
    for end in ("initial", "final"):
        for c, v in task.get(end, {}).items():
            if c not in names:
                problems.append(f"{end}.{c}: not a coordinate or velocity")
            lo, hi = task.get("bounds", {}).get(c, (-math.inf, math.inf))
            if not lo <= v <= hi:
                problems.append(f"{end}.{c} = {v} outside its bound [{lo}, {hi}]")
    for c in task.get("periodic", []):
        a, b = task["initial"].get(c), task["final"].get(c)
        if a is not None and b is not None and a != b:
            problems.append(f"periodic {c}: fixed to {a} and {b}")
    fib = robot.base
    ini, fin = task["initial"], task["final"]
    move = math.hypot(fin[fib[0]] - ini[fib[0]], fin[fib[1]] - ini[fib[1]])
    if move < 1e-3 and abs(fin[fib[2]] - ini[fib[2]]) < 1e-3:
        problems.append("the target is the start")
    if not task["horizon"] > 0:
        problems.append("horizon not positive")
    return problems


# --------------------------------------------------------------------------- #
# pairs
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class Pair:
    """One robot and one task: ``scene`` is the scene file's text ([system] and [task])."""

    name: str
    seed: int
    index: int
    robot: Robot
    task: dict
    labels: dict
    scene: str

    @property
    def family(self) -> str:
        return self.robot.family

    @property
    def task_label(self) -> str:
        return "/".join(self.labels[k] for k in ("kind", "mode", "shape", "reach", "bounds"))


def tag(robot: Robot) -> str:
    """A short name of the robot's structure: chain4r (4 links, a rotor), car2 (2 trailers),
    sleigh1r (1 slider, a rotor), board."""
    rotor = "r" if any(f.name == "rotor" for f in robot.frames) else ""
    if robot.family == "chain":
        return f"chain{sum(f.name.startswith('link') for f in robot.frames)}{rotor}"
    if robot.family == "car":
        return f"car{sum(f.name.startswith('trailer') for f in robot.frames)}"
    if robot.family == "sleigh":
        return f"sleigh{len(robot.pushes)}{rotor}"
    return "board"


def pair(seed: int, index: int = 0, family: str | None = None, intervals: int = 40) -> Pair:
    """Pair number ``index`` of ``seed``: family ``FAMILIES[index % 4]`` unless given; every other
    choice from ``numpy.random.default_rng([seed, index])``."""
    family = family or FAMILIES[index % len(FAMILIES)]
    rng = np.random.default_rng([seed, index])
    probe = BUILDERS[family](rng, "robot")
    robot = Robot(**{**probe.__dict__, "name": f"{tag(probe)}_{seed}_{index}"})
    name = f"{tag(probe)}-{seed}-{index}"
    task, labels = make_task(rng, robot, intervals)
    problems = check_task(robot, task)
    if problems:
        raise ValueError(f"{name}: a meaningless task: " + "; ".join(problems))
    toml = sibling.load("scale_tasks").task_toml(task)
    return Pair(name, seed, index, robot, task, labels, system_toml(robot).rstrip("\n") + "\n\n" + toml)


def pairs(seed: int, count: int, intervals: int = 40, families=FAMILIES) -> list:
    """``count`` pairs of ``seed`` (indices 0 … count − 1) from ``families`` in turn."""
    return [pair(seed, i, families[i % len(families)], intervals) for i in range(count)]


if __name__ == "__main__":  # pragma: no cover - prints one scene file
    args = [int(a) for a in sys.argv[1:3]] + [0, 0]
    print(pair(args[0], args[1]).scene)
