"""nhgait.gaits.figures — Figures of a plan: trajectories, paths, shape loops, stability, drawings
and the animation."""
