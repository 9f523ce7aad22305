"""Scene files: a system and a simulation stated as data (TOML). Format: docs/scene-format.md.

A scene has a ``[system]`` table (the same meaning as :class:`~nhgait.dynamics.system.System`)
and an optional ``[simulation]`` table. Unknown keys are errors, never silently ignored.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import sympy as sp

try:  # Python ≥ 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from .errors import ModelError
from .system import TIME, System, _parse

SYSTEM_KEYS = {"name", "coordinates", "lagrangian", "constraints", "forces", "parameters", "inputs",
               "fiber", "planar_frame", "description"}
SIMULATION_KEYS = {"q0", "qdot0", "t_final", "samples", "t0", "inputs", "parameters", "formulation",
                   "rtol", "atol", "method", "outputs"}
#: top-level tables; ``task``, ``units`` and ``drawing`` are kept as data for the planner and
#: the plots (validated there), ``quantities`` are named expressions of (q, q̇)
TOP_KEYS = {"system", "simulation", "task", "units", "drawing", "quantities"}


@dataclass(frozen=True, eq=False)
class ExpressionController:
    """Inputs u(t, q, q̇) given as expressions (open-loop or feedback laws from a scene file).

    ``expressions`` are sympy expressions in t, the coordinates, velocities and parameters,
    one per system input, in the order of ``system.inputs``.
    """

    system: System
    expressions: tuple
    params: dict = field(default_factory=dict)

    def __post_init__(self):
        s = self.system
        subs = s.param_subs(self.params)
        exprs = [sp.sympify(e).xreplace(subs) for e in self.expressions]
        f = sp.lambdify([TIME, s.q, s.q_dot], exprs, "numpy")
        object.__setattr__(self, "_f", f)
        object.__setattr__(self, "_exprs_num", exprs)

    def __call__(self, t, q, qdot):
        return np.array(self._f(float(t), np.asarray(q, float), np.asarray(qdot, float)), dtype=float).ravel()

    def casadi(self, t, q, qdot):
        """The same law as CasADi SX (for DAE solvers that need u symbolically)."""
        import casadi as ca
        from .bridge import to_casadi
        s = self.system
        syms = [TIME] + list(s.q) + list(s.q_dot)
        sx = [t] + [q[i] for i in range(s.n)] + [qdot[i] for i in range(s.n)]
        return ca.vertcat(*to_casadi(self._exprs_num, syms, sx)) if self._exprs_num else ca.SX(0, 1)


@dataclass(frozen=True, eq=False)
class SimulationSpec:
    """The ``[simulation]`` table: initial state, horizon, output grid and inputs."""

    q0: np.ndarray
    qdot0: np.ndarray
    t_final: float
    samples: int
    t0: float = 0.0
    controller: ExpressionController | None = None
    parameters: dict = field(default_factory=dict)
    formulation: str | None = None
    rtol: float | None = None
    atol: float | None = None
    method: str | None = None
    outputs: tuple | None = None

    @property
    def t_eval(self) -> np.ndarray:
        return np.linspace(self.t0, self.t_final, self.samples)


@dataclass(frozen=True, eq=False)
class Scene:
    """A system plus (optionally) how to simulate it."""

    system: System
    simulation: SimulationSpec | None
    source: str = ""
    task: dict | None = None
    units: dict = field(default_factory=dict)
    drawing: dict | None = None
    quantities: dict = field(default_factory=dict)


def _number(value, where, problems):
    if isinstance(value, str):
        try:
            return float(sp.sympify(value, locals={"pi": sp.pi}).evalf())
        except (sp.SympifyError, TypeError, ValueError):
            problems.append(f"{where}: {value!r} is not a number")
            return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        problems.append(f"{where}: {value!r} is not a number")
        return math.nan


def parse_scene(data: dict, source: str = "<scene>") -> Scene:
    """Build a :class:`Scene` from a parsed TOML document; every problem is reported at once."""
    problems = []
    unknown = set(data) - TOP_KEYS
    if unknown:
        problems.append(f"unknown top-level table(s) {sorted(unknown)} (allowed: {', '.join(sorted(TOP_KEYS))})")
    sysd = data.get("system")
    if not isinstance(sysd, dict):
        problems.append("missing [system] table")
        raise ModelError(problems, title=f"invalid scene {source}")
    unknown = set(sysd) - SYSTEM_KEYS
    if unknown:
        problems.append(f"[system]: unknown key(s) {sorted(unknown)} (allowed: {', '.join(sorted(SYSTEM_KEYS))})")
    for key in ("coordinates", "lagrangian"):
        if key not in sysd:
            problems.append(f"[system]: missing key {key!r}")
    sim_early = data.get("simulation")
    if isinstance(sim_early, dict) and set(sim_early) - SIMULATION_KEYS:
        problems.append(f"[simulation]: unknown key(s) {sorted(set(sim_early) - SIMULATION_KEYS)} "
                        f"(allowed: {', '.join(sorted(SIMULATION_KEYS))})")
    params = sysd.get("parameters", {})
    if not isinstance(params, dict):
        problems.append("[system].parameters must be a table of name = value")
        params = {}
    params = {k: _number(v, f"parameter {k}", problems) for k, v in params.items()}
    forces = sysd.get("forces", {})
    if not isinstance(forces, dict):
        problems.append("[system].forces must be a table of coordinate = expression")
        forces = {}
    if problems:
        raise ModelError(problems, title=f"invalid scene {source}")
    system = System(coordinates=sysd["coordinates"], lagrangian=sysd["lagrangian"],
                    constraints=sysd.get("constraints", []), forces=forces, parameters=params,
                    inputs=sysd.get("inputs"), name=sysd.get("name", Path(source).stem or "system"),
                    fiber=sysd.get("fiber"), planar_frame=sysd.get("planar_frame", "auto"))
    sim = data.get("simulation")
    spec = None
    if sim is not None:
        if not isinstance(sim, dict):
            raise ModelError(["[simulation] must be a table"], title=f"invalid scene {source}")
        for key in ("q0", "qdot0", "t_final", "samples"):
            if key not in sim:
                problems.append(f"[simulation]: missing key {key!r}")
        if problems:
            raise ModelError(problems, title=f"invalid scene {source}")
        q0 = np.array([_number(v, "q0", problems) for v in sim["q0"]])
        qd0 = np.array([_number(v, "qdot0", problems) for v in sim["qdot0"]])
        if q0.size != system.n:
            problems.append(f"[simulation].q0 has {q0.size} entries, the system has {system.n} coordinates")
        if qd0.size != system.n:
            problems.append(f"[simulation].qdot0 has {qd0.size} entries, the system has {system.n} coordinates")
        t0 = _number(sim.get("t0", 0.0), "t0", problems)
        tf = _number(sim["t_final"], "t_final", problems)
        if not tf > t0:
            problems.append(f"[simulation]: t_final = {tf} must be greater than t0 = {t0}")
        samples = sim["samples"]
        if not isinstance(samples, int) or samples < 2:
            problems.append(f"[simulation].samples must be an integer ≥ 2, got {samples!r}")
        sim_params = {k: _number(v, f"simulation parameter {k}", problems) for k, v in sim.get("parameters", {}).items()}
        bad = [k for k in sim_params if k not in system.parameters]
        if bad:
            problems.append(f"[simulation].parameters: unknown parameter(s) {bad}")
        inputs = sim.get("inputs", {})
        controller = None
        if system.inputs:
            if not isinstance(inputs, dict):
                problems.append("[simulation].inputs must be a table of input = expression")
                inputs = {}
            missing = [u for u in system.inputs if u not in inputs]
            extra = [u for u in inputs if u not in system.inputs]
            if missing:
                problems.append(f"[simulation].inputs: no law for input(s) {missing} (write 0 for none)")
            if extra:
                problems.append(f"[simulation].inputs: {extra} are not inputs of the system ({', '.join(system.inputs)})")
            if not missing and not extra:
                names = {s.name: s for s in system.q + system.q_dot + system.param_symbols}
                names["t"] = TIME
                exprs = []
                for u in system.inputs:
                    e = _parse(str(inputs[u]), names, f"input law {u}", problems)
                    if e is not None:
                        bad_syms = [s.name for s in e.free_symbols if s not in set(names.values())]
                        if bad_syms:
                            problems.append(f"input law {u}: unknown symbol(s) {sorted(bad_syms)}")
                        exprs.append(e)
                if not problems:
                    controller = ExpressionController(system, tuple(exprs), sim_params)
        elif inputs:
            problems.append("[simulation].inputs given but the system has no inputs")
        formulation = sim.get("formulation")
        if formulation is not None and formulation not in ("reduced", "lagrange", "hamilton"):
            problems.append(f"[simulation].formulation {formulation!r} is not reduced, lagrange or hamilton")
        if problems:
            raise ModelError(problems, title=f"invalid scene {source}")
        spec = SimulationSpec(q0=q0, qdot0=qd0, t_final=tf, samples=samples, t0=t0,
                              controller=controller, parameters=sim_params, formulation=formulation,
                              rtol=sim.get("rtol"), atol=sim.get("atol"), method=sim.get("method"),
                              outputs=_outputs(sim.get("outputs"), problems))
        if problems:
            raise ModelError(problems, title=f"invalid scene {source}")
    extra = {}
    for key in ("task", "units", "drawing", "quantities"):
        value = data.get(key)
        if value is not None and not isinstance(value, dict):
            problems.append(f"[{key}] must be a table")
        elif value is not None:
            extra[key] = value
    if "units" in extra:
        bad = [k for k, v in extra["units"].items() if not isinstance(v, str)]
        if bad:
            problems.append(f"[units]: values must be strings such as \"N*m\" (not for {bad})")
    quantities = _quantities(system, extra.pop("quantities", {}), problems)
    if problems:
        raise ModelError(problems, title=f"invalid scene {source}")
    return Scene(system=system, simulation=spec, source=source, quantities=quantities, **extra)


def _outputs(value, problems):
    """``[simulation].outputs``: the names the scene needs (see docs/scene-format.md)."""
    if value is None:
        return None
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        problems.append(f"[simulation].outputs must be a list of names, got {value!r}")
        return None
    return tuple(value)


def _quantities(system, table, problems) -> dict:
    """``[quantities]``: name = expression in the coordinates, velocities and parameters."""
    names = {s.name: s for s in system.q + system.q_dot + system.param_symbols}
    taken = set(names) | set(system.inputs) | {"t"}
    out = {}
    for key, text in table.items():
        where = f"[quantities].{key}"
        if not str(key).isidentifier() or key in taken:
            problems.append(f"{where}: the name must be a new identifier (not a coordinate, velocity, "
                            "parameter, input or t)")
            continue
        if not isinstance(text, str):
            problems.append(f"{where}: must be an expression string, got {text!r}")
            continue
        e = _parse(text, names, where, problems)
        if e is None:
            continue
        bad = sorted(s.name for s in e.free_symbols if s.name not in names)
        if bad:
            problems.append(f"{where}: unknown symbol(s) {bad} (allowed: coordinates, velocities, parameters)")
            continue
        out[key] = e
    return out


def load_scene(path_or_name) -> Scene:
    """Read a scene file, or a built-in scene by name ("unicycle", "snakeboard", ...)."""
    p = Path(str(path_or_name))
    if not p.exists() and p.suffix != ".toml":
        name = str(path_or_name).replace("-", "_")
        try:
            text = resources.files("nhgait.dynamics").joinpath("scenes", f"{name}.toml").read_text()
        except (FileNotFoundError, OSError):
            available = sorted(f.name[:-5] for f in resources.files("nhgait.dynamics").joinpath("scenes").iterdir()
                               if f.name.endswith(".toml"))
            raise ModelError([f"{path_or_name!r} is neither a scene file nor a built-in scene "
                              f"(built-ins: {', '.join(available)})"], title="unknown scene") from None
        source = f"built-in scene {name}"
    else:
        if not p.exists():
            raise ModelError([f"scene file {p} does not exist"], title="unknown scene")
        text = p.read_text()
        source = str(p)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError([f"TOML syntax error: {exc}"], title=f"invalid scene {source}") from None
    return parse_scene(data, source)
