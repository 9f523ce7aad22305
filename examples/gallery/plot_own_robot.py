"""
Plan your own robot from a scene file
=====================================

A car (a planar body with a steered front axle and a driven rear axle) stated in a TOML scene
file — the system, its units, its outline and a parallel-parking task, all in your own names —
and planned with one value changed, as ``nhgait plan car.toml --set final.y=0.8`` would.
The same file is ``examples/car.toml`` in the repository.
"""
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from nhgait.gaits import plan
from nhgait.gaits.figures.plots import figure_context, plot_path, plot_shape_loop

SCENE = '''
[system]
name = "car"
coordinates = ["x", "y", "theta", "phi"]       # rear axle (x, y), heading, steering angle
lagrangian = "m*(x_dot**2 + y_dot**2)/2 + I_z*theta_dot**2/2 + I_s*phi_dot**2/2"
constraints = [
  "-sin(theta)*x_dot + cos(theta)*y_dot",                                      # rear wheel
  "-sin(theta + phi)*x_dot + cos(theta + phi)*y_dot + l*cos(phi)*theta_dot",   # front wheel
]
inputs = ["F", "tau_phi"]
[system.forces]
x = "F*cos(theta)"
y = "F*sin(theta)"
phi = "tau_phi"
[system.parameters]
m = 1.0
I_z = 0.1
I_s = 0.01
l = 0.5

[units]
F = "N"
tau_phi = "N*m"

[drawing]
[[drawing.segment]]
from = [0, 0]
to = ["l", 0]
width = 3
label = "chassis"
[[drawing.segment]]
from = ["l - 0.08*cos(phi)", "-0.08*sin(phi)"]
to = ["l + 0.08*cos(phi)", "0.08*sin(phi)"]
label = "front wheel"

[task]
name = "parallel-park"
horizon = 6.0
intervals = 30
initial = {x = 0.0, y = 0.0, theta = 0.0, phi = 0.0, forward_velocity = 0.0, phi_dot = 0.0}
final = {x = 0.0, y = 0.5, theta = 0.0, phi = 0.0, forward_velocity = 0.0, phi_dot = 0.0}
bounds = {phi = [-0.7, 0.7]}
control_bounds = {F = [-5.0, 5.0], tau_phi = [-1.0, 1.0]}
objective = "effort"
'''

with tempfile.TemporaryDirectory() as folder:
    scene_file = Path(folder) / "car.toml"
    scene_file.write_text(SCENE)
    result = plan(scene_file, overrides=["final.y=0.8"], jit=False)
print(result)

# %%
# The path of the rear axle, the car drawn at five instants coloured by time.
ctx = figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)
fig, ax = plt.subplots(figsize=(7.4, 4.4), layout="constrained")
plot_path(result.solution, ctx, ax)

# %%
# The shape: the steering angle against its rate.
fig, ax = plt.subplots(figsize=(5.4, 4.6), layout="constrained")
plot_shape_loop(result.solution, ctx, ax)
