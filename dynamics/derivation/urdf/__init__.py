"""Systems from a URDF: the ``[system] urdf = "..."`` keys of a scene (docs/scene-format.md).

:mod:`.reader` reads the file (standard-library XML, no DTD), :mod:`.tree` merges the links of
fixed and locked joints into moving bodies, :mod:`.energy` writes T(q, q̇) and V(q) on a planar
base, :mod:`.wheels` the rolling and no-side-slip constraints, :mod:`.builder` makes the
:class:`~nhgait.dynamics.derivation.system.System`.
"""
from .builder import KEYS, UrdfSystem, urdf_system

__all__ = ["KEYS", "UrdfSystem", "urdf_system"]
