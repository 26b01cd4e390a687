"""Direct-summation Newtonian gravity with Plummer softening (jitted).

The acceleration of body i is

    a_i = G * sum_{j != i} m_j (x_j - x_i) / (|x_j - x_i|^2 + eps^2)^(3/2)

computed in float64. Zero-mass test bodies feel gravity and exert none (their m_j is 0).

Layout: positions, velocities and accelerations are ``(3, N)`` C-contiguous arrays, so each
coordinate is its own contiguous row (structure of arrays: 4.4x faster than ``(N, 3)`` here).

Each pair is computed once (Newton's third law): row i sums over j > i and scatters the equal and
opposite term into j. The rows are cut into ``n_blocks(N)`` blocks of about equal pair counts; each
block accumulates into its own private slab and the slabs are added in block order.
The block partition depends on N only, never on the thread count, so the serial and the ``prange``
kernel produce identical bits, and so do 1 and 2 threads.

Speed (2 cores, float64): the loop is bound by the square-root/division unit. Three regimes, each
measured (benchmarks/README.md):

* N <= :data:`SMALL_N_MAX`: a step is latency, not arithmetic. :func:`all_pairs_accelerations`
  sums over all ordered pairs (each pair twice, the self term masked): no third-law scatter into
  a[j] that the next row reloads, no per-row vector prologue; 2x faster than the third-law rows
  at N = 5.
* N < :data:`PARALLEL_MIN_N`: the third-law rows in one block, on one thread.
* from :data:`PARALLEL_MIN_N` up: the blocks spread over the threads.

Every path is used by the serial and the parallel kernel alike (the parallel one hands a single
block to the serial one), so the two stay bit-identical for every N and every partition.

A stop (Ctrl-C, SIGTERM) reaches the row loops through :func:`orbitsim._jit.stop_requested`: they
look at it before every pair of rows and return early, so a force evaluation that takes minutes at
N = 10^6 ends within milliseconds of the request; the caller throws the step away
(:mod:`orbitsim.stopping`). Only :func:`all_pairs_accelerations` (N <= 48: nanoseconds) does not look.

The force context that names which of these kernels a run calls is
:mod:`orbitsim.physics.force_context`'s.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_force, jit_parallel, stop_requested

#: Smallest N for which the parallel kernel is faster than the serial one on this machine
#: (measured crossover: see benchmarks/README.md; at N = 128 the thread start-up still dominates).
#: Re-measured with the two-row kernel: 16 blocks on 2 threads tie the one-block rows at N = 192-256
#: and beat them by 9% at 384, 23% at 512. The margin is kept on purpose: on a busy machine every
#: parallel region can wait a scheduler timeslice for its second thread.
PARALLEL_MIN_N = 384

#: Largest N summed over all ordered pairs by :func:`all_pairs_accelerations` (one block only).
#: Measured per evaluation on one core: 2x the rows' speed at N = 5 and 16, 1.1x at 48; the rows
#: win from about 56 (exact crossover 40-64, it alternates with the vector width; benchmarks/README.md).
SMALL_N_MAX = 48

#: Number of row blocks for large N: enough to balance 2-16 threads, few enough that adding the
#: private slabs (B * 3 * N doubles) stays a few percent of the pair loop.
MAX_BLOCKS = 16


def n_blocks(n: int) -> int:
    """Number of row blocks used for N bodies (a function of N alone, for reproducibility)."""
    if n < PARALLEL_MIN_N:
        return 1
    return MAX_BLOCKS


def block_bounds(n: int) -> np.ndarray:
    """Row boundaries ``(B + 1,)`` that split the N(N-1)/2 pairs into blocks of about equal size.

    Row i owns N - 1 - i pairs, so the cumulative count up to row i is i*N - i*(i+1)/2.
    """
    blocks = n_blocks(n)
    total = n * (n - 1) / 2.0
    bounds = np.zeros(blocks + 1, dtype=np.int64)
    for b in range(1, blocks):
        target = total * b / blocks
        # Solve i*N - i*(i+1)/2 = target for i (smaller root of the quadratic).
        disc = (2.0 * n - 1.0) ** 2 - 8.0 * target
        bounds[b] = int(np.floor(((2.0 * n - 1.0) - np.sqrt(max(disc, 0.0))) / 2.0))
    bounds[blocks] = n
    return np.maximum.accumulate(bounds)


def force_scratch(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Allocate the per-block slabs ``(B, 3, N)`` and the bounds for an N-body force kernel."""
    blocks = n_blocks(n)
    slabs = np.zeros((blocks if blocks > 1 else 0, 3, n))
    return slabs, block_bounds(n)


@jit_force
def _accumulate_row(x, y, z, m, eps2, i, ax, ay, az):
    """Add the pair terms of row i (pairs i < j) into (ax, ay, az), without the factor G.

    The inner index runs over an unsigned range: with a signed index LLVM emitted gathers
    (1.8x slower); unsigned, it emits contiguous vector loads.
    """
    n = x.shape[0]
    xi = x[i]
    yi = y[i]
    zi = z[i]
    mi = m[i]
    axi = 0.0
    ayi = 0.0
    azi = 0.0
    for j in range(np.uint64(i + 1), np.uint64(n)):
        dx = x[j] - xi
        dy = y[j] - yi
        dz = z[j] - zi
        r2 = dx * dx + dy * dy + dz * dz + eps2
        inv_r3 = 1.0 / (r2 * np.sqrt(r2))
        mj_inv_r3 = m[j] * inv_r3
        mi_inv_r3 = mi * inv_r3
        axi += mj_inv_r3 * dx
        ayi += mj_inv_r3 * dy
        azi += mj_inv_r3 * dz
        ax[j] -= mi_inv_r3 * dx
        ay[j] -= mi_inv_r3 * dy
        az[j] -= mi_inv_r3 * dz
    ax[i] += axi
    ay[i] += ayi
    az[i] += azi


@jit_force
def _accumulate_rows(x, y, z, m, eps2, i_start, i_stop, ax, ay, az):
    """Add the pair terms of rows [i_start, i_stop) into (ax, ay, az), without the factor G.

    Rows go two at a time: both rows share each load of x_j, y_j, z_j, m_j and each update of
    a_j, which cut the loop's memory operations per pair by almost half and made it 4% faster
    per core at N = 1024 ... 16384 (it is bound by the square-root/division unit, at about 80% of
    it). The tiling starts at ``i_start``, a function of N alone, so the sums stay deterministic.
    An odd last row goes alone.

    Before each pair of rows it looks at :func:`~orbitsim._jit.stop_requested` (one atomic load per
    2N pairs, outside the vectorised j-loop) and returns at once when a stop is asked: at N = 10^6
    the next look is a few milliseconds away, where the whole sum takes minutes. The sum is then
    incomplete and the caller discards the call (:func:`orbitsim.stopping.run_interruptible`).
    """
    n = x.shape[0]
    # Callers pass ``i_start`` as a run-time int64 (``bounds[b]``, ``np.int64(0)``), never a literal 0:
    # Numba compiles a callee once per literal, and this loop compiled twice in every run with
    # N > SMALL_N_MAX (0.4 s of CPU). The clamp (a no-op: starts are >= 0) tells LLVM that every row
    # index is non-negative, as the literal did: without it the one-block sum ran 1-3% slower at
    # N = 50-256 (benchmarks/README.md, "One compile of the row loop").
    i = max(i_start, 0)
    while i + 1 < i_stop:
        if stop_requested():
            return
        xa = x[i]
        ya = y[i]
        za = z[i]
        ma = m[i]
        xb = x[i + 1]
        yb = y[i + 1]
        zb = z[i + 1]
        mb = m[i + 1]
        dx = xb - xa
        dy = yb - ya
        dz = zb - za
        r2 = dx * dx + dy * dy + dz * dz + eps2
        inv_r3 = 1.0 / (r2 * np.sqrt(r2))
        axa, aya, aza = mb * inv_r3 * dx, mb * inv_r3 * dy, mb * inv_r3 * dz
        axb, ayb, azb = -ma * inv_r3 * dx, -ma * inv_r3 * dy, -ma * inv_r3 * dz
        for j in range(np.uint64(i + 2), np.uint64(n)):
            xj = x[j]
            yj = y[j]
            zj = z[j]
            dxa, dya, dza = xj - xa, yj - ya, zj - za
            dxb, dyb, dzb = xj - xb, yj - yb, zj - zb
            r2a = dxa * dxa + dya * dya + dza * dza + eps2
            r2b = dxb * dxb + dyb * dyb + dzb * dzb + eps2
            inv_a = 1.0 / (r2a * np.sqrt(r2a))
            inv_b = 1.0 / (r2b * np.sqrt(r2b))
            wa, wb = m[j] * inv_a, m[j] * inv_b
            axa, aya, aza = axa + wa * dxa, aya + wa * dya, aza + wa * dza
            axb, ayb, azb = axb + wb * dxb, ayb + wb * dyb, azb + wb * dzb
            va, vb = ma * inv_a, mb * inv_b
            ax[j] -= va * dxa + vb * dxb
            ay[j] -= va * dya + vb * dyb
            az[j] -= va * dza + vb * dzb
        ax[i] += axa
        ay[i] += aya
        az[i] += aza
        ax[i + 1] += axb
        ay[i + 1] += ayb
        az[i + 1] += azb
        i += 2
    if i < i_stop:
        _accumulate_row(x, y, z, m, eps2, i, ax, ay, az)


@jit_force
def all_pairs_accelerations(pos, m, G, eps2, acc):
    """a_i = G sum_{j != i} m_j (x_j - x_i) / r_ij^3 over all ordered pairs, written (not added)
    into ``acc``. For a handful of bodies: see the module docstring.

    It indexes the (3, N) arrays directly instead of taking row views: a view costs an atomic
    reference-count increment and decrement per call, which at N = 5 is a measurable part of a step.
    The self term has dx = dy = dz = 0 and, unsoftened, a quotient of inf: it is masked to 0 rather
    than skipped, so the j-loop stays one contiguous vectorisable loop.
    """
    n = pos.shape[1]
    for i in range(n):
        xi = pos[0, i]
        yi = pos[1, i]
        zi = pos[2, i]
        axi = 0.0
        ayi = 0.0
        azi = 0.0
        for j in range(n):
            dx = pos[0, j] - xi
            dy = pos[1, j] - yi
            dz = pos[2, j] - zi
            r2 = dx * dx + dy * dy + dz * dz + eps2
            s = m[j] / (r2 * np.sqrt(r2))
            if j == i:
                s = 0.0
            axi += s * dx
            ayi += s * dy
            azi += s * dz
        acc[0, i] = G * axi
        acc[1, i] = G * ayi
        acc[2, i] = G * azi


@jit
def _scale(acc, G):
    for c in range(3):
        for i in range(acc.shape[1]):
            acc[c, i] *= G


@jit
def _zero_from(slab, lo):
    """Zero columns ``lo:`` of one block's slab: rows i >= lo touch no column below lo."""
    for c in range(3):
        for j in range(lo, slab.shape[1]):
            slab[c, j] = 0.0


@jit
def _combine_blocks(slabs, bounds, G, acc):
    """``acc = G * (0 + slabs[0] + slabs[1] + ...)``, every element summed in block order.

    Exact arithmetic (plain :func:`jit`): under ``reassoc`` LLVM reorders the block sum and the
    kernels stop matching bit for bit. The loop runs block by block over contiguous rows (it used
    to run over blocks innermost, a stride of 3N doubles: 10x slower, and a second parallel region
    per evaluation). Columns below ``bounds[b]`` of block b hold exact zeros; a sum that starts at
    +0.0 is unchanged by adding +0.0, so skipping them gives the same bits.
    """
    n = acc.shape[1]
    for c in range(3):
        for j in range(n):
            acc[c, j] = 0.0
    for b in range(slabs.shape[0]):
        for c in range(3):
            for j in range(bounds[b], n):
                acc[c, j] += slabs[b, c, j]
    _scale(acc, G)


@jit
def accelerations_serial(pos, m, G, eps2, acc, slabs, bounds):
    """Accelerations at ``pos`` into ``acc`` (3, N), in place, on one thread.

    ``slabs`` (B, 3, N) and ``bounds`` (B + 1,) come from :func:`force_scratch`; with one block the
    slabs are empty and the sum goes straight into ``acc``.
    """
    blocks = bounds.shape[0] - 1
    if blocks == 1 and pos.shape[1] <= SMALL_N_MAX:
        all_pairs_accelerations(pos, m, G, eps2, acc)
        return
    if blocks == 1:
        acc[:, :] = 0.0
        _accumulate_rows(pos[0], pos[1], pos[2], m, eps2, np.int64(0), pos.shape[1], acc[0], acc[1], acc[2])
        _scale(acc, G)
        return
    for b in range(blocks):
        slab = slabs[b]
        _zero_from(slab, bounds[b])
        _accumulate_rows(pos[0], pos[1], pos[2], m, eps2, bounds[b], bounds[b + 1], slab[0], slab[1], slab[2])
    _combine_blocks(slabs, bounds, G, acc)


@jit
def accelerations_rows(pos, m, G, eps2, acc):
    """Accelerations at ``pos`` into ``acc`` (3, N), in place: one block of third-law rows on one thread,
    :func:`accelerations_serial`'s path for ``SMALL_N_MAX < N`` and one block, alone.

    The :class:`~orbitsim.physics.force_context.Rows` context calls it, so a run of that N compiles
    neither the all-pairs kernel nor the slabs' code of the other paths (about a second of a first run).
    """
    acc[:, :] = 0.0
    # np.int64(0), not the literal 0: the blocks' calls pass an int64, and a literal would compile the rows again
    _accumulate_rows(pos[0], pos[1], pos[2], m, eps2, np.int64(0), pos.shape[1], acc[0], acc[1], acc[2])
    _scale(acc, G)


@jit
def accelerations_parallel(pos, m, G, eps2, acc, slabs, bounds):
    """As :func:`accelerations_serial`, with the blocks spread over Numba's threads.

    Every block writes its private slab; the slabs are then added in block order on the calling
    thread (about 1% of an evaluation at N = 4096, and one parallel region per evaluation instead
    of two: on a shared machine every region waits for its slowest thread), so the result is
    bit-identical to the serial kernel and independent of the thread count.
    """
    if bounds.shape[0] == 2:  # nothing to spread: the serial kernel, so the bits are the same by construction
        accelerations_serial(pos, m, G, eps2, acc, slabs, bounds)
        return
    accelerations_blocks(pos, m, G, eps2, acc, slabs, bounds)


@jit_parallel
def accelerations_blocks(pos, m, G, eps2, acc, slabs, bounds):
    """:func:`accelerations_parallel` for two blocks or more, alone: the
    :class:`~orbitsim.physics.force_context.Blocks` context calls it, so a run of that N compiles neither
    the serial kernel nor the all-pairs one (a second and a half of a first run at N = 1000)."""
    blocks = bounds.shape[0] - 1
    for b in prange(blocks):
        slab = slabs[b]
        _zero_from(slab, bounds[b])
        _accumulate_rows(pos[0], pos[1], pos[2], m, eps2, bounds[b], bounds[b + 1], slab[0], slab[1], slab[2])
    _combine_blocks(slabs, bounds, G, acc)


@jit
def accelerations(pos, m, G, eps2, acc, slabs, bounds):
    """Accelerations at ``pos`` into ``acc``: the serial kernel for one block, else the parallel.

    This is the kernel every integrator step calls (as a module global, so callers cache). Once a
    stop is asked (:func:`~orbitsim._jit.stop_requested`) it returns at once, ``acc`` untouched:
    the steps left in a call that is being undone then cost O(N) each, not O(N^2).
    """
    if stop_requested():
        return
    if bounds.shape[0] == 2:
        accelerations_serial(pos, m, G, eps2, acc, slabs, bounds)
    else:
        accelerations_parallel(pos, m, G, eps2, acc, slabs, bounds)
