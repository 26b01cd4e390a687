"""The front door of the GPU ensemble: check K systems as the CPU ensemble does, run them on the GPU.

:func:`run_ensemble_gpu` takes the arguments of :func:`orbitsim.ensemble.run_ensemble` (plus ``scheme``),
checks them with the same :func:`~orbitsim.ensemble.run.prepare_systems`, lays them out with the system
index last, copies them to the device once (:func:`upload_ensemble`, a :class:`DeviceEnsemble`), launches
one thread per system (:mod:`orbitsim.gpu.ensemble_kernels`) and copies the results back once: an
:class:`~orbitsim.ensemble.run.EnsembleResult` with the CPU ensemble's statuses and indicator columns.

Schemes: ``wisdom_holman`` (Jacobi coordinates, no corrector) with its tangent map, MEGNO and the mLCE,
as the CPU ensemble's variational kernel and ``orbitsim map``; ``leapfrog`` (drift-kick-drift) and ``verlet``
(velocity Verlet, kick-drift-kick) with the same stops and the other indicators (``megno`` and ``lyapunov``
NaN).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbitsim.ensemble.run import EnsembleResult, EnsembleSystems, check_variation, prepare_systems
from orbitsim.ensemble.status import N_COLUMNS

__all__ = ["GPU_SCHEMES", "DeviceEnsemble", "run_ensemble_gpu", "upload_ensemble"]

#: The schemes the GPU ensemble runs.
GPU_SCHEMES = ("wisdom_holman", "leapfrog", "verlet")


def _device_layout(a: np.ndarray) -> np.ndarray:
    """(K, ...) -> (..., K), contiguous: the system index innermost, as the kernels read it."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1))


def _host_layout(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.moveaxis(a, -1, 0))


class DeviceEnsemble:
    """K checked systems on the device (:func:`upload_ensemble`): :meth:`launch` queues their kernel, one thread
    per system, and :meth:`result` waits for it and copies the results back. The kernel leaves each system's
    state at its stop in the device arrays, so a second launch goes on from there (benchmarks time
    :meth:`launch` alone, the copies apart)."""

    def __init__(self, cuda: Any, systems: EnsembleSystems, tangent: tuple[np.ndarray, np.ndarray] | None,
                 scheme: str, G: float, dt: float, t_start: float, n_steps: int, escape_distance: float,
                 watch: int) -> None:
        from orbitsim.gpu import ensemble_kernels  # noqa: PLC0415 - lazy: loads numba-cuda

        self.cuda = cuda
        self._kernels = ensemble_kernels  # its THREADS_PER_BLOCK read at each launch
        self.k, self.n = systems.masses.shape
        self.systems = systems
        if not self.k:  # nothing to copy or launch
            return
        self.status = cuda.to_device(np.zeros(self.k, dtype=np.int64))
        self.steps = cuda.to_device(np.zeros(self.k, dtype=np.int64))
        self.out = cuda.to_device(np.zeros((N_COLUMNS, self.k)))
        self.pos, self.vel, m, weights, mu, radii = (
            cuda.to_device(_device_layout(value)) for value in
            (systems.pos, systems.vel, systems.masses, systems.weights, systems.mu, systems.radii))
        scalars = (float(G), float(dt), float(t_start), np.int64(n_steps), float(escape_distance) ** 2,
                   bool(systems.check_collisions))
        results = (self.status, self.steps, self.out)
        if tangent is not None:
            dpos, dvel = (cuda.to_device(_device_layout(value)) for value in tangent)
            self._kernel = ensemble_kernels.wh_variational_kernel(self.n, int(watch))
            self._args = (self.pos, self.vel, dpos, dvel, m, weights, mu, radii, *scalars, *results)
        else:
            self._kernel = ensemble_kernels.fixed_step_kernel(self.n, int(watch), scheme)
            self._args = (self.pos, self.vel, m, weights, mu, radii, *scalars, *results)

    def launch(self) -> None:
        """Queue the kernel over every system (asynchronous; compiled at the first launch of its kind)."""
        if self.k:
            per_block = self._kernels.THREADS_PER_BLOCK
            self._kernel[-(-self.k // per_block), per_block](*self._args)

    def result(self) -> EnsembleResult:
        """Wait for the kernel; the statuses, steps, indicators and states at the stops, copied back."""
        if not self.k:
            return EnsembleResult(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64),
                                  np.zeros((0, N_COLUMNS)), self.systems.pos, self.systems.vel)
        self.cuda.synchronize()
        return EnsembleResult(self.status.copy_to_host(), self.steps.copy_to_host(), self.out.copy_to_host().T.copy(),
                              _host_layout(self.pos.copy_to_host()), _host_layout(self.vel.copy_to_host()))


def upload_ensemble(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float, dt: float,
                    n_steps: int, t_start: float = 0.0, escape_distance: float = np.inf,
                    radii: np.ndarray | None = None, watch: int = 1,
                    variation: tuple[np.ndarray, np.ndarray] | None = None,
                    scheme: str = "wisdom_holman") -> DeviceEnsemble:
    """Check K systems of N bodies as the CPU ensemble does and copy them to the GPU, ready to launch.

    Parameters as :func:`orbitsim.ensemble.run_ensemble`; ``scheme`` is one of :data:`GPU_SCHEMES`.
    ``wisdom_holman`` needs ``variation`` (its kernel carries the tangent vector: MEGNO and the Lyapunov
    time); ``leapfrog`` and ``verlet`` take none.

    Raises
    ------
    orbitsim.gpu.device.GPUUnavailableError
        Without numba-cuda or a CUDA device (the one line of :func:`~orbitsim.gpu.device.require_cuda`).
    ValueError
        For input the CPU ensemble would refuse, an unknown scheme, or a variation the scheme cannot take.
    """
    if scheme not in GPU_SCHEMES:
        raise ValueError(f"ensemble: scheme {scheme!r} has no GPU kernel; use one of {', '.join(GPU_SCHEMES)}")
    if scheme == "wisdom_holman" and variation is None:
        raise ValueError("ensemble: the GPU wisdom_holman kernel carries the tangent vector; give variation")
    if scheme != "wisdom_holman" and variation is not None:
        raise ValueError(f"ensemble: the GPU {scheme} kernel has no variational equations; give no variation")
    systems = prepare_systems(masses, positions, velocities, G=G, dt=dt, n_steps=n_steps,
                              escape_distance=escape_distance, radii=radii, watch=watch)
    k, n = systems.masses.shape
    tangent = None if variation is None else check_variation(variation, k, n)
    from orbitsim.gpu.device import require_cuda  # noqa: PLC0415 - lazy: loads numba-cuda

    return DeviceEnsemble(require_cuda(), systems, tangent, scheme, G, dt, t_start, n_steps, escape_distance, watch)


def run_ensemble_gpu(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                     **options: Any) -> EnsembleResult:
    """Run K systems of N bodies on the GPU, one thread per system: :func:`upload_ensemble` (its arguments
    and errors), launch, and the results copied back."""
    ensemble = upload_ensemble(masses, positions, velocities, **options)
    ensemble.launch()
    return ensemble.result()
