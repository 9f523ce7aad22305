"""nhgait.dynamics.derivation.input — What a user writes, read: scene files and their tables, the
system's expressions and names, sympy.mechanics objects."""
