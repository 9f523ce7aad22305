"""nhgait.dynamics.simulation — integrating a derived model in time.

* :mod:`.driver` — :func:`simulate`; :mod:`.trajectory` — what it returns (:class:`Trajectory`,
  :class:`Diagnostics`); :mod:`.failures` — what produced a failure;
* :mod:`.integrators` — what the routes share and the scipy route; :mod:`.route_sundials`,
  :mod:`.route_compiled` — the SUNDIALS and compiled routes; :mod:`.compiled` and
  ``explicit_rk.c`` — the compiled explicit Runge–Kutta integrator; :mod:`.rk_tableaus`;
* :mod:`.closed_loop`, :mod:`.closure`, :mod:`.controllers` — inputs u(t, q, q̇).
"""
