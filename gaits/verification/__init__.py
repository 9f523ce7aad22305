"""nhgait.gaits.verification — Verification of a plan and what follows from it: checks, refinement,
diagnosis, feedback."""
