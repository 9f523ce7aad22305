"""T(q, q̇), V(q) and M(q) of systems built from URDF files against Pinocchio's
``computeKineticEnergy``, ``computePotentialEnergy`` and ``crba`` (an independent rigid-body
library reading the same file with its own parser), at random states, to 1e-10 relative.

Conventions: Pinocchio's planar root has q = (x, y, cos θ, sin θ) and the body-frame velocity
(u, w, θ̇) with u = cos θ ẋ + sin θ ẏ, w = −sin θ ẋ + cos θ ẏ; a continuous joint has
q = (cos, sin). With v = G q̇ (G: the base rotation, and the multiplier of a mimic joint, which
Pinocchio's model here treats as a joint of its own), M(q) = Gᵀ M_pin G. Joints that are neither
coordinates nor mimics are locked with ``buildReducedModel`` at the scene's values.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

pin = pytest.importorskip("pinocchio")

from nhgait.dynamics.derivation.urdf import urdf_system  # noqa: E402
from nhgait.dynamics.derivation.urdf.builder import resolve_path  # noqa: E402
from nhgait.dynamics.errors import ModelError  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TIAGO = "example-robot-data:tiago_description/robots/tiago.urdf"
WHEELS = ["wheel_left_joint", "wheel_right_joint"]

CASES = {
    "snakeboard": ({"urdf": "snakeboard.urdf", "joints": ["psi", "phi"],
                    "skates": ["back_wheels", "front_wheels"]}, {"back_axle_joint": ("phi", -1.0, 0.0)}),
    "roller_racer": ({"urdf": "roller_racer.urdf", "joints": ["phi"],
                      "skates": ["front_axle", "rear_axle"]}, {}),
    "tiago_base": ({"urdf": TIAGO, "joints": WHEELS, "rolling": WHEELS}, {}),
    "tiago_arm": ({"urdf": TIAGO, "joints": WHEELS + ["arm_2_joint", "torso_lift_joint", "arm_4_joint"],
                   "rolling": WHEELS, "locked": {"arm_1_joint": 0.2, "head_2_joint": -0.3,
                                                 "arm_6_joint": 0.7}}, {}),
}


def _pinocchio_model(table, mimics):
    try:
        path = resolve_path(table["urdf"], EXAMPLES)
    except ModelError:
        pytest.skip("example-robot-data is not installed")
    full = pin.buildModelFromUrdf(str(path), pin.JointModelPlanar())
    reference = pin.neutral(full)
    for name, value in table.get("locked", {}).items():
        joint = full.joints[full.getJointId(name)]
        values = [np.cos(value), np.sin(value)] if joint.nq == 2 else [value]
        reference[joint.idx_q:joint.idx_q + joint.nq] = values
    keep = set(table["joints"]) | set(mimics)
    lock = [full.getJointId(name) for name in full.names[2:] if name not in keep]
    return pin.buildReducedModel(full, lock, reference)


def _pinocchio_state(model, system, mimics, q, q_dot):
    """Pinocchio's (q, v) and G with v = G q̇ for nhgait's (q, q̇)."""
    c, s = np.cos(q[2]), np.sin(q[2])
    G = np.zeros((model.nv, system.n))
    G[0, :2], G[1, :2], G[2, 2] = (c, s), (-s, c), 1.0
    config = [q[0], q[1], c, s]
    for name in model.names[2:]:
        joint = model.joints[model.getJointId(name)]
        source, multiplier, offset = mimics.get(name, (name, 1.0, 0.0))
        k = system.coordinates.index(source)
        value = multiplier * q[k] + offset
        config += [np.cos(value), np.sin(value)] if joint.nq == 2 else [value]
        G[joint.idx_v, k] = multiplier
    return np.array(config), G @ q_dot, G


@pytest.mark.parametrize("case", list(CASES) + ["tiago_arm_nested"])
def test_energy_and_metric_agree_with_pinocchio(case, monkeypatch):
    if case.endswith("_nested"):     # T as a sum over bodies, the form of trees beyond the budget
        from nhgait.dynamics.derivation.urdf import energy
        monkeypatch.setattr(energy, "EXPANSION_BUDGET", 0)
    table, mimics = CASES[case.removesuffix("_nested")]
    model = _pinocchio_model(table, mimics)          # skips when TIAGo's URDF is not installed
    system = urdf_system(table, EXAMPLES).system
    data = model.createData()
    f_M = sp.lambdify([system.q], system.mass_matrix(), "numpy")
    f_V = sp.lambdify([system.q], system.potential(), "numpy")
    rng = np.random.default_rng(17)
    worst = {"T": 0.0, "V": 0.0, "M": 0.0}
    for _ in range(20):
        q, q_dot = rng.uniform(-1.2, 1.2, system.n), rng.uniform(-1.0, 1.0, system.n)
        config, v, G = _pinocchio_state(model, system, mimics, q, q_dot)
        M = np.array(f_M(q), dtype=float)
        T_ref = pin.computeKineticEnergy(model, data, config, v)
        V_ref = pin.computePotentialEnergy(model, data, config)
        M_pin = pin.crba(model, data, config)
        M_ref = G.T @ (np.triu(M_pin) + np.triu(M_pin, 1).T) @ G
        worst["T"] = max(worst["T"], abs(0.5 * q_dot @ M @ q_dot - T_ref) / abs(T_ref))
        worst["V"] = max(worst["V"], abs(float(f_V(q)) - V_ref) / max(1.0, abs(V_ref)))
        worst["M"] = max(worst["M"], np.abs(M - M_ref).max() / np.abs(M_ref).max())
    print(case, "n =", system.n, "k =", system.k, {k: f"{v:.2e}" for k, v in worst.items()})
    assert max(worst.values()) < 1e-10, worst
