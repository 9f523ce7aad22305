"""Scene files: a system and a simulation stated as data (TOML). Format: docs/scene-format.md.

A scene has a ``[system]`` table (the same meaning as :class:`~nhgait.dynamics.derivation.system.System`)
and an optional ``[simulation]`` table. Unknown keys are errors, never silently ignored.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path

import numpy as np
import sympy as sp

from nhgait.dynamics.suggestions import known_names

from ...errors import ModelError
from ..system import TIME, System, jump_times, parse_field
from .expressions import number_problems
from .textfiles import names_a_file, read_text_file
from .tomldata import read_toml

SYSTEM_KEYS = {"name", "coordinates", "lagrangian", "constraints", "forces", "parameters", "inputs",
               "fiber", "planar_frame", "forward", "description", "holonomic", "dependent"}
#: the most output samples of a [simulation] (about 1.2 kB and 30–80 µs per sample for the unicycle's outputs)
MAX_SAMPLES = 1_000_000
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

    @cached_property
    def _exprs_num(self) -> list:
        """The laws with the parameter values substituted."""
        subs = self.system.param_subs(self.params)
        return [e.xreplace(subs) for e in self.expressions]

    @cached_property
    def _law(self):
        """The laws as one numpy function of (t, q, q̇)."""
        return sp.lambdify([TIME, self.system.q, self.system.q_dot], self._exprs_num, "numpy")

    @property
    def breakpoints(self):
        """Times at which a law jumps (Heaviside/sign of a·t + b) or the forces do: the
        simulator restarts there; None when there are none."""
        times = sorted(set(jump_times(self._exprs_num)) | set(self.system.force_jump_times(self.params)))
        return np.array(times) if times else None

    def __call__(self, t, q, qdot):
        return np.array(self._law(float(t), np.asarray(q, float), np.asarray(qdot, float)),
                        dtype=float).ravel()

    def casadi(self, t, q, qdot):
        """The same law as CasADi SX (for DAE solvers that need u symbolically)."""
        import casadi as ca

        from ...numerics.bridge import to_casadi
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
    urdf: object = None          # the UrdfSystem of a scene with [system] urdf = "..." (else None)
    #: the ``[quantities]`` that use inputs or accelerations ``<q>_ddot`` (path bounds and integrands of a
    #: task)
    motion_quantities: dict = field(default_factory=dict)

    @property
    def all_quantities(self) -> dict:
        """Every named quantity: of (q, q̇) (``quantities``) and of the motion (``motion_quantities``)."""
        return {**self.quantities, **self.motion_quantities}


def _number(value, where, problems):
    return number_problems(value, where, problems)


def _table(value, where, problems) -> dict:
    """A TOML table or {} with one problem."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        problems.append(f"{where} must be a table of name = value, got {_kind(value)}")
        return {}
    return value


def _kind(value) -> str:
    """The TOML kind of ``value`` with its article: "a string", "an integer (5)", "a table"."""
    if isinstance(value, str):
        return "a string"
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, int):
        return f"an integer ({value})"
    if isinstance(value, float):
        return f"a number ({value!r})"
    return {dict: "a table", list: "an array"}.get(type(value), f"a {type(value).__name__}")


def _vector(value, where, n, problems):
    """A list of n numbers (or constant expressions)."""
    if not isinstance(value, list):
        problems.append(f"{where} must be a list of {n if n else 'the'} numbers (coordinate order), "
                        f"got {_kind(value)}")
        return None
    out = np.array([_number(v, f"{where}[{i}]", problems) for i, v in enumerate(value)])
    if n is not None and out.size != n:
        problems.append(f"{where} has {out.size} entries, the system has {n} coordinates")
        return None
    return out


def parse_scene(data: dict, source: str = "<scene>") -> Scene:
    """Build a :class:`Scene` from a parsed TOML document; every problem (system, simulation,
    further tables) is reported at once in one :class:`ModelError`."""
    problems: list = []
    unknown = set(data) - TOP_KEYS
    if unknown:
        problems.append(f"unknown top-level table(s) {sorted(unknown)}"
                        f"{known_names(sorted(unknown)[0], sorted(TOP_KEYS), label='allowed')}")
    urdf = None
    if isinstance(data.get("system"), dict) and "urdf" in data["system"]:
        urdf, system = _urdf_system(data["system"], source, problems)
    elif isinstance(data.get("system"), dict) and "bodies" in data["system"]:
        system = _bodies_system(data["system"], source, problems)
    else:
        system = _system(data.get("system"), source, problems)
    spec = None
    if data.get("simulation") is not None:
        spec = _simulation(data["simulation"], system, problems)
    extra = {}
    for key in ("task", "units", "drawing", "quantities"):
        value = data.get(key)
        if value is not None and not isinstance(value, dict):
            problems.append(f"[{key}] must be a table, got {_kind(value)}")
        elif value is not None:
            extra[key] = value
    bad = [k for k, v in extra.get("units", {}).items() if not isinstance(v, str)]
    if bad:
        problems.append(f"[units]: values must be strings such as \"N*m\" (not for {bad})")
    quantities = _quantities(system, extra.pop("quantities", {}), problems) if system else {}
    motion = {k: e for k, e in quantities.items() if e.free_symbols & _motion_symbols(system)}
    quantities = {k: e for k, e in quantities.items() if k not in motion}
    if problems:
        raise ModelError(problems, title=f"invalid scene {source}")
    if urdf is not None and "task" in extra:
        extra["task"] = _urdf_task_defaults(extra["task"], urdf)
    if "bodies" in (data.get("system") or {}):
        extra["units"] = {**_bodies_units(system), **extra.get("units", {})}
    return Scene(system=system, simulation=spec, source=source, quantities=quantities, urdf=urdf,
                 motion_quantities=motion, **extra)


def _urdf_system(sysd, source, problems):
    """(UrdfSystem, System) of a ``[system]`` table with ``urdf = ...`` (a path relative to the
    scene file's folder), or (None, None) after recording its problems."""
    from ..urdf import urdf_system
    try:
        built = urdf_system(sysd, Path(source).parent, source)
    except ModelError as exc:
        problems.extend(exc.problems)
        return None, None
    return built, built.system


def _bodies_units(system) -> dict:
    """Units of a bodies robot's coordinates, which its statement fixes (the scene's [units]
    override them): the base position in m; the heading, every joint (all revolute) and every
    wheel's spin in rad (a spin enters no sine: the plots took it for a length)."""
    position = tuple(system.planar_frame[:2])
    return {c: "m" if c in position else "rad" for c in system.coordinates}


def _bodies_system(sysd, source, problems):
    """The System of a ``[system]`` table stated with ``bodies`` and ``wheels`` (docs/bodies.md),
    or None after recording its problems."""
    from ..bodies import bodies_system
    try:
        return bodies_system(sysd, source)
    except ModelError as exc:
        problems.extend(exc.problems)
        return None


def _urdf_task_defaults(task: dict, urdf) -> dict:
    """``[task]`` with the URDF's limits where the scene states none: effort limits as
    ``control_bounds``, joint position and velocity limits as ``bounds``."""
    task = dict(task)
    controls = task.get("control_bounds")
    if controls is None or isinstance(controls, dict):
        task["control_bounds"] = {**{k: list(v) for k, v in urdf.control_bounds.items()}, **(controls or {})}
    bounds = task.get("bounds")
    if bounds is None or isinstance(bounds, dict):
        task["bounds"] = {**{k: list(v) for k, v in urdf.bounds.items()}, **(bounds or {})}
    return task


def _system(sysd, source, problems) -> System | None:
    """The ``[system]`` table as a :class:`System` (None after recording its problems)."""
    if not isinstance(sysd, dict):
        problems.append("missing [system] table" if sysd is None
                        else f"[system] must be a table, got {_kind(sysd)}")
        return None
    unknown = set(sysd) - SYSTEM_KEYS
    if unknown:
        problems.append(f"[system]: unknown key(s) {sorted(unknown)}"
                        f"{known_names(sorted(unknown)[0], sorted(SYSTEM_KEYS), label='allowed')}")
    missing = [key for key in ("coordinates", "lagrangian") if key not in sysd]
    problems.extend(f"[system]: missing key {key!r}" for key in missing)
    name = sysd.get("name", Path(source).stem or "system")
    if not isinstance(name, str):
        problems.append(f"[system].name must be a string, got {_kind(name)}")
        name = "system"
    if not isinstance(sysd.get("description", ""), str):
        problems.append(f"[system].description must be a string, got {_kind(sysd['description'])}")
    if missing:
        return None
    try:
        return System(coordinates=sysd["coordinates"], lagrangian=sysd["lagrangian"],
                      constraints=sysd.get("constraints", []), forces=sysd.get("forces", {}),
                      parameters=sysd.get("parameters", {}), inputs=sysd.get("inputs"), name=name,
                      fiber=sysd.get("fiber"), planar_frame=sysd.get("planar_frame", "auto"),
                      forward=sysd.get("forward", "x"),
                      holonomic=sysd.get("holonomic", ()), dependent=sysd.get("dependent"))
    except ModelError as exc:
        problems.extend(exc.problems)
        return None


def _simulation(sim, system, problems) -> SimulationSpec | None:
    """The ``[simulation]`` table (its checks that need the system are skipped without one)."""
    if not isinstance(sim, dict):
        problems.append(f"[simulation] must be a table, got {_kind(sim)}")
        return None
    start = len(problems)
    unknown = set(sim) - SIMULATION_KEYS
    if unknown:
        problems.append(f"[simulation]: unknown key(s) {sorted(unknown)}"
                        f"{known_names(sorted(unknown)[0], sorted(SIMULATION_KEYS), label='allowed')}")
    for key in ("q0", "qdot0", "t_final", "samples"):
        if key not in sim:
            problems.append(f"[simulation]: missing key {key!r}")
    n = system.n if system else None
    q0 = _vector(sim["q0"], "[simulation].q0", n, problems) if "q0" in sim else None
    if q0 is None and system is not None and system.eliminated and "q0" in sim:
        problems.append("the holonomic constraints eliminated " + ", ".join(
            f"{c} (= {e})" for c, e in system.eliminated) + f": q0 lists the other coordinates "
            f"({', '.join(system.coordinates)})")
    t0 = _number(sim.get("t0", 0.0), "[simulation].t0", problems)
    tf = _number(sim["t_final"], "[simulation].t_final", problems) if "t_final" in sim else math.nan
    if math.isfinite(t0) and math.isfinite(tf) and not tf > t0:
        problems.append(f"[simulation]: t_final = {tf} must be greater than t0 = {t0}")
    samples = sim.get("samples", 2)
    if isinstance(samples, bool) or not isinstance(samples, int) or not 2 <= samples <= MAX_SAMPLES:
        problems.append(f"[simulation].samples must be an integer from 2 to 10⁶, got {samples!r} "
                        "(10⁶ samples already take about a gigabyte and a minute to evaluate and write)")
    sim_params = {k: _number(v, f"[simulation].parameters.{k}", problems)
                  for k, v in _table(sim.get("parameters"), "[simulation].parameters", problems).items()}
    for key in ("rtol", "atol"):
        if key in sim and not (isinstance(sim[key], (int, float)) and not isinstance(sim[key], bool)
                               and 0 < sim[key] < 1):
            problems.append(f"[simulation].{key} must be a number in (0, 1), got {sim[key]!r}")
    for key in ("method", "formulation"):
        if key in sim and not isinstance(sim[key], str):
            problems.append(f"[simulation].{key} must be a string, got {_kind(sim[key])}")
    formulation = sim.get("formulation")
    if isinstance(formulation, str) and formulation not in ("reduced", "lagrange", "hamilton"):
        problems.append(f"[simulation].formulation {formulation!r} is not reduced, lagrange or hamilton")
    outputs = _outputs(sim.get("outputs"), problems)
    if system is None:
        return None
    bad = [k for k in sim_params if k not in system.parameters]
    if bad:
        problems.append(f"[simulation].parameters: unknown parameter(s) {bad}"
                        f"{known_names(bad[0], system.parameters, label='parameters')}")
    elif sim_params and len(problems) == start:
        problems.extend(system.parameter_problems(sim_params, label="the [simulation] parameters"))
    if q0 is not None and system.holonomic and len(problems) == start:
        q0 = _consistent_q0(system, q0, sim_params, problems)
    qd0 = _initial_velocities(sim.get("qdot0"), system, q0, sim_params, problems) if "qdot0" in sim else None
    controller = _input_laws(sim.get("inputs", {}), system, sim_params, problems)
    if len(problems) > start:
        return None
    return SimulationSpec(q0=q0, qdot0=qd0, t_final=tf, samples=samples, t0=t0, controller=controller,
                          parameters=sim_params, formulation=formulation, rtol=sim.get("rtol"),
                          atol=sim.get("atol"), method=sim.get("method"), outputs=outputs)


def _consistent_q0(system, q0, params, problems):
    """``q0`` with its dependent coordinates solved from the kept holonomic constraints (the
    values written are Newton's starting point; :func:`~.holonomic.consistent_configuration`)."""
    from ..holonomic import consistent_configuration
    try:
        return consistent_configuration(system, q0, params=params)
    except ModelError as exc:
        problems.extend(f"[simulation].q0: {p}" for p in exc.problems)
        return None


def _initial_velocities(value, system, q0, params, problems):
    """``qdot0``: a full list, or a partial table {name = value} whose remaining velocities are
    solved from ω(q0)q̇ = 0 (:func:`~nhgait.dynamics.derivation.states.consistent_velocities`)."""
    if isinstance(value, dict):
        given = {}
        for k, v in value.items():
            name = k[:-4] if k.endswith("_dot") else k
            given[name] = _number(v, f"[simulation].qdot0.{k}", problems)
        if q0 is None:
            return None
        from ..states import consistent_velocities
        try:
            return consistent_velocities(system, q0, given, params=params)
        except ModelError as exc:
            problems.extend(f"[simulation].qdot0: {p}" for p in exc.problems)
            return None
    return _vector(value, "[simulation].qdot0", system.n, problems)


def _input_laws(inputs, system, params, problems):
    """``[simulation.inputs]``: one law per system input, as an :class:`ExpressionController`."""
    inputs = _table(inputs, "[simulation].inputs", problems)
    if not system.inputs:
        if inputs:
            problems.append("[simulation].inputs given but the system has no inputs")
        return None
    missing = [u for u in system.inputs if u not in inputs]
    extra = [u for u in inputs if u not in system.inputs]
    if missing:
        problems.append(f"[simulation].inputs: no law for input(s) {missing} (write 0 for none)")
    if extra:
        problems.append(f"[simulation].inputs: {extra} are not inputs of the system"
                        f"{known_names(extra[0], system.inputs, label='inputs')}")
    if missing or extra:
        return None
    names = {s.name: s for s in system.q + system.q_dot + system.param_symbols}
    names["t"] = TIME
    exprs, ok = [], True
    for u in system.inputs:
        e = _known_expression(inputs[u], names, f"[simulation].inputs.{u}", problems,
                              "allowed: t, coordinates, velocities, parameters")
        ok = ok and e is not None
        exprs.append(e)
    return ExpressionController(system, tuple(exprs), params) if ok else None


def _outputs(value, problems):
    """``[simulation].outputs``: the names the scene needs (see docs/scene-format.md)."""
    if value is None:
        return None
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        problems.append(f"[simulation].outputs must be a list of names, got {value!r}")
        return None
    return tuple(value)


def _motion_symbols(system) -> set:
    """The symbols that make a quantity one of the motion: the inputs and the accelerations."""
    from ..quantities import acceleration_symbols
    return set(system.input_symbols) | set(acceleration_symbols(system))


def _quantities(system, table, problems) -> dict:
    """``[quantities]``: name = expression in the coordinates, velocities, accelerations
    ``<q>_ddot``, inputs and parameters."""
    from ..quantities import acceleration_symbols
    names = {s.name: s for s in system.q + system.q_dot + system.param_symbols}
    taken = set(names) | set(system.inputs) | {"t"} | {s.name for s in acceleration_symbols(system)}
    names.update({s.name: s for s in (*acceleration_symbols(system), *system.input_symbols)})
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
        e = _known_expression(text, names, where, problems,
                              "allowed: coordinates, velocities, accelerations, inputs, parameters")
        if e is not None:
            out[key] = e
    return out


def _known_expression(text, names: dict, where: str, problems: list, allowed: str):
    """The expression of ``text`` (:func:`parse_field`: data, never code) when every symbol in
    it is one of ``names``; else None, its problem in ``problems`` (the unknown symbols, the
    close matches of the first, and what is ``allowed``)."""
    e = parse_field(text, names, where, problems)
    if e is None:
        return None
    bad = sorted(s.name for s in e.free_symbols if s.name not in names)
    if bad:
        problems.append(f"{where}: unknown symbol(s) {bad}{known_names(bad[0], list(names), label=allowed)}")
        return None
    return e


def load_scene(path_or_name, overrides=()) -> Scene:
    """Read a scene file, or a built-in scene by name ("unicycle", "snakeboard", ...);
    ``overrides``: ``--set`` assignments to its ``[simulation]`` table
    (:func:`~nhgait.dynamics.derivation.input.assignments.apply_simulation_overrides`).

    Examples
    --------
    The snakeboard (thesis Example 3.2): five coordinates, two torques, and the rotor radius
    written in the scene as r = √((J + J_r + 2J_w)/m):

    >>> from nhgait.dynamics import load_scene
    >>> scene = load_scene("snakeboard")
    >>> scene.system.coordinates, scene.system.inputs
    (('x', 'y', 'theta', 'psi', 'phi'), ('tau_psi', 'tau_phi'))
    >>> p = scene.system.parameters
    >>> abs(p["r"] - ((p["J"] + p["J_r"] + 2 * p["J_w"]) / p["m"]) ** 0.5) < 1e-15
    True
    >>> scene.simulation.q0.tolist()     # Table 3.3: the shape on ψ = sin t, φ = sin(t + π/2)
    [0.0, 0.0, 0.0, 0.0, 1.0]
    """
    p = Path(str(path_or_name))
    if not names_a_file(p) and p.suffix != ".toml":
        name = str(path_or_name).replace("-", "_")
        try:
            text = (resources.files("nhgait.dynamics.derivation").joinpath("scenes", f"{name}.toml")
                    .read_text())
        except (FileNotFoundError, OSError):
            available = sorted(f.name[:-5] for f in resources.files("nhgait.dynamics.derivation")
                               .joinpath("scenes").iterdir()
                               if f.name.endswith(".toml"))
            raise ModelError([f"{path_or_name!r} is neither a scene file nor a built-in scene"
                              f"{known_names(name, available, label='built-ins')}"],
                             title="unknown scene") from None
        source = f"built-in scene {name}"
    else:
        text = read_text_file(p, "scene file", title="cannot read the scene")
        source = str(p)
    return scene_from_text(text, source, overrides)



def scene_from_text(text: str, source: str = "<scene>", overrides=()) -> Scene:
    """A :class:`Scene` from the text of a scene file (``source`` names it in errors)."""
    from nhgait.dynamics.derivation.input.assignments import apply_simulation_overrides
    return parse_scene(apply_simulation_overrides(read_toml(text, source), overrides), source)
