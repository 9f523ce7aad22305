"""The one unit inference of nhgait: the unit of a named column or axis — a coordinate, a
velocity, an input, a momentum, a quantity, t or an energy — for the CSV files and the figures
alike (``x [m]`` in both).

The scene's ``[units]`` table decides first (``tau = "N*m"``, shown as ``N·m``). Without an
entry: t in s; energies (``energy``, ``work``, ``energy_balance``) in J; ``<q>_dot`` in the unit
of q per second; the planar body velocities in m/s; and, given the :class:`System`, a
coordinate in m when it is the planar frame's position, in rad when it is named by a Greek
letter, appears inside a trigonometric function of L, ω or τ, or is driven only by inputs in
N·m, else m; an input in N·m when every coordinate it drives is an angle, else N; the momentum
``pt_<q>`` conjugate to q in N·m·s (angle) or N·s. Anything else: "" (unknown).
"""
from __future__ import annotations

__all__ = ["unit_of", "pretty", "GREEK", "is_angle", "coordinate_unit"]

GREEK = ("alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa", "lambda",
         "mu", "nu", "xi", "pi", "rho", "sigma", "tau", "upsilon", "phi", "chi", "psi", "omega")

_TRIG = ("sin", "cos", "tan", "cot", "sec", "csc")
_ENERGIES = ("energy", "work", "energy_balance")


def pretty(unit) -> str:
    """``kg*m**2`` → ``kg·m²``."""
    return str(unit).replace("**2", "²").replace("^2", "²").replace("*", "·")


def is_angle(system, name: str) -> bool:
    """Does coordinate ``name`` appear inside a trigonometric function of L, ω or τ?"""
    sym = system.q[tuple(system.coordinates).index(name)]
    for e in (system.L, *system.constraint_exprs, *system.tau):
        for call in e.find(lambda x: getattr(getattr(x, "func", None), "__name__", "") in _TRIG):
            if sym in call.free_symbols:
                return True
    return False


def _is_frame_position(system, name: str) -> bool:
    frame = getattr(system, "planar_frame", None)
    return bool(frame) and name in tuple(frame)[:2]


def coordinate_unit(system, name: str, units: dict) -> str:
    """m for the planar frame's position; rad for a coordinate named by a Greek letter, inside a
    trigonometric function, or driven only by inputs in N·m; else m."""
    if _is_frame_position(system, name):
        return "m"
    if name.split("_")[0] in GREEK or is_angle(system, name):
        return "rad"
    i = tuple(system.coordinates).index(name)
    driving = [s.name for s in getattr(system.tau[i], "free_symbols", ()) if s.name in tuple(system.inputs)]
    if driving and all(pretty(units.get(u, "")) == "N·m" for u in driving):
        return "rad"
    return "m"


def _input_unit(system, name: str, units: dict) -> str:
    """N·m for an input acting on angles only, N when it acts on a length."""
    syms = [s for s in system.input_symbols if s.name == name]
    if not syms:
        return ""
    on = [c for c, f in zip(system.coordinates, system.tau, strict=True)
          if syms[0] in getattr(f, "free_symbols", ())]
    if on and all(pretty(units.get(c, "")) == "rad"
                  or (is_angle(system, c) and not _is_frame_position(system, c)) for c in on):
        return "N·m"
    return "N" if on else ""


def unit_of(name: str, units=None, system=None) -> str:
    """The unit of ``name`` (see the module docstring), pretty-printed; "" when unknown.

    >>> from nhgait.dynamics import load_scene
    >>> scene = load_scene("snakeboard")
    >>> [unit_of(n, scene.units, scene.system) for n in ("t", "x", "theta", "phi_dot", "tau_psi")]
    ['s', 'm', 'rad', 'rad/s', 'N·m']
    """
    units = dict(units or {})
    if name in units:
        return pretty(units[name])
    if name == "t":
        return "s"
    if name in _ENERGIES:
        return "J"
    if name in ("forward_velocity", "lateral_velocity"):
        return "m/s"
    coords = tuple(getattr(system, "coordinates", ()))
    if name.endswith("_dot") and (name[:-4] in units or name[:-4] in coords):
        base = unit_of(name[:-4], units, system)
        return f"{base}/s" if base else ""
    if system is None:
        return ""
    if name in coords:
        return coordinate_unit(system, name, units)
    if name in tuple(system.inputs):
        return _input_unit(system, name, units)
    if name.startswith("pt_") and name[3:] in coords:
        return "N·m·s" if unit_of(name[3:], units, system) == "rad" else "N·s"
    return ""
