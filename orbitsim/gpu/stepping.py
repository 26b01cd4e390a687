"""The fixed-step schemes on the GPU: the state on the device, whole steps as kernel launches.

:class:`DeviceSystem` holds one system's (3, N) positions, velocities and accelerations, its masses
and the scratch a scheme needs, all in device memory, and steps them with the kernels of
:mod:`orbitsim.gpu.direct`. The host loop only launches kernels (they queue on the default stream
and run in order); it waits for the device only where it reads a result back: a sample's nine sums
(:meth:`DeviceSystem.sample`), the state (:meth:`DeviceSystem.download`) or :meth:`DeviceSystem.sync`.

The schemes are the CPU's, operation for operation (:mod:`orbitsim.integrators`): the same kicks,
drifts and stages in the same order, with the same coefficients, read from the CPU's records (the
leapfrog family's ``kicks``/``drifts`` tables, RK4's ``B_WEIGHTS``/``C_NODES``), never a copy. On
entry ``acc`` holds the accelerations at ``pos`` (every scheme but the leapfrog family reads them:
euler, semi-implicit Euler and RK4 as their first stage, verlet as its opening kick) and on exit
those at the final positions, as on the CPU. Only the force sum's order and the GPU's fused
multiply-adds differ (:mod:`orbitsim.gpu.direct`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from orbitsim.gpu.direct import SAMPLE_ROWS, DirectKernels, cuda, direct_kernels
from orbitsim.gpu.support import GPU_SCHEMES

#: The leapfrog family: drift-kick-drift compositions driven by their record's tables.
_COMPOSITIONS = ("leapfrog", "leapfrog4", "leapfrog6", "leapfrog8")


class Sums(NamedTuple):
    """A sample's reductions, read back from the device: energies, momenta and a finiteness check."""

    kinetic: float
    potential: float
    momentum: np.ndarray  # (3,)
    angular_momentum: np.ndarray  # (3,)
    non_finite: int  # bodies whose position or velocity is not finite

    @property
    def scalars(self) -> np.ndarray:
        """The 8 numbers of a CPU sample's ``scalars`` row (:data:`orbitsim.integrators.base.SCALAR_COLUMNS`)."""
        return np.concatenate([[self.kinetic, self.potential], self.momentum, self.angular_momentum])


class DeviceSystem:
    """One N-body system on the GPU, stepped by one fixed-step scheme.

    Parameters
    ----------
    masses : (N,) array
    pos, vel : (3, N) arrays
        Copied to the device.
    scheme : str
        A name of :data:`GPU_SCHEMES` (canonical registry name).
    G, eps2 : float
        Gravitational constant and the softening length squared.
    tile : int, optional
        Bodies per shared-memory tile (default :func:`orbitsim.gpu.direct.default_tile`).
    """

    def __init__(self, masses: np.ndarray, pos: np.ndarray, vel: np.ndarray, scheme: str, G: float, eps2: float,
                 tile: int | None = None) -> None:
        if scheme not in GPU_SCHEMES:
            raise ValueError(f"{scheme} does not run on the GPU; it runs {', '.join(GPU_SCHEMES)}")
        self.scheme = scheme
        self.k: DirectKernels = direct_kernels(tile)
        self.G = float(G)
        self.eps2 = float(eps2)
        self.n = int(np.asarray(masses).shape[0])
        self.grid = self.k.blocks(self.n)
        self.m = cuda.to_device(np.ascontiguousarray(masses, dtype=np.float64))
        self.pos = cuda.to_device(np.ascontiguousarray(pos, dtype=np.float64))
        self.vel = cuda.to_device(np.ascontiguousarray(vel, dtype=np.float64))
        self.acc = cuda.device_array((3, self.n), dtype=np.float64)
        self.rows = cuda.device_array((SAMPLE_ROWS, self.n), dtype=np.float64)
        self.sums = cuda.device_array(SAMPLE_ROWS, dtype=np.float64)
        # RK4's stages: x0, v0, the weighted sums of k_x and k_v, and the current k_x.
        self.work = [cuda.device_array((3, self.n), dtype=np.float64) for _ in range(5 if scheme == "rk4" else 0)]
        self.kicks = self.drifts = None
        if scheme in _COMPOSITIONS:
            from orbitsim.integrators.registry import get_integrator  # noqa: PLC0415 - the CPU record's tables

            record = get_integrator(scheme)
            self.kicks = [float(w) for w in record.kicks]
            self.drifts = [float(d) for d in record.drifts]
        self.rk4_tables: tuple[tuple[float, ...], tuple[float, ...]] | None = None
        if scheme == "rk4":
            from orbitsim.integrators.rk4 import B_WEIGHTS, C_NODES  # noqa: PLC0415 - the CPU tableau

            self.rk4_tables = (B_WEIGHTS, C_NODES)
        self.evaluate_accelerations()

    # -- the state ---------------------------------------------------------------------------------

    def evaluate_accelerations(self) -> None:
        """``acc`` = a(``pos``) (queued)."""
        self.k.accelerations[self.grid, self.k.tile](self.pos, self.m, self.G, self.eps2, self.acc)

    def upload(self, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray | None = None) -> None:
        """Replace the state with host (3, N) arrays; without ``acc`` it is evaluated at ``pos``."""
        self.pos.copy_to_device(np.ascontiguousarray(pos, dtype=np.float64))
        self.vel.copy_to_device(np.ascontiguousarray(vel, dtype=np.float64))
        if acc is None:
            self.evaluate_accelerations()
        else:
            self.acc.copy_to_device(np.ascontiguousarray(acc, dtype=np.float64))

    def download(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Host copies of (pos, vel, acc), each (3, N); waits for the queued steps."""
        return self.pos.copy_to_host(), self.vel.copy_to_host(), self.acc.copy_to_host()

    def sample(self) -> Sums:
        """The current state's energies and momenta, reduced on the device; nine numbers come back."""
        self.k.sample_rows[self.grid, self.k.tile](self.pos, self.vel, self.m, self.eps2, self.rows)
        self.k.reduce_rows[1, self.k.tile](self.rows, self.G, self.sums)
        s = self.sums.copy_to_host()
        return Sums(float(s[0]), float(s[1]), s[2:5].copy(), s[5:8].copy(), int(s[8]))

    @staticmethod
    def sync() -> None:
        """Wait for every queued kernel."""
        cuda.synchronize()

    # -- steps -------------------------------------------------------------------------------------

    def advance(self, steps: int, dt: float) -> None:
        """Queue ``steps`` whole steps of size ``dt``."""
        if steps <= 0:
            return
        step = {"euler": self._euler, "semi_implicit_euler": self._semi_implicit_euler, "verlet": self._verlet,
                "rk4": self._rk4}.get(self.scheme, self._composition)
        for _ in range(int(steps)):
            step(dt)

    def _launch(self, kernel: Any, *args: Any) -> None:
        kernel[self.grid, self.k.tile](*args)

    def _euler(self, dt: float) -> None:
        self._launch(self.k.euler_update, self.pos, self.vel, self.acc, dt)
        self.evaluate_accelerations()

    def _semi_implicit_euler(self, dt: float) -> None:
        self._launch(self.k.kick_drift, self.pos, self.vel, self.acc, dt, dt)
        self.evaluate_accelerations()

    def _verlet(self, dt: float) -> None:
        half_dt = 0.5 * dt
        self._launch(self.k.kick, self.vel, self.acc, half_dt)
        self._launch(self.k.drift, self.pos, self.vel, dt)
        self.evaluate_accelerations()
        self._launch(self.k.kick, self.vel, self.acc, half_dt)

    def _composition(self, dt: float) -> None:
        kicks, drifts = self.kicks, self.drifts
        self._launch(self.k.drift, self.pos, self.vel, dt * drifts[0])
        for s in range(len(kicks)):
            self.evaluate_accelerations()
            self._launch(self.k.kick_drift, self.pos, self.vel, self.acc, dt * kicks[s], dt * drifts[s + 1])

    def _rk4(self, dt: float) -> None:
        b_weights, c_nodes = self.rk4_tables
        x0, v0, sum_x, sum_v, k_x = self.work
        self._launch(self.k.rk4_begin, self.pos, self.vel, x0, v0, k_x, sum_x, sum_v)
        for s in range(3):
            self._launch(self.k.rk4_stage, self.pos, x0, v0, k_x, self.acc, c_nodes[s] * dt, b_weights[s], sum_x,
                         sum_v)
            self.evaluate_accelerations()
        self._launch(self.k.rk4_finish, self.pos, self.vel, x0, v0, k_x, self.acc, sum_x, sum_v, dt, b_weights[3])
        self.evaluate_accelerations()
