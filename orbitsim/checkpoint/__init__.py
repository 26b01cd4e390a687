"""Checkpoints and exact restarts: what a run saves, and where its samples go while it runs.

The promise: a run killed at any instant (SIGKILL included) and resumed with ``orbitsim resume``
writes a trace whose every dataset is bit-identical to the uninterrupted run's, and ends in the
same state. Three things make it hold:

1. **The whole state is saved, never recomputed.** :func:`capture_state` copies ``pos``, ``vel``,
   ``acc`` (first-same-as-last schemes start each step from it, and the others leave in it
   whatever they evaluated last, so it is state, not a function of ``pos`` to trust) and *every*
   array of the integrator's ``work``, whatever its nesting: a plain array or a tuple of arrays
   and constants, such as ``wisdom_holman``'s mapping coordinates and phase. Saving scratch too
   costs a few hundred kilobytes at N = 4096 and makes one generic path exact for every scheme,
   present and future, with nothing for a scheme's author to keep in step;
   :func:`restore_state` writes them back in place and checks that the constants agree.
2. **Checkpoints are taken only where state and samples agree.** The runner asks
   :meth:`orbitsim.simulation.Simulation.chunks` for a (possibly empty) chunk after every jitted
   call; there every sample up to ``steps_done`` has been handed over, and the next sample is
   the first planned step after the last one written. Chunking never changes the arithmetic.
3. **A kill cannot damage what a checkpoint names.** A checkpointed run appends its samples to a
   journal and publishes checkpoints atomically (:mod:`orbitsim.io.checkpoint` explains why the
   HDF5 trace itself cannot be trusted across a kill); the trace is built from the journal at the
   end, with the same writer, so its datasets are the same bits as a streamed run's.

A run without ``output.checkpoint`` streams into the HDF5 trace as before (:class:`StreamSink`);
when it stops on Ctrl-C or SIGTERM, or completes, the trace still gets the final state as its
``checkpoint`` group, so it can be resumed or extended; only a hard kill loses it.

Modules: :mod:`~orbitsim.checkpoint.state` (capture and restore), :mod:`~orbitsim.checkpoint.sinks`
(journal or trace), :mod:`~orbitsim.checkpoint.plan` (what ``resume`` and ``run --from`` continue),
:mod:`~orbitsim.checkpoint.report` (what ``info`` shows); the file formats are in
:mod:`orbitsim.io.checkpoint`. Typical use::

    from orbitsim.checkpoint import prepare_resume
    from orbitsim.runner import run_scenario

    plan = prepare_resume("out.h5")
    if plan.start is not None:
        summary = run_scenario(plan.scenario, plan.output, start=plan.start)
"""

from orbitsim.checkpoint.plan import Continuation, prepare_extension, prepare_resume, resolve_output
from orbitsim.checkpoint.sinks import JournalSink, RunStart, StreamSink
from orbitsim.checkpoint.state import capture_state, restore_state
from orbitsim.io.checkpoint import Checkpoint, CheckpointError, SimState

__all__ = [
    "Checkpoint",
    "CheckpointError",
    "Continuation",
    "JournalSink",
    "RunStart",
    "SimState",
    "StreamSink",
    "capture_state",
    "prepare_extension",
    "prepare_resume",
    "resolve_output",
    "restore_state",
]
