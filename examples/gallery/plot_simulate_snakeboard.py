"""
Simulate the snakeboard
=======================

The thesis's PD run of the snakeboard (Example 3.2, eqs. 3.95–3.96, initial state of Table 3.3):
derive the reduced equations, integrate them over 10π s and look at the path, the constraint
residual and the energy balance — the run's own checks.
"""
import matplotlib.pyplot as plt
import numpy as np

from nhgait.dynamics import derive, load_scene, simulate
from nhgait.gaits.figures.plots import figure_context, plot_path
from nhgait.gaits.figures.trajectory import TrajectoryView, plot_checks
from nhgait.gaits.tasks.sources import figure_tables

scene = load_scene("snakeboard")                 # the built-in scene: system, units, [simulation]
model = derive(scene.system)                     # the reduced ODE, cached on disk
print(model)

spec = scene.simulation
traj = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, controller=spec.controller,
                t_eval=np.linspace(spec.t0, spec.t_final, 301), rtol=1e-10, atol=1e-12)
print(traj)
print(f"x(10π) = {traj.q[-1, 0]:.8f} m")

# %%
# The path, with the board drawn at five instants coloured by time (the built-in's
# ``[drawing]`` lives in its gait library: ``figure_tables`` finds it, as ``nhgait plan`` does).
tables = figure_tables(scene)
view = TrajectoryView.of(traj, model)
ctx = figure_context(view, model, tables.units, tables.drawing)
fig, ax = plt.subplots(figsize=(7.4, 3.6), layout="constrained")
plot_path(view, ctx, ax)

# %%
# The constraint residual ω(q)q̇ stays at rounding level (the reduced ODE satisfies the
# constraints by construction) and so does the energy balance E − E(t₀) − W.
fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5), layout="constrained")
plot_checks(traj, ctx, axes)
