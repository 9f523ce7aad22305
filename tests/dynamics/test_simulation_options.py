"""The options of one simulation (dynamics/simulation/options.py): keywords resolved once into
a frozen object, every problem named — unknown names with a suggestion, unknown methods, a
projection with a route that cannot project, Baumgarte gains that are not two finite numbers
≥ 0, a step cap that is not a positive integer."""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.simulation.options import METHODS, SimulationOptions


def test_keywords_replace_fields_and_unknown_ones_are_named():
    options = SimulationOptions.from_keywords(method="RK45", rtol=1e-6)
    assert (options.method, options.rtol, options.atol) == ("RK45", 1e-6, 1e-10)
    assert SimulationOptions.from_keywords(options, atol=1e-12).rtol == 1e-6
    says = r"(?s)2 problem.*unknown option 'rtoll': did you mean 'rtol'"
    with pytest.raises(ModelError, match=says) as caught:
        SimulationOptions.from_keywords(rtoll=1e-3, zzz=1)
    assert "'zzz'" in str(caught.value)                 # every problem in one error


def test_names_and_routes():
    assert "DOP853" in METHODS and "CVODES" in METHODS and "auto" in METHODS
    bad = SimulationOptions(method="Euler", dae="ida", stabilization="magic")
    problems = bad.name_problems()
    assert len(problems) == 3 and "Euler" in problems[0] and "ida" in problems[1] and "magic" in problems[2]
    assert SimulationOptions(dae="idas").idas and SimulationOptions(dae="idas").sundials
    assert SimulationOptions(method="CVODES").sundials and not SimulationOptions().sundials
    assert SimulationOptions().name_problems() == []


def test_combinations_and_values():
    assert any("projection" in p for p in
               SimulationOptions(stabilization="projection", dae="idas").combination_problems())
    assert any("projection" in p for p in
               SimulationOptions(stabilization="projection", method="CVODES").combination_problems())
    assert SimulationOptions(stabilization="projection").combination_problems() == []
    for gains in ((-1.0, 0.0), (np.inf, 1.0), ("a", 1)):
        assert any("baumgarte" in p for p in
                   SimulationOptions(stabilization="baumgarte", baumgarte=gains).combination_problems())
    assert SimulationOptions(stabilization="baumgarte", baumgarte=(2.0, 1.0)).combination_problems() == []
    assert any("max_steps" in p for p in SimulationOptions(max_steps=0).value_problems(0.0, 1.0))
    assert any("max_steps" in p for p in SimulationOptions(max_steps=2.5).value_problems(0.0, 1.0))


def test_the_parameter_values_travel_in_the_options():
    """``params`` is a field like the others (issue 44): the unicycle rolled straight at φ̇ = 1 for
    1 s moves x = r φ = r — the radius of the options, or of the keyword on top of them — and a
    bad value is named like a keyword's."""
    from nhgait.dynamics import derive, simulate
    model = derive("unicycle")
    options = SimulationOptions(params={"r": 0.2}, t_eval=[0.0, 1.0])
    for given, radius in (({}, 0.2), ({"params": {"r": 0.05}}, 0.05)):
        traj = simulate(model, (0.0, 1.0), [0, 0, 0, 0], [radius, 0, 0, 1.0], options=options, **given)
        assert traj.success
        assert traj.q[-1] == pytest.approx([radius, 0.0, 0.0, 1.0], abs=1e-9)
    with pytest.raises(ModelError, match="the given params"):
        simulate(model, (0.0, 1.0), [0, 0, 0, 0], [0.1, 0, 0, 1.0],
                 options=SimulationOptions(params={"m": -1.0}))
