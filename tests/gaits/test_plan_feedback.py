"""What a converged plan stores beyond its trajectory (gaits/verification/feedback.py): its
time-varying LQR. On a linear time-invariant ODE ż = A z + B u over a long horizon the gain at
the start equals the stationary gain of the exact discrete system — e^{hA} and
∫₀ʰ e^{sA} ds B from scipy's ``expm``, the gain from scipy's ``solve_discrete_are`` with the
plan's own weights (the recursion's 1/N scaling of Q and R leaves the gain unchanged). Error
budget: RK4 with 4 sub-steps of h/4 = 0.025 s on ‖A‖ ≈ 4 (a relative error of about 1e-8 per
interval) and a recursion converged over 200 intervals: agreement to 1e-6."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from linear_ocp import linear_problem
from scipy.linalg import expm, solve_discrete_are

from nhgait.dynamics.progress import Progress
from nhgait.gaits.verification.feedback import feedback_and_stability

A = np.array([[0.0, 1.0, 0.0], [-4.0, -0.3, 0.5], [0.2, 0.0, -1.0]])
B = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, -2.0]])


def test_the_stored_feedback_is_the_stationary_lqr_of_the_exact_discrete_system():
    T, N = 20.0, 200
    problem = linear_problem(A, B, T, N)
    rng = np.random.default_rng(2)
    t = np.linspace(0.0, T, N + 1)
    states, controls = rng.uniform(-1, 1, (3, N + 1)), rng.uniform(-1, 1, (2, N))  # linear: any point
    solution = SimpleNamespace(problem=problem, t=t, z=states.T, u=controls.T, settings={"rk4_steps": 4})
    stored = feedback_and_stability(solution, Progress.silent())
    assert set(stored) == {"feedback"}                    # not periodic: no Floquet multipliers
    feedback = stored["feedback"]
    h = T / N
    E = expm(h * np.block([[A, B], [np.zeros((2, 5))]]))   # [e^{hA}, ∫e^{sA}ds B] in one exponential
    Ad, Bd = E[:3, :3], E[:3, 3:]
    Q, R = np.diag(feedback.weights.state), np.diag(feedback.weights.control)
    P = solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    assert feedback.gains.shape == (N, 2, 3)
    assert np.max(np.abs(feedback.gains[0] - K)) <= 1e-6 * np.max(np.abs(K))
