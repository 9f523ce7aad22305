"""Printed output in the user's names: the method's own symbols kept apart from the user's.

The 20-step method writes s for the fibre (group) coordinates, r for the shape coordinates,
p for the nonholonomic momentum, p̃ (``pt_<r>``) for the shape momenta, Ω, ξ and μ. A user's
robot may use any of these names for its own coordinates or parameters (a sleigh with a
sliding mass at lateral offset ``s``). This module

* gives the method's symbols names that differ from every name of the system
  (:func:`method_name`: ``p`` → ``p_nh`` when the system has a ``p``; applied where the
  reduction creates its symbols, so equations never mix the two);
* states the symmetry choice in words, with its reason and how to choose another
  (:func:`symmetry_choice_lines`), instead of the letters s and r.
"""
from __future__ import annotations

__all__ = ["system_names", "method_name", "symmetry_choice_lines", "choice_reason"]

#: suffixes tried, in order, when a method symbol's name is taken by the system
_QUALIFIERS = ("_nh", "_red", "_m")


def system_names(system) -> set:
    """Every name the user gave: coordinates, velocities, parameters, inputs, and t."""
    names = set(system.coordinates) | {v.name for v in system.q_dot} | set(system.parameters)
    return names | set(system.inputs) | {"t"}


def method_name(base: str, taken) -> str:
    """``base`` if no user name equals it, else ``base`` qualified (``p`` → ``p_nh``)."""
    if base not in taken:
        return base
    for suffix in _QUALIFIERS:
        if base + suffix not in taken:
            return base + suffix
    k = 2
    while f"{base}_nh{k}" in taken:
        k += 1
    return f"{base}_nh{k}"


def _key_parts(candidate, system):
    """The selection rule's key of ``candidate`` (:func:`~.symmetry.selection_key`)."""
    from ..symmetry import selection_key
    return selection_key(system, candidate)


_REASONS = ("fewer constraints restrict its shape velocities",
            "a full group (with nonholonomic momenta) comes before a principally kinematic one",
            "SE(2) on the planar frame (x, y, heading) comes first, the convention for a planar robot",
            "it has fewer fibre coordinates",
            "fewer of its fibre coordinates are driven by forces",
            "first in coordinate order among equals")


def choice_reason(symmetry) -> str:
    """Why the symmetry test chose its candidate over the next admissible one."""
    system = symmetry.system
    chosen = symmetry.chosen
    others = [c for c in symmetry.candidates if c.admissible and c is not chosen]
    if not others:
        return "the only admissible group"
    mine = _key_parts(chosen, system)
    runner = min(others, key=lambda c: _key_parts(c, system))
    theirs = _key_parts(runner, system)
    which = next((i for i, (a, b) in enumerate(zip(mine, theirs, strict=True)) if a != b), len(_REASONS) - 1)
    return f"preferred to the next candidate {runner.group}: {_REASONS[which]} (rule: docs/reduction.md)"


def symmetry_choice_lines(symmetry, fiber, shape) -> list:
    """Lines saying which group acts on which coordinates, why, and how to choose another."""
    chosen = symmetry.chosen
    admissible = [c for c in symmetry.candidates if c.admissible]
    lines = [f"  symmetry group {chosen.group} moves the fibre (group) coordinates ({', '.join(fiber)}); "
             f"shape coordinates ({', '.join(shape) or 'none'})"]
    if symmetry.chosen_by == "user":
        lines.append(f"  chosen by the system's fiber = [{', '.join(repr(f) for f in fiber)}]; "
                     f"{chosen.reason}")
    else:
        lines.append(f"  chosen by the full-symmetry test ({chosen.reason}): {choice_reason(symmetry)}")
    system = symmetry.system
    alternatives = sorted((c for c in admissible if c is not chosen),
                          key=lambda c: _key_parts(c, system))
    if alternatives:
        listed = "; ".join(f"fiber = [{', '.join(repr(f) for f in c.fiber)}] ({c.group}, "
                           f"{c.verdict.split(' (')[0]})"
                           for c in alternatives)
        lines.append(f"  to choose another, write it in [system] (or System(fiber=…)): {listed}; "
                     "all candidates: nhgait derive --table")
    return lines
