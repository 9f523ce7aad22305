"""
Stability of a rolling disc against speed
=========================================

A thin disc rolling upright on a plane (sympy's own rolling-disc example) falls over when slow;
above √(g r / 3) its eigenvalues are on the imaginary axis (neutral: nothing in the model
dissipates energy). The eigenvalues of the reduced ODE linearised about upright rolling,
against the forward speed, with the speed where stability changes refined by root finding.
"""
import matplotlib.pyplot as plt
import numpy as np

from nhgait.dynamics import derive, load_scene
from nhgait.dynamics.linearisation import stability_chart
from nhgait.gaits.figures.stability import plot_eigenvalues

model = derive(load_scene("rolling_disc").system)      # a built-in scene
chart = stability_chart(model, np.linspace(0.0, 3.0, 31))
for change in chart.changes:
    print(change)
g, r = (model.system.parameters[k] for k in ("g", "r"))
print(f"√(g r / 3) = {np.sqrt(g * r / 3):.12f} m/s")

# %%
fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
plot_eigenvalues(chart, ax)
