"""docs/interop.md's Python blocks run as written (issue 43: a sympy.mechanics or rockit user
brings a model in and takes a gait out without reading the source); each block asserts what it
shows against the robot's physics or sympy's own objects."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "interop.md"
BLOCKS = re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)


def test_the_page_has_its_examples():
    assert len(BLOCKS) == 4


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_block_runs(index):
    exec(compile(BLOCKS[index], f"{DOC.name} block {index + 1}", "exec"), {})
