"""Import a script of ``experiments/`` by name (they are headless ``main(argv)`` scripts, not a
package), so smoke tests can run them at tiny sizes. The folder goes on ``sys.path`` so that the
scripts find their loader of one another (``experiments/sibling.py``)."""
import sys
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
if str(EXPERIMENTS) not in sys.path:
    sys.path.insert(0, str(EXPERIMENTS))

import sibling  # noqa: E402  (experiments/ is not a package)


def load(name: str):
    """The module ``experiments/<name>.py`` (registered in ``sys.modules`` under ``name``)."""
    return sibling.load(name)
