"""What stops a sweep: the first Ctrl-C or SIGTERM, and only the first.

A sweep's driver waits on a Dask cluster for minutes to hours. The first Ctrl-C, or SIGTERM (what
``timeout`` and Slurm's ``scancel`` or time limit send), raises :class:`SweepSignal` in the main
thread, a ``KeyboardInterrupt`` that says which signal it was; what follows is the sweep's shutdown
(:func:`orbitsim.batch.driver.run_sweep`: cancel, close the cluster, write the summary), during
which later signals are ignored (:func:`interrupt_once`).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

from orbitsim.stopping import STOP_SIGNALS

__all__ = ["SweepSignal", "interrupt_once"]


class SweepSignal(KeyboardInterrupt):
    """SIGINT or SIGTERM stopped the sweep (``signum`` says which); handled like Ctrl-C."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def interrupt_once() -> Iterator[None]:
    """Within the block the first Ctrl-C or SIGTERM raises :class:`SweepSignal` (a KeyboardInterrupt)
    and later ones are ignored.

    What follows the first signal is the sweep's shutdown: cancel, close the cluster, write the
    summary. A second Ctrl-C used to break it halfway (the cluster left for the interpreter's exit
    to close, with tracebacks; no summary), and SIGTERM, which ``timeout`` and Slurm send, killed the
    driver outright: no summary, the runs' lock files left behind, the cluster's semaphores leaked.
    The shutdown is bounded by Dask's own timeouts (a worker that does not stop within seconds is
    killed), so ignoring the later signals costs a few seconds at most. Only in the main thread,
    and only over Python's default handlers: a caller's handler is left alone. The previous
    handlers are back when the block ends.
    """
    defaults = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    ours = [signum for signum in STOP_SIGNALS if signal.getsignal(signum) is defaults[signum]]

    def first(signum: int, frame: Any) -> None:
        for each in ours:
            signal.signal(each, signal.SIG_IGN)
        raise SweepSignal(signum)

    for signum in ours:
        signal.signal(signum, first)
    try:
        yield
    finally:
        for signum in ours:
            signal.signal(signum, defaults[signum])
