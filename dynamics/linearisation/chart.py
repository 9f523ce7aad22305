"""Eigenvalues of the straight steady motion against forward speed, and the speeds where its
stability changes (the Whipple benchmark's Fig. 3 and its weave and capsize speeds).

At each speed of the grid the motion is linearised (:func:`~.linearise.linearise`) and given a
verdict from its largest real part h(V) = max Re λ(V): unstable (h > τ), stable (h < −τ) or
neutral. Where two neighbouring grid speeds differ, the change is refined by Brent's method
on a continuous function that changes sign there:

* stable ↔ unstable: h(V) itself (a real eigenvalue or a complex pair crossing the imaginary
  axis transversally: the capsize and weave speeds);
* unstable ↔ neutral: h(V) − τ (a real pair ±√c(V) meeting at 0 and leaving along the
  imaginary axis, as the rolling disc's lean pair at √(g r/3): h = √c is zero on the neutral
  side, so h − τ changes sign where c(V) = τ², within τ²/c′ of the true speed);
* stable ↔ neutral: h(V) + τ.

The eigenvalues themselves are accurate to rounding of A (≈ 10⁻¹⁵ relative) except where two
of them coincide (error ≈ √ε); the refinement is taken to the speed resolution of the root
finder (``xtol``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .linearised import STABLE, UNSTABLE, linearise

__all__ = ["StabilityChart", "StabilityChange", "stability_chart", "parse_speeds"]

#: absolute speed resolution of the refined changes [m/s]
XTOL = 1e-14


@dataclass(frozen=True)
class StabilityChange:
    """Where the verdict changes: ``speed`` [m/s] (refined), the verdicts below and above, and
    the eigenvalues there."""

    speed: float
    below: str
    above: str
    eigenvalues: np.ndarray = field(repr=False)

    def sentence(self) -> str:
        return f"{self.speed:.14g} m/s: {self.below} below, {self.above} above"


@dataclass(frozen=True)
class StabilityChart:
    """Eigenvalues over ``speeds`` (rows: speeds; columns: the eigenvalues of each
    linearisation, sorted by real part; all rows have the same count), the verdict at each
    speed and the refined :class:`StabilityChange` list."""

    speeds: np.ndarray
    eigenvalues: np.ndarray = field(repr=False)
    verdicts: tuple
    changes: tuple
    states: tuple = ()

    def stable_ranges(self) -> list:
        """[(from, to)] speed intervals where the motion is stable (ends at the refined changes
        or the grid's ends)."""
        edges = [float(self.speeds[0])] + [c.speed for c in self.changes] + [float(self.speeds[-1])]
        verdicts = [self.verdicts[0]] + [c.above for c in self.changes]
        return [(a, b) for a, b, v in zip(edges[:-1], edges[1:], verdicts, strict=True) if v == STABLE]

    def to_text(self) -> str:
        lines = [f"eigenvalues at {len(self.speeds)} speeds from {self.speeds[0]:g} to "
                 f"{self.speeds[-1]:g} m/s (states {', '.join(self.states)})"]
        if not self.changes:
            lines.append(f"  stability does not change: {self.verdicts[0]} at every speed")
        lines += [f"  stability changes at {c.sentence()}" for c in self.changes]
        lines += [f"  stable from {a:.14g} to {b:.14g} m/s" for a, b in self.stable_ranges()]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"speeds": self.speeds.tolist(),
                "eigenvalues": [[[float(v.real), float(v.imag)] for v in row] for row in self.eigenvalues],
                "verdicts": list(self.verdicts),
                "changes": [{"speed": c.speed, "below": c.below, "above": c.above,
                             "eigenvalues": [[float(v.real), float(v.imag)] for v in c.eigenvalues]}
                            for c in self.changes],
                "stable_ranges": [list(r) for r in self.stable_ranges()], "states": list(self.states)}


def parse_speeds(text: str) -> np.ndarray:
    """``"start:stop:count"`` (``numpy.linspace``) or a comma-separated list of speeds."""
    problems = []
    parts = str(text).split(":")
    try:
        if len(parts) == 3:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
            if count < 2 or count > 100_000 or not start < stop or not np.isfinite([start, stop]).all():
                problems.append(f"--speeds {text!r}: need start < stop and 2 ≤ count ≤ 100000")
            else:
                return np.linspace(start, stop, count)
        else:
            values = np.array([float(v) for v in str(text).split(",")])
            if values.size < 2 or np.any(np.diff(values) <= 0) or not np.isfinite(values).all():
                problems.append(f"--speeds {text!r}: need at least two increasing speeds")
            else:
                return values
    except ValueError:
        problems.append(f"--speeds {text!r}: expected start:stop:count (e.g. 0:10:101) or v1,v2,...")
    raise ModelError(problems, title="invalid linearisation request")


def stability_chart(model, speeds, *, configuration=None, inputs=None, params=None,
                    progress=None) -> StabilityChart:
    """Linearise the straight steady motion of ``model`` at each of ``speeds`` and refine the
    speeds where its stability changes (module docstring)."""
    speeds = np.asarray(speeds, dtype=float)

    def at(v):
        return linearise(model, speed=float(v), configuration=configuration, inputs=inputs, params=params)
    import time
    rows, verdicts, tolerances, states = [], [], [], ()
    start = time.perf_counter()
    for i, v in enumerate(speeds):
        lin = at(v)
        rows.append(lin.eigenvalues)
        verdicts.append(lin.stability)
        tolerances.append(lin.tolerance)
        states = lin.states
        if progress is not None:
            progress.heartbeat(f"linearised at {i + 1} of {len(speeds)} speeds", time.perf_counter() - start)
    changes = []
    for i in range(len(speeds) - 1):
        if verdicts[i] != verdicts[i + 1]:
            changes.append(_refine(at, speeds[i], speeds[i + 1], verdicts[i], verdicts[i + 1],
                                   max(tolerances[i], tolerances[i + 1])))
    width = max(len(r) for r in rows)
    table = np.full((len(speeds), width), np.nan + 0j)
    for i, r in enumerate(rows):
        table[i, :len(r)] = r
    return StabilityChart(speeds=speeds, eigenvalues=table, verdicts=tuple(verdicts), changes=tuple(changes),
                          states=tuple(states))


def _refine(at, lo, hi, below, above, tau) -> StabilityChange:
    """The speed in [lo, hi] where the verdict changes from ``below`` to ``above``."""
    from scipy.optimize import brentq
    pair = {below, above}
    offset = 0.0 if pair == {STABLE, UNSTABLE} else (-tau if UNSTABLE in pair else tau)

    def h(v):
        return float(np.max(at(v).eigenvalues.real)) + offset
    try:
        speed = brentq(h, lo, hi, xtol=XTOL, rtol=4 * np.finfo(float).eps, maxiter=200)
    except ValueError:       # no sign change of h in the bracket: keep the grid interval's middle
        speed = 0.5 * (lo + hi)
    return StabilityChange(float(speed), below, above, at(speed).eigenvalues)
