"""FP64 direct-sum gravity on one CUDA GPU: accelerations, a sample's sums, and the steps' updates.

The acceleration of body i is, as on the CPU (:mod:`orbitsim.physics.gravity`),

    a_i = G * sum_{j != i} m_j (x_j - x_i) / (|x_j - x_i|^2 + eps^2)^(3/2)

with Plummer softening eps (``eps2`` = eps^2), in float64. One thread owns one body i and sums over
every j in order 0, 1, ..., N-1 (no third law: on a GPU the scatter into a_j would need atomics and
would make the sum's order depend on scheduling). The j-bodies pass through shared memory a tile of
``tile`` bodies at a time (:data:`TILE`, 256 on hardware): each thread of the block loads one body of
the tile, the block waits, and every thread then reads all of the tile from shared memory. Full tiles
run an inner loop of constant length (unrolled by the compiler); the last, partial tile its own loop.

``1 / r^3`` is ``rsqrt(r^2)^3`` through ``numba.cuda.libdevice.rsqrt`` (measured 1.4x over
``1.0 / math.sqrt`` in numba-cuda on an H100: issue 30). Numba's CUDA simulator has no libdevice
(its ``rsqrt`` is a stub that returns None), so under the simulator the same kernels use
``1.0 / math.sqrt(r2)``. Either way the results are not bitwise those of the CPU kernels: the order
of the sum differs (the CPU uses the third law), the GPU compiler fuses multiply-adds, and ``rsqrt``
is not a correctly rounded ``1 / sqrt``. They agree to round-off (tests/gpu/).

A sample is reduced on the device: :func:`DirectKernels.sample_rows` writes each body's kinetic
energy, potential row sum, momentum and angular momentum (and whether its state is finite) into a
(9, N) array, and :func:`DirectKernels.reduce_rows`, one block, adds those rows in a fixed order
(thread t takes bodies t, t + tile, ..., then one tree in shared memory for the nine rows): deterministic, no atomics,
and only nine numbers come back to the host. The potential uses the same tiles as the force:
U = -G/2 sum_i m_i sum_{j != i} m_j / r_ij.

Arrays are the CPU's layout: (3, N) float64 positions, velocities, accelerations, (N,) masses.
Importing this module needs a usable device or the simulator (:func:`orbitsim.gpu.device.require_cuda`).
"""

from __future__ import annotations

import functools
import warnings
from typing import Any, NamedTuple

from numba import float64
from numba.core.errors import NumbaPerformanceWarning

from orbitsim._jit import cuda_device, cuda_kernel
from orbitsim.gpu.device import require_cuda, simulated
from orbitsim.gpu.rsqrt import rsqrt

cuda = require_cuda()

# A grid of few blocks is what a small N needs (one block per 256 bodies); numba-cuda would warn of low
# occupancy at every launch configuration below 128 blocks, i.e. on stderr of every run below N = 32,768.
warnings.filterwarnings("ignore", message="Grid size .* under-utilization", category=NumbaPerformanceWarning)

#: Bodies per shared-memory tile and threads per block on hardware (issue 30's measured kernel: 256).
TILE = 256

#: Tile under Numba's CUDA simulator, which runs every thread of a block as a Python thread: 32 keeps
#: a block's threads few, and with 40-64 test bodies still gives several tiles and a partial last one.
SIM_TILE = 32

#: Rows of :func:`DirectKernels.sample_rows`: T, the potential row sum, P (3), L (3), non-finite flag.
SAMPLE_ROWS = 9

#: Largest finite float64: |x| <= DBL_MAX is False exactly for NaN and +-inf.
DBL_MAX = 1.7976931348623157e308


def default_tile() -> int:
    """The tile the kernels use here: :data:`TILE` on a GPU, :data:`SIM_TILE` under the simulator."""
    return SIM_TILE if simulated() else TILE


class DirectKernels(NamedTuple):
    """The compiled kernels for one tile size (:func:`direct_kernels`); launch ``[blocks(n), tile]``
    except ``reduce_rows``, which is one block: ``[1, tile]``."""

    tile: int
    accelerations: Any  # (pos, m, G, eps2, acc): acc = a(pos)
    sample_rows: Any  # (pos, vel, m, eps2, rows): rows (9, N), see the module docstring
    reduce_rows: Any  # (rows, G, out): out (9,) = T, U, P, L, count of non-finite bodies
    kick: Any  # (vel, acc, h): v += h a
    drift: Any  # (pos, vel, h): x += h v
    kick_drift: Any  # (pos, vel, acc, h_kick, h_drift): v += h_kick a, then x += h_drift v
    euler_update: Any  # (pos, vel, acc, dt): x += dt v_old, v += dt a
    rk4_begin: Any  # (pos, vel, x0, v0, k_x, sum_x, sum_v)
    rk4_stage: Any  # (pos, x0, v0, k_x, acc, h, weight, sum_x, sum_v)
    rk4_finish: Any  # (pos, vel, x0, v0, k_x, acc, sum_x, sum_v, dt, last)

    def blocks(self, n: int) -> int:
        """Blocks of ``tile`` threads that cover ``n`` bodies."""
        return max(1, (n + self.tile - 1) // self.tile)


@functools.cache
def direct_kernels(tile: int | None = None) -> DirectKernels:
    """The kernels with ``tile`` bodies per shared-memory tile (default :func:`default_tile`); a power of
    two (the sample reduction halves it) of at least 16 (one thread writes each of the nine sums).
    Compiled on first launch, once per process and tile."""
    tile = default_tile() if tile is None else int(tile)
    if tile < 16 or tile & (tile - 1):
        raise ValueError(f"tile must be a power of two >= 16, got {tile}")
    return DirectKernels(tile, *_build(tile))


def _build(tile: int) -> tuple[Any, ...]:
    """Compile-on-launch kernels over the constant ``tile`` (the shared arrays' size must be constant)."""

    @cuda_device
    def pair_accel(xi, yi, zi, xj, yj, zj, mj, eps2):
        dx = xj - xi
        dy = yj - yi
        dz = zj - zi
        inv = rsqrt(dx * dx + dy * dy + dz * dz + eps2)
        s = mj * (inv * inv * inv)
        return s * dx, s * dy, s * dz

    @cuda_device
    def pair_potential(xi, yi, zi, xj, yj, zj, mj, eps2):
        dx = xj - xi
        dy = yj - yi
        dz = zj - zi
        return mj * rsqrt(dx * dx + dy * dy + dz * dz + eps2)

    @cuda_kernel
    def accelerations(pos, m, G, eps2, acc):
        sx = cuda.shared.array(tile, float64)
        sy = cuda.shared.array(tile, float64)
        sz = cuda.shared.array(tile, float64)
        sm = cuda.shared.array(tile, float64)
        n = m.shape[0]
        t = cuda.threadIdx.x
        i = cuda.blockIdx.x * tile + t
        xi = yi = zi = 0.0
        if i < n:
            xi = pos[0, i]
            yi = pos[1, i]
            zi = pos[2, i]
        ax = ay = az = 0.0
        for base in range(0, n, tile):
            j = base + t
            if j < n:
                sx[t] = pos[0, j]
                sy[t] = pos[1, j]
                sz[t] = pos[2, j]
                sm[t] = m[j]
            cuda.syncthreads()
            if base + tile <= n and (i < base or i >= base + tile):  # a full tile without body i
                for k in range(tile):
                    fx, fy, fz = pair_accel(xi, yi, zi, sx[k], sy[k], sz[k], sm[k], eps2)
                    ax += fx
                    ay += fy
                    az += fz
            else:
                for k in range(min(tile, n - base)):
                    if base + k != i:
                        fx, fy, fz = pair_accel(xi, yi, zi, sx[k], sy[k], sz[k], sm[k], eps2)
                        ax += fx
                        ay += fy
                        az += fz
            cuda.syncthreads()
        if i < n:
            acc[0, i] = G * ax
            acc[1, i] = G * ay
            acc[2, i] = G * az

    @cuda_kernel
    def sample_rows(pos, vel, m, eps2, rows):
        sx = cuda.shared.array(tile, float64)
        sy = cuda.shared.array(tile, float64)
        sz = cuda.shared.array(tile, float64)
        sm = cuda.shared.array(tile, float64)
        n = m.shape[0]
        t = cuda.threadIdx.x
        i = cuda.blockIdx.x * tile + t
        xi = yi = zi = 0.0
        if i < n:
            xi = pos[0, i]
            yi = pos[1, i]
            zi = pos[2, i]
        u = 0.0
        for base in range(0, n, tile):
            j = base + t
            if j < n:
                sx[t] = pos[0, j]
                sy[t] = pos[1, j]
                sz[t] = pos[2, j]
                sm[t] = m[j]
            cuda.syncthreads()
            if base + tile <= n and (i < base or i >= base + tile):
                for k in range(tile):
                    u += pair_potential(xi, yi, zi, sx[k], sy[k], sz[k], sm[k], eps2)
            else:
                for k in range(min(tile, n - base)):
                    if base + k != i:
                        u += pair_potential(xi, yi, zi, sx[k], sy[k], sz[k], sm[k], eps2)
            cuda.syncthreads()
        if i < n:
            mi = m[i]
            vx = vel[0, i]
            vy = vel[1, i]
            vz = vel[2, i]
            rows[0, i] = 0.5 * mi * (vx * vx + vy * vy + vz * vz)
            rows[1, i] = mi * u
            rows[2, i] = mi * vx
            rows[3, i] = mi * vy
            rows[4, i] = mi * vz
            rows[5, i] = mi * (yi * vz - zi * vy)
            rows[6, i] = mi * (zi * vx - xi * vz)
            rows[7, i] = mi * (xi * vy - yi * vx)
            finite = (abs(xi) <= DBL_MAX and abs(yi) <= DBL_MAX and abs(zi) <= DBL_MAX
                      and abs(vx) <= DBL_MAX and abs(vy) <= DBL_MAX and abs(vz) <= DBL_MAX)
            rows[8, i] = 0.0 if finite else 1.0

    @cuda_kernel
    def reduce_rows(rows, G, out):
        partial = cuda.shared.array((SAMPLE_ROWS, tile), float64)  # 18 KiB at tile 256
        n = rows.shape[1]
        t = cuda.threadIdx.x
        for q in range(SAMPLE_ROWS):
            s = 0.0
            for i in range(t, n, tile):
                s += rows[q, i]
            partial[q, t] = s
        cuda.syncthreads()
        width = tile // 2
        while width > 0:  # one tree for all nine rows: one barrier a level
            if t < width:
                for q in range(SAMPLE_ROWS):
                    partial[q, t] += partial[q, t + width]
            cuda.syncthreads()
            width //= 2
        if t < SAMPLE_ROWS:
            out[t] = -0.5 * G * partial[1, 0] if t == 1 else partial[t, 0]

    @cuda_kernel
    def kick(vel, acc, h):
        i = cuda.grid(1)
        if i < vel.shape[1]:
            for c in range(3):
                vel[c, i] += h * acc[c, i]

    @cuda_kernel
    def drift(pos, vel, h):
        i = cuda.grid(1)
        if i < pos.shape[1]:
            for c in range(3):
                pos[c, i] += h * vel[c, i]

    @cuda_kernel
    def kick_drift(pos, vel, acc, h_kick, h_drift):
        i = cuda.grid(1)
        if i < pos.shape[1]:
            for c in range(3):
                v_new = vel[c, i] + h_kick * acc[c, i]
                vel[c, i] = v_new
                pos[c, i] += h_drift * v_new

    @cuda_kernel
    def euler_update(pos, vel, acc, dt):
        i = cuda.grid(1)
        if i < pos.shape[1]:
            for c in range(3):
                v_old = vel[c, i]
                vel[c, i] = v_old + dt * acc[c, i]
                pos[c, i] += dt * v_old

    @cuda_kernel
    def rk4_begin(pos, vel, x0, v0, k_x, sum_x, sum_v):
        i = cuda.grid(1)
        if i < pos.shape[1]:
            for c in range(3):
                x0[c, i] = pos[c, i]
                v0[c, i] = vel[c, i]
                k_x[c, i] = vel[c, i]
                sum_x[c, i] = 0.0
                sum_v[c, i] = 0.0

    @cuda_kernel
    def rk4_stage(pos, x0, v0, k_x, acc, h, weight, sum_x, sum_v):
        i = cuda.grid(1)
        if i < pos.shape[1]:
            for c in range(3):
                kx = k_x[c, i]
                kv = acc[c, i]
                sum_x[c, i] += weight * kx
                sum_v[c, i] += weight * kv
                pos[c, i] = x0[c, i] + h * kx
                k_x[c, i] = v0[c, i] + h * kv

    @cuda_kernel
    def rk4_finish(pos, vel, x0, v0, k_x, acc, sum_x, sum_v, dt, last):
        i = cuda.grid(1)
        if i < pos.shape[1]:
            for c in range(3):
                pos[c, i] = x0[c, i] + dt * (sum_x[c, i] + last * k_x[c, i])
                vel[c, i] = v0[c, i] + dt * (sum_v[c, i] + last * acc[c, i])

    return (accelerations, sample_rows, reduce_rows, kick, drift, kick_drift, euler_update, rk4_begin, rk4_stage,
            rk4_finish)
