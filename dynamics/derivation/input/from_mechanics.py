"""The statement of a :class:`~.system.System` (``System.from_mechanics``) from the objects of
sympy.physics.mechanics: a ``KanesMethod``, a
``LagrangesMethod`` or a ``sympy.physics.mechanics.System``, with parameter values.

nhgait states a system by q, L(q, q̇) = T − V, the Pfaffian constraints ω(q) q̇ = 0 and the
generalized forces τ (thesis §3). Lagrange–d'Alembert needs T and τ at *every* velocity, not
only on the constraint surface (∂L/∂q̇ off the surface enters the equations), so they are read
off the configuration, never off velocities a model may have written with the constraints
already in them (sympy's rolling disc sets its centre's velocity to ω × r — true only while it
rolls):

* the coordinates q = (q_ind, q_dep); a generalized speed u is replaced by its value in (q, q̇)
  from the kinematic differential equations k_ku(q) u + k_q̇(q) q̇ + f_k(q) = 0,
  u = −k_ku⁻¹ (k_q̇ q̇ + f_k);
* T = Σ ½ m v·v + ½ ω·I·ω with v the time derivative of each mass centre's position from a
  point fixed in the inertial frame N (``origin``; found on the point graph when not given) and
  ω the body frame's angular velocity from the time derivative of its direction cosines
  (skew(ω) = Ċ Cᵀ, C = B.dcm(N)); a ``LagrangesMethod`` gives L itself;
* τ_i = Σ F·∂v_P/∂q̇_i + Σ M·∂ω_B/∂q̇_i over the loads (gravity included: it is a force here,
  V = 0), a load's u replaced as above;
* the velocity constraints (``velocity_constraints``, the nonholonomic ones), in q̇; a row that
  is the time derivative of a configuration constraint is dropped (nhgait appends its own
  row ∇h·q̇ for each kept holonomic constraint h(q) = 0, ``holonomic=``);
* every symbol with a value in ``parameters`` is a parameter; every other symbol (and every
  other dynamicsymbol f(t)) of the loads is an input.

The model's own velocities are then checked against these at random states on the constraint
surface: a point or a frame whose stated velocity is not the time derivative of its position
or orientation there (a point set fixed that moves, a configuration that does not determine
the positions) is refused, as is anything else the conversion cannot carry (auxiliary speeds,
fewer speeds than coordinates), each problem in one :class:`ModelError`.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import sympy as sp
from sympy.physics import mechanics as me

from ...algebra.trig import trig_normal
from ...errors import ModelError
from .system_parsing import velocity_name

__all__ = ["read_statement", "check_stated_velocities", "MechanicsStatement", "MechanicsSource",
           "read_source"]

T_SYMBOL = me.dynamicsymbols._t
_SAMPLES = 6           # random consistent states at which the stated velocities are checked
_AGREE = 1e-9          # relative agreement of a stated velocity with the configuration's


@dataclass(kw_only=True, frozen=True)
class MechanicsSource:
    """What nhgait reads from a sympy.physics.mechanics object.

    Attributes
    ----------
    kind : "KanesMethod", "LagrangesMethod" or "System".
    frame : the inertial frame N; origin : a point fixed in N (None: found or not needed).
    q : (n,) dynamicsymbols, independent then dependent; q_dep : the dependent ones.
    u : the generalized speeds (empty: the speeds are q̇).
    kdes : kinematic differential equations, each meaning ``expr = 0``.
    velocity_rows : the velocity constraints (in u or q̇), each ``expr = 0``.
    holonomic : the configuration constraints h(q) = 0.
    bodies, loads : the bodies (RigidBody, Particle) and loads ((Point | frame, Vector)).
    lagrangian : L of a LagrangesMethod (None: T − 0 from the bodies).
    """

    kind: str
    frame: object
    origin: object
    q: tuple
    q_dep: tuple
    u: tuple
    kdes: tuple
    velocity_rows: tuple
    holonomic: tuple
    bodies: tuple
    loads: tuple
    lagrangian: object = None


def _loads(loads) -> tuple:
    return tuple((load[0], load[1]) for load in (loads or ()))


def read_source(source, origin=None) -> MechanicsSource:
    """The fields of a ``KanesMethod``, ``LagrangesMethod`` or mechanics ``System`` (some
    KanesMethod fields are held only in its private attributes: read there)."""
    if isinstance(source, me.System):
        actuated = tuple(load for actuator in source.actuators for load in actuator.to_loads())
        return MechanicsSource(kind="System", frame=source.frame, origin=origin or source.fixed_point,
                               q=tuple(source.q), q_dep=tuple(source.q_dep), u=tuple(source.u),
                               kdes=tuple(source.kdes), velocity_rows=tuple(source.velocity_constraints),
                               holonomic=tuple(source.holonomic_constraints), bodies=tuple(source.bodies),
                               loads=_loads(source.loads) + _loads(actuated))
    if isinstance(source, me.KanesMethod):
        if len(getattr(source, "_uaux", ())):
            raise ModelError(["KanesMethod: auxiliary speeds (u_auxiliary) measure constraint forces; "
                              "nhgait computes its own multipliers — build it without them"])
        kdes = (() if source._qdot_u_map is None       # built without kinematic differential equations
                else source._k_kqdot_implicit * source.q.diff(T_SYMBOL)
                + source._k_ku_implicit * source.u + source._f_k_implicit)
        rows = source._k_nh * source.u + source._f_nh if len(source._k_nh) else sp.Matrix()
        return MechanicsSource(kind="KanesMethod", frame=source._inertial, origin=origin, q=tuple(source.q),
                               q_dep=tuple(source._qdep), u=tuple(source.u), kdes=tuple(kdes),
                               velocity_rows=tuple(rows), holonomic=tuple(source._f_h),
                               bodies=tuple(source.bodies or ()), loads=_loads(source.loads))
    if isinstance(source, me.LagrangesMethod):
        holonomic = tuple(source._hol_coneqs)
        return MechanicsSource(kind="LagrangesMethod", frame=source.inertial, origin=origin,
                               q=tuple(source.q), q_dep=(), u=(), kdes=(),
                               velocity_rows=tuple(source.coneqs[len(holonomic):]), holonomic=holonomic,
                               bodies=tuple(source.bodies or ()), loads=_loads(source.loads),
                               lagrangian=source._L[0])
    raise ModelError([f"from_mechanics: expected a KanesMethod, a LagrangesMethod or a "
                      f"sympy.physics.mechanics.System, got {type(source).__name__}"])


# ---------------------------------------------------------------------------- plain symbols
@dataclass(frozen=True)
class Plain:
    """The real symbols q, q̇ (``<q>_dot``) nhgait states a system in, for the dynamicsymbols
    q(t), q(t)' of the model; ``of(expr)`` rewrites an expression (sympy expression, Matrix or
    mechanics Vector in N components) in them, :func:`simplified` gives its trig normal form."""

    q: tuple
    q_dot: tuple
    reps: dict

    @classmethod
    def of_source(cls, src: MechanicsSource) -> Plain:
        q = tuple(sp.Symbol(qi.func.__name__, real=True) for qi in src.q)
        qd = tuple(sp.Symbol(velocity_name(qi.func.__name__), real=True) for qi in src.q)
        reps = {**{qi.diff(T_SYMBOL): v for qi, v in zip(src.q, qd, strict=True)},
                **dict(zip(src.q, q, strict=True))}
        return cls(q, qd, reps)

    def of(self, expr):
        return _expression(expr).xreplace(self.reps)


def simplified(expr):
    """The trig normal form (:func:`~nhgait.dynamics.algebra.trig.trig_normal`) of each entry."""
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(simplified)
    return trig_normal(sp.expand(expr)) if expr.free_symbols else expr


# ---------------------------------------------------------------------------- speeds
def speeds_in_qdot(src: MechanicsSource, plain: Plain) -> dict:
    """u(t) → its value in (q, q̇), solved from the kinematic differential equations (empty
    when the model has no speeds of its own)."""
    if not src.u:
        return {}
    problems = []
    if len(src.u) != len(src.q):
        problems.append(f"{src.kind}: {len(src.u)} generalized speeds for {len(src.q)} coordinates; "
                        "nhgait needs one speed per coordinate (its kinematic differential equations "
                        "then give every q̇)")
    if len(src.kdes) != len(src.u):
        problems.append(f"{src.kind}: {len(src.kdes)} kinematic differential equations for "
                        f"{len(src.u)} speeds")
    if problems:
        raise ModelError(problems)
    kdes = plain.of(sp.Matrix(src.kdes))
    k_ku = kdes.jacobian(list(src.u))
    rest = kdes.xreplace(dict.fromkeys(src.u, 0))
    if k_ku.free_symbols & set(plain.q_dot) or _time_functions(k_ku):
        raise ModelError([f"{src.kind}: the kinematic differential equations are not linear in the speeds"])
    if simplified(k_ku.det()) == 0:
        raise ModelError([f"{src.kind}: the kinematic differential equations do not determine the "
                          "speeds from q̇ (their Jacobian in u is singular)"])
    solved = simplified(k_ku.LUsolve(-rest))
    return dict(zip(src.u, solved, strict=True))


def _in_qdot(expr, plain: Plain, u_map: dict):
    """``expr`` in the plain q, q̇, its speeds replaced by their values."""
    return plain.of(expr).xreplace(u_map)


# ---------------------------------------------------------------------------- kinematics
def find_origin(src: MechanicsSource, points) -> object:
    """A point fixed in the inertial frame connected to ``points`` by positions (the model's
    ``origin`` when given): a point whose velocity in N was set to 0."""
    if src.origin is not None:
        return src.origin
    seen, todo = set(), list(points)
    while todo:
        point = todo.pop()
        if point in seen:
            continue
        seen.add(point)
        vel = point._vel_dict.get(src.frame)
        if vel is not None and not vel.args:
            return point
        todo.extend(point._pos_dict)
    raise ModelError([f"{src.kind}: no point fixed in {src.frame} (velocity set to 0) is located from the "
                      "bodies' mass centres; nhgait reads velocities off positions — pass origin=<Point>"])


def angular_velocity(frame, inertial, plain: Plain) -> sp.Matrix:
    """ω of ``frame`` in ``inertial``, N components, from the direction cosines: with
    R = N.dcm(B) (N components from B ones), skew(ω) = Ṙ Rᵀ."""
    R = inertial.dcm(frame)
    W = plain.of(R.diff(T_SYMBOL)) * plain.of(R).T
    return simplified(sp.Matrix([W[2, 1], W[0, 2], W[1, 0]]))


@dataclass(frozen=True)
class Kinematics:
    """Each point's velocity and each frame's angular velocity in N, from the configuration,
    as column matrices of N components in the plain (q, q̇)."""

    velocity: dict
    angular: dict


def kinematics(src: MechanicsSource, plain: Plain) -> Kinematics:
    """Velocities of the mass centres and load points (from their positions relative to the
    origin) and angular velocities of the body and load frames (from the direction cosines)."""
    N = src.frame
    points = [b.masscenter for b in src.bodies] + [loc for loc, _ in src.loads if isinstance(loc, me.Point)]
    frames = [b.frame for b in src.bodies if hasattr(b, "frame")]
    frames += [loc for loc, _ in src.loads if isinstance(loc, me.ReferenceFrame)]
    origin = find_origin(src, points) if points else None
    problems, velocity, angular = [], {}, {}
    for point in dict.fromkeys(points):
        try:
            r = point.pos_from(origin).to_matrix(N)
        except ValueError:
            problems.append(f"{src.kind}: point {point} is not located from the fixed point {origin}")
            continue
        velocity[point] = simplified(plain.of(r.diff(T_SYMBOL)))
    for frame in dict.fromkeys(frames):
        try:
            angular[frame] = angular_velocity(frame, N, plain)
        except ValueError:
            problems.append(f"{src.kind}: frame {frame} has no orientation relative to {N}")
    if problems:
        raise ModelError(problems)
    return Kinematics(velocity, angular)


def kinetic_energy(src: MechanicsSource, kin: Kinematics, plain: Plain):
    """T = Σ ½ m v·v + ½ ω·I_c·ω (I_c the central inertia, in N components)."""
    N, T = src.frame, sp.S.Zero
    for body in src.bodies:
        v = kin.velocity[body.masscenter]
        T += plain.of(body.mass) * (v.T * v)[0] / 2
        if hasattr(body, "frame"):
            w = kin.angular[body.frame]
            T += (w.T * simplified(plain.of(body.central_inertia.to_matrix(N))) * w)[0] / 2
    return simplified(T)


def generalized_forces(src: MechanicsSource, kin: Kinematics, plain: Plain, u_map: dict) -> list:
    """τ_i = Σ F·∂v_P/∂q̇_i + Σ M·∂ω_B/∂q̇_i (the loads' speeds in q̇)."""
    tau = sp.zeros(len(plain.q), 1)
    for loc, vec in src.loads:
        moved = kin.velocity[loc] if isinstance(loc, me.Point) else kin.angular[loc]
        load = _in_qdot(vec.to_matrix(src.frame), plain, u_map)
        tau += moved.jacobian(plain.q_dot).T * load
    return list(simplified(tau))


# ---------------------------------------------------------------------------- constraints
def velocity_constraints(src: MechanicsSource, plain: Plain, u_map: dict, values: dict) -> list:
    """The velocity constraints in q̇, without the rows that are time derivatives of the
    configuration constraints (in their span at random configurations)."""
    rows = [simplified(_in_qdot(r, plain, u_map)) for r in src.velocity_rows]
    if not src.holonomic:
        return rows
    grads = sp.Matrix([[sp.diff(plain.of(h), qi) for qi in plain.q] for h in src.holonomic])
    row_mat = sp.Matrix([[sp.diff(r, v) for v in plain.q_dot] for r in rows])
    subs = {sp.Symbol(k): v for k, v in values.items()}
    G = sp.lambdify([plain.q], _numbers(grads, subs), "numpy")
    R = sp.lambdify([plain.q], _numbers(row_mat, subs), "numpy")
    rng = np.random.default_rng(3)
    kept = []
    for i, row in enumerate(rows):
        in_span = True
        for q in rng.uniform(-1.2, 1.2, (3, len(plain.q))):
            g, r = np.asarray(G(q), float), np.asarray(R(q), float)[i]
            coef = np.linalg.lstsq(g.T, r, rcond=None)[0]
            in_span &= bool(np.linalg.norm(g.T @ coef - r) <= 1e-10 * max(1.0, np.linalg.norm(r)))
        if not in_span:
            kept.append(row)
    return kept


def _numbers(expr, subs: dict):
    """``expr`` with the parameter values substituted by name."""
    by_name = {s.name: v for s, v in subs.items()}
    return expr.xreplace({s: by_name[s.name] for s in expr.free_symbols if s.name in by_name})


# ---------------------------------------------------------------------------- names
def _parameter_values(parameters) -> dict:
    if not isinstance(parameters, Mapping):
        raise ModelError([f"from_mechanics: parameters is a mapping name → value, got "
                          f"{type(parameters).__name__}"])
    return {(k.name if isinstance(k, sp.Symbol) else str(k)): v for k, v in parameters.items()}


def _expression(expr):
    """A sympy object as it is, a Python number as sympy's; anything else (text above all, which
    sympify would evaluate) is refused with its type."""
    if isinstance(expr, (sp.Basic, sp.MatrixBase)):
        return expr
    if isinstance(expr, int) and not isinstance(expr, bool):
        return sp.Integer(expr)
    if isinstance(expr, float):
        return sp.Float(expr)
    raise ModelError([f"from_mechanics: expected sympy expressions from the mechanics object, "
                      f"got {type(expr).__name__} {expr!r}"])


def _free(expr) -> set:
    return {s for s in _expression(expr).free_symbols if s != T_SYMBOL}


def _time_functions(expr) -> set:
    return {f for f in _expression(expr).atoms(sp.core.function.AppliedUndef)
            if len(f.args) == 1 and f.args[0] == T_SYMBOL}


@dataclass(kw_only=True, frozen=True)
class Converted:
    """The statement read off the model, in the plain q, q̇: L, the constraints (each ``= 0``),
    the generalized forces by coordinate, the configuration constraints h(q) = 0 and the
    configuration's kinematics (None for a LagrangesMethod)."""

    plain: Plain
    lagrangian: object
    constraints: list
    forces: dict
    holonomic: list
    kinematics: Kinematics | None
    speeds: dict


def convert(src: MechanicsSource, values: dict) -> Converted:
    """Read q, L, the constraints and τ off ``src`` (see the module docstring)."""
    plain = Plain.of_source(src)
    u_map = speeds_in_qdot(src, plain)
    if src.lagrangian is not None:        # LagrangesMethod: L given; loads move with Point.vel
        kin = Kinematics({loc: simplified(plain.of(loc.vel(src.frame).to_matrix(src.frame)))
                          for loc, _ in src.loads if isinstance(loc, me.Point)},
                         {loc: simplified(plain.of(loc.ang_vel_in(src.frame).to_matrix(src.frame)))
                          for loc, _ in src.loads if isinstance(loc, me.ReferenceFrame)})
        L = simplified(plain.of(src.lagrangian))
    else:
        kin = kinematics(src, plain)
        L = kinetic_energy(src, kin, plain)
    cons = velocity_constraints(src, plain, u_map, values)
    tau = generalized_forces(src, kin, plain, u_map)
    return Converted(plain=plain, lagrangian=L, constraints=cons,
                     forces={q: t for q, t in zip(plain.q, tau, strict=True) if t != 0},
                     holonomic=[simplified(plain.of(h)) for h in src.holonomic],
                     kinematics=None if src.lagrangian is not None else kin, speeds=u_map)


def _symbol_problems(conv: Converted, values: dict) -> list:
    """Symbols of L, the constraints and h(q) without a value; dynamicsymbols left over."""
    problems = []
    stated = [conv.lagrangian, *conv.constraints, *conv.holonomic]
    known = {s.name for s in conv.plain.q + conv.plain.q_dot}
    missing = sorted({s.name for e in stated for s in _free(e)} - set(values) - known)
    if missing:
        problems.append(f"from_mechanics: {', '.join(missing)} appear in the kinetic energy, the constraints "
                        "or the configuration constraints but have no value: give them in parameters")
    left = sorted({str(f) for e in stated for f in _time_functions(e)})
    if left:
        problems.append(f"from_mechanics: the functions of time {', '.join(left)} are neither coordinates "
                        "nor speeds of the model (a speed without a kinematic differential equation?)")
    return problems


def _inputs(conv: Converted, values: dict) -> tuple:
    """The loads' inputs: their symbols without a value and their functions of time that are
    not coordinates (each replaced by a plain symbol of its name)."""
    reps = {f: sp.Symbol(f.func.__name__, real=True)
            for e in conv.forces.values() for f in _time_functions(e)}
    forces = {q: e.xreplace(reps) for q, e in conv.forces.items()}
    known = {s.name for s in conv.plain.q + conv.plain.q_dot} | set(values)
    names = sorted({s.name for e in forces.values() for s in _free(e)} - known)
    return forces, tuple(names)


@dataclass(frozen=True)
class MechanicsStatement:
    """A model read: ``fields`` are the :class:`~.system.System` keywords (coordinates, the
    Lagrangian, constraints, forces, parameters, inputs, name, holonomic, dependent), ``source``
    and ``converted`` what :func:`check_stated_velocities` compares once the System is built."""

    fields: dict
    source: MechanicsSource
    converted: Converted


def read_statement(source, parameters: Mapping, *, inputs=None, origin=None,
                   name: str | None = None) -> MechanicsStatement:
    """The System fields of a sympy.physics.mechanics model (see the module docstring and
    :meth:`~.system.System.from_mechanics` for the arguments)."""
    values = _parameter_values(parameters)
    src = read_source(source, origin)
    conv = convert(src, values)
    problems = _symbol_problems(conv, values)
    if problems:
        raise ModelError(problems)
    forces, found = _inputs(conv, values)
    fields = {"coordinates": list(conv.plain.q), "lagrangian": conv.lagrangian,
              "constraints": conv.constraints, "forces": forces, "parameters": values,
              "inputs": list(inputs) if inputs is not None else list(found),
              "name": name or src.kind.lower(), "holonomic": conv.holonomic}
    if src.q_dep:
        fields["dependent"] = [q.func.__name__ for q in src.q_dep]
    return MechanicsStatement(fields, src, conv)


# ---------------------------------------------------------------------------- the check
def check_stated_velocities(statement: MechanicsStatement, system) -> None:
    """The model's own velocities (``Point.vel``, ``ReferenceFrame.ang_vel_in``, its speeds
    replaced by their values in q̇) equal the configuration's time derivatives at random
    states on the constraint surface; else a :class:`ModelError` naming each that differs.
    ``system`` is the :class:`~.system.System` built from ``statement.fields``."""
    src, conv = statement.source, statement.converted
    if conv.kinematics is None:
        return
    N, subs = src.frame, system.param_subs()
    names, stated, derived = [], [], []
    kin = conv.kinematics
    for what, items, read in (("the velocity of", kin.velocity, lambda p: p.vel(N)),
                              ("the angular velocity of", kin.angular, lambda f: f.ang_vel_in(N))):
        for obj, value in items.items():
            try:
                own = _in_qdot(read(obj).to_matrix(N), conv.plain, conv.speeds)
            except ValueError:
                continue                     # no velocity stated: nothing to compare
            names += [f"{what} {obj}"] * 3
            stated.append(own)
            derived.append(value)
    if not stated:
        return
    stated = _numbers(sp.Matrix.vstack(*stated), subs)
    derived = _numbers(sp.Matrix.vstack(*derived), subs)
    if _time_functions(stated) or _free(stated) - set(system.q) - set(system.q_dot):
        return                 # a velocity with inputs or unknowns: nothing to compare numerically
    args = [list(system.q), list(system.q_dot)]
    f_stated, f_derived = (sp.lambdify(args, m, "numpy") for m in (stated, derived))
    omega = sp.lambdify([list(system.q)], _numbers(system.omega(), subs), "numpy")
    rng = np.random.default_rng(11)
    worst = np.zeros(len(names))
    for q in rng.uniform(-1.2, 1.2, (_SAMPLES, system.n)):
        basis = _null_space(np.asarray(omega(q), float).reshape(system.k, system.n))
        v = basis @ rng.uniform(-1.0, 1.0, basis.shape[1])
        a, b = np.asarray(f_stated(q, v), float).ravel(), np.asarray(f_derived(q, v), float).ravel()
        worst = np.maximum(worst, np.abs(a - b) / max(1.0, float(np.abs(b).max())))
    bad = sorted({what for what, w in zip(names, worst, strict=True) if w > _AGREE})
    if bad:
        raise ModelError([f"{src.kind}: {what} stated in the model is not the time derivative of its "
                          "position/orientation on the constraint surface (is a point set fixed that "
                          "moves, or does the configuration not determine it?)" for what in bad])


def _null_space(A: np.ndarray) -> np.ndarray:
    if A.shape[0] == 0:
        return np.eye(A.shape[1])
    _, s, vt = np.linalg.svd(A)
    rank = int((s > 1e-12 * max(1.0, s[0])).sum())
    return vt[rank:].T
