"""The front door of the GPU ensemble: check K systems as the CPU ensemble does, run them on the GPU.

:func:`run_ensemble_gpu` takes the arguments of :func:`orbitsim.ensemble.run_ensemble` (plus ``scheme``),
checks them with the same :func:`~orbitsim.ensemble.run.prepare_systems`, lays them out with the system
index last, copies them to the device once, launches one thread per system
(:mod:`orbitsim.gpu.ensemble_kernels`) and copies the results back once: an
:class:`~orbitsim.ensemble.run.EnsembleResult` with the CPU ensemble's statuses and indicator columns.

Schemes: ``wisdom_holman`` (Jacobi coordinates, no corrector) with its tangent map, MEGNO and the mLCE,
as the CPU ensemble's variational kernel and ``orbitsim map``; ``leapfrog`` (drift-kick-drift) and ``verlet``
(velocity Verlet, kick-drift-kick) with the same stops and the other indicators (``megno`` and ``lyapunov``
NaN).
"""

from __future__ import annotations

import numpy as np

from orbitsim.ensemble.run import EnsembleResult, check_variation, prepare_systems
from orbitsim.ensemble.status import N_COLUMNS

__all__ = ["GPU_SCHEMES", "run_ensemble_gpu"]

#: The schemes the GPU ensemble runs.
GPU_SCHEMES = ("wisdom_holman", "leapfrog", "verlet")


def _device_layout(a: np.ndarray) -> np.ndarray:
    """(K, ...) -> (..., K), contiguous: the system index innermost, as the kernels read it."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1))


def _host_layout(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.moveaxis(a, -1, 0))


def run_ensemble_gpu(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float, dt: float,
                     n_steps: int, t_start: float = 0.0, escape_distance: float = np.inf,
                     radii: np.ndarray | None = None, watch: int = 1,
                     variation: tuple[np.ndarray, np.ndarray] | None = None,
                     scheme: str = "wisdom_holman") -> EnsembleResult:
    """Run K systems of N bodies on the GPU, one thread per system.

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

    cuda = require_cuda()
    from orbitsim.gpu import ensemble_kernels  # noqa: PLC0415 - lazy: loads numba-cuda

    status = np.zeros(k, dtype=np.int64)
    steps = np.zeros(k, dtype=np.int64)
    out = np.zeros((N_COLUMNS, k))
    if k == 0:
        return EnsembleResult(status, steps, out.T.copy(), systems.pos, systems.vel)
    d = {name: cuda.to_device(_device_layout(value)) for name, value in
         (("pos", systems.pos), ("vel", systems.vel), ("m", systems.masses), ("weights", systems.weights),
          ("mu", systems.mu), ("radii", systems.radii))}
    d_status, d_steps, d_out = cuda.to_device(status), cuda.to_device(steps), cuda.to_device(out)
    scalars = (float(G), float(dt), float(t_start), np.int64(n_steps), float(escape_distance) ** 2,
               bool(systems.check_collisions))
    per_block = ensemble_kernels.THREADS_PER_BLOCK
    blocks = -(-k // per_block)
    if tangent is not None:
        d_dpos, d_dvel = cuda.to_device(_device_layout(tangent[0])), cuda.to_device(_device_layout(tangent[1]))
        ensemble_kernels.wh_variational_kernel(n, int(watch))[blocks, per_block](
            d["pos"], d["vel"], d_dpos, d_dvel, d["m"], d["weights"], d["mu"], d["radii"], *scalars, d_status,
            d_steps, d_out)
    else:
        ensemble_kernels.fixed_step_kernel(n, int(watch), scheme)[blocks, per_block](
            d["pos"], d["vel"], d["m"], d["weights"], d["mu"], d["radii"], *scalars, d_status, d_steps, d_out)
    cuda.synchronize()
    return EnsembleResult(d_status.copy_to_host(), d_steps.copy_to_host(), d_out.copy_to_host().T.copy(),
                          _host_layout(d["pos"].copy_to_host()), _host_layout(d["vel"].copy_to_host()))
