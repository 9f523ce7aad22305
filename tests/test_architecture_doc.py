"""docs/architecture.md names every library module (issue 44).

The page's "Packages" table has one row per package (``| `nhgait.ocp` | `ocp/` | owns … |``;
the "Layout" table's row of the same package counts too) that names the package's modules by
their short names in backticks (`` `schedule` ``); a module of a sub-package without its own
row (``reduction/``, ``bodies/``, ``urdf/``) is named in the row of the nearest package above it
that has one, and such a sub-package itself as `` `reduction/` `` (or `` `reduction` ``). A
module is also named by its dotted name (``nhgait.ocp.schedule``) or its path
(``ocp/schedule.py``) anywhere on the page. The modules are read from the folders (as
tests/test_architecture.py reads them), so a new module fails here until the page names it."""
from __future__ import annotations

import re

from test_architecture import FOLDERS, ROOT, modules

DOC = ROOT / "docs" / "architecture.md"
#: a row of the "Packages" table (package, folder, owns) or of the "Layout" table (folder, package, holds)
ROW = re.compile(r"^\| (?:`(?P<package>nhgait[\w.]*)` \| `[^`]*`|`[^`]*` \| `(?P<package2>nhgait[\w.]*)`) "
                 r"\| (?P<owns>.*) \|$")


def package_rows(text: str) -> dict:
    """Package → the text of its rows in the page's tables (the "Packages" and "Layout" tables)."""
    rows = {}
    for m in filter(None, map(ROW.match, text.splitlines())):
        package = m["package"] or m["package2"]
        rows[package] = rows.get(package, "") + " " + m["owns"]
    return rows


def _path(name: str) -> str:
    """``nhgait.ocp.schedule`` → ``ocp/schedule.py`` (the folder of pyproject's package-dir)."""
    for folder, package in sorted(FOLDERS.items(), key=lambda item: -len(item[1])):
        if name == package or name.startswith(package + "."):
            rest = name[len(package):].lstrip(".").replace(".", "/")
            return f"{folder}/{rest}.py" if rest else f"{folder}/__init__.py"
    return name


def unnamed(found: dict, text: str) -> list:
    """The modules of ``found`` (name → path) that ``text`` does not name (module docstring)."""
    rows = package_rows(text)
    missing = []
    for name, path in sorted(found.items()):
        if name in rows or f"`{name}`" in text or _path(name) in text:
            continue
        owner = max((p for p in rows if name.startswith(p + ".")), key=len, default=None)
        short = name.rsplit(".", 1)[1]
        words = (f"`{short}`", f"`{short}/`") if path.name == "__init__.py" else (f"`{short}`",)
        if owner is None or not any(w in rows[owner] for w in words):
            missing.append(name)
    return missing


def test_every_library_module_is_named_in_the_architecture_page():
    missing = unnamed(modules(), DOC.read_text(encoding="utf-8"))
    assert not missing, ("docs/architecture.md does not name these modules (add each to its package's "
                         "row in the Packages table, by its short name in backticks): " + ", ".join(missing))


def test_the_check_finds_an_unnamed_module_and_accepts_the_three_spellings(tmp_path):
    """The checker itself, on a page written here: a module missing from its row is reported;
    the short name in its package's row, the dotted name and the path are each accepted."""
    page = ("| package | folder | owns |\n|---|---|---|\n"
            "| `nhgait.ocp` | `ocp/` | the statement (`statement`), `reduction/` |\n\n## Next\n"
            "`nhgait.ocp.solver` and ocp/backends.py\n")
    found = {name: tmp_path / f"{name.rsplit('.', 1)[1]}.py" for name in
             ("nhgait.ocp.statement", "nhgait.ocp.solver", "nhgait.ocp.backends", "nhgait.ocp.schedule",
              "nhgait.ocp.reduction.pipeline")}
    found["nhgait.ocp"] = tmp_path / "__init__.py"
    found["nhgait.ocp.reduction"] = tmp_path / "reduction" / "__init__.py"
    assert unnamed(found, page) == ["nhgait.ocp.reduction.pipeline", "nhgait.ocp.schedule"]
