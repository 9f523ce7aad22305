"""The snakeboard's forward gait planned in rockit on nhgait's model.

nhgait derives the snakeboard's reduced equations (thesis §3) and hands them over as one CasADi
Function, ż = f(t, z, u, p); rockit states the optimal-control problem and transcribes it.
The task is ``nhgait plan snakeboard --gait forward`` (gaits/library/snakeboard.toml, the
thesis' P2): horizon 2π s, 100 intervals, J = ∫ (τ_ψ² + τ_φ²) dt, |τ| ≤ 10 N·m, |φ| ≤ 1 rad,
start at the origin at rest, end 1 m ahead with θ = 0 at rest, the shape motion periodic.
Both use multiple shooting with 4 RK4 steps per interval, so both solve the same NLP: the
example prints rockit's J beside nhgait's (they agree to 1e-4 relative or better).

Run:  pip install 'nhgait[rockit]'  then  python examples/rockit_gait.py
"""
from __future__ import annotations

import math
import sys

import casadi as ca
import numpy as np

#: the states the planner solves this gait in: q, then n − k velocity quantities
VELOCITIES = ("forward_velocity", "psi_dot", "phi_dot")


def nhgait_model():
    """The snakeboard's reduced ODE with its parameter values bound, in the states
    z = (x, y, θ, ψ, φ, forward_velocity, ψ̇, φ̇): ``numeric["rhs"]`` is the CasADi Function
    f(t, z, u, p) → ż the planner integrates (p is ignored: the values are bound)."""
    from nhgait.dynamics import derive, load_scene
    from nhgait.dynamics.numerics.specialisation import specialise
    scene = load_scene("snakeboard")
    return specialise(derive(scene.system, "reduced"), velocities=VELOCITIES)


def rockit_plan(model, intervals: int = 100, rk4_steps: int = 4):
    """The forward gait in rockit: returns (J, the rockit solution)."""
    from rockit import MultipleShooting, Ocp
    f = model.numeric["rhs"]
    names = list(model.state_names)
    i = {n: names.index(n) for n in names}
    params = model.numeric.params()
    ocp = Ocp(T=2 * math.pi)
    z = ocp.state(len(names))
    u = ocp.control(2)
    ocp.set_der(z, f(0, z, u, params))
    ocp.add_objective(ocp.integral(ca.sumsqr(u)))
    ocp.subject_to(-10 <= (u <= 10))
    ocp.subject_to(-1 <= (z[i["phi"]] <= 1))
    for name in ("x", "y", "theta", "psi", "forward_velocity"):
        ocp.subject_to(ocp.at_t0(z[i[name]]) == 0)
    for name, value in (("x", 1.0), ("theta", 0.0), ("forward_velocity", 0.0)):
        ocp.subject_to(ocp.at_tf(z[i[name]]) == value)
    for name in ("psi", "phi", "psi_dot", "phi_dot"):
        ocp.subject_to(ocp.at_tf(z[i[name]]) == ocp.at_t0(z[i[name]]))
    # a first guess of the thesis' kind: ψ and φ on a loop, ψ̇ and φ̇ their rates
    t = np.linspace(0, 2 * math.pi, intervals + 1)
    guess = np.zeros((len(names), t.size))
    guess[i["psi"]], guess[i["phi"]] = np.sin(t), 0.9 * np.cos(t)
    guess[i["psi_dot"]], guess[i["phi_dot"]] = np.cos(t), -0.9 * np.sin(t)
    guess[i["x"]] = t / (2 * math.pi)
    ocp.set_initial(z, guess)
    ocp.method(MultipleShooting(N=intervals, M=rk4_steps, intg="rk"))
    ocp.solver("ipopt", {"ipopt.print_level": 0, "print_time": False, "ipopt.tol": 1e-10})
    solution = ocp.solve()
    return float(solution.value(ocp.objective)), solution


def nhgait_plan() -> float:
    """J of ``nhgait plan snakeboard --gait forward`` (no files written)."""
    from nhgait.gaits import plan
    result = plan("snakeboard", "forward")
    if not result.success:
        raise SystemExit(f"nhgait's plan failed: {result.solution.message}")
    return float(result.solution.objective)


def main() -> int:
    try:
        import rockit  # noqa: F401
    except ImportError:
        print("rockit is not installed: pip install 'nhgait[rockit]' (the package rockit-meco)")
        return 1
    J_rockit, _ = rockit_plan(nhgait_model())
    J_nhgait = nhgait_plan()
    gap = abs(J_rockit - J_nhgait) / abs(J_nhgait)
    print(f"snakeboard forward gait: J (rockit, on nhgait's model) = {J_rockit:.8f}")
    print(f"                         J (nhgait plan)                = {J_nhgait:.8f}")
    print(f"                         relative difference            = {gap:.1e}")
    return 0 if gap <= 1e-4 else 1


if __name__ == "__main__":
    sys.exit(main())
