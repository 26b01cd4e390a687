"""Parameter sweeps on Dask: ``orbitsim batch`` and its Python API.

Modules, in the order a sweep flows through them:

* :mod:`~orbitsim.batch.overrides`: dotted key paths (``bodies.1.e``) into raw scenario documents;
* :mod:`~orbitsim.batch.sweep`: sweep files -> validated cases with stable run ids;
* :mod:`~orbitsim.batch.cluster`: an embedded ``LocalCluster`` or an existing scheduler;
* :mod:`~orbitsim.batch.task`: what a worker runs for one case;
* :mod:`~orbitsim.batch.driver`: resume, submit, collect;
* :mod:`~orbitsim.batch.summary`: ``summary.csv``, ``summary.h5`` and the terminal table.

Typical use::

    from orbitsim.batch import load_sweep, run_sweep
    outcome = run_sweep(load_sweep("integrators_dt"), "out/integrators_dt")
    outcome.counts            # Counter({'complete': 40})

Importing this package imports neither numba nor dask.
"""

from orbitsim.batch.driver import SweepInterrupted, SweepOutcome, run_sweep
from orbitsim.batch.sweep import Case, InvalidCase, Sweep, SweepError, load_sweep

__all__ = ["Case", "InvalidCase", "Sweep", "SweepError", "SweepInterrupted", "SweepOutcome", "load_sweep",
           "run_sweep"]
