"""A canonical form for the trigonometric polynomials of rigid-body kinematics, fast.

Every entry of a rotation, a velocity Jacobian or the kinetic metric of a tree of revolute and
prismatic joints is a sum of terms  c · m(s) · Π sin/cos(a_j),  m a monomial in the prismatic
coordinates and a_j linear forms in the angles. With cos a = (e^{ia} + e^{−ia})/2 and
sin a = (e^{ia} − e^{−ia})/(2i) each product becomes a sum of exponentials e^{i k·s}; collected
per (m, k) and written back with the pair (k, −k) as  A cos(k·s) + B sin(k·s)  (the first
non-zero entry of k positive), the expression is in a canonical form: sin² + cos² = 1 and the
angle-sum identities hold by construction, where ``trigsimp`` searches for them (minutes on an
8-coordinate robot, against a fraction of a second here).

Coefficients are floating point (the URDF's numbers); terms below ``noise`` times the largest
coefficient are dropped as rounding.
"""
from __future__ import annotations

import cmath
from collections import defaultdict

import sympy as sp

__all__ = ["canonical_trig"]


def _linear_form(arg):
    """({symbol: coefficient}, constant phase) of a linear argument, or None."""
    parts = sp.expand(arg).as_coefficients_dict()
    frequency, phase = {}, 0.0
    for key, value in parts.items():
        if key == 1:
            phase += float(value)
        elif isinstance(key, sp.Symbol) and value.is_number:
            frequency[key] = value
        else:
            return None
    return frequency, phase


def _times(waves: dict, function, frequency: dict, phase: float) -> dict:
    """``waves`` (key → complex amplitude, key a sorted tuple of (symbol, coefficient)) times
    sin or cos of (frequency · s + phase)."""
    rotor = cmath.exp(1j * phase)
    if function is sp.cos:
        factors = ((1, rotor / 2), (-1, rotor.conjugate() / 2))
    else:
        factors = ((1, rotor / 2j), (-1, -rotor.conjugate() / 2j))
    out: dict = defaultdict(complex)
    for key, amplitude in waves.items():
        base = dict(key)
        for sign, factor in factors:
            new = dict(base)
            for symbol, coefficient in frequency.items():
                new[symbol] = new.get(symbol, 0) + sign * coefficient
            out[tuple(sorted(((s, c) for s, c in new.items() if c != 0), key=lambda sc: sc[0].name))] \
                += amplitude * factor
    return out


def _negated(key):
    return tuple((s, -c) for s, c in key)


def canonical_trig(expr, noise: float = 1e-13):
    """``expr`` (numeric coefficients) as Σ m(s) (A cos(k·s) + B sin(k·s)); see the module
    docstring. Factors that are not sin/cos of a linear form are kept as part of m."""
    expr = sp.expand(expr)
    table: dict = defaultdict(complex)
    for term in sp.Add.make_args(expr):
        coefficient, factors = term.as_coeff_mul()
        waves: dict = {(): complex(coefficient)}
        plain = []
        for factor in factors:
            base, exponent = factor.as_base_exp()
            form = _linear_form(base.args[0]) if isinstance(base, (sp.sin, sp.cos)) else None
            if form is None or not (exponent.is_Integer and exponent > 0):
                plain.append(factor)
                continue
            for _ in range(int(exponent)):
                waves = _times(waves, type(base), *form)
        monomial = sp.Mul(*plain)
        for key, amplitude in waves.items():
            table[(monomial, key)] += amplitude
    return _written_back(table, noise)


def _written_back(table: dict, noise: float):
    """Σ m (A cos(k·s) + B sin(k·s)) from the amplitudes of e^{i k·s} per (m, k)."""
    terms = []
    done = set()
    for (monomial, key), amplitude in table.items():
        if (monomial, key) in done:
            continue
        mirror = _negated(key)
        done.update({(monomial, key), (monomial, mirror)})
        if not key:
            terms.append((monomial, None, amplitude.real, 0.0))
            continue
        if key[0][1] < 0:
            key, mirror = mirror, key
        plus, minus = table.get((monomial, key), 0j), table.get((monomial, mirror), 0j)
        terms.append((monomial, key, (plus + minus).real, (1j * (plus - minus)).real))
    biggest = max((max(abs(a), abs(b)) for _, _, a, b in terms), default=0.0)
    out = []
    for monomial, key, a, b in terms:
        angle = sp.Add(*[c * s for s, c in key]) if key else None
        if abs(a) > noise * biggest:
            out.append(_number(a) * monomial * (sp.cos(angle) if angle is not None else 1))
        if abs(b) > noise * biggest:
            out.append(_number(b) * monomial * sp.sin(angle))
    return sp.Add(*out)


def _number(value: float):
    return sp.Integer(int(value)) if float(value).is_integer() else sp.Float(value)
