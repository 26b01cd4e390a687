"""Events: what a fixed-dt run cannot see by its energy alone, watched for after every step.

A scenario's ``events:`` section (:mod:`orbitsim.events.config`) asks for collisions, close
encounters, escapes and unresolved steps; each scheme's ``run_watched`` checks them after every
step (:mod:`orbitsim.events.kernels`), and :mod:`orbitsim.events.driver` resolves what Python must
(merges, removals, halts) and keeps the log (:mod:`orbitsim.events.log`). Importing this package
imports no numba.
"""

from orbitsim.events.config import Collisions, Encounters, Escape, EventsConfig, Unresolved
from orbitsim.events.log import Event, RunEvents

__all__ = ["Collisions", "Encounters", "Escape", "Event", "EventsConfig", "RunEvents", "Unresolved"]
