"""nhgait.dynamics.derivation — stating a system and deriving its equations of motion (sympy).

* :mod:`.system` — :class:`System` (q, L, ω, τ, parameters); :mod:`.scene`, :mod:`.tomldata`,
  :mod:`.expressions` — scene files and the safe expression parser; :mod:`.models` — built-in systems;
* :mod:`.formulations` — :func:`derive`, the one entry point (cached on disk);
* :mod:`.lagrange`, :mod:`.hamilton`, :mod:`.reduction` (the 20 steps) — one result type per
  equation form; :mod:`.steps` — the steps' records; :mod:`.symbolic`, :mod:`.symmetry` — helpers;
* :mod:`.states` — each formulation's state layout; :mod:`.quantities`, :mod:`.analysis`.
"""
