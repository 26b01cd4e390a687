"""How each system of an ensemble ended: its status code, and the indicator columns it carries.

Every system of an ensemble stops alone (:mod:`orbitsim.ensemble.kernels`); what stopped it is one of

* :data:`COMPLETE`: it reached the end time;
* :data:`ESCAPED`: a body's distance from body 0 exceeded the escape distance (REBOUND's
  ``exit_max_distance`` measured from the star rather than the origin);
* :data:`COLLIDED`: two bodies with radii came closer than the sum of their radii;
* :data:`DIVERGED`: the state became non-finite, or a Kepler drift failed to converge.

The numbers are stored in a map file (``status`` grid), so they never change meaning.
"""

from __future__ import annotations

COMPLETE = 0
ESCAPED = 1
COLLIDED = 2
DIVERGED = 3

#: Status names by code, in code order (the map file stores this list beside the codes).
STATUS_NAMES = ("complete", "escaped", "collided", "diverged")

#: Columns of the indicator array a kernel fills, one row per system. ``megno`` and ``lyapunov`` are
#: NaN when the run carries no variations.
SURVIVAL_TIME = 0
MAX_E = 1
DELTA_A = 2
ENERGY_ERROR = 3
MEGNO = 4
LYAPUNOV = 5
N_COLUMNS = 6

#: Column names, in column order.
COLUMN_NAMES = ("survival_time", "max_e", "delta_a", "energy_error", "megno", "lyapunov")

#: The schemes an ensemble runs (registry names): the Wisdom-Holman map (:mod:`.kernels`), and the
#: kick-drift schemes with their variational equations (:mod:`.kick_drift`, whose kernel table names
#: the same five; tests/ensemble/test_kick_drift.py checks it).
SCHEMES = ("wisdom_holman", "verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8")
