"""The kinematic tree of a URDF and its rigid bodies: links joined by fixed or locked joints are
merged into one body (mass, centre of mass and inertia summed numerically), so the symbolic
work is done once per *moving* body only.

A body is the child link of a joint kept as a coordinate (or of a joint that mimics one), or the
root link. Its frame is that link's frame; ``rotation``/``translation`` place the joint frame
(before the joint's own motion) in the parent body's frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .reader import Joint, Robot

MOVING = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class Body:
    """A rigid body of the reduced tree.

    ``joint`` moves it relative to body ``parent`` (None for the root); its value is
    ``multiplier * coordinate + offset`` (``coordinate`` an index into the joint coordinates).
    ``mass``, ``com`` (body frame) and ``inertia`` (about ``com``, body frame) are the merged
    mass properties; ``frames`` maps every merged link to its (rotation, translation) in the
    body frame.
    """

    link: str
    joint: Joint | None
    parent: int | None
    rotation: np.ndarray
    translation: np.ndarray
    coordinate: int | None
    multiplier: float
    offset: float
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    frames: dict = field(default_factory=dict)


class TreeCheck(NamedTuple):
    """The ``problems`` of a URDF tree (sentences) and its ``root`` link's name (None when
    there is no root)."""

    problems: list
    root: str | None


def tree_problems(robot: Robot) -> TreeCheck:
    """Problems of the tree (unknown links, a link with two parents, a cycle, no or several
    roots, floating or planar joints) and the root link's name."""
    problems = []
    parent_of = {}
    for joint in robot.joints.values():
        for role, link in (("parent", joint.parent), ("child", joint.child)):
            if link and link not in robot.links:
                problems.append(f"joint {joint.name!r}: its {role} link {link!r} is not a <link> of the file")
        if joint.type in ("floating", "planar"):
            problems.append(f"joint {joint.name!r} is {joint.type}: nhgait gives the root link its planar "
                            "motion (base = \"planar\"); remove the joint and root the URDF at "
                            "its child link")
        if joint.child in parent_of:
            problems.append(f"link {joint.child!r} is the child of two joints "
                            f"({parent_of[joint.child].name!r} "
                            f"and {joint.name!r}): a closed loop, and a URDF states a tree")
        else:
            parent_of[joint.child] = joint
    roots = [name for name in robot.links if name not in parent_of]
    if not roots:
        problems.append("no root link: every link is the child of a joint (a closed loop)")
    elif len(roots) > 1:
        problems.append(f"several root links {roots}: the links do not form one tree")
    root = roots[0] if len(roots) == 1 else None
    if root is not None:
        seen, stack = {root}, [root]
        children = _children(robot)
        while stack:
            for joint in children.get(stack.pop(), ()):
                if joint.child not in seen:
                    seen.add(joint.child)
                    stack.append(joint.child)
        cut_off = [name for name in robot.links if name not in seen]
        if cut_off:
            problems.append(f"links {cut_off} are not reached from the root {root!r}: a closed loop")
    return TreeCheck(problems, root)


def _children(robot: Robot) -> dict:
    out: dict = {}
    for joint in robot.joints.values():
        out.setdefault(joint.parent, []).append(joint)
    return out


def joint_motion(joint: Joint, value: float) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, translation) of a joint's motion at ``value`` (numeric)."""
    if joint.type in ("revolute", "continuous"):
        return axis_rotation(joint.axis, value), np.zeros(3)
    if joint.type == "prismatic":
        return np.eye(3), joint.axis * value
    return np.eye(3), np.zeros(3)


def axis_rotation(axis, angle) -> np.ndarray:
    """Rodrigues' formula R = cos·E + sin·[a]× + (1 − cos)·a aᵀ for a unit axis a."""
    a = np.asarray(axis, dtype=float)
    cross = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.cos(angle) * np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * np.outer(a, a)


def build_bodies(robot: Robot, root: str, coordinates: dict, locked: dict) -> list:
    """The moving bodies of the tree, root first (parents before children).

    ``coordinates`` maps a joint name to its coordinate index; ``locked`` maps a joint name to
    its fixed value (joints in neither are held at 0, fixed joints merged). A joint that mimics a
    coordinate joint moves its child as ``multiplier * q + offset``.
    """
    children = _children(robot)
    placed: list = []        # per body: its placement (Body fields but the mass properties)
    frames: list = []        # per body: link → (rotation, translation) in the body frame

    def value_of(joint):
        if joint.mimic and joint.mimic[0] not in coordinates:
            source = robot.joints.get(joint.mimic[0])
            base = locked.get(joint.mimic[0], 0.0) if source is not None else 0.0
            return joint.mimic[1] * base + joint.mimic[2]
        return locked.get(joint.name, 0.0)

    def moving(joint):
        if joint.type not in MOVING:
            return None
        if joint.name in coordinates:
            return coordinates[joint.name], 1.0, 0.0
        if joint.mimic and joint.mimic[0] in coordinates:
            return coordinates[joint.mimic[0]], joint.mimic[1], joint.mimic[2]
        return None

    def add_body(**placement):
        placed.append(placement)
        frames.append({})
        return len(placed) - 1

    # depth first, parents before children, in file order: an explicit stack, so that a chain
    # of any length (1000 fixed links) needs no recursion. An item is a link to place in a body
    # ("link") or a joint to cross from its parent link's placement ("joint").
    add_body(link=root, joint=None, parent=None, rotation=np.eye(3), translation=np.zeros(3),
             coordinate=None, multiplier=1.0, offset=0.0)
    stack = [("link", root, 0, np.eye(3), np.zeros(3))]
    while stack:
        kind, item, body_index, rotation, translation = stack.pop()
        if kind == "link":
            frames[body_index][item] = (rotation, translation)
            stack.extend(("joint", joint, body_index, rotation, translation)
                         for joint in reversed(children.get(item, ())))
            continue
        joint = item
        origin_r = rotation @ joint.rotation
        origin_t = translation + rotation @ joint.translation
        motion = moving(joint)
        if motion is None:
            r, t = joint_motion(joint, value_of(joint))
            stack.append(("link", joint.child, body_index, origin_r @ r, origin_t + origin_r @ t))
        else:
            index = add_body(link=joint.child, joint=joint, parent=body_index, rotation=origin_r,
                             translation=origin_t, coordinate=motion[0], multiplier=motion[1],
                             offset=motion[2])
            stack.append(("link", joint.child, index, np.eye(3), np.zeros(3)))
    bodies = []
    for placement, body_frames in zip(placed, frames, strict=True):
        mass, com, inertia = _mass_properties(body_frames, robot)
        bodies.append(Body(**placement, mass=mass, com=com, inertia=inertia, frames=body_frames))
    return bodies


def _mass_properties(frames: dict, robot: Robot) -> tuple:
    """(mass, centre of mass, inertia about it) of the links in ``frames``, in the body frame
    (parallel-axis theorem)."""
    parts = []
    for link_name, (rotation, translation) in frames.items():
        inertial = robot.links[link_name].inertial
        if inertial is None or (inertial.mass == 0 and not np.any(inertial.inertia)):
            continue
        frame = rotation @ inertial.rotation
        parts.append((inertial.mass, translation + rotation @ inertial.com,
                      frame @ inertial.inertia @ frame.T))
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass if mass > 0 else np.zeros(3)
    inertia = np.zeros((3, 3))
    for m, c, tensor in parts:
        d = c - com
        inertia += tensor + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, inertia
