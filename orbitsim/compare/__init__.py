"""``orbitsim compare``: run a scenario in orbitsim and REBOUND and judge the matched pairs.

* :mod:`~orbitsim.compare.run`: the runs of both codes and the :class:`~orbitsim.compare.run.CompareResult`
  (also :func:`~orbitsim.compare.run.run_orbitsim`, the one orbitsim run that ``convergence`` and the
  lesson reuse);
* :mod:`~orbitsim.compare.ias15`, :mod:`~orbitsim.compare.references`: the two IAS15s side by side;
* :mod:`~orbitsim.compare.metrics`: max |dE/E|, drift slope, position errors, pair verdicts;
* :mod:`~orbitsim.compare.output`, :mod:`~orbitsim.compare.figures`, :mod:`~orbitsim.compare.tracegroup`:
  what it writes (summary.json, reports, figures, compare.h5).

Runs are :class:`orbitsim.record.RunRecord`; reports are :mod:`orbitsim.report`; figures use
:mod:`orbitsim.plots.style`. Nothing here is imported by ``import orbitsim``; matplotlib and REBOUND
load only when used.
"""
