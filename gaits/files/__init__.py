"""nhgait.gaits.files — What a plan writes: staged output folders, solution.json and
trajectory.csv."""
