"""Scene text of the scaling families of issue 8 (and the issue's two reproduction cases).

Each function returns the text of a scene file (TOML); ``system(name)`` parses it. The
Lagrangian is generated here from the positions of the bodies (T = Σ ½ m |v_G|² + ½ I ω²,
velocities by differentiation), the constraints from the velocities of the wheel contact
points. ``tests/oracles.py`` models the same robots independently (frames, bodies and
contact-point velocities in ``sympy.physics.mechanics``).

Families
--------
* ``cart_trailers(k)``: q = (x, y, theta, phi, beta1 … betak), n = 4 + k. A cart (axle midpoint
  (x, y), heading θ, centre of mass a ahead of the axle, mass m, inertia I) rolls on one driven
  wheel (radius rho, spin angle φ, spin inertia J_w) with no side slip; trailer i hangs on a
  hitch b behind the axle of the body ahead, its axle l_t behind the hitch, its centre of mass
  c_t behind the hitch (mass m_t, inertia I_t); βᵢ = heading of trailer i − heading of body i−1
  (relative hitch angles). Inputs: wheel torque tau_phi, steering torque tau_theta.
  Constraints: 2 + k (no side slip of every axle, rolling of the driven wheel).
* ``snake(N, rotor=False)``: q = (x, y, theta, [psi,] alpha1 … alpha_{N−1}), n = N + 2 (+1).
  N links of length 2 l_s (mass m_s, inertia I_s about the centre), an axle with no side slip
  at the centre of each link; (x, y) the centre of the head link, θ its heading, αⱼ the joint
  angle between link j and link j+1; joint torques tau_alpha<j>; an optional rotor (inertia
  J_r, angle ψ relative to the head) driven by tau_psi.
* ``cart_trailer_absolute()``: the cart with one trailer in absolute headings,
  q = (x, y, theta0, theta1, phi) (issue 8's first reproduction case).
* ``snakeboard_two_steering()``: a snakeboard whose front and back wheels steer independently,
  q = (x, y, theta, psi, phi_f, phi_b) (issue 8's second reproduction case).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

CART = {"m": 2.0, "I": 0.3, "a": 0.15, "rho": 0.1, "J_w": 0.02}
TRAILER = {"m_t": 1.0, "I_t": 0.12, "l_t": 0.6, "c_t": 0.35}
SNAKE = {"m_s": 1.0, "I_s": 0.08, "l_s": 0.25}
ROTOR = {"J_r": 0.05}
BOARD = {"m": 0.5, "J": 0.3, "J_r": 0.2, "J_w": 0.1, "r": 1.3784048752090221}


def _e(th):
    return sp.Matrix([sp.cos(th), sp.sin(th)])


def _n(th):
    return sp.Matrix([-sp.sin(th), sp.cos(th)])


def _velocity_text(coords):
    """Time derivative along q̇ of an expression of q (the velocity symbols `<q>_dot`)."""
    qs = [sp.Symbol(c, real=True) for c in coords]
    qds = [sp.Symbol(f"{c}_dot", real=True) for c in coords]

    def d(expr):
        return sum((sp.diff(expr, a) * b for a, b in zip(qs, qds, strict=True)), sp.Integer(0))
    return qs, d


def _compact(e):
    """A velocity expression grouped by its sines and cosines (short scene text)."""
    e = sp.expand(e)
    return sp.collect(e, sorted(e.atoms(sp.sin, sp.cos), key=sp.default_sort_key), func=sp.factor)


def _kinetic(points, angles, d):
    """Σ ½ m |ṗ|² + ½ I θ̇² for (mass, position) and (inertia, absolute angle) pairs, written
    as sums of squares of velocity components (as a user would write it)."""
    T = sp.Integer(0)
    for mass, pos in points:
        v = pos.applyfunc(d)
        T += mass * (_compact(v[0]) ** 2 + _compact(v[1]) ** 2) / 2
    for inertia, ang in angles:
        T += inertia * _compact(d(ang)) ** 2 / 2
    return T


def _trig_tidy(c):
    """Products of sin/cos to sums and back to sines/cosines of sums, masses collected (cheap,
    readable, and short enough for the scene parser's size limit)."""
    from sympy.simplify.fu import TR8, TR10i
    c = sp.factor_terms(TR10i(sp.expand(TR8(c))))
    masses = [sp.Symbol(n, real=True) for n in ("m_t", "m", "m_s")]
    return sp.collect(sp.expand(c), masses, func=sp.factor_terms)


def _tidy_form(expr, coords):
    """Collect a form in the velocities and trigsimp each coefficient (readable scene text)."""
    qds = [sp.Symbol(f"{c}_dot", real=True) for c in coords]
    poly = sp.Poly(sp.expand(expr), *qds)
    return sp.Add(*[_trig_tidy(c) * sp.Mul(*[v ** k for v, k in zip(qds, mon, strict=True)])
                    for mon, c in poly.terms()])


@dataclass(frozen=True)
class _Member:
    """One member of a family: its name and the comment line of its scene, the coordinates, the
    Lagrangian L (here the kinetic energy), the constraints, the forces (coordinate → input
    name; the inputs are these names, in this order) and the parameter values."""

    name: str
    description: str
    coords: list
    L: object
    constraints: list
    forces: dict
    params: dict

    def toml(self) -> str:
        """The member's scene text."""
        constraints = [_tidy_form(c, self.coords) for c in self.constraints]
        lines = [f"# {self.description}", "[system]", f'name = "{self.name}"',
                 "coordinates = [" + ", ".join(f'"{c}"' for c in self.coords) + "]",
                 f'lagrangian = "{sp.sstr(self.L)}"', "constraints = ["]
        lines += [f'  "{sp.sstr(c)}",' for c in constraints]
        lines += ["]", "inputs = [" + ", ".join(f'"{u}"' for u in self.forces.values()) + "]", "",
                  "[system.forces]"]
        lines += [f'{c} = "{f}"' for c, f in self.forces.items()]
        lines += ["", "[system.parameters]"] + [f"{k} = {v!r}" for k, v in self.params.items()]
        return "\n".join(lines) + "\n"


def _cart_chain(coords, headings, k, d):
    """Positions, constraints and T of the cart with k trailers (headings: absolute angles)."""
    x, y = (sp.Symbol(c, real=True) for c in coords[:2])
    P = {s: sp.Symbol(s, real=True) for s in (*CART, *TRAILER)}
    phi = sp.Symbol("phi", real=True)
    axle = sp.Matrix([x, y])
    th0 = headings[0]
    points = [(P["m"], axle + P["a"] * _e(th0))]
    angles = [(P["I"], th0), (P["J_w"], phi)]
    cons = [_n(th0).dot(axle.applyfunc(d)), _e(th0).dot(axle.applyfunc(d)) - P["rho"] * d(phi)]
    for i in range(1, k + 1):
        hitch = axle                       # on-axle hitching
        axle = hitch - P["l_t"] * _e(headings[i])
        points.append((P["m_t"], hitch - P["c_t"] * _e(headings[i])))
        angles.append((P["I_t"], headings[i]))
        cons.append(_n(headings[i]).dot(axle.applyfunc(d)))
    return _kinetic(points, angles, d), cons


def cart_trailers(k: int) -> str:
    """Scene text of the cart with ``k`` trailers in relative hitch angles (n = 4 + k)."""
    coords = ["x", "y", "theta", "phi"] + [f"beta{i}" for i in range(1, k + 1)]
    qs, d = _velocity_text(coords)
    th = qs[2]
    headings = [th]
    for i in range(k):
        headings.append(headings[-1] + qs[4 + i])
    T, cons = _cart_chain(coords, headings, k, d)
    params = {**CART, **(TRAILER if k else {})}
    return _Member(f"cart_trailers_{k}",
                   f"Cart with {k} trailer(s), relative hitch angles (experiments/scaling_systems.py).",
                   coords, T, cons, {"theta": "tau_theta", "phi": "tau_phi"}, params).toml()


def cart_trailer_absolute() -> str:
    """Scene text of the cart with one trailer in absolute headings (n = 5, k = 3)."""
    coords = ["x", "y", "theta0", "theta1", "phi"]
    qs, d = _velocity_text(coords)
    T, cons = _cart_chain(coords, [qs[2], qs[3]], 1, d)
    return _Member("cart_trailer_absolute",
                   "Cart with one trailer, absolute headings (issue 8 reproduction).",
                   coords, T, cons, {"theta0": "tau_theta", "phi": "tau_phi"}, {**CART, **TRAILER}).toml()


def snake(N: int, rotor: bool = False) -> str:
    """Scene text of the wheeled N-link snake (optionally with a rotor on the head link)."""
    joints = [f"alpha{j}" for j in range(1, N)]
    coords = ["x", "y", "theta"] + (["psi"] if rotor else []) + joints
    qs, d = _velocity_text(coords)
    P = {s: sp.Symbol(s, real=True) for s in (*SNAKE, *ROTOR)}
    th = qs[2]
    alphas = qs[4 if rotor else 3:]
    centre = sp.Matrix(qs[:2])
    heading = th
    points, angles, cons = [], [], []
    for i in range(N):
        if i:
            joint = centre - P["l_s"] * _e(heading)
            heading = heading + alphas[i - 1]
            centre = joint - P["l_s"] * _e(heading)
        points.append((P["m_s"], centre))
        angles.append((P["I_s"], heading))
        cons.append(_n(heading).dot(centre.applyfunc(d)))
    if rotor:
        angles.append((P["J_r"], th + qs[3]))
    T = _kinetic(points, angles, d)
    forces = {j: f"tau_{j}" for j in joints}
    if rotor:
        forces = {"psi": "tau_psi", **forces}
    params = {**SNAKE, **(ROTOR if rotor else {})}
    name = f"snake_{N}" + ("_rotor" if rotor else "")
    return _Member(name, f"Wheeled {N}-link snake{' with a head rotor' if rotor else ''} "
                         "(experiments/scaling_systems.py).", coords, T, cons, forces, params).toml()


def snakeboard_two_steering() -> str:
    """Scene text of a snakeboard whose wheels steer independently (n = 6, k = 2)."""
    coords = ["x", "y", "theta", "psi", "phi_f", "phi_b"]
    qs, d = _velocity_text(coords)
    x, y, th, psi, pf, pb = qs
    P = {s: sp.Symbol(s, real=True) for s in BOARD}
    centre = sp.Matrix([x, y])
    T = _kinetic([(P["m"], centre)], [(P["J"], th), (P["J_r"], th + psi), (P["J_w"], th + pf),
                                      (P["J_w"], th + pb)], d)
    front = centre + P["r"] * _e(th)
    back = centre - P["r"] * _e(th)
    cons = [_n(th + pb).dot(back.applyfunc(d)), _n(th + pf).dot(front.applyfunc(d))]
    return _Member("snakeboard_two_steering",
                   "Snakeboard with independently steered wheels (issue 8 reproduction).",
                   coords, T, cons, {"psi": "tau_psi", "phi_f": "tau_f", "phi_b": "tau_b"}, BOARD).toml()


def scene_text(name: str) -> str:
    """Scene text by family member name: cart_trailers_<k>, snake_<N>[_rotor],
    cart_trailer_absolute, snakeboard_two_steering."""
    if name.startswith("cart_trailers_"):
        return cart_trailers(int(name.rsplit("_", 1)[1]))
    if name.startswith("snake_") and name != "snakeboard_two_steering":
        parts = name.split("_")
        return snake(int(parts[1]), rotor=name.endswith("_rotor"))
    if name == "cart_trailer_absolute":
        return cart_trailer_absolute()
    if name == "snakeboard_two_steering":
        return snakeboard_two_steering()
    raise KeyError(name)


def system(name: str):
    """The :class:`~nhgait.dynamics.System` of a family member (parsed from its scene text)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    from nhgait.dynamics.derivation.input.scene import parse_scene
    return parse_scene(tomllib.loads(scene_text(name)), f"<{name}>").system


FAMILIES = {
    "cart_trailers": [f"cart_trailers_{k}" for k in range(6)],
    "snake": [f"snake_{N}" for N in range(2, 6)],
    "snake_rotor": [f"snake_{N}_rotor" for N in range(2, 6)],
    "reproduction": ["cart_trailer_absolute", "snakeboard_two_steering"],
}
