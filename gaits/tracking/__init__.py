"""nhgait.gaits.tracking — does a planned gait survive the real robot?

* :mod:`.study` — :func:`track` (``nhgait track``): the plan re-simulated on the general model
  with changed parameters and noise, open loop and with the plan's feedback, K samples;
  ``tracking.json``;
* :mod:`.request` — the request checked before any work (samples, seed, noise, mismatch);
* :mod:`.runs` — one sample (the worker side; picklable :class:`~.runs.TrackingCase`);
* :mod:`.plots` — tracking_paths.png, tracking_errors.png.

The feedback itself is planned with every gait (:mod:`nhgait.gaits.verification.feedback`,
:mod:`nhgait.ocp.feedback`); its stability over a period is in :mod:`nhgait.ocp.floquet`.
"""
