"""nhgait.dynamics.numerics — from sympy expressions to fast numeric functions.

* :mod:`.bridge` — sympy → CasADi; :mod:`.numeric_model` — CasADi functions of each formulation;
* :mod:`.specialisation` — a reduced model specialised to parameter values, for planning;
* :mod:`.linsolve` — symbolic-structure linear solves; :mod:`.cache` — the content-keyed disk
  cache and its trust rules; :mod:`.compiler` — the one C compiler entry point.
"""
