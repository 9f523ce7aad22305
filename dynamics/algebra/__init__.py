"""nhgait.dynamics.algebra — sympy algebra with no physics, the layer below both the derivation
and the numerics (neither imports the other's internals for it).

* :mod:`.ring` — rational functions as fractions of one sparse polynomial ring over ℚ;
* :mod:`.trig` — the trig normal form (``trig_normal``, ``tidy``);
* :mod:`.fraction_field` — the exact fraction field of a derivation (``FracField``);
* :mod:`.matrix_ops` — matrix operations over any arithmetic back end (``MatrixOps``);
* :mod:`.matrices` — symbolic matrices: division-free null spaces, plain determinants, pivots;
* :mod:`.symbols` — the symbols every layer shares (the time ``TIME`` of the forces);
* :mod:`.determinism` — sympy's random choices seeded during a derivation (``seeded``).
"""
