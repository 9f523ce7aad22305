"""
Plan a gait of the unicycle
===========================

The built-in task P1: the unicycle (a vertical rolling disc) parks 0.5 m to its side in 4 s,
from rest to rest with the same heading, with the least effort ∫|τ|² dt. The planner tries
its own guesses, solves, and re-simulates the optimum with an independent integrator.
"""
import matplotlib.pyplot as plt

from nhgait.gaits import plan
from nhgait.gaits.figures.plots import figure_context, plot_histories, plot_path

result = plan("unicycle", "parallel-park", intervals=40, jit=False)
print(result)
solution = result.solution
print(f"J = {solution.objective:.6f}, verified to {solution.verification_error:.1e}")

# %%
# The path of the wheel's contact point, the wheel drawn at five instants (colour: time):
# it backs and turns, then drives forward into the slot.
ctx = figure_context(solution, result.model, result.plan.units, result.plan.drawing)
fig, ax = plt.subplots(figsize=(7.4, 4.2), layout="constrained")
plot_path(solution, ctx, ax)

# %%
# The shape and the inputs (constant on each of the 40 intervals).
fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 6), layout="constrained")
plot_histories(solution, ctx, axes)
