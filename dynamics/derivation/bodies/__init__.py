"""Systems stated as rigid bodies and rolling wheels: the ``[[system.bodies]]`` and
``[[system.wheels]]`` tables of a scene (docs/bodies.md).

:mod:`.statement` reads the tables (expressions of the parameters, the reference
configuration), :mod:`.kinematics` places the bodies by the product of exponentials on a planar
base, :mod:`.builder` writes L = T − V and the wheels' rolling constraints (Pfaffian rows and
contact heights as holonomic constraints) and makes the
:class:`~nhgait.dynamics.derivation.system.System`.
"""
from .builder import KEYS, bodies_system

__all__ = ["KEYS", "bodies_system"]
