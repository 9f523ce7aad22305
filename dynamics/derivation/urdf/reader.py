"""Reading a URDF file into frozen records of links and joints (no symbolic work).

The reader is the standard library's expat parser with the document type declaration refused:
a URDF needs no DTD, and refusing it removes entity expansion (the "billion laughs" and
external-entity attacks) without a further dependency. Only what the dynamics needs is kept:
each link's ``<inertial>`` (mass, centre of mass and inertia tensor with the rotation of their
frame) and its collision cylinders (wheel radii); each joint's type, parent, child, origin,
axis, limits and ``<mimic>``. Elements a URDF may hold for other tools (``<transmission>``,
``<gazebo>``, ``<material>``, visuals, meshes) are skipped; a ``<joint>`` inside a
``<transmission>`` is not a joint of the tree.

Every problem found (malformed XML, a missing attribute, a number that is not one) is reported
in one :class:`~nhgait.dynamics.errors.ModelError` naming the element.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from xml.parsers import expat

import numpy as np

from ...errors import ModelError
from ..input.expressions import MAX_MAGNITUDE, finite_or_nan, magnitude_problem

#: joint types of the URDF specification
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


@dataclass(frozen=True)
class Inertial:
    """A link's mass properties: mass m, centre of mass ``com`` and rotation ``rotation`` of the
    inertial frame in the link frame, inertia tensor ``inertia`` (3×3, about the centre of mass,
    in the inertial frame)."""

    mass: float
    com: np.ndarray
    rotation: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Link:
    """A URDF ``<link>``: its inertial (None when massless) and its collision cylinders as
    (radius, rotation of the cylinder frame in the link frame) pairs (the cylinder's axis is the
    z axis of its frame)."""

    name: str
    inertial: Inertial | None
    cylinders: tuple = ()


@dataclass(frozen=True)
class Joint:
    """A URDF ``<joint>``: the child frame is ``origin`` (rotation, translation) in the parent
    frame followed by the motion along/about the unit ``axis``; ``mimic`` is (joint, multiplier,
    offset) or None; limits are None when absent."""

    name: str
    type: str
    parent: str
    child: str
    rotation: np.ndarray
    translation: np.ndarray
    axis: np.ndarray
    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None
    mimic: tuple | None = None


@dataclass(frozen=True)
class Robot:
    """A URDF ``<robot>``: links and joints by name, in file order."""

    name: str
    links: dict
    joints: dict
    source: str = "<urdf>"


def rpy_matrix(rpy) -> np.ndarray:
    """Rotation of URDF roll-pitch-yaw angles: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp_, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp_ * sr - sy * cr, cy * sp_ * cr + sy * sr],
                     [sy * cp, sy * sp_ * sr + cy * cr, sy * sp_ * cr - cy * sr],
                     [-sp_, cp * sr, cp * cr]])


def parse_xml(text: str, source: str) -> ET.Element:
    """The element tree of ``text``; a DTD (hence any entity declaration) is refused, malformed
    XML is one :class:`ModelError` with its line and column."""
    builder = ET.TreeBuilder()
    parser = expat.ParserCreate()

    def refuse(*_args):
        raise ModelError([f"{source}: a document type declaration (<!DOCTYPE ...>) is not allowed "
                          "in a URDF read by nhgait (entity expansion is refused)"], title="invalid URDF")

    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.StartElementHandler = lambda tag, attrs: builder.start(tag, attrs)
    parser.EndElementHandler = lambda tag: builder.end(tag)
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        raise ModelError([f"{source}: malformed XML: {expat.ErrorString(exc.code)} at line {exc.lineno}, "
                          f"column {exc.offset}"], title="invalid URDF") from None
    return builder.close()


def _floats(text, count, where, problems, default):
    """``count`` numbers from a whitespace-separated attribute (``default`` when absent)."""
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    try:
        values = np.array([float(v) for v in parts], dtype=float)
    except ValueError:
        problems.append(f"{where} = {text!r} is not {count} numbers")
        return np.array(default, dtype=float)
    if values.size != count or not np.all(np.isfinite(values)):
        problems.append(f"{where} = {text!r} is not {count} finite numbers")
        return np.array(default, dtype=float)
    if np.any(np.abs(values) > MAX_MAGNITUDE):
        problems.append(f"{where} = {text!r}: a value exceeds {MAX_MAGNITUDE:.0e} in magnitude, the largest "
                        "number nhgait accepts")
        return np.array(default, dtype=float)
    return values


def _number(element, key, where, problems, default=None):
    text = element.get(key) if element is not None else None
    if text is None:
        return default
    value = finite_or_nan(text)
    if math.isnan(value):
        problems.append(f"{where}: {key} = {text!r} is not a finite number")
        return default
    if math.isnan(magnitude_problem(value, f"{where}: {key}", problems)):
        return default
    return value


def _origin(element, where, problems):
    origin = element.find("origin")
    if origin is None:
        return np.eye(3), np.zeros(3)
    rpy = _floats(origin.get("rpy"), 3, f"{where} <origin rpy>", problems, [0, 0, 0])
    xyz = _floats(origin.get("xyz"), 3, f"{where} <origin xyz>", problems, [0, 0, 0])
    return rpy_matrix(rpy), xyz


def _inertial(link, where, problems):
    element = link.find("inertial")
    if element is None:
        return None
    rotation, com = _origin(element, f"{where} <inertial>", problems)
    mass = _number(element.find("mass"), "value", f"{where} <mass>", problems, default=0.0)
    if element.find("mass") is None:
        problems.append(f"{where}: <inertial> has no <mass>")
    if mass < 0:
        problems.append(f"{where}: negative mass {mass}")
    tensor = element.find("inertia")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    values = {k: _number(tensor, k, f"{where} <inertia>", problems, default=0.0) for k in keys}
    if tensor is None and mass > 0:
        problems.append(f"{where}: <inertial> has no <inertia>")
    inertia = np.array([[values["ixx"], values["ixy"], values["ixz"]],
                        [values["ixy"], values["iyy"], values["iyz"]],
                        [values["ixz"], values["iyz"], values["izz"]]])
    return Inertial(mass=mass, com=com, rotation=rotation, inertia=inertia)


def _cylinders(link, where, problems):
    out = []
    for collision in link.findall("collision"):
        cylinder = collision.find("geometry/cylinder")
        if cylinder is None:
            continue
        radius = _number(cylinder, "radius", f"{where} <cylinder>", problems)
        if radius is None or radius <= 0:
            problems.append(f"{where}: a collision <cylinder> needs a positive radius")
            continue
        out.append((radius, _origin(collision, f"{where} <collision>", problems)[0]))
    return tuple(out)


def _joint(element, where, problems):
    kind = element.get("type")
    if kind not in JOINT_TYPES:
        problems.append(f"{where}: type {kind!r} is not a URDF joint type ({', '.join(JOINT_TYPES)})")
    parent, child = element.find("parent"), element.find("child")
    names = [e.get("link") if e is not None else None for e in (parent, child)]
    for role, name in zip(("parent", "child"), names, strict=True):
        if not name:
            problems.append(f"{where}: no <{role} link=...>")
    rotation, translation = _origin(element, where, problems)
    axis_el = element.find("axis")
    axis = _floats(axis_el.get("xyz") if axis_el is not None else None, 3, f"{where} <axis xyz>",
                   problems, [1, 0, 0])
    norm = float(np.linalg.norm(axis))
    if kind in ("revolute", "continuous", "prismatic") and norm < 1e-12:
        problems.append(f"{where}: the axis is zero")
    axis = axis / norm if norm >= 1e-12 else axis
    limit = element.find("limit")
    lower = _number(limit, "lower", f"{where} <limit>", problems)
    upper = _number(limit, "upper", f"{where} <limit>", problems)
    mimic_el = element.find("mimic")
    mimic = None
    if mimic_el is not None:
        if not mimic_el.get("joint"):
            problems.append(f"{where}: <mimic> names no joint")
        else:
            mimic = (mimic_el.get("joint"),
                     _number(mimic_el, "multiplier", f"{where} <mimic>", problems, 1.0),
                     _number(mimic_el, "offset", f"{where} <mimic>", problems, 0.0))
    return Joint(name=element.get("name"), type=kind or "", parent=names[0] or "", child=names[1] or "",
                 rotation=rotation, translation=translation, axis=axis, lower=lower, upper=upper,
                 effort=_number(limit, "effort", f"{where} <limit>", problems),
                 velocity=_number(limit, "velocity", f"{where} <limit>", problems), mimic=mimic)


def _link(element, where, problems) -> Link:
    return Link(element.get("name"), _inertial(element, where, problems),
                _cylinders(element, where, problems))


def _named_elements(root, tag, read, problems) -> dict:
    """The ``<tag>`` elements of ``root`` by name, each read by ``read(element, where,
    problems)``; a missing or repeated name is a problem."""
    out = {}
    for element in root.findall(tag):
        name = element.get("name")
        where = f"{tag} {name!r}"
        if not name:
            problems.append(f"a <{tag}> has no name")
        elif name in out:
            problems.append(f"{where} is defined twice")
        else:
            out[name] = read(element, where, problems)
    return out


def read_urdf(text: str, source: str = "<urdf>") -> Robot:
    """The links and joints of a URDF document; every problem in one :class:`ModelError`."""
    root = parse_xml(text, source)
    problems: list = []
    if root.tag != "robot":
        raise ModelError([f"{source}: the root element is <{root.tag}>, not <robot>"], title="invalid URDF")
    links = _named_elements(root, "link", _link, problems)
    joints = _named_elements(root, "joint", _joint, problems)
    if not links:
        problems.append(f"{source}: no <link>")
    if problems:
        raise ModelError(problems, title=f"invalid URDF {source}")
    return Robot(name=root.get("name", "robot"), links=links, joints=joints, source=source)
