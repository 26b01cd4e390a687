"""Figures: ``orbitsim plot`` and the shared look of every orbitsim figure.

* :mod:`~orbitsim.plots.style`: Agg backend, fonts, unit labels and colours, for every figure
  (``compare``, ``convergence`` and the lesson's included);
* :mod:`~orbitsim.plots.elements`: ``orbitsim plot --elements``;
* :mod:`~orbitsim.plots.resonance`: ``orbitsim plot --resonance P:Q``;
* :mod:`~orbitsim.plots.event_marks`: ``orbitsim plot --events``.

matplotlib is imported inside the functions that draw.
"""
