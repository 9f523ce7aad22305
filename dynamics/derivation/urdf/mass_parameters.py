"""Link masses as parameters: ``masses = {base_link = "m_base"}`` in a URDF scene's ``[system]``.

A URDF gives every mass as a number; a user who wants to vary one (a payload, a battery, a
mismatch study: ``nhgait track ... --mismatch params.m_base=1.1``) names the link and the
parameter. The parameter m_p is the link's mass, default the URDF's m; the link keeps its
centre of mass and the shape of its inertia, I → (m_p/m) I (a uniform change of density).

T and V are sums over links, each linear in the link's mass properties (m, m c, I about its
origin), so with L_link the Lagrangian of that link alone (every other link massless, the same
tree and coordinates)::

    L(m_p) = L_URDF + (m_p/m − 1) L_link,

exact, and L(m) is the URDF's own Lagrangian.
"""
from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import sympy as sp

__all__ = ["mass_problems", "with_mass_parameters"]


def mass_problems(robot, masses: dict, parameters: dict) -> list:
    """Every problem of ``masses`` (link → parameter name): unknown or massless links, names
    that are not identifiers or clash with ``parameters`` or with each other."""
    problems, seen = [], {}
    for link, name in masses.items():
        where = f"[system].masses.{link}"
        if link not in robot.links:
            problems.append(f"{where}: unknown link {link!r} (links: {', '.join(robot.links)})")
        elif robot.links[link].inertial is None or not robot.links[link].inertial.mass > 0:
            problems.append(f"{where}: link {link!r} has no mass in the URDF to scale")
        if not isinstance(name, str) or not name.isidentifier():
            problems.append(f"{where} must be a parameter name, got {name!r}")
        elif name in parameters:
            problems.append(f"{where}: {name!r} is also in [system].parameters")
        elif name in seen:
            problems.append(f"{where}: {name!r} already names the mass of link {seen[name]!r}")
        else:
            seen[name] = link
    return problems


class MassParameters(NamedTuple):
    """What :func:`with_mass_parameters` returns."""

    L: sp.Expr     #: the Lagrangian, each named link's mass a parameter
    values: dict   #: {parameter: URDF mass}


def with_mass_parameters(L, robot, masses: dict, lagrangian_of) -> MassParameters:
    """(L with each named link's mass a parameter, {parameter: URDF mass}); ``lagrangian_of``
    builds the Lagrangian of a :class:`~.reader.Robot` on the same coordinates."""
    values = {}
    for link, name in masses.items():
        mass = float(robot.links[link].inertial.mass)
        alone = replace(robot, links={k: (v if k == link else replace(v, inertial=None))
                                      for k, v in robot.links.items()})
        L = L + (sp.Symbol(name, real=True) / sp.Float(mass) - 1) * lagrangian_of(alone)
        values[name] = mass
    return MassParameters(L, values)
