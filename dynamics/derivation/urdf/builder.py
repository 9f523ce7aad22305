"""A :class:`~nhgait.dynamics.derivation.system.System` from a URDF and the ``[system]`` keys of a scene
(docs/scene-format.md, "Systems from a URDF").

q = (x, y, theta, joints...): the root link's pose on the ground plane and the joints kept as
coordinates (named as in the URDF); L = T − V from :mod:`.energy`; the constraints of the
rolling wheels and skates from :mod:`.wheels` (rows that are combinations of others, such as
the second side-slip row of two wheels on one axle, are dropped and listed in ``notes``); the
generalized force on a joint is its input symbol. Input bounds default to the joints' effort
limits, state bounds to their position and velocity limits.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np
import sympy as sp

from ...errors import ModelError
from ..input.textfiles import read_text_file
from . import energy, wheels
from .mass_parameters import mass_problems, with_mass_parameters
from .reader import read_urdf
from .tree import MOVING, build_bodies, tree_problems

KEYS = {"urdf", "base", "joints", "names", "locked", "rolling", "skates", "radius", "inputs", "gravity",
        "name", "description", "forces", "parameters", "fiber", "planar_frame", "masses"}
BASE_COORDINATES = ("x", "y", "theta")
#: ``urdf = "example-robot-data:<path>"`` names a file of the installed example-robot-data package
ROBOT_DATA = "example-robot-data:"


@dataclass(frozen=True)
class UrdfSystem:
    """The System built from a URDF, with what the URDF says beyond it: ``control_bounds``
    (input → (lo, hi) from effort limits), ``bounds`` (coordinate or velocity → (lo, hi) from
    joint limits) and ``notes`` (constraint rows dropped as dependent)."""

    system: object
    control_bounds: dict = field(default_factory=dict)
    bounds: dict = field(default_factory=dict)
    notes: tuple = ()
    source: str = ""

    def to_text(self) -> str:
        """The generated system: L = T − V, the constraints ω(q)q̇ = 0, the forces, the limits."""
        s = self.system
        lines = [f"System {s.name} from the URDF {self.source}: n = {s.n} coordinates "
                 f"({', '.join(s.coordinates)}), k = {s.k} constraints",
                 f"  L = {sp.sstr(s.L)}"]
        lines += [f"  0 = {sp.sstr(c)}" for c in s.constraint_exprs]
        lines += [f"  force on {c}: {sp.sstr(f)}"
                  for c, f in zip(s.coordinates, s.tau, strict=True) if f != 0]
        lines += [f"  {name} in [{lo:g}, {hi:g}] (URDF limit)" for name, (lo, hi) in
                  {**self.control_bounds, **self.bounds}.items()]
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines)


def resolve_path(text: str, base_dir: Path) -> Path:
    """The URDF file a scene names: relative to the scene's folder, or inside the installed
    example-robot-data package (``example-robot-data:tiago_description/robots/tiago.urdf``).

    A scene is data from anyone, so the file must lie (after following links) inside the
    scene's own folder tree, inside example-robot-data's robots, or inside a folder the user
    allows in ``$NHGAIT_URDF_PATH`` (folders separated by ``os.pathsep``); anything else —
    ``/etc/shadow``, ``../../../etc/passwd`` — is refused before the file is opened, and the
    message does not say whether it exists."""
    if text.startswith(ROBOT_DATA):
        try:
            dist = metadata.distribution("example-robot-data")
        except metadata.PackageNotFoundError:
            raise ModelError([f"urdf = {text!r} needs the example-robot-data package "
                              "(pip install 'nhgait[pinocchio]')"], title="unknown URDF") from None
        root = Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
        return _inside(root / text[len(ROBOT_DATA):], [root], text, "example-robot-data's robots folder")
    path = Path(text)
    path = path if path.is_absolute() else base_dir / path
    return _inside(path, [base_dir, *allowed_urdf_folders()], text, f"the scene's folder {base_dir}")


#: folders (``os.pathsep``-separated) from which a scene may read URDFs besides its own folder tree
URDF_PATH_VARIABLE = "NHGAIT_URDF_PATH"


def allowed_urdf_folders() -> list:
    """The folders of ``$NHGAIT_URDF_PATH`` (the user's explicit permission)."""
    import os
    return [Path(f).expanduser() for f in os.environ.get(URDF_PATH_VARIABLE, "").split(os.pathsep) if f]


def _inside(path: Path, roots: list, text: str, where: str) -> Path:
    """``path`` when it resolves (links followed) inside one of ``roots``; else a ModelError."""
    resolved = path.resolve()
    for root in roots:
        if resolved.is_relative_to(Path(root).resolve()):
            return path
    raise ModelError([f"[system].urdf = {text!r} is outside {where}: a scene may name a URDF inside its own "
                      f"folder tree or 'example-robot-data:<path>'; to allow another folder, add it to "
                      f"${URDF_PATH_VARIABLE}"], title="URDF refused")


def _names(table, key, problems) -> list:
    value = table.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        problems.append(f"[system].{key} must be a list of joint names, got {value!r}")
        return []
    return value


def _mapping(table, key, problems, kind) -> dict:
    value = table.get(key, {})
    if not isinstance(value, dict):
        problems.append(f"[system].{key} must be a table of joint = {kind}, got {value!r}")
        return {}
    return value


def _numbers(table, key, problems) -> dict:
    out = {}
    for name, value in _mapping(table, key, problems, "number").items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            problems.append(f"[system].{key}.{name} must be a number, got {value!r}")
        else:
            out[name] = float(value)
    return out


def _check_keys(table, problems):
    unknown = set(table) - KEYS
    if unknown:
        problems.append(f"[system]: unknown key(s) {sorted(unknown)} with urdf (allowed: "
                        f"{', '.join(sorted(KEYS))})")
    if table.get("base", "planar") != "planar":
        problems.append(f"[system].base = {table.get('base')!r}: only \"planar\" (the root link "
                        "moves in SE(2) on the ground plane) is supported")
    for key in ("forces", "parameters"):
        if not isinstance(table.get(key, {}), dict):
            problems.append(f"[system].{key} must be a table, got {table.get(key)!r}")
    gravity = table.get("gravity", 9.81)
    if isinstance(gravity, bool) or not isinstance(gravity, (int, float)) or not math.isfinite(gravity):
        problems.append(f"[system].gravity must be a number (m/s²), got {gravity!r}")


def _joint_problems(robot, spec, problems):
    """Names in the scene that do not fit the URDF's joints."""
    joints = robot.joints
    known = ", ".join(name for name, j in joints.items() if j.type in MOVING)

    def check(name, where, movable=True):
        if name not in joints:
            problems.append(f"[system].{where}: unknown joint {name!r} (movable joints: {known})")
            return False
        if movable and joints[name].type not in MOVING:
            problems.append(f"[system].{where}: joint {name!r} is {joints[name].type}, not movable")
            return False
        return True

    for name in spec.joints:
        if check(name, "joints") and joints[name].mimic:
            problems.append(f"[system].joints: joint {name!r} mimics {joints[name].mimic[0]!r}; "
                            "keep that one")
    for name, value in spec.locked.items():
        if not check(name, "locked"):
            continue
        joint = joints[name]
        if name in spec.joints:
            problems.append(f"[system].locked: joint {name!r} is also a coordinate")
        elif joint.type != "continuous" and joint.lower is not None and joint.upper is not None \
                and not joint.lower <= value <= joint.upper:
            problems.append(f"[system].locked.{name} = {value:g} is outside the joint's limits "
                            f"[{joint.lower:g}, {joint.upper:g}]")
    for key in ("rolling", "skates"):
        for name in spec.wheels(key):
            if check(name, key) and joints[name].type == "prismatic":
                problems.append(f"[system].{key}: joint {name!r} is prismatic; a wheel turns about its axle")
    for name in spec.rolling:
        if name in joints and name not in spec.joints:
            problems.append(f"[system].rolling: wheel {name!r} must be a coordinate (list it in joints)")
    for name in set(spec.rolling) & set(spec.skates):
        problems.append(f"[system]: joint {name!r} is both rolling and a skate")
    for name in spec.radius:
        if name not in spec.rolling:
            problems.append(f"[system].radius: {name!r} is not a rolling wheel")
    for name, alias in spec.names.items():
        if name not in spec.joints:
            problems.append(f"[system].names: {name!r} is not a joint kept as a coordinate")
        if not isinstance(alias, str) or not alias.isidentifier():
            problems.append(f"[system].names.{name} must be an identifier, got {alias!r}")
    for name, symbol in spec.inputs.items():
        if name not in spec.joints:
            problems.append(f"[system].inputs: {name!r} is not a joint kept as a coordinate")
        if not isinstance(symbol, str) or not symbol.isidentifier():
            problems.append(f"[system].inputs.{name} must be the input's name, got {symbol!r}")


def wheel_radius(robot, joint, given, problems):
    """The wheel's radius: ``radius = {joint = ...}`` or its child link's collision cylinder,
    which must share the joint's axis."""
    if joint.name in given:
        if given[joint.name] <= 0:
            problems.append(f"[system].radius.{joint.name} must be positive")
        return given[joint.name]
    cylinders = robot.links[joint.child].cylinders
    if not cylinders:
        problems.append(f"wheel {joint.name!r}: link {joint.child!r} has no collision cylinder; "
                        f"give radius = {{{joint.name} = ...}}")
        return None
    radius, rotation = cylinders[0]
    if abs(abs(float(rotation[:, 2] @ joint.axis)) - 1) > 1e-6:
        problems.append(f"wheel {joint.name!r}: the collision cylinder of {joint.child!r} is not "
                        f"coaxial with the joint axis; give radius = {{{joint.name} = ...}}")
        return None
    return radius


@dataclass(frozen=True)
class _Spec:
    """The URDF keys of a scene's ``[system]`` table: the joints kept as coordinates, the locked
    joints (name → value), the rolling wheels and skates, the given wheel radii, the inputs
    (joint → input name) and the coordinate names (joint → name)."""

    joints: list
    locked: dict
    rolling: list
    skates: list
    radius: dict
    inputs: dict
    names: dict
    masses: dict = field(default_factory=dict)

    def wheels(self, key: str) -> list:
        """The joints listed under ``key`` ("rolling" or "skates")."""
        return self.rolling if key == "rolling" else self.skates


def _spec(table, problems) -> _Spec:
    return _Spec(joints=_names(table, "joints", problems), locked=_numbers(table, "locked", problems),
                 rolling=_names(table, "rolling", problems), skates=_names(table, "skates", problems),
                 radius=_numbers(table, "radius", problems),
                 inputs=_mapping(table, "inputs", problems, "input name"),
                 names=_mapping(table, "names", problems, "coordinate name"),
                 masses=_mapping(table, "masses", problems, "parameter name"))


def coordinate_name(spec, joint: str) -> str:
    """The coordinate of a joint: its ``names = {...}`` entry, else the joint's own name."""
    return spec.names.get(joint, joint)


def urdf_system(table: dict, base_dir: Path, source: str = "<scene>") -> UrdfSystem:
    """The :class:`UrdfSystem` of a scene's ``[system]`` table with ``urdf = ...``; every problem
    (scene keys, the URDF file, the tree, the wheels, then the System's own checks) in one
    :class:`ModelError`."""
    problems: list = []
    _check_keys(table, problems)
    spec = _spec(table, problems)
    robot = _robot(table.get("urdf"), base_dir, problems)
    root = None
    if robot is not None:
        tree, root = tree_problems(robot)
        problems.extend(tree)
        _joint_problems(robot, spec, problems)
        problems.extend(mass_problems(robot, spec.masses, table.get("parameters", {})))
    if problems:
        raise ModelError(problems, title=f"invalid scene {source}")
    return _build(robot, root, spec, table, source)


def _robot(text, base_dir, problems):
    """The parsed URDF named by ``urdf = ...`` (None after recording its problems)."""
    if not isinstance(text, str):
        problems.append(f"[system].urdf must be a file name, got {text!r}")
        return None
    try:
        path = resolve_path(text, base_dir)
    except ModelError as exc:
        problems.extend(exc.problems)
        return None
    if not path.exists():
        problems.append(f"[system].urdf: file {path} does not exist")
        return None
    try:
        return read_urdf(read_text_file(path, "URDF"), str(path))
    except ModelError as exc:
        problems.extend(exc.problems)
        return None


def _lagrangian(bodies, kin, q, q_dot, gravity):
    """L = T − V: T expanded entry by entry within the budget, else a sum over bodies."""
    V = energy.potential(bodies, kin, gravity)
    if energy.expansion_size(kin) <= energy.EXPANSION_BUDGET:
        K = energy.metric_in_nu(bodies, kin)
        return energy.lagrangian(energy.metric_in_qdot(K, q[2], sum(b.mass for b in bodies)), V, q_dot)
    c, s = sp.cos(q[2]), sp.sin(q[2])
    nu = [c * q_dot[0] + s * q_dot[1], -s * q_dot[0] + c * q_dot[1]] + q_dot[2:]
    return energy.nested_kinetic_energy(bodies, kin, nu) - V


def _build(robot, root, spec, table, source) -> UrdfSystem:
    names = list(BASE_COORDINATES) + [coordinate_name(spec, j) for j in spec.joints]
    q = [sp.Symbol(n, real=True) for n in names]
    q_dot = [sp.Symbol(f"{n}_dot", real=True) for n in names]
    bodies, kin = _tree(robot, root, spec, q)
    problems: list = []
    rows = _wheel_rows(robot, bodies, kin, spec, q, problems)
    if problems:
        raise ModelError(problems, title=f"invalid scene {source}")
    L = _lagrangian(bodies, kin, q, q_dot, float(table.get("gravity", 9.81)))
    L, masses = with_mass_parameters(L, robot, spec.masses, lambda alone: _lagrangian(
        *_tree(alone, root, spec, q), q, q_dot, float(table.get("gravity", 9.81))))
    exprs = [wheels.in_qdot(r, q[2], q_dot) for r in rows]
    kept = wheels.independent_rows(exprs, (q[2:], q_dot)) if exprs else []
    notes = tuple(f"constraint {i + 1} of the wheels dropped: a combination of the others" for i in
                  range(len(exprs)) if i not in kept)
    forces = {coordinate_name(spec, j): sp.Symbol(symbol, real=True) for j, symbol in spec.inputs.items()}
    for name, value in table.get("forces", {}).items():
        forces[name] = value if name not in forces else f"{forces[name]} + ({value})"
    declared = list(spec.inputs.values()) if spec.inputs or "forces" not in table else None
    from ..system import System
    try:
        system = System(coordinates=names, lagrangian=L, constraints=[exprs[i] for i in kept], forces=forces,
                        parameters={**table.get("parameters", {}), **masses}, inputs=declared,
                        name=table.get("name", robot.name), fiber=table.get("fiber"),
                        planar_frame=table.get("planar_frame", "auto"))
    except ModelError as exc:
        raise ModelError(list(exc.problems), title=f"invalid scene {source}") from None
    return UrdfSystem(system=system, control_bounds=_effort_bounds(robot, spec),
                      bounds=_limit_bounds(robot, spec), notes=notes, source=robot.source)


def _tree(robot, root, spec, q) -> tuple:
    """(bodies, their kinematics) of the tree with the scene's coordinates and locked joints."""
    bodies = build_bodies(robot, root, {name: i for i, name in enumerate(spec.joints)}, spec.locked)
    return bodies, energy.body_kinematics(bodies, q[3:])


def _wheel_rows(robot, bodies, kin, spec, q, problems) -> list:
    """Constraint rows in ν of every rolling wheel (two) and skate (one), in scene order."""
    samples = np.random.default_rng(5).uniform(-1.2, 1.2, (4, len(q) - 3))
    rows = []
    for key in ("rolling", "skates"):
        for name in spec.wheels(key):
            joint = robot.joints[name]
            index, rotation, translation = wheels.wheel_frame(bodies, joint.child)
            radius = wheel_radius(robot, joint, spec.radius, problems) if key == "rolling" else None
            if key == "rolling" and radius is None:
                continue
            tilt = wheels.axle_tilt(kin[index], rotation, joint.axis, q[3:], samples)
            if tilt > wheels.HORIZONTAL:
                problems.append(f"wheel {name!r}: its axle is not horizontal (|a·n| up to {tilt:.3g}), so it "
                                "cannot roll on the ground plane")
                continue
            if radius is not None:
                heights = wheels.centre_heights(kin[index], translation, q[3:], samples)
                if np.max(np.abs(heights - radius)) > 1e-6 * max(radius, 1e-3):
                    problems.append(f"wheel {name!r}: its centre is at height {heights[0]:.6g} m, "
                                    f"its radius is {radius:.6g} m: it does not touch the ground (z = 0 of "
                                    "the root link)")
                    continue
            side, roll = wheels.wheel_rows(kin[index], rotation, translation, joint.axis, radius)
            rows += [side] + ([roll] if roll is not None else [])
    return rows


def _effort_bounds(robot, spec) -> dict:
    out = {}
    for name, symbol in spec.inputs.items():
        effort = robot.joints[name].effort
        if effort is not None and effort > 0:
            out[symbol] = (-effort, effort)
    return out


def _limit_bounds(robot, spec) -> dict:
    out = {}
    for joint_name in spec.joints:
        joint, name = robot.joints[joint_name], coordinate_name(spec, joint_name)
        if joint.type != "continuous" and joint.lower is not None and joint.upper is not None \
                and joint.lower < joint.upper:
            out[name] = (joint.lower, joint.upper)
        if joint.velocity is not None and joint.velocity > 0:
            out[f"{name}_dot"] = (-joint.velocity, joint.velocity)
    return out
