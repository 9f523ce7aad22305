#!/usr/bin/env python3
"""The house metrics of issue 44's closing note, read from the library's source with ``ast``.

For the library (``api/``, ``dynamics/``, ``ocp/``, ``gaits/``; tests and experiments aside):

* **functions with more than 6 parameters** — every ``def`` (methods too), counting its named
  parameters (positional-only, ordinary and keyword-only) without ``self``/``cls`` and without
  ``*args``/``**kwargs``; the count and the largest, with the list (``--list``);
* **bare ``-> tuple`` returns** — return annotations that are exactly ``tuple`` (not
  ``tuple[...]``), as the name or the string;
* **imports inside functions** — ``import``/``from … import`` statements inside a ``def``;
* **modules per folder** — the ``*.py`` files of each library folder, ``__init__.py`` not counted,
  and the largest folder.

Prints one line per metric (then ``--list`` details). Usage:
python experiments/house_metrics.py [--list] [--root DIR]
"""
from __future__ import annotations

import argparse
import ast
import sys
from collections import Counter
from pathlib import Path

FOLDERS = ("api", "dynamics", "ocp", "gaits")
MAX_PARAMETERS = 6


def library_files(root: Path) -> list:
    return sorted(p for folder in FOLDERS for p in (root / folder).rglob("*.py"))


def parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Named parameters of ``node`` without ``self``/``cls`` (module docstring)."""
    args = node.args
    names = [a.arg for a in (*args.posonlyargs, *args.args, *args.kwonlyargs)]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names)


def bare_tuple(node) -> bool:
    r = node.returns
    named = isinstance(r, ast.Name) and r.id == "tuple"
    return named or (isinstance(r, ast.Constant) and r.value == "tuple")


def measure(root: Path) -> dict:
    """The metrics (module docstring) of the library under ``root``."""
    wide, tuples, inner_imports = [], [], []
    for path in library_files(root):
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        where = str(path.relative_to(root))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = parameters(node)
                if n > MAX_PARAMETERS:
                    wide.append((n, f"{where}:{node.lineno} {node.name}"))
                if bare_tuple(node):
                    tuples.append(f"{where}:{node.lineno} {node.name}")
                for inner in ast.walk(node):
                    if inner is not node and isinstance(inner, (ast.Import, ast.ImportFrom)):
                        inner_imports.append(f"{where}:{inner.lineno}")
    folders = Counter(str(p.parent.relative_to(root)) for p in library_files(root) if p.name != "__init__.py")
    inner_imports = sorted(set(inner_imports))     # a nested def's import counted once
    return {"wide": sorted(wide, reverse=True), "tuples": tuples, "inner_imports": inner_imports,
            "folders": folders, "modules": len(library_files(root))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true", help="list every finding")
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1])
    args = parser.parse_args(argv)
    m = measure(args.root)
    largest = m["wide"][0][0] if m["wide"] else 0
    folder, most = m["folders"].most_common(1)[0]
    print(f"library modules: {m['modules']}")
    print(f"functions with more than {MAX_PARAMETERS} parameters: {len(m['wide'])} (max {largest})")
    print(f"bare -> tuple returns: {len(m['tuples'])}")
    print(f"imports inside functions: {len(m['inner_imports'])}")
    print(f"largest folder: {folder} with {most} modules; folders over 20 modules: "
          f"{sum(1 for n in m['folders'].values() if n > 20)}")
    if args.list:
        print("\nmodules per folder:")
        for name, n in sorted(m["folders"].items()):
            print(f"  {name}: {n}")
        print("\nfunctions with more than 6 parameters:")
        for n, where in m["wide"]:
            print(f"  {n} {where}")
        print("\nbare -> tuple returns:")
        for where in m["tuples"]:
            print(f"  {where}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
