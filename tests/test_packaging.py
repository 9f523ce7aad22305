"""pyproject.toml lists every package of the library and ships its data: a package folder left out
of ``[tool.setuptools] packages`` works in an editable install and is missing from a wheel."""
from __future__ import annotations

import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:                                   # pragma: no cover - Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"api": "nhgait", "dynamics": "nhgait.dynamics", "ocp": "nhgait.ocp", "gaits": "nhgait.gaits"}


def _setuptools() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _packages_on_disk() -> set:
    found = set()
    for folder, package in FOLDERS.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            parts = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join((package, *parts)))
    return found


def test_every_package_folder_is_listed_in_pyproject():
    listed = set(_setuptools()["packages"])
    missing = sorted(_packages_on_disk() - listed)
    assert not missing, f"add to [tool.setuptools] packages: {missing}"


def test_every_listed_package_exists():
    listed = set(_setuptools()["packages"])
    data_only = {p for p in listed if p in _setuptools().get("package-data", {})}
    assert sorted(listed - _packages_on_disk() - data_only) == []
