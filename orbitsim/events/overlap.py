"""Bodies that touch at the start of a run: pairs closer than the sum of their radii.

The events watch checks contacts after every step, so a pair that already overlaps at t = 0 was
never seen: a body placed inside the star ran, was flung out, and no collision was logged. Two
users of this module close that gap: :mod:`orbitsim.preflight` refuses such a start when the
scenario has no ``events.collisions`` (``validate`` and ``run`` alike), and
:meth:`orbitsim.events.driver.Watcher.contacts_at_start` logs it as a collision at step 0 and
resolves it by the scenario's rule when it has one.

Plain numpy (no numba): it runs once, before the first step.
"""

from __future__ import annotations

import numpy as np

__all__ = ["overlapping_pairs"]

#: Candidate pairs measured per numpy pass (8 bytes x a few arrays each: ~100 MiB at most).
_BLOCK_PAIRS = 2**22


def overlapping_pairs(positions: np.ndarray, radii: np.ndarray | None) -> list[tuple[int, int, float, float]]:
    """Every pair ``(i, j, d, r_i + r_j)`` with ``i < j`` whose centres are closer than ``r_i + r_j``,
    in increasing ``(i, j)``.

    The test is the events watch's ``direct`` contact test, on the same numbers:
    ``dx^2 + dy^2 + dz^2 < (r_i + r_j)^2`` with ``dx = x_i - x_j``, so a pair refused or logged
    here is one the watch would have seen. Two bodies without a radius never touch.

    Only bodies with a radius can be in a pair, and only partners within ``r_i + max r`` along
    x: the bodies are sorted by x once and each body with a radius measures just that window
    (sweep and prune), so the cost is O(N log N) plus the pairs in the windows, not O(N^2).

    Parameters
    ----------
    positions : (N, 3) array
    radii : (N,) array or None
        Radii >= 0; None means no body has one.
    """
    x = np.asarray(positions, dtype=np.float64)
    if radii is None or x.shape[0] < 2:
        return []
    r = np.asarray(radii, dtype=np.float64)
    with_radius = np.flatnonzero(r > 0.0)
    if with_radius.size == 0:
        return []
    reach_max = float(r.max())
    order = np.argsort(x[:, 0], kind="stable")
    xs = x[order, 0]
    lo = np.searchsorted(xs, x[with_radius, 0] - (r[with_radius] + reach_max), side="left")
    hi = np.searchsorted(xs, x[with_radius, 0] + (r[with_radius] + reach_max), side="right")
    found: set[tuple[int, int]] = set()
    pairs: list[tuple[int, int, float, float]] = []
    start = 0
    while start < with_radius.size:
        # a block of bodies whose windows hold at most _BLOCK_PAIRS candidates (at least one body)
        sizes = np.cumsum(hi[start:] - lo[start:])
        stop = start + max(1, int(np.searchsorted(sizes, _BLOCK_PAIRS, side="right")))
        counts = hi[start:stop] - lo[start:stop]
        a = np.repeat(with_radius[start:stop], counts)
        offsets = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        b = order[np.repeat(lo[start:stop], counts) + offsets]
        keep = a != b
        a, b = a[keep], b[keep]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        reach = r[a] + r[b]
        with np.errstate(over="ignore", invalid="ignore"):  # far-flung bodies: inf is "not touching"
            d2 = dx * dx + dy * dy + dz * dz
            touching = np.flatnonzero(d2 < reach * reach)
        for k in touching:
            i, j = (int(a[k]), int(b[k])) if a[k] < b[k] else (int(b[k]), int(a[k]))
            if (i, j) not in found:
                found.add((i, j))
                pairs.append((i, j, float(np.sqrt(d2[k])), float(reach[k])))
        start = stop
    return sorted(pairs)
