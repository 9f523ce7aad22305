"""nhgait.gaits — gait tasks, guesses, the planner, plots; :mod:`.sweeps`, :mod:`.cli`, :mod:`.bench`.

Entry points (imported lazily): :func:`plan` (:mod:`.planner`), :func:`sweep` (:mod:`.sweeps.driver`).

Examples
--------
Park the unicycle half a metre to the side (the built-in task P1: from rest at the origin to
rest at y = 0.5 m with the same heading in T = 4 s, |τ| ≤ 5 N·m, least effort); ``jit=False``
runs the NLP functions interpreted (no C compiler needed):

>>> from nhgait.gaits import plan
>>> result = plan("unicycle", "parallel-park", jit=False)
>>> solution = result.solution                   # an nhgait.ocp.solution.Solution
>>> solution.success, solution.state_names[:4], solution.control_names
(True, ('x', 'y', 'theta', 'phi'), ('tau_theta', 'tau_phi'))
>>> float(solution.t[-1]) == solution.horizon == 4.0, solution.z.shape[0] == len(solution.t)   # time first
(True, True)
>>> y = solution.state("y")                      # node values of one state
>>> float(abs(y[0])) < 1e-9, float(abs(y[-1] - 0.5)) < 1e-9
(True, True)
>>> float(abs(solution.u).max()) <= 5.0 + 1e-9
True
>>> solution.verification_error < 1e-6           # re-simulated by an independent integrator
True
"""
from __future__ import annotations

from nhgait.lazy import lazy_getattr

_EXPORTS = {"plan": "planner", "sweep": "sweeps.driver", "load_sweep": "sweeps.driver"}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
