"""nhgait.gaits.bench — benchmarks and the thesis reproduction.

* :mod:`.work_precision` — speed against error of every formulation × method × tolerance;
* :mod:`.command` — ``nhgait bench``; :mod:`.reproduction`, :mod:`.thesis_plots` — ``nhgait reproduce``.
"""
