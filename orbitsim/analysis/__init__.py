"""Comparison metrics, convergence fits, figures and reports (``compare``, ``convergence``, ``demo``).

* :mod:`~orbitsim.analysis.record`: ``RunRecord``, one sampled run of any engine;
* :mod:`~orbitsim.analysis.metrics`: max |dE/E|, drift slope, position errors, pair verdicts;
* :mod:`~orbitsim.analysis.compare` / :mod:`~orbitsim.analysis.compare_output`: ``orbitsim compare``;
* :mod:`~orbitsim.analysis.convergence` / :mod:`~orbitsim.analysis.convergence_output`:
  ``orbitsim convergence``;
* :mod:`~orbitsim.analysis.lesson` / :mod:`~orbitsim.analysis.lesson_output`: ``orbitsim demo``;
* :mod:`~orbitsim.analysis.tracegroup`: runs stored as trace-layout groups of one HDF5 file;
* :mod:`~orbitsim.analysis.report`, :mod:`~orbitsim.analysis.plotstyle`,
  :mod:`~orbitsim.analysis.figures`: Markdown/HTML reports and matplotlib figures.

Nothing here is imported by ``import orbitsim``; matplotlib and REBOUND load only when used.
"""
