"""``orbitsim convergence``: error against dt for each scheme, and the fitted order of accuracy.

* :mod:`~orbitsim.convergence.run`: the dt ladders, extended per scheme to its asymptotic range;
* :mod:`~orbitsim.convergence.fit`: which rungs are asymptotic, the slope there, and why when none are;
* :mod:`~orbitsim.convergence.output`: summary.json, report.md/.html and the figures.

Each rung is run as ``orbitsim compare`` runs a scheme (:func:`orbitsim.compare.run.run_orbitsim`) and
measured with :mod:`orbitsim.compare.metrics`.
"""
