"""Stopping a run on SIGINT/SIGTERM or a ``stop()`` callback without losing or corrupting samples.

:func:`orbitsim.runner.run_scenario` holds a :class:`Stopper` for the length of a run; the class
docstring says what a signal does at each point of the run.

:func:`run_interruptible` is how a stop reaches a jitted call that runs for minutes (one step at
N = 10^6). Python runs a signal handler only in the main thread, between bytecodes, so while the
main thread itself is inside a kernel nothing happens until the kernel returns (a SIGINT took
586 s at N = 10^6). Here the call runs in a kernel thread instead (the kernels release the GIL)
while the main thread waits, free to run handlers; when the wait ends by an exception (the
Stopper's :class:`StopRequest`, a ``KeyboardInterrupt``), the kernels are asked to stop
(:func:`orbitsim._jit.stop_kernels`: they look between row blocks, milliseconds apart), the
call's partial work is undone by the caller's ``restore``, and the exception goes on.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from types import FrameType
from typing import Any, TypeVar

__all__ = ["STOP_SIGNALS", "StopRequest", "Stopper", "run_interruptible"]

T = TypeVar("T")

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest(BaseException):
    """Raised by the signal handler to unwind a run that is computing (see :class:`Stopper`)."""


class Stopper:
    """SIGINT/SIGTERM handling for one run: stop promptly, lose nothing, never cut a write short.

    The handler records the signal. What happens next depends on where the run is:

    * in a critical section (appending to the trace, user callbacks): nothing until it ends,
      then the stop takes effect;
    * computing chunks, where one call can be long (from N = 2048; the main thread waits on the
      call in :func:`run_interruptible`): :class:`StopRequest` at once; the
      kernels stop within milliseconds and the call is undone, so the state is the last whole
      step before it, the one the samples so far agree with, and the run ends well within 2 s
      of the signal however long a step is. Every sample written is kept; the call's own are
      taken again by ``orbitsim resume``;
    * computing other chunks: the runner stops at the next chunk of samples, which arrives within
      about 0.2 s when samples are dense, so every sample taken is kept. When the next chunk is
      further away, a :data:`GRACE_S` alarm then raises :class:`StopRequest` between two jitted
      calls (Python runs handlers between bytecodes, never inside a jitted call); at most the
      samples of the one call just finished are lost;
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
        if self.in_chunks and not repeated and not _waiting_on_kernels and signal.SIGALRM in self._previous:
            signal.setitimer(signal.ITIMER_REAL, self.GRACE_S)
            return
        raise StopRequest  # waiting on kernels (run_interruptible): they stop, and the call is undone

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


#: The kernel thread of :func:`run_interruptible` (one, kept: Numba's thread pool for parallel
#: kernels is made per calling thread) and the process that made it (a forked child makes its own).
_KERNEL_THREAD: tuple[int, ThreadPoolExecutor] | None = None
#: Seconds between the waiting main thread's wake-ups: signal handlers also run on a wake-up, where a
#: platform does not interrupt a lock wait for them.
_WAIT_S = 0.25
#: True while the main thread waits on a kernel call in :func:`run_interruptible` (read by the
#: :class:`Stopper`'s handler, which runs in that thread).
_waiting_on_kernels = False


def _kernel_thread() -> ThreadPoolExecutor:
    global _KERNEL_THREAD
    if _KERNEL_THREAD is None or _KERNEL_THREAD[0] != os.getpid():
        _KERNEL_THREAD = (os.getpid(), ThreadPoolExecutor(max_workers=1, thread_name_prefix="orbitsim-kernel"))
    return _KERNEL_THREAD[1]


def _in_kernel_thread(call: Callable[[], T], threads: int) -> T:
    import numba  # noqa: PLC0415 -- lazy: loads numba

    numba.set_num_threads(threads)  # Numba's thread count is per calling thread
    return call()


def run_interruptible(call: Callable[[], T], threads: int, restore: Callable[[], None] | None = None) -> T:
    """``call()`` (jitted kernels, which release the GIL), stoppable by a signal while it runs.

    From the main thread, ``call`` runs in the kernel thread on ``threads`` Numba threads while this
    thread waits and runs signal handlers. If the wait ends by an exception (a handler's
    :class:`StopRequest` or ``KeyboardInterrupt``), the kernels are asked to stop
    (:func:`orbitsim._jit.stop_kernels`), the call is waited for (its kernels return within
    milliseconds, their results incomplete), ``restore()`` undoes what it changed, and the
    exception is raised again. A further signal meanwhile restarts the wait and the restore (both
    can be repeated), so a second Ctrl-C can never leave a half-restored state.

    From any other thread (a Dask worker's, where no signal handler runs) ``call`` runs here, on
    the calling thread's Numba threads. The stop flag is one per process, so such a call is watched
    with :func:`orbitsim._jit.stop_sequence`: if the main thread's run was being stopped at any
    moment of it, ``restore()`` undoes it and it is made again (``call`` must be repeatable once
    restored, or by itself where ``restore`` is None), and its results are never those of a
    kernel cut short.

    Cost: one hand-off to the kernel thread and back, 50-250 us a call on a busy 2-core machine;
    callers use it where one call can be long (large N), and their calls then last ~0.2 s or one step.
    """
    from orbitsim._jit import stop_kernels, stop_sequence  # noqa: PLC0415 -- lazy: loads numba

    if threading.current_thread() is not threading.main_thread():
        while True:
            before = stop_sequence()
            if before % 2 == 0:
                result = call()
                if stop_sequence() == before:
                    return result
                if restore is not None:
                    restore()
            time.sleep(0.001)  # the main thread's stop lasts milliseconds
    global _waiting_on_kernels
    future: Future[T] | None = None
    try:
        _waiting_on_kernels = True
        future = _kernel_thread().submit(_in_kernel_thread, call, threads)
        while not future.done():
            wait_for([future], timeout=_WAIT_S)
    except BaseException:
        stop_kernels(True)
        try:
            _wind_down(future, restore)
        finally:
            stop_kernels(False)
        raise
    finally:
        _waiting_on_kernels = False
    return future.result()  # an error of the call itself is raised here, as a direct call raises it


def _wind_down(future: Future[Any] | None, restore: Callable[[], None] | None) -> None:
    """Wait for the stopped call to return, then ``restore()``; a further stop signal meanwhile
    (the stop is under way already) starts both again."""
    while True:
        try:
            if future is not None:
                while not future.done():
                    wait_for([future], timeout=_WAIT_S)
            if restore is not None:
                restore()
            return
        except (StopRequest, KeyboardInterrupt):
            continue
