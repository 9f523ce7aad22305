"""Text from a scene file or the API is data, never code: hostile strings in every field are one
ModelError each, with no side effect and no hang (a generous hang guard, ``adversarial.watchdog``: evaluating
``9**9**9**9`` would never return); no module evaluates user text."""
import json
import re
from pathlib import Path

import pytest
from adversarial import watchdog

from nhgait.dynamics import ModelError, System, load_scene

ROOT = Path(__file__).resolve().parent.parent.parent


def hostile(marker: Path) -> list:
    """Strings that would run code, hang or exhaust memory if evaluated."""
    m = str(marker)
    return [
        f"__import__('os').system('touch {m}')",
        f"sin(x).__class__.__init__.__globals__['__builtins__']['open']('{m}', 'w')",
        f"open('{m}', 'w')",
        f"(lambda: open('{m}', 'w'))()",
        "x.__class__",
        "x[0]",
        "f'{x}'",
        "(y := 2)",
        "[open(str(i), 'w') for i in range(3)]",
        "9**9**9**9",
        "((9**99)**99)**99",
        "exp(exp(exp(exp(100))))",
        "(" * 300 + "x" + ")" * 300,
        "x + " * 200_000 + "x",            # about 1 MB
        "1" * 1_000_000,
        "x if x else 1",
        "lambda x: x",
        "__builtins__",
        "sqrt(-1)",
        "1/0",
        "getattr(x, 'y')",
        "x; import os",
    ]


GOOD = {
    "coordinates": ["x", "phi"],
    "lagrangian": "m*x_dot**2/2 + J*phi_dot**2/2",
    "constraints": ["x_dot - r*phi_dot"],
    "forces": {"phi": "tau"},
    "parameters": {"m": 1.0, "J": 0.1, "r": 0.5},
}
SIM = {"q0": [0, 0], "qdot0": [0.5, 1.0], "t_final": 1.0, "samples": 3, "inputs": {"tau": "0"}}


def _scene_with(path_to_field, text):
    """A scene dict with ``text`` placed at ``path_to_field`` (a tuple of keys / list index)."""
    data = {"system": json.loads(json.dumps(GOOD)), "simulation": json.loads(json.dumps(SIM))}
    node = data
    for key in path_to_field[:-1]:
        node = node[key]
    node[path_to_field[-1]] = text
    return data


SCENE_FIELDS = [
    ("system", "lagrangian"), ("system", "constraints", 0), ("system", "forces", "phi"),
    ("system", "parameters", "m"), ("system", "coordinates", 0), ("system", "inputs"),
    ("system", "fiber"), ("simulation", "q0", 1), ("simulation", "qdot0", 0),
    ("simulation", "t_final"), ("simulation", "inputs", "tau"), ("quantities", "v"),
]


def _place(field, text):
    if field == ("system", "inputs"):
        return _scene_with(("system", "inputs"), [text])
    if field == ("system", "fiber"):
        return _scene_with(("system", "fiber"), [text])
    if field[0] == "quantities":
        data = _scene_with(("system", "lagrangian"), GOOD["lagrangian"])
        data["quantities"] = {"v": text}
        return data
    return _scene_with(field, text)


@pytest.mark.parametrize("field", SCENE_FIELDS, ids=lambda f: ".".join(map(str, f)))
def test_hostile_strings_in_every_scene_field(field, tmp_path):
    from nhgait.dynamics.derivation.input.scene import parse_scene
    marker = tmp_path / "marker"
    for text in hostile(marker):
        with watchdog(), pytest.raises(ModelError):
            parse_scene(_place(field, text), "hostile.toml")
        assert not marker.exists(), (field, text[:60])


@pytest.mark.parametrize("field", ["lagrangian", "constraint", "force", "parameter", "coordinate"])
def test_hostile_strings_in_every_system_argument(field, tmp_path):
    marker = tmp_path / "marker"
    for text in hostile(marker):
        args = json.loads(json.dumps(GOOD))
        if field == "lagrangian":
            args["lagrangian"] = text
        elif field == "constraint":
            args["constraints"] = [text]
        elif field == "force":
            args["forces"] = {"phi": text}
        elif field == "parameter":
            args["parameters"]["m"] = text
        else:
            args["coordinates"] = [text, "phi"]
        with watchdog(), pytest.raises(ModelError):
            System(**args)
        assert not marker.exists()


def test_messages_name_the_offending_text():
    with pytest.raises(ModelError, match=r"lagrangian: attribute access is not allowed: 'x.__class__'"):
        System(**{**GOOD, "lagrangian": "x.__class__"})
    with pytest.raises(ModelError, match=r"parameter 'm': exponent 387420489 is too large"):
        System(**{**GOOD, "parameters": {**GOOD["parameters"], "m": "9**9**9**9"}})
    with pytest.raises(ModelError, match=r"'\^' is not a power: write '\*\*'"):
        System(**{**GOOD, "lagrangian": "m*x_dot^2/2 + J*phi_dot**2/2"})


def test_a_parse_error_does_not_hide_other_problems():
    with pytest.raises(ModelError) as info:
        System(**{**GOOD, "lagrangian": "m*x_dot**2/2 + (", "constraints": ["x_dot**2 - r*phi_dot"],
                  "parameters": {**GOOD["parameters"], "J": "heavy"}})
    msg = str(info.value)
    assert "lagrangian: cannot parse" in msg
    assert "constraint 1" in msg
    assert "not linear in the velocities" in msg
    assert "'heavy' is not a number" in msg
    assert "not finite" not in msg
    assert len(info.value.problems) == 3


def test_a_string_where_a_list_belongs_is_one_problem():
    with pytest.raises(ModelError) as info:
        System(**{**GOOD, "coordinates": "x phi"})
    assert len(info.value.problems) == 1
    assert ('coordinates: expected a list of names, got a string (write coordinates = '
            '["x", "phi"])' in str(info.value))
    with pytest.raises(ModelError) as info:      # the hint was ["x,", ...] (a user's trial, 2026-11-29)
        System(**{**GOOD, "coordinates": "x, phi"})
    assert '(write coordinates = ["x", "phi"])' in str(info.value)
    with pytest.raises(ModelError) as info:
        System(**{**GOOD, "constraints": "x_dot - r*phi_dot"})
    assert len(info.value.problems) == 1
    assert "constraints: expected a list of expressions" in str(info.value)


def test_scene_reports_system_and_simulation_problems_together(tmp_path):
    from nhgait.dynamics.derivation.input.scene import parse_scene
    data = _scene_with(("system", "lagrangian"), "m*x_dot**2/2 + J*phi_dot**2/2 + k*x")
    data["simulation"]["t_final"] = -1
    data["simulation"]["samples"] = "many"
    with pytest.raises(ModelError) as info:
        parse_scene(data, "s.toml")
    msg = str(info.value)
    assert "unknown symbol 'k' in the Lagrangian" in msg
    assert "t_final = -1.0 must be greater" in msg
    assert "samples must be an integer" in msg


def test_discontinuous_functions_only_in_forces():
    with pytest.raises(ModelError, match="the Lagrangian uses a discontinuous function"):
        System(**{**GOOD, "lagrangian": "m*x_dot**2/2 + J*phi_dot**2/2 + Heaviside(x)"})
    s = System(**{**GOOD, "forces": {"phi": "tau*Heaviside(t - 1)"}})
    assert s.inputs == ("tau",)


def test_no_module_evaluates_user_text():
    """eval/exec/sympify/parse_expr appear nowhere in the package (lambdify prints our own,
    already validated expressions to code; it never sees user text). A method *defined* as
    ``eval`` (CasADi's Callback interface) is not a call."""
    banned = re.compile(r"\b(eval|exec|sympify|parse_expr|S)\s*\(|sympy_parser|__import__")
    offenders = []
    for folder in ("api", "dynamics", "ocp", "gaits"):
        for path in (ROOT / folder).rglob("*.py"):
            for number, line in enumerate(path.read_text().splitlines(), 1):
                code = line.split("#")[0]
                code = code.replace("._eval(", "").replace("def eval(self", "")
                if banned.search(code):
                    offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


def test_scene_file_never_runs_code_end_to_end(tmp_path):
    marker = tmp_path / "marker"
    scene = tmp_path / "evil.toml"
    scene.write_text(f'''
[system]
coordinates = ["x", "phi"]
lagrangian = "m*x_dot**2/2 + J*phi_dot**2/2"
constraints = ["x_dot - r*phi_dot"]
[system.parameters]
m = "__import__('os').system('touch {marker}')"
J = 0.1
r = 0.5
''')
    with pytest.raises(ModelError, match="parameter 'm'"):
        load_scene(scene)
    assert not marker.exists()


def test_long_legitimate_expressions_parse():
    """A Lagrangian of thousands of terms is not 'nested': sums and products are chains."""
    import sympy as sp

    from nhgait.dynamics.derivation.input.expressions import expression_problems
    names = {f"x{i}": sp.Symbol(f"x{i}", real=True) for i in range(50)}
    text = " + ".join(f"x{i % 50}*x{(3 * i) % 50}/7" for i in range(2500))
    problems = []
    expr = expression_problems(text, names, "lagrangian", problems)
    assert not problems
    expected = sum(sp.Rational(1, 7) * names[f"x{i % 50}"] * names[f"x{(3 * i) % 50}"] for i in range(2500))
    assert sp.expand(expr - expected) == 0
    assert expression_problems("x1 - (x2 - x3) - -x4 + 2**-x1", names, "L", []) == (
        names["x1"] - names["x2"] + names["x3"] + names["x4"] + 2 ** -names["x1"])
