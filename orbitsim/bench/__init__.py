"""Benchmarks of orbitsim against REBOUND: matrices, the runner, results and figures.

``orbitsim bench`` is the front door. The pieces:

* :mod:`~orbitsim.bench.matrix`: the YAML matrix (groups of scenarios x integrators x N x steps)
  and its validation;
* :mod:`~orbitsim.bench.systems`: the systems benchmarked (generated, or bundled scenarios);
* :mod:`~orbitsim.bench.engines`: timed stepping through orbitsim's loop and REBOUND's;
* :mod:`~orbitsim.bench.adaptive`: IAS15 over one span, orbitsim beside REBOUND, per accepted step;
* :mod:`~orbitsim.bench.probes` and :mod:`~orbitsim.bench.memprobe`: start-up, output overhead,
  memory;
* :mod:`~orbitsim.bench.ceiling`: the measured hardware ceiling of the force loop;
* :mod:`~orbitsim.bench.runner`: runs a matrix, interleaving the cases of each N;
* :mod:`~orbitsim.bench.targets`, :mod:`~orbitsim.bench.report`, :mod:`~orbitsim.bench.plots`:
  the targets table, ``results.md`` and the figures.

Importing this package imports neither numba nor REBOUND.
"""

from orbitsim.bench.matrix import BenchMatrix, BenchMatrixError, load_matrix

__all__ = ["BenchMatrix", "BenchMatrixError", "load_matrix"]
