"""Shared fixtures: a temporary model cache for the whole session and session-scoped derived
models, so each expensive derivation runs once per test run."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))  # the Kane oracle (tests/oracles.py)


@pytest.fixture(scope="session", autouse=True)
def _no_background_builds():
    """No optimised build left running after a test (nhgait.dynamics.numerics.background):
    the tests of the background build turn it on for themselves and wait for or cancel it."""
    old = {name: os.environ.get(name) for name in ("NHGAIT_BACKGROUND_BUILDS", "NHGAIT_WARM_OPTIMA")}
    os.environ["NHGAIT_BACKGROUND_BUILDS"] = "0"
    os.environ["NHGAIT_WARM_OPTIMA"] = "0"     # no plan starts from another test's verified optimum
    yield
    for name, value in old.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value


@pytest.fixture(scope="session", autouse=True)
def _temporary_cache(tmp_path_factory):
    """An empty model cache for the run. Under pytest-xdist the workers of one run share it (in
    the run's temporary folder, beside the workers' own): a model or compiled library one
    worker made is a cache hit for the other. The cache is made for this — entries are written
    to a temporary file and renamed into place, so concurrent writers of one entry leave one
    valid entry (nhgait.dynamics.numerics.cache; tests/dynamics/test_cache.py)."""
    old = os.environ.get("NHGAIT_CACHE_DIR")
    if os.environ.get("PYTEST_XDIST_WORKER"):
        folder = tmp_path_factory.getbasetemp().parent / "nhgait-cache"
        folder.mkdir(mode=0o700, exist_ok=True)
    else:
        folder = tmp_path_factory.mktemp("nhgait-cache")
    os.environ["NHGAIT_CACHE_DIR"] = str(folder)
    yield
    if old is None:
        os.environ.pop("NHGAIT_CACHE_DIR", None)
    else:
        os.environ["NHGAIT_CACHE_DIR"] = old


SYSTEMS = ("unicycle", "snakeboard", "chaplygin_sleigh", "knife_edge_incline")


@pytest.fixture(scope="session")
def systems(_temporary_cache):
    from nhgait.dynamics import builtin
    return {name: builtin(name) for name in SYSTEMS}


@pytest.fixture(scope="session")
def models(systems):
    """models[name][formulation] for the built-in systems (derived once, cached)."""
    from nhgait.dynamics import derive

    class _Lazy(dict):
        def __missing__(self, key):
            name, formulation = key
            value = derive(systems[name], formulation)
            self[key] = value
            return value

    lazy = _Lazy()

    class _View:
        def __getitem__(self, name):
            class _F:
                def __getitem__(_, formulation):
                    return lazy[name, formulation]
            return _F()
    return _View()


@pytest.fixture(scope="session")
def _worker_cache(tmp_path_factory, _temporary_cache):
    """A model cache of this process alone, for the sandboxes: the run's cache is shared by the
    xdist workers, and a temporary file the other worker is writing there at the moment a
    sandbox looks would count as a leftover of the case."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return Path(os.environ["NHGAIT_CACHE_DIR"])
    return tmp_path_factory.mktemp("nhgait-worker-cache")


@pytest.fixture
def sandbox(tmp_path, monkeypatch, _worker_cache):
    """A private TMPDIR and output folder and this worker's cache (shared by the sandboxes of the
    session), checked for leftovers by the hostile-input tests (tests/adversarial.py)."""
    from adversarial import make_sandbox
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(_worker_cache))
    return make_sandbox(tmp_path, monkeypatch)


@pytest.fixture(scope="session")
def particle(_temporary_cache):
    """A free particle in the plane (x, y), m = 2 kg, driven by forces Fx, Fy: its reduced model
    specialised for planning (``particle.system`` the System). The tests that use it state the
    mass they expect (MASS = 2.0) as their reference."""
    from nhgait.dynamics import System, derive
    from nhgait.dynamics.numerics.specialisation import specialise
    system = System(["x", "y"], "m*(x_dot**2 + y_dot**2)/2", [], forces={"x": "Fx", "y": "Fy"},
                    parameters={"m": 2.0}, inputs=["Fx", "Fy"])
    return specialise(derive(system, "reduced"))


@pytest.fixture(autouse=True)
def _fresh_plan_memo():
    """Each test plans as a new process would: the planner's default memo of built solvers and
    last optima (:mod:`nhgait.gaits.planning.plan_memo`) emptied after it, so that no test's
    plan starts from another test's optimum (tests/gaits/test_plan_memo.py tests the memo)."""
    yield
    memo = sys.modules.get("nhgait.gaits.planning.plan_memo")
    if memo is not None:
        memo.PLAN_MEMO.clear()


def pytest_collection_modifyitems(config, items):
    """Under pytest-xdist, the costliest test files first (tests/file_costs.py): each file is one
    unit of work of ``--dist loadfile`` and a worker takes the next when it is almost done, so
    handing out the long files first lets the workers end together (the Makefile turns xdist's
    own order, most tests first, off). The order within a file is kept; without xdist nothing
    changes."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    import file_costs
    items.sort(key=lambda item: -file_costs.cost(item.nodeid.split("::", 1)[0]))
