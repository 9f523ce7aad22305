"""Values beyond what a double or the machine can carry are refused at once with their name and
the bound; hostile command-line values get argparse's usage error or one clear message — never
an internal error, a hang or a silently wrong run (contract: tests/adversarial.py). The bound
is :data:`nhgait.dynamics.derivation.input.expressions.MAX_MAGNITUDE` (1e15); the largest requests
are :data:`nhgait.ocp.statement.MAX_INTERVALS` intervals and 10⁶ simulation samples."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from adversarial import CAR, answer

CAR_TEXT = Path(CAR).read_text()
PARK = ["plan", "unicycle", "--gait", "parallel-park"]
SIM = ["simulate", "unicycle"]
SWEEP = ["sweep", "unicycle", "--gait", "parallel-park", "--workers", "0", "--no-plots", "--quiet"]
BOUND = r"exceeds 1e\+15 in magnitude"

CASES = [
    # (id, argv after the command's own part, statuses, what the message must say)
    # --- plan: targets, horizons, bounds, intervals
    ("final.y=1e300", [*PARK, "--set", "final.y=1e300"], 2, r"final\.y.*" + BOUND),
    ("final.y=-1e16", [*PARK, "--set", "final.y=-1e16"], 2, BOUND),
    ("final.y=1e15 is still a number", [*PARK, "--set", "final.y=1e400"], 2,
     r"too large|not finite|" + BOUND),
    ("final.y=inf", [*PARK, "--set", "final.y=inf"], 2, r"final\.y"),
    ("final.y=nan", [*PARK, "--set", "final.y=nan"], 2, r"final\.y"),
    ("final.y=10**400", [*PARK, "--set", "final.y=10**400"], 2, r"final\.y"),
    ("final.y=exp(exp(100))", [*PARK, "--set", "final.y=exp(exp(100))"], 2, r"final\.y"),
    ("initial.x=1e300", [*PARK, "--set", "initial.x=1e300"], 2, r"initial\.x.*" + BOUND),
    ("horizon=1e300", [*PARK, "--set", "horizon=1e300"], 2, r"horizon.*" + BOUND),
    ("horizon=0", [*PARK, "--set", "horizon=0"], 2, r"horizon"),
    ("horizon=-1", [*PARK, "--set", "horizon=-1"], 2, r"horizon"),
    ("horizon=nan", [*PARK, "--set", "horizon=nan"], 2, r"horizon"),
    ("control_bounds=1e300", [*PARK, "--set", "control_bounds=1e300"], 2, r"control_bounds.*" + BOUND),
    ("bounds.x=-1e16,1e16", [*PARK, "--set", "bounds.x=-1e16,1e16"], 2, r"bounds\.x.*" + BOUND),
    ("bounds.x=1,-1", [*PARK, "--set", "bounds.x=1,-1"], 2, r"bounds\.x|contradictory"),
    ("objective weight 1e300", [*PARK, "--set", "objective.effort=1e300"], 2, r"objective"),
    ("--intervals 100000", [*PARK, "--intervals", "100000"], 2,
     r"intervals = 100000 must be an integer from 1 to 5000"),
    ("--intervals 5001", [*PARK, "--intervals", "5001"], 2, r"from 1 to 5000"),
    ("--intervals 0", [*PARK, "--intervals", "0"], 2, r"intervals"),
    ("--intervals -5", [*PARK, "--intervals", "-5"], 2, r"intervals"),
    ("--intervals 1e9", [*PARK, "--intervals", "1e9"], 2, r"invalid int value"),
    ("intervals=1e9", [*PARK, "--set", "intervals=1e9"], 2, r"intervals"),
    ("intervals=2.5", [*PARK, "--set", "intervals=2.5"], 2, r"intervals"),
    ("--workers abc", [*PARK, "--workers", "abc"], 2, r"--workers: 'abc' is not a whole number"),
    ("--workers 0", [*PARK, "--workers", "0"], 2, r"--workers: 0 must be at least 1"),
    ("--max-guesses 0", [*PARK, "--max-guesses", "0"], 2, r"--max-guesses: 0 must be at least 1"),
    ("--max-guesses -3", [*PARK, "--max-guesses", "-3"], 2, r"must be at least 1"),
    ("--set without =", [*PARK, "--set", "final.y"], 2, r"expected key=value"),
    ("--set =1", [*PARK, "--set", "=1"], 2, r"expected key=value"),
    ("--set code", [*PARK, "--set", "final.y=__import__('os').getcwd()"], 2, r"final\.y"),
    ("--set unknown key", [*PARK, "--set", "final.nothere=1"], 2, r"nothere"),
    ("--gait on a scene file", ["plan", CAR, "--gait", "forward"], 2,
     r"--gait forward: the built-in gaits belong"),
    ("--gait misspelt", ["plan", "snakeboard", "--gait", "fowrard"], 2, r"forward"),
    ("--solver nonsense", [*PARK, "--solver", "nonsense"], 2, r"invalid choice"),
    # --- simulate: samples, horizons, tolerances, values, input laws
    ("samples=10000000", [*SIM, "--set", "samples=10000000"], 2, r"samples must be an integer from 2 to 10⁶"),
    ("samples=1", [*SIM, "--set", "samples=1"], 2, r"samples"),
    ("samples=-5", [*SIM, "--set", "samples=-5"], 2, r"samples"),
    ("samples=2.5", [*SIM, "--set", "samples=2.5"], 2, r"samples"),
    ("t_final=1e9", [*SIM, "--set", "t_final=1e9"], 2,
     r"the first 2000 steps of DOP853 reached t = .* the whole run needs about .* steps .* far "
     r"beyond max_steps"),
    ("t_final=1e9 compiled", [*SIM, "--set", "t_final=1e9", "--method", "compiled"], 2,
     r"far beyond max_steps"),
    ("t_final=1e300", [*SIM, "--set", "t_final=1e300"], 2, r"t_final.*" + BOUND),
    ("t_final=nan", [*SIM, "--set", "t_final=nan"], 2, r"t_final"),
    ("t_final=-1", [*SIM, "--set", "t_final=-1"], 2, r"t_final"),
    ("t0=-1e300", [*SIM, "--set", "t0=-1e300"], 2, r"t0.*" + BOUND),
    ("q0.x=1e300", [*SIM, "--set", "q0.x=1e300"], 2, r"q0.*" + BOUND),
    ("qdot0.phi=1e300", [*SIM, "--set", "qdot0.phi=1e300"], 2, BOUND),
    ("params.m=1e308", [*SIM, "--set", "params.m=1e308"], 2, r"parameters\.m.*" + BOUND),
    ("params.m=0", [*SIM, "--set", "params.m=0"], 2, r"singular"),
    ("params.m=-1", [*SIM, "--set", "params.m=-1"], 2, r"not positive definite"),
    ("params.m=1e-300", [*SIM, "--set", "params.m=1e-300"], 2, r"singular"),
    ("inputs: a huge constant", [*SIM, "--set", "inputs.tau_theta=1e300*t"], 2, BOUND),
    ("inputs: exp(exp(100))", [*SIM, "--set", "inputs.tau_theta=exp(exp(100))"], 2,
     r"too large|undefined|" + BOUND),
    ("inputs: code", [*SIM, "--set", "inputs.tau_theta=().__class__"], 2, r"tau_theta"),
    ("rtol=0", [*SIM, "--set", "rtol=0"], 2, r"rtol"),
    ("--rtol inf", [*SIM, "--rtol", "inf"], 2, r"rtol must lie in \(0, 1\)"),
    ("--rtol nan", [*SIM, "--rtol", "nan"], 2, r"rtol must lie in \(0, 1\)"),
    ("--atol inf", [*SIM, "--atol", "inf"], 2, r"atol be positive and finite"),
    ("--atol -1", [*SIM, "--atol", "-1"], 2, r"atol"),
    ("rtol=1e-300", [*SIM, "--set", "rtol=1e-300"], 1, r"simulation stopped"),
    ("method=nonsense", [*SIM, "--set", "method=nonsense"], 2, r"unknown method 'nonsense'"),
    ("formulation=nonsense", [*SIM, "--set", "formulation=nonsense"], 2, r"formulation"),
    ("--set outputs=…", [*SIM, "--set", "outputs=garbage"], 2, r"unknown key 'outputs'"),
    # --- sweep and bench
    ("grid 0:1e300:3", [*SWEEP, "--grid", "final.y=0:1e300:3"], 2, BOUND),
    ("grid params.m=1e308", [*SWEEP, "--grid", "params.m=1e308"], 2, BOUND),
    ("grid n = 0", [*SWEEP, "--grid", "final.y=0:1:0"], 2, r"whole number ≥ 2"),
    ("grid of letters", [*SWEEP, "--grid", "final.y=a:b:3"], 2, r"not a number"),
    ("grid without =", [*SWEEP, "--grid", "nonsense"], 2, r"expected NAME=lo:hi:n"),
    ("grid of 10⁷ points", [*SWEEP, "--grid", "final.y=0:1:10000", "--grid", "horizon=1:2:1000"], 2,
     r"more than 1000000"),
    ("--chain 0", [*SWEEP, "--grid", "final.y=0.3,0.4", "--chain", "0"], 2, r"chain must be a whole number"),
    ("--workers -1",
     ["sweep", "unicycle", "--gait", "parallel-park", "--grid", "final.y=0.3,0.4", "--workers", "-1"],
     2, r"--workers must be ≥ 0"),
    ("bench --tols nan", ["bench", "precision", "unicycle", "--tols", "nan"], 2,
     r"tolerances must lie in \(0, 1\)"),
    ("bench --repeats 0", ["bench", "precision", "unicycle", "--repeats", "0"], 2,
     r"--repeats 0: at least 1 timed run"),
    ("reproduce --rtol 2", ["reproduce", "--rtol", "2"], 2, r"rtol must lie in \(0, 1\)"),
    ("reproduce --rtol nan", ["reproduce", "--rtol", "nan"], 2, r"rtol"),
    ("derive --version C", ["derive", "unicycle", "--version", "C"], 2, r"invalid choice"),
]


@pytest.mark.parametrize("argv, statuses, said", [pytest.param(*c[1:], id=c[0]) for c in CASES])
def test_an_extreme_value_is_refused_with_its_name_and_bound(argv, statuses, said, sandbox):
    """Each case answers with its exit status and a message naming the value (and the bound)."""
    out = ["--out", sandbox.out / ("t.csv" if argv[0] == "simulate" else "o")]
    answer([*argv, *out]).check(statuses, said, sandbox)


SCENE_VALUES = [
    ("m = 1e308", "m = 1e308 ", BOUND),
    ("m = '1e308'", 'm = "1e308" ', BOUND),
    ("m = 'exp(800)'", 'm = "exp(800)" ', r"too large|" + BOUND),
    ("m = 1e16", "m = 1e16 ", BOUND),
    ("m = 0", "m = 0.0 ", r"singular"),
    ("m = -1", "m = -1.0 ", r"not positive definite"),
    ("m = nan", "m = nan ", r"not finite"),
    ("m = inf", "m = inf ", r"not finite"),
    ("m = a date", "m = 1979-05-27 ", r"parameter 'm'"),
    ("m = true", "m = true ", r"parameter 'm'"),
]


@pytest.mark.parametrize("value, said", [pytest.param(*c[1:], id=c[0]) for c in SCENE_VALUES])
def test_a_scene_parameter_beyond_a_double_is_refused_before_any_work(value, said, sandbox):
    """The car's mass: m = 1e308 made M(q)'s eigenvalues undefined (an internal error); now one
    message naming the parameter and the bound, for derive and for plan alike."""
    scene = sandbox.root / "car.toml"
    scene.write_text(CAR_TEXT.replace("m = 1.0 ", value))
    answer(["derive", scene]).check(2, said, sandbox)
    answer(["plan", scene, "--out", sandbox.out / "p"]).check(2, said, sandbox)
    assert not (sandbox.out / "p").exists()                    # nothing written for bad input


def test_a_lagrangian_constant_beyond_the_bound_is_refused(sandbox):
    scene = sandbox.root / "car.toml"
    scene.write_text(CAR_TEXT.replace("m*(x_dot**2 + y_dot**2)/2", "1e300*m*(x_dot**2 + y_dot**2)/2"))
    answer(["derive", scene]).check(2, r"lagrangian.*a constant in .* exceeds 1e\+15", sandbox)


def test_the_bound_is_the_one_stated_and_values_within_it_pass():
    """1e15 passes and the next double above it is refused, in every reader."""
    import math

    from nhgait.dynamics.derivation.input.expressions import MAX_MAGNITUDE, number_problems
    problems = []
    assert number_problems(MAX_MAGNITUDE, "x", problems) == MAX_MAGNITUDE
    assert problems == []
    assert number_problems(-MAX_MAGNITUDE, "x", problems) == -MAX_MAGNITUDE
    assert problems == []
    assert math.isnan(number_problems(math.nextafter(MAX_MAGNITUDE, math.inf), "x", problems))
    assert len(problems) == 1
    assert "x: 1e+15 exceeds 1e+15" in problems[0]


def test_a_plan_of_many_intervals_says_its_size_first():
    """N > 1000: the note names the number of NLP variables, (N + 1)·n_x + N·n_u."""
    from types import SimpleNamespace

    from nhgait.gaits.planner import large_request_note
    note = large_request_note(SimpleNamespace(intervals=2000, n_states=6, n_controls=2))
    assert note.startswith("N = 2000 intervals is a large request: 16006 NLP variables and 12000")


def test_a_long_simulation_says_its_estimate_first(sandbox):
    """t_final = 300 s of the unicycle's PD run (about 8000 DOP853 steps): the first 2000 steps
    reach a quarter of it, so the run says it needs about 4× as many; it then runs to the end,
    and its own step count agrees with the estimate to a factor 2."""
    got = answer([*SIM, "--set", "t_final=300", "--out", sandbox.out / "t.csv"]).check(0, None, sandbox)
    import re
    said = re.search(r"reached t = ([\d.e+]+) s of t_final = 300 s: the whole run needs about "
                     r"([\d.e+]+) steps", got.err)
    if said is None:                      # a machine fast enough that the estimate is under 10 s: not said
        return
    assert 0 < float(said.group(1)) < 300
    rows = (sandbox.out / "t.csv").read_text().splitlines()
    assert len(rows) == 202
    assert rows[-1].startswith("300.0")


def test_the_sweep_store_and_grid_accept_the_bound_itself(tmp_path):
    """A grid axis at ±1e15 is read (the bound is inclusive); one beyond is refused."""
    from nhgait.gaits.sweeps.grid import parse_grid
    from nhgait.ocp import ProblemError
    grid = parse_grid(["final.y=-1e15:1e15:3"])
    assert json.loads(json.dumps(grid.to_dict()))["axes"][0]["values"] == [-1e15, 0.0, 1e15]
    with pytest.raises(ProblemError, match=BOUND):
        parse_grid(["final.y=0:1.000001e15:3"])


# ----------------------------------------------------------------------------- reachable targets
@pytest.mark.parametrize("target, statuses, said", [
    ("final.y=1e4", 2,
     r"final y is 10000 from initial y = 0, but starting at rest with \|F\| ≤ 5, \|tau_phi\| ≤ 1 "
                       r"no input moves y more than 270 in T = 6 s"),
    ("final.y=300", 2, r"no input moves y more than 270"),
    ("final.x=-1e5", 2, r"final x is 100000 .* more than 270"),
])
def test_a_target_no_bounded_input_can_reach_is_refused_before_solving(target, statuses, said, sandbox):
    """The car at |F| ≤ 5 N, |τ_φ| ≤ 1 N·m from rest for 6 s: y moves at most
    √((M⁻¹)_yy)·(5·1 + 1·√(1/I_s))·T²/2 = 1·15·18 = 270 m (FATROP spun for minutes on 1e4)."""
    answer(["plan", CAR, "--set", target, "--out", sandbox.out / "p"]).check(statuses, said, sandbox)


def test_the_reach_bound_is_exact_for_a_pushed_mass():
    """A knife edge of mass m pushed along its heading by |F| ≤ F̄ from rest: with θ = 0,
    bang-bang reaches x = F̄T²/(2m), the bound's value for x (the bound is tight here)."""
    from nhgait.dynamics import System
    from nhgait.dynamics.derivation.reach import displacement_bounds
    mass = System(coordinates=["x", "y", "theta"], lagrangian="m*(x_dot**2 + y_dot**2)/2 + I*theta_dot**2/2",
                  constraints=["sin(theta)*x_dot - cos(theta)*y_dot"],
                  forces={"x": "F*cos(theta)", "y": "F*sin(theta)"}, parameters={"m": 2.0, "I": 0.1})
    bound = displacement_bounds(mass, {"F": (-3.0, 3.0)}, 4.0)
    assert bound["x"] == pytest.approx(3.0 * 4.0 ** 2 / (2 * 2.0), rel=1e-12)


@pytest.mark.parametrize("lagrangian, forces, why", [
    ("m*(1 + x**2)*x_dot**2/2 + m*y_dot**2/2", {"x": "F"}, "M depends on x"),
    ("m*(x_dot**2 + y_dot**2)/2 - m*9.81*y", {"x": "F"}, "a potential"),
    ("m*(x_dot**2 + y_dot**2)/2", {"x": "F - 0.1*x_dot"}, "a force in the velocities"),
    ("m*(x_dot**2 + y_dot**2)/2", {"x": "F*x"}, "an input coefficient unbounded in x"),
])
def test_the_reach_bound_claims_nothing_it_cannot_judge(lagrangian, forces, why):
    from nhgait.dynamics import System
    from nhgait.dynamics.derivation.reach import displacement_bounds
    system = System(coordinates=["x", "y"], lagrangian=lagrangian, forces=forces, parameters={"m": 1.0})
    assert displacement_bounds(system, {"F": (-1.0, 1.0)}, 2.0) is None, why
