"""The text forms of results (dynamics/reprs.py): shapes and spans as they are, the status in
words; a derived model's repr and Markdown name its system, dimension and states (the particle:
4 states x, y, p, pt_y, its fibre x, purely mechanical)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from nhgait.dynamics.reprs import arrays_text, model_markdown, model_repr, shape_of, trajectory_repr


def test_shapes_and_arrays():
    assert shape_of(np.zeros((81, 4))) == "(81, 4)" and shape_of(np.zeros(3)) == "(3,)"
    assert shape_of(None) == "-"
    obj = SimpleNamespace(t=np.zeros(81), q=np.zeros((81, 4)), lam=None)
    assert arrays_text(obj, ("t", "q", "lam", "missing")) == "t (81,), q (81, 4)"


def test_a_trajectory_in_one_glance():
    traj = SimpleNamespace(settings={"system": "unicycle"}, formulation="reduced", method="DOP853",
                           success=False, message="step size too small " * 10, t=np.linspace(0, 2, 5),
                           q=np.zeros((5, 4)), qdot=None, state=None, u=None, lam=None,
                           coordinates=("x", "y", "theta", "phi"), nfev=123)
    text = trajectory_repr(traj)
    assert text.startswith("<Trajectory unicycle: reduced, DOP853, FAILED (step size too small")
    assert "t = 0 … 2 s (5 samples)" in text and "q (5, 4)" in text and "qdot" not in text
    assert text.endswith("coordinates (x, y, theta, phi); 123 evaluations>")


def test_a_derived_model():
    from nhgait.dynamics import System, derive
    model = derive(System(["x", "y"], "m*(x_dot**2 + y_dot**2)/2", [], parameters={"m": 2.0}), "reduced")
    assert model_repr(model) == (f"<ReducedODE of {model.system.name}: 4 states z = (x, y, p, pt_y); "
                                 "model.to_text() prints the equations>")
    md = model_markdown(model)
    assert "| dimension | 4 |" in md and "| fibre (group) coordinates | x |" in md and md.count("```") == 2
