#!/usr/bin/env python3
"""Which library modules no test module names (issue 44): prints them, one a line, and a count.

A test module (``tests/**/test_*.py``) *names* a library module when it imports it — ``import
nhgait.x.y``, ``from nhgait.x.y import name`` or ``from nhgait.x import y`` (``y`` a module),
at the top or inside a function; a package (``__init__``) is named by any import from it or
from one of its modules (importing ``nhgait.ocp.schedule`` runs ``nhgait/ocp/__init__``). A
public name a package re-exports (``from nhgait.dynamics import jacobi_test``, a lazy name)
also names the module that defines it (its ``__module__``; ``--strict`` leaves these out, and
resolving them imports the library). The library modules are every ``*.py`` under ``api/``,
``dynamics/``, ``ocp/`` and ``gaits/`` (pyproject's package-dir: ``api`` is ``nhgait``).

Usage: python experiments/modules_named_by_tests.py [--all] [--strict]   (``--all``: every
module with the test modules that name it)
"""
from __future__ import annotations

import argparse
import ast
import importlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"api": "nhgait", "dynamics": "nhgait.dynamics", "ocp": "nhgait.ocp", "gaits": "nhgait.gaits"}


def library_modules(root: Path = ROOT) -> dict:
    """Dotted name → path of every library module."""
    found = {}
    for folder, package in FOLDERS.items():
        for path in sorted((root / folder).rglob("*.py")):
            parts = path.relative_to(root / folder).with_suffix("").parts
            found[".".join([package, *parts]).removesuffix(".__init__")] = path
    return found


def imported_names(path: Path) -> set:
    """Every dotted name an ``import`` in ``path`` reaches: the module and, for ``from m import
    a``, also ``m.a`` (a submodule when there is one)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def defining_module(dotted: str) -> str | None:
    """``nhgait.dynamics.jacobi_test`` → the module that defines that object (its
    ``__module__``), or None (not an attribute of a package, or a value without one)."""
    package, _, attribute = dotted.rpartition(".")
    try:
        value = getattr(importlib.import_module(package), attribute)
    except (ImportError, AttributeError, ValueError):
        return None
    return getattr(value, "__module__", None)


def named_by(root: Path = ROOT, *, strict: bool = False) -> dict:
    """Library module → sorted test modules (paths relative to ``root``) that name it."""
    library = library_modules(root)
    named = {name: [] for name in library}
    for test in sorted((root / "tests").rglob("test_*.py")):
        names = imported_names(test)
        found = names & set(library)
        if not strict:
            found |= {defining_module(n) for n in names
                      if n.startswith("nhgait.") and n not in library and n.rpartition(".")[0] in library}
        found = {name for name in found if name in library}
        found |= {name.rsplit(".", k)[0] for name in found for k in range(1, name.count(".") + 1)}
        for name in sorted(found & set(library)):
            named[name].append(str(test.relative_to(root)))
    return named


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--all", action="store_true", help="every module with the tests naming it")
    parser.add_argument("--strict", action="store_true", help="module imports only (no public names)")
    args = parser.parse_args(argv)
    named = named_by(strict=args.strict)
    unnamed = [name for name, tests in named.items() if not tests]
    for name, tests in named.items():
        if args.all:
            print(f"{name}: {', '.join(tests) or '-'}")
        elif not tests:
            print(name)
    print(f"{len(unnamed)} of {len(named)} library modules named by no test module", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
