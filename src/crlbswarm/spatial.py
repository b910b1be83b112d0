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
from numba import njit
from numpy.typing import ArrayLike

from . import _validation as _v

__all__ = ["SEPARATION_BRUTE_FORCE_MAX", "min_separation", "smallest_separation"]


#: Up to this many UAVs the smallest separation is found by checking every pair.
SEPARATION_BRUTE_FORCE_MAX = 64


@njit(cache=True)
def min_separation(q):
    """Smallest distance between two of the points ``q`` (M, 2): all pairs for small swarms,
    a uniform grid (cell list, O(M) for a spread-out swarm) for large ones; exact in both
    cases (+inf for fewer than two points). Compiled kernel, no checks."""
    n = q.shape[0]
    if n < 2:
        return math.inf
    if n <= SEPARATION_BRUTE_FORCE_MAX:
        best = math.inf
        for m in range(n):
            for p in range(m + 1, n):
                dx = q[m, 0] - q[p, 0]
                dy = q[m, 1] - q[p, 1]
                best = min(best, dx * dx + dy * dy)
        return math.sqrt(best)
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
        best = cell * cell
        found = False
        for m in range(n):
            cx, cy = key[m] // ny, key[m] % ny
            for ax in range(max(cx - 1, 0), min(cx + 2, nx)):
                for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
                    k = ax * ny + ay
                    for j in range(start[k], start[k + 1]):
                        p = order[j]
                        if p > m:
                            dx = q[m, 0] - q[p, 0]
                            dy = q[m, 1] - q[p, 1]
                            d2 = dx * dx + dy * dy
                            if d2 < best:
                                best = d2
                                found = True
        if found:
            return math.sqrt(best)
        cell *= 2.0


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
