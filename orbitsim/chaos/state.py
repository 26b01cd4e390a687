"""The variational state a run carries beside its bodies: the tangent vector and MEGNO's sums.

A :class:`~orbitsim.simulation.Simulation` made with ``chaos`` holds one :class:`VariationalState`
and calls the scheme's ``run_chaos`` through :meth:`VariationalState.run` instead of its ``run``
(contract item 17 of :mod:`orbitsim.integrators.base`); every sample then carries ``megno`` and
``mlce``. For checkpoints the state is a few named arrays (:meth:`VariationalState.arrays`): the
tangent vector with its scratch and rescaling count, and MEGNO's running sums by field, so a
resumed run continues bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbitsim.chaos.megno import MEGNO_FIELDS, MegnoState, megno_start
from orbitsim.forces.compat import TANGENT_BUILT, check_chaos_forces
from orbitsim.integrators.base import make_tangent

__all__ = ["CHAOS_SERIES", "VariationalState", "forces_with_derivatives", "variational_refusal"]

#: The per-sample series a variational run adds to its samples (trace datasets of these names).
CHAOS_SERIES = ("megno", "mlce")
class VariationalState:
    """The tangent vector (:class:`~orbitsim.integrators.base.Tangent`) and MEGNO's sums of one run.

    Parameters
    ----------
    dpos, dvel : (3, N) arrays
        The initial tangent vector (copied).
    t0 : float
        The time the indicators start from (REBOUND's ``init_megno`` time: the run's start).
    make : callable
        The scheme's tangent record maker (its ``make_tangent``: the shared
        :class:`~orbitsim.integrators.base.Tangent`, or IAS15's with its tangent polynomial). A
        checkpoint keeps every field of that record (``dacc`` and scratch too, as a checkpoint keeps an
        integrator's scratch, so nothing is recomputed).
    """

    def __init__(self, dpos: np.ndarray, dvel: np.ndarray, t0: float, make: Any = make_tangent) -> None:
        self.tangent = make(dpos, dvel)
        self.megno: MegnoState = megno_start(t0)
        self.indicators = np.zeros((0, 2))

    def run(self, scheme: Any, state: tuple[np.ndarray, ...], force: Any, dt: float, work: Any, t0: float,
            n_done: int, targets: np.ndarray, record: np.ndarray, out: Any) -> tuple[int, int, bool, MegnoState]:
        """The scheme's ``run_chaos`` over ``targets`` from the sums held here: ``(samples_written, n_done,
        finite, sums)``, the sums after the call, which the caller keeps (:attr:`megno`) once the call
        stands: a call a stop undid (:func:`orbitsim.stopping.run_interruptible`) must leave the old
        ones. (MEGNO, mLCE) of each sample written are left for :meth:`series`."""
        if self.indicators.shape[0] < targets.shape[0]:
            self.indicators = np.zeros((targets.shape[0], 2))
        return scheme.run_chaos(state, self.tangent, force, dt, work, t0, np.int64(n_done), targets, record, out,
                                self.indicators, self.megno)

    def series(self, written: int) -> dict[str, np.ndarray]:
        """Copies of the last call's ``megno`` and ``mlce`` samples, by trace dataset name."""
        return {"megno": self.indicators[:written, 0].copy(), "mlce": self.indicators[:written, 1].copy()}

    def now(self, time: float) -> tuple[float, float]:
        """(MEGNO, mLCE) of the sums as they stand, at ``time`` (the state's): REBOUND's ``megno()`` and
        ``lyapunov()``, the arithmetic of :func:`~orbitsim.chaos.megno.megno_value` and
        :func:`~orbitsim.chaos.megno.lyapunov` in Python (nothing to compile for a summary)."""
        sums = self.megno
        megno = 0.0 if time == sums.initial_t else sums.yss / (time - sums.initial_t)
        return float(megno), float(0.0 if sums.var_t == 0.0 else sums.cov_yt / sums.var_t)

    def changing_arrays(self) -> list[np.ndarray]:
        """Every array a jitted call changes (for a call undone by a stop, :mod:`orbitsim.simulation`)."""
        return list(self.tangent)

    def arrays(self) -> dict[str, np.ndarray]:
        """Copies of the whole state by checkpoint dataset name: the tangent's arrays, and MEGNO's sums
        (``megno_sums``, float64, in :data:`~orbitsim.chaos.megno.MEGNO_FIELDS` order without ``n``;
        ``megno_updates``, int64)."""
        arrays = {name: np.array(getattr(self.tangent, name)) for name in self.tangent._fields}
        arrays["megno_sums"] = np.array([getattr(self.megno, name) for name in MEGNO_FIELDS if name != "n"],
                                        dtype=np.float64)
        arrays["megno_updates"] = np.array([self.megno.n], dtype=np.int64)
        return arrays

    def restore(self, arrays: dict[str, np.ndarray]) -> None:
        """Put :meth:`arrays`' state back in place; ValueError (one line) if it does not fit this run."""
        names = (*self.tangent._fields, "megno_sums", "megno_updates")
        if sorted(arrays) != sorted(names):
            raise ValueError(f"the checkpoint's variational state has {sorted(arrays)}, the run needs {sorted(names)}")
        for name in self.tangent._fields:
            have, saved = getattr(self.tangent, name), arrays[name]
            if have.shape != saved.shape or have.dtype != saved.dtype:
                raise ValueError(f"the checkpoint's tangent {name} has shape {saved.shape}, the run needs {have.shape}")
            have[...] = saved
        sums = [float(value) for value in arrays["megno_sums"]]
        if len(sums) != len(MEGNO_FIELDS) - 1 or arrays["megno_updates"].shape != (1,):
            raise ValueError("the checkpoint's MEGNO sums do not fit this run")
        self.megno = MegnoState(*sums, int(arrays["megno_updates"][0]))


def forces_with_derivatives() -> tuple[str, ...]:
    """The scenario force names whose derivatives enter the variational equations
    (:mod:`orbitsim.forces.tangent`, :data:`orbitsim.forces.compat.TANGENT_BUILT`)."""
    return tuple(TANGENT_BUILT)


def _force_refusal(name: str, integrator: str) -> str | None:
    """Why a variational run of ``integrator`` cannot take force ``name`` (one line), or None:
    :func:`orbitsim.forces.compat.check_chaos_forces` knows which derivatives are built and which
    schemes' variational kernels take forces."""
    why = check_chaos_forces((name,), integrator)
    return None if why is None else f"the variational equations would leave out {name}: {why}"


def variational_refusal(integrator: str, settings: dict[str, Any], force_names: Any,
                        has_events: bool) -> tuple[str, str] | None:
    """``(what, why)`` when a run of ``integrator`` with these settings, forces and events cannot carry
    the variational equations (``what``: ``"integrator"``, ``"forces[k]"`` or ``"events"``, the scenario
    key to fix; ``why`` one line), or None. The scheme's part is
    :func:`orbitsim.integrators.registry.chaos_refusal`'s (each scheme's ``check_chaos``), so a scheme
    or a force that gains variational equations is accepted with no change here."""
    from orbitsim.integrators.registry import chaos_refusal  # noqa: PLC0415 - lazy: loads numba

    why = chaos_refusal(integrator, settings)
    if why is not None:
        return "integrator", f"chaos indicators need the variational equations: {why}"
    for k, name in enumerate(force_names):
        why = _force_refusal(name, integrator)
        if why is not None:
            return f"forces[{k}]", why
    if has_events:
        return "events", ("output.chaos does not combine with events: a merge or a removal would change the bodies "
                          "the tangent vector belongs to mid-run; remove the events section or output.chaos")
    return None
