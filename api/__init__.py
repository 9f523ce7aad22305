"""nhgait — dynamics and gait planning for nonholonomic robots.

From the coordinates q, a Lagrangian L(q, q̇), Pfaffian constraints ω(q)q̇ = 0, generalized
forces τ and parameters, nhgait derives the equations of motion three ways (Euler–Lagrange and
Hamilton with multipliers, and the reduced constrained Hamiltonian of the 20-step method),
simulates them, and plans gaits with CasADi + Ipopt, each optimum verified by an independent
simulation.

Subpackages (each imports only the ones before it):

* :mod:`nhgait.dynamics` — systems, scenes, derivations, simulation (``System``, ``load_scene``,
  ``derive``, ``simulate``);
* :mod:`nhgait.ocp` — optimal-control problems, transcriptions and solvers (no sympy);
* :mod:`nhgait.gaits` — gait tasks, guesses, the planner, plots and the ``nhgait`` command line.

Importing nhgait does no symbolic work.
"""
__version__ = "0.2.0.dev0"
