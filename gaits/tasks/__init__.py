"""nhgait.gaits.tasks — The task: its statement (`Task`), the built-in and scene sources, phases,
robust tasks, values."""
