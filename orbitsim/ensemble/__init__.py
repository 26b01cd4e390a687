"""Ensembles: K systems of the same N, scheme and dt in one jitted call (issue 29).

:mod:`.status` holds the status codes, indicator columns and the schemes, :mod:`.kernels` the
parallel Wisdom-Holman kernel (made of the single-system scheme's own jitted operators),
:mod:`.system_lanes` and :mod:`.system_tangent_lanes` the same step (without and with the variational
equations) for 16 systems side by side in SIMD lanes, :mod:`.restricted` and :mod:`.lanes` a map over a
massless body,
:mod:`.kick_drift` those of velocity Verlet and the leapfrog orders (each system the scheme's own
variational step) and :mod:`.run` the front door, :func:`run_ensemble`.
"""

from orbitsim.ensemble.run import EnsembleResult, run_ensemble
from orbitsim.ensemble.status import COLUMN_NAMES, STATUS_NAMES

__all__ = ["COLUMN_NAMES", "STATUS_NAMES", "EnsembleResult", "run_ensemble"]
