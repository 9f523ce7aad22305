"""
Track a gait on a robot that differs
====================================

A plan is an input sequence for a model; the robot's masses differ. ``track`` re-simulates the
unicycle's parking manoeuvre on a wheel 10 % heavier, with noise, open loop and with the
plan's own feedback (a time-varying LQR on the plan's stage Jacobians).
"""
import matplotlib.pyplot as plt

from nhgait.gaits.tracking.plots import plot_final_positions, plot_tracking_paths
from nhgait.gaits.tracking.study import summary_lines, track

result = track("unicycle", "parallel-park", overrides=["intervals=40"], mismatch=["params.m=1.1"],
               samples=6, seed=1)
print("\n".join(summary_lines(result)))          # what nhgait track prints
for loop in ("open_loop", "closed_loop"):
    error = result.report[loop]["final_position_error"]
    median, worst = 1e3 * error["median"], 1e3 * error["max"]
    print(f"{loop}: final position error median {median:.3g} mm, max {worst:.3g} mm")

# %%
# The paths of the samples, open loop (left) and closed loop (right), and where they end.
fig, axes = plt.subplots(1, 2, figsize=(9, 4), layout="constrained", sharex=True, sharey=True)
plot_tracking_paths(result, axes)
fig, ax = plt.subplots(figsize=(5, 4), layout="constrained")
plot_final_positions(result, ax)
