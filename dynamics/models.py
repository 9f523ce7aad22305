"""Built-in systems: the thesis's two examples and two more that exercise other structures.

Each factory returns a fresh :class:`~nhgait.dynamics.system.System`; the same systems ship as
scene files in ``nhgait/dynamics/scenes/`` (see :func:`nhgait.dynamics.scene.builtin_scene`).
"""
from __future__ import annotations

import math

from .system import System

#: thesis parameters of the snakeboard (§3.3, simulation of Example 3.2)
SNAKEBOARD_PARAMETERS = {"m": 0.5, "J": 0.3, "J_r": 0.2, "J_w": 0.1}
SNAKEBOARD_PARAMETERS["r"] = math.sqrt((SNAKEBOARD_PARAMETERS["J"] + SNAKEBOARD_PARAMETERS["J_r"]
                                        + 2 * SNAKEBOARD_PARAMETERS["J_w"]) / SNAKEBOARD_PARAMETERS["m"])


def unicycle(**parameters) -> System:
    """Vertical rolling disc (thesis Examples 2.2, 2.3, 3.1).

    q = (x, y, theta, phi): contact point, heading, rolling angle. L = eq. 2.9, constraints
    eq. 2.10, torques tau_theta (steering) and tau_phi (rolling). Defaults: the thesis's
    simulation parameters m = 0.5, r = 0.1, J_phi = 0.2, J_theta = 0.3.
    """
    params = {"m": 0.5, "r": 0.1, "J_phi": 0.2, "J_theta": 0.3}
    params.update(parameters)
    return System(
        name="unicycle",
        coordinates=["x", "y", "theta", "phi"],
        lagrangian="m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2",
        constraints=["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"],
        forces={"theta": "tau_theta", "phi": "tau_phi"},
        parameters=params,
        inputs=["tau_theta", "tau_phi"],
    )


def snakeboard(**parameters) -> System:
    """Snakeboard (thesis Example 3.2).

    q = (x, y, theta, psi, phi): board centre, board heading, rotor angle relative to the board,
    wheel steering angle (front +phi, back −phi). L = eq. 3.54 (general inertias; the thesis's
    3.55 is the special case J + J_r + 2J_w = m r²). Constraints eq. 3.56 (the printed matrix 3.57
    swaps the rows' angles; see docs/thesis-errata.md). Torques tau_psi (rotor) and tau_phi
    (steering). Defaults: m = 0.5, J = 0.3, J_r = 0.2, J_w = 0.1, r = √((J+J_r+2J_w)/m).
    """
    params = dict(SNAKEBOARD_PARAMETERS)
    params.update(parameters)
    return System(
        name="snakeboard",
        coordinates=["x", "y", "theta", "psi", "phi"],
        lagrangian=("m*(x_dot**2 + y_dot**2)/2 + J*theta_dot**2/2 + J_r*(theta_dot + psi_dot)**2/2"
                    " + J_w*(theta_dot - phi_dot)**2/2 + J_w*(theta_dot + phi_dot)**2/2"),
        constraints=["-sin(theta - phi)*x_dot + cos(theta - phi)*y_dot - r*cos(phi)*theta_dot",
                     "-sin(theta + phi)*x_dot + cos(theta + phi)*y_dot + r*cos(phi)*theta_dot"],
        forces={"psi": "tau_psi", "phi": "tau_phi"},
        parameters=params,
        inputs=["tau_psi", "tau_phi"],
    )


def chaplygin_sleigh(**parameters) -> System:
    """Chaplygin sleigh: a rigid body on a knife edge; no shape variables (m = 0).

    q = (x, y, theta): knife-edge contact point and heading; the centre of mass is a distance
    ``a`` ahead of the contact point. Inputs: thrust F along the heading at the contact point,
    torque tau. One constraint (no lateral slip of the contact point).
    """
    params = {"m": 1.0, "I_c": 0.2, "a": 0.3}
    params.update(parameters)
    return System(
        name="chaplygin_sleigh",
        coordinates=["x", "y", "theta"],
        lagrangian=("m*((x_dot - a*sin(theta)*theta_dot)**2 + (y_dot + a*cos(theta)*theta_dot)**2)/2"
                    " + I_c*theta_dot**2/2"),
        constraints=["-sin(theta)*x_dot + cos(theta)*y_dot"],
        forces={"x": "F*cos(theta)", "y": "F*sin(theta)", "theta": "tau"},
        parameters=params,
        inputs=["F", "tau"],
        fiber=["x", "y", "theta"],
    )


def knife_edge_incline(**parameters) -> System:
    """Knife edge (skate) on an inclined plane: gravity, V(q) ≠ 0, principally kinematic.

    q = (x, y, theta), x down the slope. V = −m g sin(alpha) x. Input: steering torque tau.
    """
    params = {"m": 1.0, "I": 0.1, "g": 9.81, "alpha": 0.3}
    params.update(parameters)
    return System(
        name="knife_edge_incline",
        coordinates=["x", "y", "theta"],
        lagrangian="m*(x_dot**2 + y_dot**2)/2 + I*theta_dot**2/2 + m*g*sin(alpha)*x",
        constraints=["sin(theta)*x_dot - cos(theta)*y_dot"],
        forces={"theta": "tau"},
        parameters=params,
        inputs=["tau"],
    )


BUILTIN = {
    "unicycle": unicycle,
    "snakeboard": snakeboard,
    "chaplygin_sleigh": chaplygin_sleigh,
    "knife_edge_incline": knife_edge_incline,
}


def builtin(name: str, **parameters) -> System:
    """Build a built-in system by name."""
    try:
        factory = BUILTIN[name.replace("-", "_")]
    except KeyError:
        from .errors import ModelError
        raise ModelError([f"unknown built-in system {name!r} (built-ins: {', '.join(BUILTIN)})"],
                         title="unknown system") from None
    return factory(**parameters)
