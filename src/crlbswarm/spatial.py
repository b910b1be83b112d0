"""Spatial queries on a swarm: the smallest distance between two UAVs.

:func:`min_separation` is exact at every size: all pairs up to
:data:`SEPARATION_BRUTE_FORCE_MAX` UAVs, above that a cell list built by a counting sort, so
the work per step grows linearly with the number of UAVs for a spread-out swarm. It is a
compiled kernel called by the mission kernel once per step; :func:`smallest_separation` is
its public, batched form.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike

from . import _validation as _v
from ._numba import leaf

__all__ = [
    "SEPARATION_BLOCK",
    "SEPARATION_BRUTE_FORCE_MAX",
    "min_separation",
    "min_separation_parallel",
    "pair_separation",
    "smallest_separation",
]


#: Up to this many UAVs the smallest separation is found by checking every pair.
SEPARATION_BRUTE_FORCE_MAX = 64


@njit(cache=True)
def min_separation(q):
    """Smallest distance between two of the points ``q`` (M, 2): all pairs for small swarms,
    a uniform grid (cell list, O(M) for a spread-out swarm) for large ones; exact in both
    cases (+inf for fewer than two points). Compiled kernel, no checks."""
    return _min_separation(q, None)


@leaf
def pair_separation(q):
    """Smallest distance between two of the points ``q`` (M, 2) by checking every pair
    (+inf for fewer than two points): :func:`min_separation` for small swarms. Compiled
    kernel, no checks."""
    n = q.shape[0]
    best = math.inf
    for m in range(n):
        for p in range(m + 1, n):
            dx = q[m, 0] - q[p, 0]
            dy = q[m, 1] - q[p, 1]
            best = min(best, dx * dx + dy * dy)
    return math.sqrt(best)


@njit(cache=True)
def min_separation_parallel(q):
    """:func:`min_separation` with the cell list's search on all threads (for one large
    swarm; the same value: a minimum is exact in any order). Compiled kernel, no checks."""
    return _min_separation(q, np.empty(0))


@njit(cache=True)
def _min_separation(q, wide):
    n = q.shape[0]
    if n < 2:
        return math.inf
    if n <= SEPARATION_BRUTE_FORCE_MAX:
        return pair_separation(q)
    x0, x1 = q[:, 0].min(), q[:, 0].max()
    y0, y1 = q[:, 1].min(), q[:, 1].max()
    # Cells of about one UAV each; a pair closer than the cell size is always found in the
    # same or a neighbouring cell. If no pair is that close, grow the cells and try again.
    cell = max(math.sqrt(max((x1 - x0) * (y1 - y0), 1e-12) / n), 1e-9)
    while True:
        nx = min(int((x1 - x0) / cell) + 1, 4 * n)
        ny = min(int((y1 - y0) / cell) + 1, 4 * n)
        cell = max(cell, (x1 - x0) / nx * (1 + 1e-12), (y1 - y0) / ny * (1 + 1e-12))
        # Counting sort of the UAVs by cell: start[k] .. start[k + 1] index ``order``.
        key = np.empty(n, dtype=np.int64)
        start = np.zeros(nx * ny + 1, dtype=np.int64)
        for m in range(n):
            cx = min(int((q[m, 0] - x0) / cell), nx - 1)
            cy = min(int((q[m, 1] - y0) / cell), ny - 1)
            key[m] = cx * ny + cy
            start[key[m] + 1] += 1
        for k in range(nx * ny):
            start[k + 1] += start[k]
        fill = start[:-1].copy()
        order = np.empty(n, dtype=np.int64)
        for m in range(n):
            order[fill[key[m]]] = m
            fill[key[m]] += 1
        n_blocks = (n + SEPARATION_BLOCK - 1) // SEPARATION_BLOCK
        block_best = np.empty(n_blocks)
        if wide is not None:
            _search_blocks(q, key, start, order, ny, nx, cell * cell, block_best)
        else:
            for b in range(n_blocks):
                block_best[b] = _search(q, key, start, order, ny, nx, cell * cell,
                                        b * SEPARATION_BLOCK,
                                        min(n, (b + 1) * SEPARATION_BLOCK))  # fmt: skip
        best = block_best.min()
        if best < cell * cell:
            return math.sqrt(best)
        cell *= 2.0


#: UAVs per block of the cell list's search (:func:`min_separation_parallel`).
SEPARATION_BLOCK = 1024


@leaf
def _search(q, key, start, order, ny, nx, limit, lo, hi):
    """Smallest squared distance below ``limit`` from a UAV ``lo .. hi - 1`` to a UAV of
    higher index in its own or a neighbouring cell (``limit`` if none)."""
    best = limit
    for m in range(lo, hi):
        cx, cy = key[m] // ny, key[m] % ny
        for ax in range(max(cx - 1, 0), min(cx + 2, nx)):
            for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
                k = ax * ny + ay
                for j in range(start[k], start[k + 1]):
                    p = order[j]
                    if p > m:
                        dx = q[m, 0] - q[p, 0]
                        dy = q[m, 1] - q[p, 1]
                        best = min(best, dx * dx + dy * dy)
    return best


@njit(cache=True, parallel=True)
def _search_blocks(q, key, start, order, ny, nx, limit, block_best):
    n = q.shape[0]
    for b in prange(block_best.shape[0]):
        block_best[b] = _search(q, key, start, order, ny, nx, limit, b * SEPARATION_BLOCK,
                                min(n, (b + 1) * SEPARATION_BLOCK))  # fmt: skip


@njit(cache=True)
def _min_separation_batch(q, out):
    for b in range(q.shape[0]):
        out[b] = min_separation(q[b])


def smallest_separation(positions: ArrayLike) -> np.ndarray:
    """Smallest distance between two UAVs of each formation, m.

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        UAV positions, m.

    Returns
    -------
    ndarray, shape (...)
        The smallest pairwise distance (+inf for a single UAV).
    """
    q = _v.coordinates(positions, "positions")
    qb = np.ascontiguousarray(q).reshape(-1, *q.shape[-2:])
    out = np.empty(qb.shape[0])
    _min_separation_batch(qb, out)
    return out.reshape(q.shape[:-2])
