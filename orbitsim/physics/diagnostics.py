"""Conserved quantities of the N-body problem (jitted, exact arithmetic).

* kinetic energy   T = sum_i m_i |v_i|^2 / 2
* potential energy U = - sum_{i<j} G m_i m_j / sqrt(|x_i - x_j|^2 + eps^2)
* total energy     E = T + U
* momentum         P = sum_i m_i v_i
* angular momentum L = sum_i m_i x_i x v_i   (about the origin)
* centre of mass   X = sum_i m_i x_i / sum_i m_i

Arrays are ``(3, N)`` as in :mod:`orbitsim.physics.gravity`. The potential is summed per row i
(a private partial for each row), then the partials are added in row order: the result is
deterministic and the same on any number of threads.

The parallel potential (a sample's cost at large N) looks at :func:`orbitsim._jit.stop_requested`
before each row, as the force loop does, so a stop reaches it within a row of N terms.

The potential is exact arithmetic: the compiler may not reorder its sum. Its order is fixed here
instead: each row's terms m_j / r_ij (j > i, in order) go round-robin into four partial sums,
added as (s0 + s1) + (s2 + s3). The terms are computed a block of :data:`TERM_BLOCK` at a time into
a buffer, where the square roots and divisions run as vector instructions (each is correctly
rounded, so a lane gives the bits of the scalar operation); the four chains of additions then run
at the adders' throughput instead of one addition per 3-cycle latency. One evaluation at
N = 16384 on one core: 0.53 s with one chain and a signed term index (LLVM emitted gathers),
0.23 s with an unsigned index, 0.14 s with four chains. The parallel version deals the rows out
in strides, so every thread gets a fair share of the triangle: split into halves, the first
thread had three quarters of it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_inline, jit_parallel_exact, overload_inline, stop_requested
from orbitsim.physics.force_context import AllPairs, Blocks, Rows, kernel_class
from orbitsim.physics.gravity import SMALL_N_MAX

#: Above this N the O(N^2) potential runs its rows in parallel (its rows are independent).
PARALLEL_POTENTIAL_MIN_N = 384

#: Terms per buffered block: 2 KiB, which stays in L1 next to the four position/mass streams.
TERM_BLOCK = 256

#: From this N on the serial potential buffers its terms: the N at which the force leaves the all-pairs
#: kernel (SMALL_N_MAX + 1), so a force context's kind names one potential path to compile. Below it a row
#: is too short for the vector loop to pay for its buffer and per-row calls; from 49 bodies on the buffered
#: rows were already faster (N = 49, 56, 63: 9-12, 14-16, 17-18 us a sample against 14, 19, 24-26).
BUFFERED_POTENTIAL_MIN_N = SMALL_N_MAX + 1

#: Row strides of the parallel potential: chunk c takes rows c, c + S, c + 2S, ... so the chunks
#: hold nearly equal shares of the N(N-1)/2 terms whatever the thread count.
POTENTIAL_STRIDES = 64


@jit_inline
def kinetic_energy(vel, m):
    """Kinetic energy sum m v^2 / 2 of velocities ``vel`` (3, N) and masses ``m`` (N,)."""
    total = 0.0
    for i in range(m.shape[0]):
        total += 0.5 * m[i] * (vel[0, i] * vel[0, i] + vel[1, i] * vel[1, i] + vel[2, i] * vel[2, i])
    return total


@jit_inline
def _add_in_four_lanes(buf, count, s0, s1, s2, s3):
    """Add ``buf[:count]`` to four running sums: term k goes to sum k mod 4, in order.

    This is the potential's fixed order of addition (each row is ``(s0 + s1) + (s2 + s3)``):
    four independent chains of exact additions instead of one, so the sum runs at the adders'
    throughput rather than at one addition per 3-cycle latency. ``count`` is a multiple of 4
    except in a row's last block.
    """
    k = 0
    while k + 4 <= count:
        s0 += buf[k]
        s1 += buf[k + 1]
        s2 += buf[k + 2]
        s3 += buf[k + 3]
        k += 4
    if k < count:
        s0 += buf[k]
    if k + 1 < count:
        s1 += buf[k + 1]
    if k + 2 < count:
        s2 += buf[k + 2]
    return s0, s1, s2, s3


@jit
def _potential_small(pos, m, eps2):
    """sum_i m_i sum_{j>i} m_j / r_ij for a few bodies: every row in this one call, no buffer.

    A sample of a small system is dominated by overheads, not terms: no allocation, no call and
    no row views per row. The terms and the four-lane order of :func:`_add_in_four_lanes` are
    those of the buffered rows (a vector square root or division gives the bits of the scalar
    one), so both paths give the same bits.
    """
    n = m.shape[0]
    total = 0.0
    for i in range(n):
        s0 = s1 = s2 = s3 = 0.0
        for j in range(i + 1, n):
            dx = pos[0, j] - pos[0, i]
            dy = pos[1, j] - pos[1, i]
            dz = pos[2, j] - pos[2, i]
            # math.sqrt, the same IEEE square root: numba-cuda lacks the numpy ufunc (the GPU ensemble calls this)
            term = m[j] / math.sqrt(dx * dx + dy * dy + dz * dz + eps2)
            lane = (j - i - 1) & 3
            if lane == 0:
                s0 += term
            elif lane == 1:
                s1 += term
            elif lane == 2:
                s2 += term
            else:
                s3 += term
        total += m[i] * ((s0 + s1) + (s2 + s3))
    return total


@jit
def _potential_row_buffered(pos, m, eps2, i, buf):
    """m_i sum_{j>i} m_j / r_ij, the terms computed a block at a time into ``buf``, then added in
    the order of :func:`_add_in_four_lanes`."""
    x = pos[0]
    y = pos[1]
    z = pos[2]
    xi = x[i]
    yi = y[i]
    zi = z[i]
    n = m.shape[0]
    s0 = s1 = s2 = s3 = 0.0
    for start in range(i + 1, n, TERM_BLOCK):
        stop = min(n, start + TERM_BLOCK)
        # No reduction here: vectorises without reordering anything. The index is unsigned: with
        # a signed one LLVM emitted gathers, 2.3x slower (as in the force loop).
        first = np.uint64(start)
        for j in range(first, np.uint64(stop)):
            dx = x[j] - xi
            dy = y[j] - yi
            dz = z[j] - zi
            buf[j - first] = m[j] / np.sqrt(dx * dx + dy * dy + dz * dz + eps2)
        s0, s1, s2, s3 = _add_in_four_lanes(buf, stop - start, s0, s1, s2, s3)
    return m[i] * ((s0 + s1) + (s2 + s3))


@jit
def _potential_serial(pos, m, G, eps2):
    if m.shape[0] < BUFFERED_POTENTIAL_MIN_N:
        return -G * _potential_small(pos, m, eps2)
    return _potential_buffered(pos, m, G, eps2)


@jit
def _potential_buffered(pos, m, G, eps2):
    n = m.shape[0]
    total = 0.0
    buf = np.empty(TERM_BLOCK)  # one small allocation per evaluation, none per row
    for i in range(n):
        total += _potential_row_buffered(pos, m, eps2, i, buf)
    return -G * total


@jit_parallel_exact
def _potential_parallel(pos, m, G, eps2, rows):
    n = m.shape[0]
    if rows.shape[0] < n:  # a caller's scratch for a serial N (the Blocks context's N never has one)
        rows = np.zeros(n)
    # One buffer per chunk, allocated before the parallel loop (an allocation inside a prange
    # body may be hoisted out of it by Numba and then shared between threads).
    bufs = np.empty((POTENTIAL_STRIDES, TERM_BLOCK))
    for c in prange(POTENTIAL_STRIDES):
        for i in range(c, n, POTENTIAL_STRIDES):
            if stop_requested():  # a stop: the sum is left incomplete, and the caller discards it
                break
            rows[i] = _potential_row_buffered(pos, m, eps2, i, bufs[c])
    total = 0.0
    for i in range(n):
        total += rows[i]
    return -G * total


@jit
def potential_energy(pos, m, G, eps2, rows):
    """Softened potential energy; ``rows`` (N,) is scratch for the parallel row partials.

    Pass an empty ``rows`` for small N (serial). Serial and parallel add the rows in the same
    order, so they give the same bits.
    """
    if rows.shape[0] == 0:
        return _potential_serial(pos, m, G, eps2)
    return _potential_parallel(pos, m, G, eps2, rows)


def potential_of(force, pos, m, rows):
    """:func:`potential_energy` at ``pos`` with the force context's G and eps2, by the kernel its N
    needs (jitted callers only; its meaning is the overload below): an :class:`AllPairs` context
    (N <= 48) compiles only :func:`_potential_small`, a :class:`Rows` one the serial rows, and only
    a :class:`Blocks` one the parallel rows."""
    raise NotImplementedError("called from jitted code only")


@overload_inline(potential_of)
def _potential_of(force, pos, m, rows):
    kind = kernel_class(force)
    if kind is AllPairs:  # N <= 48 < BUFFERED_POTENTIAL_MIN_N: _potential_serial's first branch
        return lambda force, pos, m, rows: -force.G * _potential_small(pos, m, force.eps2)
    if kind is Rows:  # N > SMALL_N_MAX, so N >= BUFFERED_POTENTIAL_MIN_N: _potential_serial's second branch
        return lambda force, pos, m, rows: _potential_buffered(pos, m, force.G, force.eps2)
    if kind is Blocks:  # N >= PARALLEL_MIN_N >= PARALLEL_POTENTIAL_MIN_N: potential_energy's parallel branch
        return lambda force, pos, m, rows: _potential_parallel(pos, m, force.G, force.eps2, rows)
    return None


@jit
def potential_energy_at(force, pos, m, rows):
    """:func:`potential_of`, for Python callers."""
    return potential_of(force, pos, m, rows)


@jit_inline
def momentum_into(vel, m, out):
    """Total linear momentum into ``out`` (3,)."""
    for c in range(3):
        total = 0.0
        for i in range(m.shape[0]):
            total += m[i] * vel[c, i]
        out[c] = total


@jit_inline
def angular_momentum_into(pos, vel, m, out):
    """Total angular momentum about the origin into ``out`` (3,)."""
    lx = 0.0
    ly = 0.0
    lz = 0.0
    for i in range(m.shape[0]):
        lx += m[i] * (pos[1, i] * vel[2, i] - pos[2, i] * vel[1, i])
        ly += m[i] * (pos[2, i] * vel[0, i] - pos[0, i] * vel[2, i])
        lz += m[i] * (pos[0, i] * vel[1, i] - pos[1, i] * vel[0, i])
    out[0] = lx
    out[1] = ly
    out[2] = lz


@jit
def centre_of_mass(pos, vel, m):
    """Centre-of-mass position and velocity, each (3,)."""
    com_x = np.zeros(3)
    com_v = np.zeros(3)
    total = 0.0
    for i in range(m.shape[0]):
        total += m[i]
        for c in range(3):
            com_x[c] += m[i] * pos[c, i]
            com_v[c] += m[i] * vel[c, i]
    if total > 0.0:
        for c in range(3):
            com_x[c] /= total
            com_v[c] /= total
    return com_x, com_v


def potential_rows_scratch(n: int) -> np.ndarray:
    """Scratch for :func:`potential_energy`: empty (serial) below the parallel threshold."""
    return np.zeros(n if n >= PARALLEL_POTENTIAL_MIN_N else 0)
