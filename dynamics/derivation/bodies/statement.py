"""Reading a system stated as rigid bodies and wheels (``[[system.bodies]]``,
``[[system.wheels]]`` of a scene; docs/bodies.md) into frozen specifications with sympy
expressions in the parameters. Every problem of every table is collected.

Every geometric quantity is written in the **reference configuration** (every joint angle 0)
in the base frame: x forward, y left, z up, the origin on the ground at the base point (for a
bicycle, the rear wheel's contact point). A joint is a revolute joint given by its axis and a
point on it; a body's mass centre and inertia (about the mass centre) are given in that frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ..input.expressions import expression_problems

__all__ = ["BodySpec", "WheelSpec", "Multibody", "read_multibody", "BODY_KEYS", "WHEEL_KEYS", "BASE"]

BODY_KEYS = {"name", "parent", "joint", "axis", "point", "mass", "com", "inertia"}
WHEEL_KEYS = {"name", "parent", "spin", "centre", "axle", "radius", "mass", "inertia", "rolls"}
#: the parent name of a body attached to the planar base
BASE = "base"


@dataclass(frozen=True)
class BodySpec:
    """A rigid body moved relative to ``parent`` by the revolute joint ``joint`` (a coordinate
    name; None: fixed to the parent) about the unit ``axis`` through ``point``; ``mass``,
    mass centre ``com`` and ``inertia`` (3×3 about the mass centre) — all in the reference
    configuration."""

    name: str
    parent: str
    joint: str | None
    axis: sp.Matrix
    point: sp.Matrix
    mass: sp.Expr
    com: sp.Matrix
    inertia: sp.Matrix


@dataclass(frozen=True)
class WheelSpec:
    """A thin axisymmetric wheel on ``parent`` spinning by the coordinate ``spin`` about the unit
    ``axle`` through ``centre``; ``radius``, ``mass``, moments of inertia about a diameter and
    about the axle; ``rolls``: it rolls without slipping on the ground (z = 0)."""

    name: str
    parent: str
    spin: str
    centre: sp.Matrix
    axle: sp.Matrix
    radius: sp.Expr
    mass: sp.Expr
    diametral: sp.Expr
    axial: sp.Expr
    rolls: bool


@dataclass(frozen=True)
class Multibody:
    """The base coordinates (x, y, heading) of the planar base frame, the bodies (parents
    before children) and the wheels, and the gravity acceleration (along −z)."""

    base: tuple
    bodies: tuple
    wheels: tuple
    gravity: sp.Expr

    @property
    def joints(self) -> tuple[str, ...]:
        """Joint coordinate names in the order of the bodies."""
        return tuple(b.joint for b in self.bodies if b.joint)

    @property
    def coordinates(self) -> tuple[str, ...]:
        """q = (base, body joints, wheel spins)."""
        return tuple(self.base) + self.joints + tuple(w.spin for w in self.wheels)


def read_multibody(table: dict, names: dict, problems: list) -> Multibody | None:
    """The multibody statement of a ``[system]`` table with ``bodies``; ``names`` maps the
    parameter names to their symbols (the only names the expressions may use)."""
    start = len(problems)
    base = table.get("base", ["x", "y", "theta"])
    if not (isinstance(base, list) and len(base) == 3 and all(isinstance(c, str) for c in base)):
        problems.append("[system].base must name the three planar base coordinates (x, y, heading), "
                        f"got {base!r}")
        base = ["x", "y", "theta"]
    raw_bodies, raw_wheels = table.get("bodies", []), table.get("wheels", [])
    for key, value in (("bodies", raw_bodies), ("wheels", raw_wheels)):
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            problems.append(f"[system].{key} must be an array of tables ([[system.{key}]]), got "
                            f"{type(value).__name__}")
            return None
    reader = _Reader(names, problems)
    bodies = tuple(reader.body(b, i) for i, b in enumerate(raw_bodies))
    wheels = tuple(reader.wheel(w, i) for i, w in enumerate(raw_wheels))
    gravity = reader.scalar(table.get("gravity", "g"), "[system].gravity")
    _check_tree(tuple(base), bodies, wheels, problems)
    return None if len(problems) > start else Multibody(tuple(base), bodies, wheels, gravity)


class _Reader:
    """Expressions of one statement: numbers or parameter expressions, vectors, matrices."""

    def __init__(self, names: dict, problems: list):
        self.names, self.problems = names, problems

    def scalar(self, value, where):
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            self.problems.append(f"{where}: expected a number or an expression of the parameters, "
                                 f"got {value!r}")
            return sp.Integer(0)
        if isinstance(value, (int, float)):
            return sp.Integer(value) if isinstance(value, int) else sp.Float(repr(value))
        sub: list = []
        expr = expression_problems(value, self.names, where, sub, allow_unknown=True)
        unknown = sorted(s.name for s in getattr(expr, "free_symbols", ()) if s.name not in self.names)
        if unknown:
            sub.append(f"{where}: unknown name(s) {', '.join(unknown)} (only parameters: "
                       f"{', '.join(sorted(self.names)) or 'none declared'})")
        self.problems.extend(sub)
        return sp.Integer(0) if sub else expr

    def vector(self, value, where):
        if not isinstance(value, list) or len(value) != 3:
            self.problems.append(f"{where}: expected a list of 3 numbers or expressions, got {value!r}")
            return sp.zeros(3, 1)
        return sp.Matrix([self.scalar(v, f"{where}[{i}]") for i, v in enumerate(value)])

    def direction(self, value, where):
        """A unit vector (the given one normalised); zero is a problem."""
        v = self.vector(value, where)
        norm = sp.sqrt(sum(c ** 2 for c in v))
        if v == sp.zeros(3, 1):
            self.problems.append(f"{where}: the axis is zero")
            return sp.Matrix([1, 0, 0])
        return v if sp.simplify(norm - 1) == 0 else (v / norm).applyfunc(sp.simplify)

    def inertia(self, value, where):
        if value is None:
            return sp.zeros(3, 3)
        if not (isinstance(value, list) and len(value) == 3
                and all(isinstance(r, list) and len(r) == 3 for r in value)):
            self.problems.append(f"{where}: expected a 3×3 list of lists (about the mass centre), "
                                 f"got {value!r}")
            return sp.zeros(3, 3)
        M = sp.Matrix([[self.scalar(v, f"{where}[{i}][{j}]") for j, v in enumerate(row)]
                       for i, row in enumerate(value)])
        if M != M.T:
            self.problems.append(f"{where}: the inertia matrix is not symmetric")
        return M

    def keys(self, table, allowed, where):
        unknown = set(table) - allowed
        if unknown:
            self.problems.append(f"{where}: unknown key(s) {sorted(unknown)} (allowed: "
                                 f"{', '.join(sorted(allowed))})")
        for key in ("name", "parent"):
            if not isinstance(table.get(key), str):
                self.problems.append(f"{where}: {key} must be a name, got {table.get(key)!r}")

    def body(self, table, i) -> BodySpec:
        where = f"[[system.bodies]] {table.get('name', i + 1)!r}"
        self.keys(table, BODY_KEYS, where)
        joint = table.get("joint")
        if joint is not None and not isinstance(joint, str):
            self.problems.append(f"{where}: joint must be a coordinate name, got {joint!r}")
            joint = None
        moving = joint is not None
        return BodySpec(name=str(table.get("name")), parent=str(table.get("parent")), joint=joint,
                        axis=self.direction(table.get("axis"), f"{where}.axis") if moving
                        else sp.Matrix([1, 0, 0]),
                        point=self.vector(table.get("point"), f"{where}.point") if moving else sp.zeros(3, 1),
                        mass=self.scalar(table.get("mass", 0), f"{where}.mass"),
                        com=self.vector(table.get("com", [0, 0, 0]), f"{where}.com"),
                        inertia=self.inertia(table.get("inertia"), f"{where}.inertia"))

    def wheel(self, table, i) -> WheelSpec:
        where = f"[[system.wheels]] {table.get('name', i + 1)!r}"
        self.keys(table, WHEEL_KEYS, where)
        if not isinstance(table.get("spin"), str):
            self.problems.append(f"{where}: spin must name the wheel's rotation coordinate, got "
                                 f"{table.get('spin')!r}")
        inertia = table.get("inertia", [0, 0])
        if not (isinstance(inertia, list) and len(inertia) == 2):
            self.problems.append(f"{where}.inertia: expected [about a diameter, about the axle], got "
                                 f"{inertia!r}")
            inertia = [0, 0]
        rolls = table.get("rolls", True)
        if not isinstance(rolls, bool):
            self.problems.append(f"{where}.rolls must be true or false, got {rolls!r}")
        return WheelSpec(name=str(table.get("name")), parent=str(table.get("parent")),
                         spin=str(table.get("spin")),
                         centre=self.vector(table.get("centre"), f"{where}.centre"),
                         axle=self.direction(table.get("axle"), f"{where}.axle"),
                         radius=self.scalar(table.get("radius"), f"{where}.radius"),
                         mass=self.scalar(table.get("mass", 0), f"{where}.mass"),
                         diametral=self.scalar(inertia[0], f"{where}.inertia[0]"),
                         axial=self.scalar(inertia[1], f"{where}.inertia[1]"), rolls=rolls is not False)


def _check_tree(base, bodies, wheels, problems) -> None:
    """Names distinct, parents declared before their children, coordinates distinct."""
    seen = {BASE}
    for b in bodies:
        if b.name in seen:
            problems.append(f"body {b.name!r}: the name is used twice (or is {BASE!r}, the planar base)")
        if b.parent not in seen:
            problems.append(f"body {b.name!r}: its parent {b.parent!r} is not {BASE!r} or a body "
                            "declared before it")
        seen.add(b.name)
    for w in wheels:
        if w.parent not in seen:
            problems.append(f"wheel {w.name!r}: its parent {w.parent!r} is not {BASE!r} or a body")
    coordinates = list(base) + [b.joint for b in bodies if b.joint] + [w.spin for w in wheels]
    repeated = sorted({c for c in coordinates if coordinates.count(c) > 1})
    if repeated:
        problems.append(f"coordinates used twice (base, joints, wheel spins): {', '.join(repeated)}")
