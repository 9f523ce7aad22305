"""Bad input gets one clear ModelError naming every problem — never a sympy/CasADi traceback."""
import math

import numpy as np
import pytest

from nhgait.dynamics import ModelError, SingularConfigurationError, System, derive, to_state

UNI_L = "m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2"
UNI_C = ["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"]
UNI_P = {"m": 0.5, "r": 0.1, "J_phi": 0.2, "J_theta": 0.3}


def uni(**kw):
    args = dict(coordinates=["x", "y", "theta", "phi"], lagrangian=UNI_L, constraints=UNI_C,
                forces={"theta": "tau_theta", "phi": "tau_phi"}, parameters=UNI_P)
    args.update(kw)
    return System(**args)


def test_constraint_not_linear_in_velocities():
    with pytest.raises(ModelError, match=r"constraint 1 .* is not linear in the velocities"):
        uni(constraints=["x_dot**2 - r*cos(theta)*phi_dot", UNI_C[1]])


def test_constraint_with_velocity_free_term():
    with pytest.raises(ModelError, match="has a term without velocities"):
        uni(constraints=["x_dot - r*cos(theta)*phi_dot + 1", UNI_C[1]])


def test_dependent_constraints():
    with pytest.raises(ModelError, match=r"constraints are dependent: rank ω\(q\) = 2 < k = 3"):
        uni(constraints=UNI_C + ["2*x_dot - 2*r*cos(theta)*phi_dot"])


def test_singular_kinetic_metric():
    with pytest.raises(ModelError, match=r"is singular .*no kinetic energy in theta"):
        uni(lagrangian="m*(x_dot**2 + y_dot**2)/2 + J_phi*phi_dot**2/2")


def test_negative_inertia_is_not_positive_definite():
    with pytest.raises(ModelError, match="not positive definite"):
        uni(parameters={**UNI_P, "J_theta": -0.3})


def test_unknown_symbol_and_missing_parameter_listed_together():
    with pytest.raises(ModelError) as info:
        uni(lagrangian=UNI_L + " + k*x**2", parameters={"m": 0.5, "J_phi": 0.2, "J_theta": 0.3})
    msg = str(info.value)
    assert "unknown symbol 'k' in the Lagrangian" in msg
    assert "unknown symbol 'r' in constraint 1" in msg
    assert "unknown symbol 'r' in constraint 2" in msg
    assert len(info.value.problems) == 3


def test_velocity_of_unknown_coordinate():
    with pytest.raises(ModelError, match=r"unknown symbol 'z_dot'.*no coordinate named 'z'"):
        uni(constraints=["z_dot - r*cos(theta)*phi_dot", UNI_C[1]])


def test_force_on_unknown_coordinate():
    with pytest.raises(ModelError, match=r"forces: 'psi' is not a coordinate"):
        uni(forces={"psi": "tau"})


def test_undeclared_input_when_inputs_are_declared():
    with pytest.raises(ModelError, match="unknown symbol 'tau_x' in the force on theta"):
        uni(forces={"theta": "tau_x"}, inputs=["tau_theta"])


def test_inputs_inferred_when_not_declared():
    s = uni(forces={"theta": "u1 + 0*theta", "phi": "u2*cos(theta)"})
    assert s.inputs == ("u1", "u2")


def test_time_dependent_lagrangian_rejected():
    with pytest.raises(ModelError, match="depends explicitly on time"):
        uni(lagrangian=UNI_L + " + sin(t)*x")


def test_gyroscopic_terms_rejected():
    with pytest.raises(ModelError, match="terms linear in the velocities"):
        uni(lagrangian=UNI_L + " + m*x*y_dot")


def test_unparseable_expression():
    with pytest.raises(ModelError, match="lagrangian: cannot parse"):
        uni(lagrangian="m*(x_dot**2 +")


def test_name_clash_and_bad_parameter_value():
    with pytest.raises(ModelError) as info:
        System(coordinates=["x", "x"], lagrangian="x_dot**2", parameters={"m": "heavy"})
    msg = str(info.value)
    assert "used twice" in msg
    assert "'heavy' is not a number" in msg


def test_no_full_symmetry_group_shows_the_table():
    # a potential depending on every coordinate breaks every candidate group
    with pytest.raises(ModelError,
                       match=r"no full symmetry group[\s\S]*\| fibre coordinates \| group G \|") as info:
        derive(uni(lagrangian=UNI_L + " - (x**2 + y**2 + theta**2 + phi**2)"), "reduced", use_cache=False)
    assert "not a symmetry" in str(info.value)


def test_user_fiber_that_is_not_full_is_rejected():
    with pytest.raises(ModelError, match=r"fiber coordinates \(x, y, theta\) do not give a full symmetry "
                                         r"group: not full"):
        derive(uni(fiber=["x", "y", "theta"]), "reduced", use_cache=False)


def test_unknown_fiber_coordinate():
    with pytest.raises(ModelError, match="fiber: psi not coordinates"):
        uni(fiber=["x", "psi"])


def test_initial_state_violating_the_constraints(models):
    model = models["unicycle"]["reduced"]
    with pytest.raises(ModelError, match=r"violates the constraints ω\(q\)q̇ = 0") as info:
        to_state(model, [0, 0, 0, 0], [1.0, 0, 0, 0])
    # ẋ = 1 with φ̇ = 0 at θ = 0 breaks the rolling constraint ẋ = r cos θ φ̇ by exactly 1 (and
    # nothing else: ẏ = r sin θ φ̇ holds); the message names it with its residual
    lines = [p for p in info.value.problems if p.startswith("constraint")]
    assert len(lines) == 1
    assert "x_dot" in lines[0]
    assert lines[0].endswith("residual 1 at this configuration")


@pytest.mark.parametrize("phi", [math.pi / 2, -math.pi / 2])
def test_snakeboard_on_the_singular_set(models, phi):
    model = models["snakeboard"]["reduced"]
    with pytest.raises(SingularConfigurationError, match=r"phi = [-]?1\.5708.* singular set"):
        to_state(model, [0, 0, 0, 0, phi], [0, 0, 0, 1.0, 0])


def test_snakeboard_near_but_off_the_singular_set_is_fine(models):
    model = models["snakeboard"]["reduced"]
    z = to_state(model, [0, 0, 0, 0, math.pi / 2 - 1e-3], [0, 0, 0, 1.0, 0])
    assert np.all(np.isfinite(z))


def test_unknown_formulation_and_version():
    with pytest.raises(ModelError, match="unknown formulation 'euler'"):
        derive("unicycle", "euler")
    with pytest.raises(ModelError, match="unknown reconstruction version 'C'"):
        derive("unicycle", "reduced", version="C")


def test_unknown_builtin():
    with pytest.raises(ModelError, match="unknown built-in system 'bicycle'"):
        derive("bicycle")


def test_wrong_state_size(models):
    with pytest.raises(ModelError, match="q has 3 entries, expected 4"):
        to_state(models["unicycle"]["reduced"], [0, 0, 0], [0, 0, 0, 0])
