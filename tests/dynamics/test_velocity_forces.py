"""Forces that are not affine in the velocities (quadratic drag, Coulomb friction sign(q̇),
exp of a velocity) reach the reduced equations whole. Reference: the Euler–Lagrange DAE with
multipliers (λ eliminated at acceleration level), an independent derivation, at random
constraint-consistent states; tolerance 1e-10 relative."""
import numpy as np
import pytest

from nhgait.dynamics import System, derive
from nhgait.dynamics.derivation.reduction import derive_reduced
from nhgait.dynamics.derivation.states import consistent_velocities, to_state

FORCES = {
    "quadratic drag": {"theta": "u1 - c*theta_dot*Abs(theta_dot)", "phi": "u2 - c*phi_dot**2"},
    "Coulomb friction": {"theta": "u1", "phi": "u2 - c*sign(phi_dot)"},
    "exp of a velocity": {"theta": "u1 - c*exp(theta_dot)", "phi": "u2*cos(phi_dot)"},
}


def _unicycle(forces):
    return System(coordinates=["x", "y", "theta", "phi"],
                  lagrangian="m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2",
                  constraints=["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"],
                  forces=forces, inputs=["u1", "u2"],
                  parameters={"m": 0.5, "r": 0.1, "J_phi": 0.2, "J_theta": 0.3, "c": 0.7})


@pytest.mark.parametrize("form", ["explicit", "implicit"])
@pytest.mark.parametrize("case", sorted(FORCES))
def test_reduced_accelerations_match_the_lagrange_dae(case, form):
    system = _unicycle(FORCES[case])
    reduced = derive_reduced(system, form=form)
    lagrange = derive(system, "lagrange", use_cache=False)
    rng = np.random.default_rng(5)
    params = reduced.numeric.params()
    for _ in range(20):
        q = rng.uniform(-2, 2, 4)
        qdot = consistent_velocities(system, q, {"theta": rng.uniform(-2, 2), "phi": rng.uniform(-2, 2)})
        u = rng.uniform(-1, 1, 2)
        z = to_state(reduced, q, qdot)
        qdd_red = np.asarray(reduced.numeric.call("qddot", 0.0, z, u, params), dtype=float).ravel()
        xdot, _ = lagrange.numeric.call("ode", 0.0, np.r_[q, qdot], u, params)
        qdd_ref = np.asarray(xdot, dtype=float).ravel()[4:]
        np.testing.assert_allclose(qdd_red, qdd_ref, rtol=1e-10, atol=1e-10 * np.abs(qdd_ref).max())
