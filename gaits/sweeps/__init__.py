"""nhgait.gaits.sweeps — one gait task planned over a grid of parameters.

* :mod:`.driver` — :func:`sweep`, :func:`load_sweep` (continuation over the grid);
  :mod:`.options` — :class:`SweepOptions`, how a sweep runs, gathered and checked once;
* :mod:`.grid` — the grid; :mod:`.point` — one point's plan; :mod:`.backends` — local processes
  or Dask; :mod:`.store` — the SQLite store; :mod:`.plots` — the sweep's figures.
"""
