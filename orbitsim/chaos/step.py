"""What every scheme's variational run does after a step: MEGNO's read of the tangent state.

:func:`megno_after_step` is the end of REBOUND's WHFast step (``reb_integrator_whfast_step``) for
any scheme: the tangent accelerations with every pair (and the position forces' derivatives)
at the synchronised state, ``dY = 2 dt (t - t0) (delta'.delta)/(delta.delta)``, and
:func:`~orbitsim.chaos.megno.megno_update`. Then :func:`~orbitsim.chaos.megno.rescale_power_of_two`
keeps |delta| bounded (exact: it moves no bit of either indicator).
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit_inline
from orbitsim.chaos.megno import deltad_delta, megno_update, rescale_power_of_two
from orbitsim.forces.tangent import add_tangent_kick_forces
from orbitsim.physics.tangent import ALL_PAIRS, tangent_accelerations


@jit_inline
def megno_after_step(megno, pos, m, force, dpos, dvel, dacc, t, dt):
    """The MEGNO sums after a step of ``dt`` that ended at time ``t`` with state ``pos`` and tangent
    state ``dpos``, ``dvel`` (3, N); ``dacc`` (3, N) is scratch. Returns ``(megno, halvings)``,
    ``halvings`` the number of 2^-200 rescalings of the tangent state done."""
    tangent_accelerations(pos, m, force.G, force.eps2, dpos, dacc, np.int64(ALL_PAIRS))
    add_tangent_kick_forces(force, pos, m, dpos, dacc)
    dY = dt * 2.0 * (t - megno.initial_t) * deltad_delta(dpos, dvel, dacc)
    megno = megno_update(megno, t, dY, dt)
    return megno, rescale_power_of_two(dpos, dvel)
