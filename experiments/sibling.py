"""The other scripts of ``experiments/`` and the test oracles (``tests/oracles.py``), loaded by
file path: neither folder is a package. A module already loaded from the same file is reused
(so the oracles' caches are shared with the tests). The scripts import this module from their
own folder; ``tests/experiment_scripts.py`` puts that folder on ``sys.path`` first."""
import importlib.util
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def load(name: str, folder: Path = HERE):
    """The module ``<folder>/<name>.py``, registered in ``sys.modules`` under ``name``."""
    path = folder / f"{name}.py"
    module = sys.modules.get(name)
    if module is not None and getattr(module, "__file__", None) == str(path):
        return module
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def oracles():
    """``tests/oracles.py``: the KanesMethod models and oracles."""
    return load("oracles", ROOT / "tests")
