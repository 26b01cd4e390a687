"""Stopping a run on SIGINT/SIGTERM or a ``stop()`` callback without losing or corrupting samples.

:func:`orbitsim.runner.run_scenario` holds a :class:`Stopper` for the length of a run; the class
docstring says what a signal does at each point of the run.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any

__all__ = ["STOP_SIGNALS", "StopRequest", "Stopper"]

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest(BaseException):
    """Raised by the signal handler to unwind a run that is computing (see :class:`Stopper`)."""


class Stopper:
    """SIGINT/SIGTERM handling for one run: stop promptly, lose nothing, never cut a write short.

    The handler records the signal. What happens next depends on where the run is:

    * in a critical section (appending to the trace, user callbacks): nothing until it ends,
      then the stop takes effect;
    * computing chunks: the runner stops at the next chunk of samples, which arrives within about
      0.2 s when samples are dense, so every sample taken is kept. With sparse samples the next
      chunk may be minutes away, so a :data:`GRACE_S` alarm then raises :class:`StopRequest`
      between two jitted calls (Python runs handlers between bytecodes, never inside a jitted
      call); at most the samples of the one call just finished are lost;
    * anywhere else (a cold Numba compile takes seconds): :class:`StopRequest` at once.

    A second signal stops at once outside a critical section. Handlers can only be installed
    from the main thread; elsewhere (Dask workers) only ``stop()`` applies. The previous handlers
    are restored, and the alarm cancelled, on exit.
    """

    GRACE_S = 1.0

    def __init__(self, enabled: bool, stop: Callable[[], bool] | None) -> None:
        self.enabled = enabled and threading.current_thread() is threading.main_thread()
        self.stop = stop
        self.signum: int | None = None
        self.depth = 0
        self.in_chunks = False  # set while the simulation computes the next chunk
        self.finished = False  # once the trace is closed, a signal has nothing left to stop
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> Stopper:
        if self.enabled:
            for signum in STOP_SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
            if hasattr(signal, "setitimer"):
                self._previous[signal.SIGALRM] = signal.signal(signal.SIGALRM, self._alarm)
        return self

    def __exit__(self, *exc: object) -> None:
        if signal.SIGALRM in self._previous:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        repeated = self.signum is not None
        self.signum = self.signum or signum
        if self.depth > 0 or self.finished:
            return
        if self.in_chunks and not repeated and signal.SIGALRM in self._previous:
            signal.setitimer(signal.ITIMER_REAL, self.GRACE_S)
            return
        raise StopRequest

    def _alarm(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is not None and self.depth == 0 and not self.finished:
            raise StopRequest

    @contextlib.contextmanager
    def critical(self, *, stop_after: bool = True) -> Iterator[None]:
        """A section a signal must not cut short. When it ends, a pending stop raises if
        ``stop_after`` (else the caller polls :meth:`requested`)."""
        self.depth += 1
        try:
            yield
        finally:
            self.depth -= 1
        if stop_after and self.depth == 0 and self.signum is not None:
            raise StopRequest

    def requested(self) -> bool:
        """True once a signal arrived or ``stop()`` says so."""
        return self.signum is not None or bool(self.stop and self.stop())
