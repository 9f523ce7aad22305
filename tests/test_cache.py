"""The on-disk cache: a second derive does no symbolic work; --no-cache bypasses it."""
import os
import pickle
import subprocess
import sys
import warnings

import pytest

from nhgait.dynamics import cache, derive, unicycle


def test_second_derive_loads_from_disk(tmp_path, monkeypatch):
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path))
    first = derive(unicycle(), "reduced")
    assert len(list(tmp_path.glob("*.pkl"))) == 1
    import nhgait.dynamics.reduction as red

    def boom(*a, **k):
        raise AssertionError("symbolic work on a cache hit")
    monkeypatch.setattr(red, "derive_reduced", boom)
    again = derive(unicycle(), "reduced")
    assert again is not first and [str(e) for e in again.rhs] == [str(e) for e in first.rhs]
    assert "numeric" in again.__dict__          # compiled functions came from the cache too
    with pytest.raises(AssertionError, match="symbolic work"):
        derive(unicycle(), "reduced", use_cache=False)


def test_key_depends_on_content_not_parameter_values():
    a, b = unicycle(), unicycle(m=2.0)
    assert cache.cache_key(a, "reduced") == cache.cache_key(b, "reduced")
    assert cache.cache_key(a, "reduced") != cache.cache_key(a, "lagrange")
    from nhgait.dynamics import System
    c = System(coordinates=a.coordinates, lagrangian=str(a.L) + " + x_dot**2",
               constraints=[str(e) for e in a.constraint_exprs], parameters=a.parameters,
               forces={"theta": "tau_theta", "phi": "tau_phi"})
    assert cache.cache_key(c, "reduced") != cache.cache_key(a, "reduced")


def test_corrupt_entry_is_reported_and_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path))
    key = cache.cache_key(unicycle(), "lagrange", "version=None")
    cache.path_for(key).parent.mkdir(parents=True, exist_ok=True)
    cache.path_for(key).write_bytes(b"not a pickle")
    with pytest.warns(UserWarning, match="ignoring unreadable cache entry"):
        model = derive(unicycle(), "lagrange")
    assert model.formulation == "lagrange"
    with open(cache.path_for(key), "rb") as fh:
        assert pickle.load(fh).formulation == "lagrange"


def test_cache_dir_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "x"))
    assert cache.cache_dir() == tmp_path / "x"
    monkeypatch.delenv("NHGAIT_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        assert cache.cache_dir() == tmp_path / "xdg" / "nhgait"


def test_import_does_no_symbolic_work():
    code = "import sys, nhgait.dynamics, nhgait.ocp, nhgait.gaits; print('sympy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
