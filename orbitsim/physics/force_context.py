"""The force context every step receives, and the one call through which a step gets gravity.

Every step receives the force context of :func:`make_force`, a :class:`ForceContext` (G, eps2,
the blocks' scratch, and the run's forces beyond Newtonian gravity, :mod:`orbitsim.forces`). Its
class names the kernel of :mod:`orbitsim.physics.gravity` that the N of the run needs:
:class:`AllPairs` (N <= ``SMALL_N_MAX``), :class:`Rows` (one block, one thread) or :class:`Blocks`
(the parallel kernel). The classes are distinct Numba types, so a step calls
:func:`newtonian_accelerations`, which resolves to that one kernel when the step is compiled: a
5-body run compiles neither the row kernels nor the parallel one (they cost seconds on a first
run), and a 1000-body run nothing it does not call. Each class's kernel (``all_pairs_accelerations``,
``accelerations_rows``, ``accelerations_blocks``, and the sample's potential beside it,
:func:`orbitsim.physics.diagnostics.potential_of`) holds no run-time branch to another class's: Numba
compiles both sides of a branch, and such branches had cost a 201-body first run a second and a
1,000-body one two (benchmarks/README.md, "First runs, third pass").

:func:`newtonian_accelerations` is inlined at Numba's IR level into the scheme's loop. Numba gives
an inlined function its own copies of its array arguments, each an atomic increment and decrement
of a reference count that LLVM keeps when a call that may return an error lies between them; the
stepping loops once paid 4-13% of a 5-body step for helpers of that kind (benchmarks/README.md,
"Reference counts in the loop"). This one measured the same time per step as the direct call
(110-114 ns for a 5-body verlet step, either way): the kernel's own arguments are the only arrays
it passes on.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import types

from orbitsim._jit import overload_inline, stop_requested
from orbitsim.physics.gravity import (
    SMALL_N_MAX,
    accelerations_blocks,
    accelerations_rows,
    all_pairs_accelerations,
    force_scratch,
)

__all__ = ["AllPairs", "Blocks", "ForceContext", "Rows", "accelerations_at", "kernel_class", "make_force",
           "newtonian_accelerations"]


class ForceContext(NamedTuple):
    """What every step needs to evaluate the forces: the fields of the three context classes.

    ``G`` and ``eps2`` (the softening length squared); ``slabs`` (B, 3, N) and ``bounds`` (B + 1,)
    of :func:`~orbitsim.physics.gravity.force_scratch`; ``forces``: the run's forces beyond Newtonian gravity as the
    kernels read them (:class:`orbitsim.forces.hooks.Forces`), None without (every force hook then
    compiles to nothing). Steps receive one of its subclasses, which name the kernel.
    """

    G: float
    eps2: float
    slabs: np.ndarray
    bounds: np.ndarray
    forces: Any = None


class AllPairs(ForceContext):
    """N <= :data:`~orbitsim.physics.gravity.SMALL_N_MAX`: :func:`~orbitsim.physics.gravity.all_pairs_accelerations`."""

    __slots__ = ()


class Rows(ForceContext):
    """One block of third-law rows on one thread (N < :data:`~orbitsim.physics.gravity.PARALLEL_MIN_N`):
    :func:`~orbitsim.physics.gravity.accelerations_rows`."""

    __slots__ = ()


class Blocks(ForceContext):
    """Blocks of rows spread over the threads: :func:`~orbitsim.physics.gravity.accelerations_blocks`."""

    __slots__ = ()


def make_force(G: float, softening: float, n: int) -> ForceContext:
    """The force context every step receives, for N bodies, without forces beyond gravity: an
    :class:`AllPairs`, :class:`Rows` or :class:`Blocks` as N decides."""
    slabs, bounds = force_scratch(n)
    kind = AllPairs if n <= SMALL_N_MAX else (Rows if bounds.shape[0] == 2 else Blocks)
    return kind(float(G), float(softening) ** 2, slabs, bounds)


def kernel_class(force: Any) -> type | None:
    """The context class (:class:`AllPairs`, :class:`Rows`, :class:`Blocks`) of a force context's
    Numba type, or None for another type."""
    cls = getattr(force, "instance_class", None) if isinstance(force, types.BaseNamedTuple) else None
    return cls if cls in (AllPairs, Rows, Blocks) else None


def newtonian_accelerations(force, pos, m, acc):
    """``acc`` (3, N) = the Newtonian accelerations at ``pos``, by the kernel the context names
    (jitted callers only; its meaning is the overload below)."""
    raise NotImplementedError("called from jitted code only")


@overload_inline(newtonian_accelerations)
def _newtonian_accelerations(force, pos, m, acc):
    kind = kernel_class(force)
    if kind is AllPairs:
        return lambda force, pos, m, acc: all_pairs_accelerations(pos, m, force.G, force.eps2, acc)
    if kind is Rows:
        def rows(force, pos, m, acc):
            if not stop_requested():  # as accelerations(): a stopped call costs O(N) a step from here
                accelerations_rows(pos, m, force.G, force.eps2, acc)
        return rows
    if kind is Blocks:
        def blocks(force, pos, m, acc):
            if not stop_requested():
                accelerations_blocks(pos, m, force.G, force.eps2, acc, force.slabs, force.bounds)
        return blocks
    return None


def accelerations_at(force: ForceContext, pos: np.ndarray, m: np.ndarray, acc: np.ndarray) -> None:
    """:func:`newtonian_accelerations`, for Python callers (a run's first accelerations): the kernel the
    context's class names, called directly. The run's loop calls that kernel with the same types, so a
    first run compiles it once; a jitted wrapper here was one more kernel to compile and link, 0.2-0.4 s
    of every first run (benchmarks/README.md, "First runs, fourth pass")."""
    if isinstance(force, AllPairs):
        all_pairs_accelerations(pos, m, force.G, force.eps2, acc)
    elif isinstance(force, Rows):
        accelerations_rows(pos, m, force.G, force.eps2, acc)
    elif isinstance(force, Blocks):
        accelerations_blocks(pos, m, force.G, force.eps2, acc, force.slabs, force.bounds)
    else:
        raise TypeError(f"not a force context of make_force: {type(force).__name__}")
