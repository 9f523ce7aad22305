"""What :func:`~.driver.simulate` returns: :class:`Trajectory` (the samples, the run's own
checks, its status) and :class:`Diagnostics` (what the run measured about itself, some entries
computed when first read), with the CSV writer of a trajectory.
"""
from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..errors import ModelError
from ..units import unit_of

__all__ = ["Trajectory", "Diagnostics", "OnRead", "min_measure", "max_condition", "CSV_COLUMNS"]

CSV_COLUMNS = ("q", "qdot", "state", "all", "outputs")


class Columns(NamedTuple):
    """What :meth:`Trajectory.columns` returns."""

    names: list        #: the column names, t first
    table: np.ndarray  #: (N, c)


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A simulated trajectory sampled at N times.

    Attributes
    ----------
    t : (N,) times [s].
    q, qdot : (N, n) coordinates and velocities in ``coordinates`` order (angles unwrapped).
    state : (N, d) the integrated entries of the formulation's state (``state_names``).
    u : (N, m) inputs applied (at a switch time: the left limit).
    lam : (N, k) Lagrange multipliers, or None for the reduced ODE.
    constraint_residual : (N, k) ω(q) q̇.
    holonomic_residual : (N, c) h(q) of the kept holonomic constraints (the drift from the
        constraint surface; (N, 0) without them).
    energy : (N,) E (Lagrangian energy, H or h).
    work : (N,) ∫ τ·q̇ dt from t₀, integrated as a quadrature state.
    energy_balance : (N,) E − E(t₀) − work (E(t₀) at the initial state even if t_eval starts later).
    nfev, njev, n_steps : right-hand-side / Jacobian evaluations and accepted steps.
    wall_time_s : wall time of the integration and evaluation of the outputs (a compilation in
        this call is included and also reported as ``diagnostics["compile_time_s"]``).
    success, status, message : status 0 = reached the end; −1 integrator failure, −2 max_steps,
        −3 non-finite value, −4 singular set reached (module constants). The points reached are
        kept; the message names the time and the cause.
    formulation, method : "reduced" | "lagrange" | "hamilton"; the method that ran.
    coordinates, state_names, input_names : names of the columns.
    settings : every option the run used (tolerances, DAE form, stabilisation, fallbacks …).
    diagnostics : what the run measured about itself (a read-only :class:`Diagnostics`
        mapping): ``min_singular_measure``, ``max_cond_metric`` (kinetic metric of the velocity
        part), ``max_cond_gram`` (DAE forms: ω M⁻¹ ωᵀ) — both computed when first read —,
        ``stiff_at``/``h_lambda_max``/``recommendation`` (explicit methods),
        ``integrated_states``, ``state_count``, ``t_event``, ``compile_time_s``.
    outputs : name → (N,) for the run's requested outputs (empty without ``outputs``).

    Examples
    --------
    The Chaplygin sleigh pushed straight ahead at 1 m/s keeps going (no force acts; its
    energy stays what it was):

    >>> from nhgait.dynamics import derive, simulate
    >>> traj = simulate(derive("chaplygin_sleigh"), (0.0, 2.0), [0, 0, 0], [1.0, 0, 0],
    ...                 t_eval=[0.0, 1.0, 2.0])
    >>> traj.coordinates, traj.q.shape
    (('x', 'y', 'theta'), (3, 3))
    >>> traj.q[:, 0].round(12).tolist(), traj.status          # x = v t
    ([0.0, 1.0, 2.0], 0)
    >>> float(abs(traj.energy_balance).max()) < 1e-12, traj.lam is None   # reduced ODE: no λ
    (True, True)
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    state: np.ndarray
    u: np.ndarray
    lam: np.ndarray | None
    constraint_residual: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    energy_balance: np.ndarray
    nfev: int
    njev: int
    n_steps: int
    wall_time_s: float
    success: bool
    status: int
    message: str
    formulation: str
    method: str
    coordinates: tuple
    state_names: tuple
    input_names: tuple
    settings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    outputs: dict = field(default_factory=dict)
    holonomic_residual: np.ndarray | None = None

    def __repr__(self) -> str:
        from nhgait.dynamics.reprs import trajectory_repr
        return trajectory_repr(self)

    def columns(self, columns: str = "q") -> Columns:
        """(names, (N, c) table) for ``columns`` (see :meth:`to_csv`)."""
        if columns not in CSV_COLUMNS:
            raise ModelError([f"unknown columns {columns!r} (choose from {', '.join(CSV_COLUMNS)})"],
                             title="invalid request")
        names, blocks = ["t"], [self.t[:, None]]
        if columns == "outputs":
            names += list(self.outputs)
            blocks += [np.asarray(v)[:, None] for v in self.outputs.values()]
        elif columns == "state":
            names += list(self.state_names)
            blocks.append(self.state)
        else:
            names += list(self.coordinates)
            blocks.append(self.q)
        if columns in ("qdot", "all"):
            names += [f"{c}_dot" for c in self.coordinates]
            blocks.append(self.qdot)
        if columns == "all":
            names += list(self.input_names)
            blocks.append(self.u)
            if self.lam is not None:
                names += [f"lambda{i + 1}" for i in range(self.lam.shape[1])]
                blocks.append(self.lam)
            names += [f"constraint{i + 1}" for i in range(self.constraint_residual.shape[1])]
            blocks.append(self.constraint_residual)
            if self.holonomic_residual is not None and self.holonomic_residual.size:
                names += [f"holonomic{i + 1}" for i in range(self.holonomic_residual.shape[1])]
                blocks.append(self.holonomic_residual)
            names += ["energy", "work", "energy_balance"]
            blocks += [self.energy[:, None], self.work[:, None], self.energy_balance[:, None]]
        return Columns(tuple(names), np.hstack(blocks))

    def to_csv(self, path, columns: str = "q", units: dict | None = None, system=None) -> None:
        """Write column ``t`` and then, per ``columns``:

        * ``"q"``: one column per coordinate, named as in the system (``x``, ``y``, ``theta`` …);
        * ``"qdot"``: q then ``<name>_dot`` velocities;
        * ``"state"``: the formulation's integrated state (``state_names``);
        * ``"all"``: q, velocities, inputs, multipliers (``lambda1`` …), constraint residuals
          (``constraint1`` …), holonomic residuals h(q) (``holonomic1`` …, when kept),
          ``energy``, ``work``, ``energy_balance``;
        * ``"outputs"``: the run's requested outputs.

        ``units``: optional mapping name → unit (e.g. a scene's ``[units]``); with it or with
        ``system`` (the simulated :class:`~nhgait.dynamics.System`), every header cell reads
        ``name [unit]`` by the one inference of :func:`nhgait.dynamics.units.unit_of` (the
        figures' labels say the same: ``x [m]``, ``theta [rad]``, t in s, energies in J), and
        "SI" for a name it cannot place.
        """
        names, table = self.columns(columns)
        if units is not None or system is not None:
            names = [f"{nm} [{unit_of(nm, units, system) or 'SI'}]" for nm in names]
        with open(path, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(names)
            writer.writerows([[repr(float(v)) for v in row] for row in table])


class Diagnostics(Mapping):
    """``Trajectory.diagnostics``: what a run measured about itself, a read-only mapping.

    The condition numbers ``max_cond_metric`` and ``max_cond_gram`` take an SVD of the matrix
    at every output point — for a thousand points about as long as the integration itself —
    so they are computed the first time they are read (``d["max_cond_metric"]``, ``dict(d)``,
    ``repr``) and then kept: a run that never reads them does not pay for them. So is
    ``min_singular_measure``; on the compiled route the matrices and the measure at the output
    points are themselves evaluated then (one C pass, shared by the three). Every other entry is
    stored by the run. The values live as long as the trajectory."""

    def __init__(self, entries: dict):
        self._entries = dict(entries)

    def __getitem__(self, key):
        value = self._entries[key]
        if isinstance(value, OnRead):
            value = self._entries[key] = value.compute()
        return value

    def __iter__(self):
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return repr(dict(self))

    def __reduce__(self):
        """Pickled with every value computed: the entries not yet read refer to the run's
        compiled library, which does not pickle (a trajectory goes to a worker or a file)."""
        return (Diagnostics, (dict(self),))


@dataclass(frozen=True, eq=False)
class OnRead:
    """A diagnostic not yet computed: ``measure(block)`` of the diagnostic block ``name``."""

    measure: object
    blocks: object           # the run's diagnostic blocks, evaluated on first read
    name: str

    def compute(self):
        return self.measure(self.blocks[self.name])


def min_measure(block) -> float | None:
    """The smallest finite singular-set measure of the output points (None: none is finite)."""
    return float(np.nanmin(block)) if np.isfinite(block).any() else None


def max_condition(block) -> float | None:
    """Largest 2-norm condition number of the (k, k) matrices stored column-major per row."""
    if not block.size:
        return None
    k = int(round(np.sqrt(block.shape[1])))
    rows = block[np.all(np.isfinite(block), axis=1)]
    if not rows.size:
        return None
    with np.errstate(all="ignore"):
        return float(np.max(np.linalg.cond(rows.reshape(-1, k, k).transpose(0, 2, 1))))
