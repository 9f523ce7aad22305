"""TOML text as data (dynamics/derivation/input/tomldata.py): a document as a dict; a syntax error and
a document nested too deeply are each one error naming the file, never a traceback from the
parser."""
from __future__ import annotations

import pytest

from nhgait.dynamics.derivation.input.tomldata import read_toml
from nhgait.dynamics.errors import ModelError


def test_a_document_is_a_dict():
    assert read_toml('[system]\ncoordinates = ["x", "y"]\nm = 2.5\n', "scene.toml") == {
        "system": {"coordinates": ["x", "y"], "m": 2.5}}


def test_syntax_errors_name_the_file():
    with pytest.raises(ModelError, match=r"(?s)invalid file scene\.toml.*TOML syntax error") as caught:
        read_toml("[system\nm = ", "scene.toml")
    assert caught.value.__cause__ is None
    with pytest.raises(ModelError, match="nested too deeply"):
        read_toml("a = " + "[" * 100_000 + "]" * 100_000, "deep.toml")
    with pytest.raises(ValueError, match="invalid file t.toml"):
        read_toml("= 1", "t.toml", error=lambda problems, title: ValueError(f"{title}: {problems}"))
