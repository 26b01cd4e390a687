"""Between TRACE's in-step contact table (:mod:`.collide`) and the events watch.

:func:`arm_collisions` copies the watch's radii and collision codes into the step's work before a
watched call; :func:`post_contacts` hands the contacts of a step to the watch after it:

* ``log``: each contact is an episode of the watch (logged when it starts; the end-of-step scan
  then extends the same episode rather than logging it again);
* ``halt``: logged, and the run halts after this step;
* ``merge``: left in the table for Python (:func:`orbitsim.integrators.trace.take_merges`), which builds the events
  and takes the merged bodies out.
"""

from __future__ import annotations

from orbitsim._jit import jit
from orbitsim.events.layout import (
    C_DETECT,
    C_RESOLVE,
    EV_COLLISION,
    N_LOST,
    P_LAST,
    PAIR_CONTACT,
    RESOLVE_HALT,
    RESOLVE_MERGE,
    STOP,
    STOP_HALT,
    STOP_NONE,
    STOP_RESOLVE,
    find_pair,
    log_event,
    open_pair,
)
from orbitsim.integrators.trace.collide import (
    H_DIST,
    H_KEEP,
    H_LOSE,
    H_REACH,
    H_SPEED,
    H_TIME,
    K_DETECT,
    K_HITS,
    K_LOST,
    K_RESOLVE,
)

__all__ = ["arm_collisions", "post_contacts"]


@jit
def arm_collisions(radii, collide, watch):
    """The watch's radii and collision codes into the step's ``radii`` and ``collide``."""
    iconf, watch_radii = watch.iconf, watch.radii
    for i in range(radii.shape[0]):
        radii[i] = watch_radii[i]
    collide[K_DETECT] = iconf[C_DETECT]
    collide[K_RESOLVE] = iconf[C_RESOLVE]


@jit
def post_contacts(watch, hits, collide, n_done):
    """The contacts of step ``n_done`` into the watch; True when Python must act now (a merge or
    a halt), with ``watch``'s stop code set."""
    n_hits = collide[K_HITS]
    if n_hits == 0 and collide[K_LOST] == 0:
        return False
    resolve = collide[K_RESOLVE]
    stop = STOP_NONE
    if resolve == RESOLVE_MERGE:
        stop = STOP_RESOLVE  # the table stays for Python
    else:
        for r in range(min(n_hits, hits.shape[0])):
            i, j = int(hits[r, H_KEEP]), int(hits[r, H_LOSE])
            if resolve == RESOLVE_HALT:
                stop = STOP_HALT
            else:
                p = find_pair(watch, i, j, PAIR_CONTACT)
                if p >= 0:
                    watch.pair_i[p, P_LAST] = n_done
                    continue
                open_pair(watch, i, j, PAIR_CONTACT, n_done)
            log_event(watch, EV_COLLISION, n_done, n_done, i, j, hits[r, H_TIME], hits[r, H_DIST], hits[r, H_SPEED],
                      hits[r, H_REACH])
        watch.counts[N_LOST] += collide[K_LOST]
        collide[K_HITS] = 0
        collide[K_LOST] = 0
    watch.counts[STOP] = stop
    return stop != STOP_NONE
