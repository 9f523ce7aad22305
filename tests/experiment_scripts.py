"""Import a script of ``experiments/`` by name (they are headless ``main(argv)`` scripts, not a
package), so smoke tests can run them at tiny sizes."""
import importlib.util
import sys
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def load(name: str):
    """The module ``experiments/<name>.py`` (registered in ``sys.modules`` under ``name``)."""
    if name in sys.modules and getattr(sys.modules[name], "__file__", None) == str(EXPERIMENTS / f"{name}.py"):
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, EXPERIMENTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
