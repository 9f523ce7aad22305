"""The package's shape: every module imports, imports only downward, neither the module import
graph nor the graph of sub-packages has a cycle, no module imports another's private names, no
library module is longer than :data:`MAX_LINES` non-blank lines, and the ocp and gaits layers
load no sympy. The graph is read from the source with ``ast`` (imports inside functions count too: a
lazy import is still a dependency), so these tests fail on the first edge that breaks a rule,
naming it."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: source folder → package name (pyproject's package-dir)
FOLDERS = {"api": "nhgait", "dynamics": "nhgait.dynamics", "ocp": "nhgait.ocp", "gaits": "nhgait.gaits"}

#: layers, lowest first: a module may import its own layer's modules (the module graph stays
#: acyclic) and any lower layer, never a higher one. The numerics sit below the derivation
#: (derived models compile themselves; the compiler needs only the algebra below both).
LAYERS = (
    ("nhgait",),
    ("nhgait.dynamics",),                                   # errors, progress, memo
    ("nhgait.dynamics.algebra",),                           # sympy algebra, no physics
    ("nhgait.dynamics.numerics",),
    ("nhgait.dynamics.derivation",),
    ("nhgait.dynamics.simulation", "nhgait.dynamics.linearisation", "nhgait.dynamics.geometry"),
    ("nhgait.ocp",),
    ("nhgait.gaits.tasks",),                                # the task and its statement
    ("nhgait.gaits.figures", "nhgait.gaits.files"),        # figures; what a plan writes
    ("nhgait.gaits.planning",),                             # guesses, the search
    ("nhgait.gaits.verification",),                         # checks, refinement, diagnosis
    ("nhgait.gaits",),                                      # the planner
    ("nhgait.gaits.sweeps", "nhgait.gaits.bench", "nhgait.gaits.tracking"),
    ("nhgait.gaits.cli",),
)


#: a guard, not a cut that makes files (issue 44): a module's size follows its idea (sympy's kane.py
#: is 896 lines); past this many non-blank lines it almost surely holds two
MAX_LINES = 800


def modules(folders: dict = FOLDERS, root: Path = ROOT) -> dict:
    """Module name → source path of every module under ``folders``."""
    found = {}
    for folder, package in folders.items():
        for path in (root / folder).rglob("*.py"):
            parts = path.relative_to(root / folder).with_suffix("").parts
            name = ".".join([package, *parts])
            found[name.removesuffix(".__init__")] = path
    return found


def import_edges(found: dict) -> tuple[dict, list]:
    """(module → set of modules it imports, [(module, imported module, private name)]).

    ``from package import submodule`` is an edge to the submodule; any other name imported
    from a module is an edge to that module."""
    edges, private = {}, []
    for name, path in found.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    source = ".".join(base + ([node.module] if node.module else []))
                else:
                    source = node.module or ""
                for alias in node.names:
                    if f"{source}.{alias.name}" in found:
                        targets.add(f"{source}.{alias.name}")
                    elif source in found:
                        targets.add(source)
                        if alias.name.startswith("_") and not alias.name.startswith("__"):
                            private.append((name, source, alias.name))
            elif isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names if alias.name in found)
        targets.discard(name)
        edges[name] = targets
    return edges, private


def cycles(edges: dict) -> list:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def layer_of(module: str) -> tuple[int, str]:
    """(layer index, package) of ``module``: the longest package of :data:`LAYERS` it is in."""
    best = None
    for rank, packages in enumerate(LAYERS):
        for package in packages:
            if module == package or module.startswith(package + "."):
                if best is None or len(package) > len(best[1]):
                    best = (rank, package)
    return best


def package_of(module: str, found: dict) -> str:
    """The sub-package a module belongs to, at most three names deep (``nhgait.dynamics.derivation``
    holds ``derivation.reduction.*`` and ``derivation.urdf.*``; ``nhgait.gaits`` its own modules)."""
    package = module if found[module].name == "__init__.py" else module.rpartition(".")[0]
    return ".".join(package.split(".")[:3])


def package_edges(edges: dict, found: dict) -> dict:
    """Package → the other packages its modules import (the graph one level up)."""
    out = {}
    for a, targets in edges.items():
        pa = package_of(a, found)
        out.setdefault(pa, set()).update(pb for b in targets if (pb := package_of(b, found)) != pa)
    return out


def long_modules(found: dict, limit: int = MAX_LINES) -> list:
    """(module, non-blank lines) of every module longer than ``limit``."""
    sizes = ((name, sum(1 for line in path.read_text().splitlines() if line.strip()))
             for name, path in found.items())
    return sorted((name, n) for name, n in sizes if n > limit)


def upward_edges(edges: dict) -> list:
    return sorted((a, b) for a, targets in edges.items() for b in targets if layer_of(b)[0] > layer_of(a)[0])


@pytest.fixture(scope="module")
def graph():
    return import_edges(modules())


def test_the_module_graph_has_no_cycle(graph):
    edges, _ = graph
    assert len(edges) > 70                      # every module was read
    assert cycles(edges) == []


def test_the_sub_package_graph_has_no_cycle(graph):
    """No two sub-packages import each other, even through modules that do not form a module
    cycle (the derivation and the numerics once did: both now rest on the algebra below)."""
    edges, _ = graph
    packages = package_edges(edges, modules())
    assert "nhgait.dynamics.algebra" in packages                 # the graph was read
    assert cycles(packages) == []


def test_no_library_module_is_longer_than_the_limit():
    assert long_modules(modules()) == []


def test_layers_import_downward(graph):
    edges, _ = graph
    assert upward_edges(edges) == []


def test_no_module_imports_another_modules_private_names(graph):
    _, private = graph
    assert private == []


def test_the_checks_find_a_cycle_an_upward_import_and_a_private_name(tmp_path):
    """The checkers on a small package with one of each defect: each is found and named."""
    pkg = tmp_path / "gaits"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import helper\n")
    (pkg / "b.py").write_text("def helper():\n    from .a import _x\n")
    (pkg / "c.py").write_text("def f():\n    from nhgait.gaits.cli import main\n")
    found = modules({"gaits": "nhgait.gaits"}, tmp_path)
    found["nhgait.gaits.cli"] = pkg / "__init__.py"          # a module of the top layer
    edges, private = import_edges(found)
    assert cycles(edges) == [["nhgait.gaits.a", "nhgait.gaits.b"]]
    assert private == [("nhgait.gaits.b", "nhgait.gaits.a", "_x")]
    assert upward_edges(edges) == [("nhgait.gaits.c", "nhgait.gaits.cli")]


def test_the_checks_find_a_package_cycle_and_a_long_module(tmp_path):
    """Two sub-packages whose modules import each other without a module cycle (p.a → q.b,
    q.c → p.d), and a module one line over the limit: both are found and named."""
    root = tmp_path / "gaits"
    for folder in ("p", "q"):
        (root / folder).mkdir(parents=True)
        (root / folder / "__init__.py").write_text("")
    (root / "__init__.py").write_text("")
    (root / "p" / "a.py").write_text("from ..q import b\n")
    (root / "q" / "b.py").write_text("")
    (root / "q" / "c.py").write_text("from ..p.d import f\n")
    (root / "p" / "d.py").write_text("def f():\n    pass\n\n" + "x = 1\n" * (MAX_LINES - 1))
    found = modules({"gaits": "nhgait.gaits"}, tmp_path)
    edges, _ = import_edges(found)
    assert cycles(edges) == []
    assert cycles(package_edges(edges, found)) == [["nhgait.gaits.p", "nhgait.gaits.q"]]
    assert long_modules(found) == [("nhgait.gaits.p.d", MAX_LINES + 1)]


_IMPORT_ALL = """
import importlib, sys
names = sys.argv[1:]
first_sympy = None
for name in names:
    importlib.import_module(name)
    if first_sympy is None and "sympy" in sys.modules:
        first_sympy = name
print(first_sympy)
"""


def test_ocp_and_gaits_modules_import_without_sympy():
    """Every module of ocp and gaits, imported in one fresh process: none loads sympy."""
    names = sorted(m for m in modules() if m.startswith(("nhgait.ocp", "nhgait.gaits")))
    out = subprocess.run([sys.executable, "-c", _IMPORT_ALL, *names], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "None", f"{out.stdout.strip()} loads sympy at import"


def test_every_module_and_public_name_imports():
    """Every module imports, and every lazily exported public name resolves."""
    code = _IMPORT_ALL + """
for package in ("nhgait.dynamics", "nhgait.ocp", "nhgait.gaits"):
    module = importlib.import_module(package)
    for name in module.__all__:
        getattr(module, name)
print("exports ok")
"""
    out = subprocess.run([sys.executable, "-c", code, *sorted(modules())], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-2:] == ["exports", "ok"]


def test_derivation_results_are_frozen():
    """Every dataclass of the derivation (systems, the steps' results, the models) is frozen:
    no step fills in an object another step made."""
    code = """
import dataclasses, importlib, inspect, pkgutil
import nhgait.dynamics.derivation as package
found, mutable = 0, []
for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
    module = importlib.import_module(info.name)
    for name, cls in vars(module).items():
        if inspect.isclass(cls) and dataclasses.is_dataclass(cls) and cls.__module__ == module.__name__:
            found += 1
            if not cls.__dataclass_params__.frozen:
                mutable.append(f"{module.__name__}.{name}")
print(found, mutable)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    found, _, mutable = out.stdout.strip().partition(" ")
    assert int(found) >= 15, out.stdout
    assert mutable == "[]", out.stdout
