"""The on-disk cache: a cached result is always the result of *this* input, the trust rules
refuse entries and directories that could have been planted, and a second derive does no
symbolic work. References: a derivation with ``use_cache=False`` (independent of the cache)
and the file system's own metadata."""
import os
import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from nhgait.dynamics import derive, snakeboard, unicycle
from nhgait.dynamics.numerics import cache
from nhgait.dynamics.numerics.cache import UntrustedCacheWarning


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(folder))
    return folder


def _rhs(model, seed=0):
    """ż at a fixed random state with the model's own default parameters."""
    rng = np.random.default_rng(seed)
    num = model.numeric
    z = rng.uniform(-1, 1, len(model.state_names))
    u = rng.uniform(-1, 1, len(model.system.inputs))
    name = "rhs" if model.formulation == "reduced" else "ode"   # the DAEs: (ẋ, λ) by index reduction
    out = num.call(name, 0.3, z, u, num.params())
    return np.hstack([np.ravel(o) for o in (out if isinstance(out, tuple) else (out,))])


def test_second_derive_loads_from_disk(cache_dir, monkeypatch):
    first = derive(unicycle(), "reduced")
    assert first.provenance.cache_hit is False
    assert len(list(cache_dir.glob("*.pkl"))) == 1
    import nhgait.dynamics.derivation.reduction as red

    def boom(*a, **k):
        raise AssertionError("symbolic work on a cache hit")
    monkeypatch.setattr(red, "derive_reduced", boom)
    again = derive(unicycle(), "reduced")
    assert again.provenance.cache_hit is True
    assert again.provenance.key == first.provenance.key
    assert again.provenance.created == first.provenance.created
    assert [str(e) for e in again.rhs] == [str(e) for e in first.rhs]
    # compiled functions came from the cache too
    assert again.compiled is not None
    assert again.numeric is again.compiled
    with pytest.raises(AssertionError, match="symbolic work"):
        derive(unicycle(), "reduced", use_cache=False)


@pytest.mark.parametrize("formulation", ["reduced", "lagrange"])
def test_each_parameter_change_matches_an_uncached_derivation(cache_dir, formulation):
    base = derive(snakeboard(), formulation)
    reference = _rhs(base)
    for name, value in snakeboard().parameters.items():
        changed = snakeboard(**{name: 1.7 * value + 0.1})
        cached = derive(changed, formulation)
        fresh = derive(changed, formulation, use_cache=False)
        assert cached.provenance.cache_hit
        assert cached.numeric.param_defaults == changed.param_values
        np.testing.assert_allclose(_rhs(cached), _rhs(fresh), rtol=1e-13, atol=1e-13)
        assert not np.allclose(_rhs(cached), reference, rtol=1e-6), name


def test_name_and_provenance_come_from_this_call(cache_dir):
    from dataclasses import replace
    first = derive(unicycle(), "lagrange")
    renamed = replace(unicycle(m=2.0), name="my unicycle")
    again = derive(renamed, "lagrange")
    assert again.system.name == "my unicycle"
    assert again.system.parameters["m"] == 2.0
    assert again.provenance.cache_hit
    assert not first.provenance.cache_hit
    assert "sympy=" in again.provenance.versions
    assert "casadi=" in again.provenance.versions


SCENE = """
[system]
coordinates = ["x", "y", "theta", "phi"]
lagrangian = "m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2"
constraints = ["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"]
forces = {theta = "tau_theta", phi = "tau_phi"}
parameters = {m = M_VALUE, r = R_VALUE, J_phi = 0.2, J_theta = 0.3}
[simulation]
q0 = [0, 0, 0, 0]
qdot0 = {theta = 0.5, phi = 1.0}
t_final = 3.0
samples = 4
inputs = {tau_theta = "0.1*cos(t)", tau_phi = "0.2*sin(t)"}
"""


def test_cli_simulate_after_editing_parameters_matches_no_cache(cache_dir, tmp_path):
    from nhgait.gaits.cli.main import main
    scene = tmp_path / "robot.toml"
    outputs = []
    for m, r, flag in (("0.5", "0.1", []), ("1.0", "1.0", []), ("1.0", "1.0", ["--no-cache"])):
        scene.write_text(SCENE.replace("M_VALUE", m).replace("R_VALUE", r))
        out = tmp_path / f"traj{len(outputs)}.csv"
        assert main(["simulate", str(scene), "--out", str(out)] + flag) == 0
        outputs.append(np.loadtxt(out, delimiter=",", skiprows=1))
    np.testing.assert_allclose(outputs[1], outputs[2], rtol=1e-12, atol=1e-14)
    assert not np.allclose(outputs[0][-1], outputs[1][-1], rtol=1e-3)


class _Marker:
    """Unpickling this object would create a file: proof that code ran."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_planted_pickle_is_refused_without_running(cache_dir, tmp_path):
    model = derive(unicycle(), "reduced")
    entry = cache.path_for(model.provenance.key)
    marker = tmp_path / "pwned"
    entry.write_bytes(pickle.dumps(_Marker(str(marker))))
    with pytest.warns(UntrustedCacheWarning, match="ignoring unreadable cache entry"):
        again = derive(unicycle(), "reduced")
    assert not marker.exists()
    assert again.provenance.cache_hit is False                # recomputed
    assert derive(unicycle(), "reduced").provenance.cache_hit  # and rewritten


def test_entry_of_the_wrong_type_is_refused(cache_dir):
    model = derive(unicycle(), "lagrange")
    key = model.provenance.key
    cache.store(key, ["not", "a", "model"])
    with pytest.warns(UntrustedCacheWarning, match="ignoring unreadable cache entry"):
        assert cache.load(key, type(model)) is None
    with pytest.warns(UntrustedCacheWarning):
        again = derive(unicycle(), "lagrange")
    assert again.provenance.cache_hit is False


def test_corrupt_entry_is_reported_and_rebuilt(cache_dir):
    key = derive(unicycle(), "lagrange").provenance.key
    cache.path_for(key).write_bytes(b"not a pickle")
    with pytest.warns(UntrustedCacheWarning, match="ignoring unreadable cache entry"):
        model = derive(unicycle(), "lagrange")
    assert model.formulation == "lagrange"
    assert not model.provenance.cache_hit
    assert derive(unicycle(), "lagrange").provenance.cache_hit


@pytest.mark.skipif(os.name == "nt", reason="POSIX permissions")
def test_directory_is_private_and_world_writable_one_refused(cache_dir):
    derive(unicycle(), "lagrange")
    assert (cache_dir.stat().st_mode & 0o777) == 0o700
    os.chmod(cache_dir, 0o777)
    with pytest.warns(UntrustedCacheWarning, match="writable by group or others"):
        model = derive(unicycle(), "lagrange")
    assert not model.provenance.cache_hit                      # recomputed, not read


@pytest.mark.skipif(os.name == "nt", reason="POSIX permissions")
def test_group_writable_entry_refused(cache_dir):
    key = derive(unicycle(), "lagrange").provenance.key
    os.chmod(cache.path_for(key), 0o666)
    with pytest.warns(UntrustedCacheWarning, match="refusing cache entry"):
        assert not derive(unicycle(), "lagrange").provenance.cache_hit


def test_tampered_file_is_not_trusted(cache_dir):
    folder = cache.trusted_dir()
    lib = folder / "lib.so"
    lib.write_bytes(b"\x7fELF original")
    digest = cache.file_sha256(lib)
    assert cache.trusted_file(lib, digest)
    lib.write_bytes(b"\x7fELF tampered")
    with pytest.warns(UntrustedCacheWarning, match="does not match its recorded SHA-256"):
        assert not cache.trusted_file(lib, digest)


def test_key_covers_structure_formulation_code_and_versions(monkeypatch):
    from nhgait.dynamics import System
    a = unicycle()
    assert cache.cache_key(a, "reduced") == cache.cache_key(unicycle(m=2.0), "reduced")  # values bound later
    assert cache.cache_key(a, "reduced") != cache.cache_key(a, "lagrange")
    c = System(coordinates=a.coordinates, lagrangian=str(a.L) + " + x_dot**2",
               constraints=[str(e) for e in a.constraint_exprs], parameters=a.parameters,
               forces={"theta": "tau_theta", "phi": "tau_phi"})
    assert cache.cache_key(c, "reduced") != cache.cache_key(a, "reduced")
    before = cache.cache_key(a, "reduced")
    cache.code_stamp.cache_clear()
    monkeypatch.setattr(cache, "versions", lambda: "sympy=0.0")
    try:
        assert cache.cache_key(a, "reduced") != before
    finally:
        cache.code_stamp.cache_clear()


def test_concurrent_derivations_leave_one_valid_entry(cache_dir):
    code = textwrap.dedent("""
        from nhgait.dynamics import derive, unicycle
        derive(unicycle(), "lagrange")
    """)
    env = dict(os.environ, NHGAIT_CACHE_DIR=str(cache_dir))
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env) for _ in range(3)]
    assert all(p.wait(timeout=120) == 0 for p in procs)
    assert len(list(cache_dir.glob("*.pkl"))) == 1
    assert not list(cache_dir.glob(".tmp-*"))
    assert derive(unicycle(), "lagrange").provenance.cache_hit


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
