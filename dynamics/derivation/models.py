"""Built-in systems: the thesis's two examples and two more that exercise other structures.

The scene files in ``nhgait/dynamics/scenes/*.toml`` are the single source of every built-in
system (coordinates, Lagrangian, constraints, forces, default parameters); the factories here
load the scene and override parameter values::

    snakeboard(J_r=0.3)      # the snakeboard scene with J_r = 0.3

* ``unicycle`` — vertical rolling disc (thesis Examples 2.2, 2.3, 3.1; L eq. 2.9, ω eq. 2.10);
* ``snakeboard`` — thesis Example 3.2 (L eq. 3.54 with general inertias, ω eq. 3.56; the printed
  matrix 3.57 swaps the rows' angles, see docs/thesis-errata.md; r = √((J+J_r+2J_w)/m));
* ``chaplygin_sleigh`` — a knife edge with the centre of mass ahead of it, no shape (m = 0);
* ``knife_edge_incline`` — a skate on an inclined plane (gravity), principally kinematic.
"""
from __future__ import annotations

import dataclasses

from nhgait.dynamics.suggestions import known_names

from ..errors import ModelError
from .system import System


def _from_scene(name: str, parameters: dict) -> System:
    """The system of the built-in scene ``name`` with ``parameters`` overriding its defaults."""
    from .input.scene import load_scene
    system = load_scene(name).system
    if not parameters:
        return system
    unknown = sorted(set(parameters) - set(system.parameters))
    if unknown:
        raise ModelError([f"unknown parameter {k!r} of "
                          f"{name}{known_names(k, system.parameters, label='parameters')}"
                          for k in unknown], title="invalid parameters")
    return dataclasses.replace(system, parameters={**system.parameters, **parameters})


def unicycle(**parameters) -> System:
    """Vertical rolling disc, q = (x, y, theta, phi); defaults m = 0.5, r = 0.1, J_phi = 0.2,
    J_theta = 0.3 (the thesis's simulation); torques tau_theta, tau_phi."""
    return _from_scene("unicycle", parameters)


def snakeboard(**parameters) -> System:
    """Snakeboard, q = (x, y, theta, psi, phi); defaults m = 0.5, J = 0.3, J_r = 0.2,
    J_w = 0.1, r = √((J+J_r+2J_w)/m); torques tau_psi (rotor), tau_phi (steering)."""
    return _from_scene("snakeboard", parameters)


def chaplygin_sleigh(**parameters) -> System:
    """Chaplygin sleigh, q = (x, y, theta), centre of mass a ahead of the knife edge; inputs
    thrust F and torque tau."""
    return _from_scene("chaplygin_sleigh", parameters)


def knife_edge_incline(**parameters) -> System:
    """Knife edge on an inclined plane, q = (x, y, theta), x down the slope; input tau."""
    return _from_scene("knife_edge_incline", parameters)


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
        raise ModelError([f"unknown built-in system {name!r} (built-ins: {', '.join(BUILTIN)})"],
                         title="unknown system") from None
    return factory(**parameters)
