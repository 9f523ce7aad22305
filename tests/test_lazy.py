"""Lazy public names (api/lazy.py, PEP 562): a name is imported from its submodule on first use
and bound in the package; an unknown name is an AttributeError naming the package."""
from __future__ import annotations

import sys
import types

import pytest

from nhgait.lazy import lazy_getattr


def test_a_name_is_imported_on_first_use_and_bound(monkeypatch):
    package = types.ModuleType("fakepkg")
    package.__path__ = []
    monkeypatch.setitem(sys.modules, "fakepkg", package)
    sub = types.ModuleType("fakepkg.sub")
    sub.answer = 42
    monkeypatch.setitem(sys.modules, "fakepkg.sub", sub)
    package.__getattr__ = lazy_getattr("fakepkg", {"answer": "sub"})
    assert "answer" not in vars(package)
    assert package.answer == 42 and vars(package)["answer"] == 42      # bound after the first use
    with pytest.raises(AttributeError, match="module 'fakepkg' has no attribute 'question'"):
        getattr(package, "question")  # noqa: B009 - the module __getattr__ under test
