"""HDF5 energy-trace format (``orbitsim.trace``, version 1): writer and reader.

Schema
------
S is the number of samples, N the number of bodies. All floats are float64.

Root attributes written by the writer itself

=====================  ==================================================================
``format``             ``"orbitsim.trace"`` (identifies the file; checked by the reader)
``format_version``     ``1`` (checked by the reader)
``orbitsim_version``   version of the writing orbitsim
``status``             ``"running"`` while written, then ``"complete"``,
                       ``"interrupted"``, ``"diverged"`` or ``"halted"`` (an event the
                       scenario's ``events:`` asked to halt on)
``steps_done``         steps integrated (set at close; default: last sample's step)
``wall_time_s``        wall-clock seconds of the run (set at close)
``message``            free text, e.g. the divergence message (``""`` by default)
``E0``                 energy of the first sample (present once a sample was written)
``energy_scale``       what ``energy_error`` is relative to: |E0|, or T0 + |U0| when
                       |E0| < 1e-3 (T0 + |U0|) (:func:`orbitsim.io.schema.energy_scale`)
``scenario_sha256``    hex SHA-256 of the UTF-8 ``scenario`` text, unless supplied
``provenance_<key>``   one attribute per key of :func:`orbitsim.provenance.provenance`,
                       flattened into the root so ``h5dump -A`` shows them directly
=====================  ==================================================================

Root attributes supplied by the caller (documented, not enforced): ``scenario``
(YAML text), ``integrator``, ``dt``, ``steps_requested``, ``G``, ``softening``,
``units``; any other str/int/float/bool/array attribute may be added.

Datasets (per-sample ones are resizable along S, chunked, gzip+shuffle compressed)

* ``time`` (S,), ``step`` (S,) int64 step index of each sample
* ``kinetic``, ``potential``, ``energy`` (S,)
* ``energy_error`` (S,): ``(E + energy_offset - E0) / energy_scale``
* ``energy_offset`` (S,), a run with events only: the energy merges and removals took out so
  far (E + offset is what the integrator conserves)
* ``momentum``, ``angular_momentum`` (S, 3)
* ``positions``, ``velocities`` (S, N, 3): only when positions are recorded; NaN for a body
  from the step it was merged or removed on
* group ``elements`` (``output.elements``): ``a``, ``e``, ``inc``, ``Omega``, ``omega``, ``f``,
  ``M`` (S, N), degrees for angles, attribute ``primary``
* group ``bodies``: ``names`` (N,) variable-length UTF-8 strings, ``masses`` (N,); with events
  also ``radii``, ``final_radii``, ``final_masses`` (N,), ``removed_step`` (N,) int64 (-1:
  never), ``removed_time`` (N,) (nan: never), ``merged_into`` (N,) int64 (-1: not merged)
* group ``events`` (a run with events): one row per event, columns ``step``, ``step_start``,
  ``time``, ``kind``, ``i``, ``j``, ``distance``, ``speed``, ``extra``, ``outcome``, ``into``
  and ``details`` (:class:`orbitsim.events.log.Event` says what each holds)
* group ``checkpoint`` (optional): the state the run stopped in, so that it can be resumed or
  extended bit for bit; its layout is documented in :mod:`orbitsim.io.checkpoint`
* group ``scenario_bodies`` (a scenario whose resolved text would pass 256 KiB): its bodies' rows
  as datasets, the ``scenario`` attribute holding the rest (:mod:`orbitsim.io.stored_scenario`)

Writing protocol: data go to ``<path>.tmp`` in the target's directory and are renamed
onto ``<path>`` only in :meth:`TraceWriter.close`, so a file at ``<path>`` is always
complete. Samples are buffered up to a bounded size and written block-wise, because
resizing HDF5 datasets once per sample is slow; memory use therefore stays flat.

Code: the names and errors of the schema are in :mod:`orbitsim.io.schema`, the writer in
:mod:`orbitsim.io.trace_writer`, the reader in :mod:`orbitsim.io.trace_reader`; this module is
the public face and re-exports them.
"""


from __future__ import annotations

from orbitsim.io.schema import FINAL_STATUSES, TRACE_FORMAT, TRACE_VERSION, TraceError
from orbitsim.io.trace_reader import Trace, open_trace, open_trace_summary, read_trace
from orbitsim.io.trace_writer import TraceWriter

__all__ = ["FINAL_STATUSES", "TRACE_FORMAT", "TRACE_VERSION", "Trace", "TraceError", "TraceWriter",
           "open_trace", "open_trace_summary", "read_trace"]
