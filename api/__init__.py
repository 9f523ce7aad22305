"""nhgait — dynamics and gait planning for nonholonomic robots.

From the coordinates q, a Lagrangian L(q, q̇), Pfaffian constraints ω(q)q̇ = 0, generalized
forces τ and parameters, nhgait derives the equations of motion three ways (Euler–Lagrange and
Hamilton with multipliers, and the reduced constrained Hamiltonian of the 20-step method),
simulates them, and plans gaits with CasADi — by default FATROP on a stage-ordered
multiple-shooting transcription for small ODEs and Ipopt for larger ones, the other when the
first finds no solution (``solver="ipopt"`` or ``"fatrop"`` for one of them) — each optimum
verified by an independent simulation.

Sub-packages (each imports only the ones before it; ``import nhgait`` loads none of them):

* :mod:`nhgait.dynamics` — systems, scene files, the three derivations, simulation
  (``System``, ``load_scene``, ``derive``, ``simulate``, ``Trajectory``);
* :mod:`nhgait.ocp` — optimal-control problems, transcriptions, solvers, solutions (no sympy);
* :mod:`nhgait.gaits` — gait tasks, guesses, the planner (``nhgait.gaits.planner.plan``),
  sweeps (``nhgait.gaits.sweep``), plots and the ``nhgait`` command line.

The five things a user does first::

    from nhgait.dynamics import System, load_scene, derive, simulate
    from nhgait.gaits.planner import plan

    scene = load_scene("examples/car.toml")             # 1. state a robot (or System(...))
    model = derive(scene.system)                        # 2. derive: print(model.to_text())
    traj = simulate(model, (0, 5), [0, 0, 0, 0], [1, 0, 0, 0])   # 3. simulate: traj.q, traj.t
    result = plan("examples/car.toml", out_dir="out/car")        # 4. plan a gait (verified)
    print(result.solution)                              # 5. look: repr, files in out/car

The same from the shell: ``nhgait derive``, ``nhgait simulate SCENE --set t_final=20 --plot
DIR``, ``nhgait plan SCENE --out DIR``, ``nhgait sweep``, ``nhgait bench precision``
(``nhgait --help``). Result objects print short summaries (shape, time span, success, where
the arrays are); models and solutions render as Markdown in notebooks.

Importing nhgait does no symbolic work.
"""
__version__ = "0.2.0.dev0"

#: the sub-packages, in import order (see the docstring)
SUBPACKAGES = ("dynamics", "ocp", "gaits")


def __getattr__(name):
    """``nhgait.dynamics`` and friends after a bare ``import nhgait`` (imported on first use)."""
    if name in SUBPACKAGES:
        import importlib
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'nhgait' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(SUBPACKAGES))
