r"""Obstacles in the horizontal plane: shapes, signed distance, clearance and repulsion.

Obstacles are axis-aligned rectangles (the paper's) and discs (not in the paper). The
nearest point of a rectangle is the clamp of the paper (Sec. IV), that of a disc the radial
projection; inside an obstacle the distance is negative and the direction points out
through the nearest face.

The repulsive potential of eq. (18) lives here as a compiled kernel, :func:`repulsion_at`,
summed over every obstacle within :math:`l_\text{safe}` (not in the paper: the paper's
single "nearest point" is ambiguous with several obstacles), and capped per step (not in
the paper: :math:`1/l^3` is unbounded). The public, batched form with the scenario's gains is
:func:`crlbswarm.repulsion`.

Adding an obstacle shape: write its signed distance like :func:`rectangle_distance`, loop
over it in :func:`clearance_at` and :func:`repulsion_at`, store its rows in
:class:`Obstacles` and declare it in the scenario schema.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError
from .geometry import clip_norm

__all__ = [
    "Obstacles",
    "check_obstacles",
    "circle_distance",
    "clearance_at",
    "obstacle_clearance",
    "obstacle_distance",
    "rectangle_distance",
    "repulsion_at",
]


def _rows(value: ArrayLike, name: str, width: int) -> np.ndarray:
    """A finite ``(n, width)`` array; an empty input gives ``(0, width)``."""
    arr = _v.as_float_array(value, name)
    if arr.size == 0:
        return np.empty((0, width))
    if arr.ndim != 2 or arr.shape[1] != width:
        raise FieldError(name, f"expected shape (n, {width}), got {arr.shape}")
    return _v.check_finite(arr, name)


@dataclass(frozen=True, eq=False)
class Obstacles:
    """Axis-aligned rectangles and circles in the horizontal plane.

    Parameters
    ----------
    rectangles : array_like, shape (R, 4)
        Rows ``[x_min, x_max, y_min, y_max]``, m, with ``x_min < x_max`` and
        ``y_min < y_max``.
    circles : array_like, shape (C, 3)
        Rows ``[x_center, y_center, radius]``, m, radius > 0.
    """

    rectangles: np.ndarray
    circles: np.ndarray

    def __init__(self, rectangles: ArrayLike = (), circles: ArrayLike = ()) -> None:
        rects = _rows(rectangles, "rectangles", 4)
        circs = _rows(circles, "circles", 3)
        lim = _v.MAX_COORDINATE
        _v.bounded(rects, "rectangles", -lim, lim, " m")
        _v.bounded(circs[:, :2], "circles", -lim, lim, " m")
        _v.bounded(circs[:, 2], "circles", 0.0, _v.MAX_DISTANCE, " m")
        if np.any(rects[:, 0] >= rects[:, 1]) or np.any(rects[:, 2] >= rects[:, 3]):
            raise FieldError("rectangles", "need x_min < x_max and y_min < y_max")
        if np.any(circs[:, 2] <= 0):
            raise FieldError("circles", "radius must be > 0")
        for name, arr in (("rectangles", rects), ("circles", circs)):
            arr = np.ascontiguousarray(arr, dtype=np.float64).copy()
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    @property
    def count(self) -> int:
        """Number of obstacles."""
        return int(self.rectangles.shape[0] + self.circles.shape[0])


def check_obstacles(obstacles: object) -> Obstacles:
    """Return ``obstacles`` if it is an :class:`Obstacles`, else raise naming the argument.

    Parameters
    ----------
    obstacles : object
        The value to check.

    Returns
    -------
    Obstacles
        The same object.
    """
    if not isinstance(obstacles, Obstacles):
        raise FieldError(
            "obstacles", f"expected a crlbswarm.Obstacles, got {type(obstacles).__name__}"
        )
    return obstacles


# ---------------------------------------------------------------------------------------
# Compiled kernels on one point (called by the public functions and the mission kernel)
# ---------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def rectangle_distance(x, y, xmin, xmax, ymin, ymax):
    """Signed distance from (x, y) to a rectangle and the unit vector from its nearest point
    to (x, y) (inside: negative, out through the nearest face). Compiled kernel, no checks."""
    cx = min(max(x, xmin), xmax)
    cy = min(max(y, ymin), ymax)
    dx = x - cx
    dy = y - cy
    d = math.sqrt(dx * dx + dy * dy)
    if d > 0.0:
        return d, dx / d, dy / d
    # Inside: the nearest boundary point is on the closest face (negative distance).
    left = x - xmin
    right = xmax - x
    down = y - ymin
    up = ymax - y
    best = left
    ux, uy = -1.0, 0.0
    if right < best:
        best, ux, uy = right, 1.0, 0.0
    if down < best:
        best, ux, uy = down, 0.0, -1.0
    if up < best:
        best, ux, uy = up, 0.0, 1.0
    return -best, ux, uy


@njit(cache=True, inline="always")
def circle_distance(x, y, cx, cy, r):
    """Signed distance from (x, y) to a disc and the outward unit vector. Compiled kernel."""
    dx = x - cx
    dy = y - cy
    rho = math.sqrt(dx * dx + dy * dy)
    if rho > 0.0:
        return rho - r, dx / rho, dy / rho
    return -r, 1.0, 0.0


@njit(cache=True, inline="always")
def obstacle_distance(x, y, rects, circles, k):
    """Signed distance from (x, y) to obstacle ``k`` and the outward unit vector, the
    obstacles numbered rectangles first, then circles (``k`` < R + C): the one place that
    maps an obstacle's row to its shape. Compiled kernel, no checks."""
    n_r = rects.shape[0]
    if k < n_r:
        return rectangle_distance(x, y, rects[k, 0], rects[k, 1], rects[k, 2], rects[k, 3])
    c = k - n_r
    return circle_distance(x, y, circles[c, 0], circles[c, 1], circles[c, 2])


@njit(cache=True)
def clearance_at(x, y, rects, circles):
    """Signed distance from (x, y) to the nearest obstacle (+inf without obstacles).

    Compiled kernel, no checks; ``rects`` (R, 4) and ``circles`` (C, 3) as in
    :class:`Obstacles`.
    """
    best = math.inf
    for k in range(rects.shape[0] + circles.shape[0]):
        d, _, _ = obstacle_distance(x, y, rects, circles, k)
        best = min(best, d)
    return best


@njit(cache=True)
def repulsion_at(x, y, rects, circles, gain, l_safe, max_step, inflate=0.0):
    r"""Eq. (18) at (x, y), summed over the obstacles within ``l_safe``, capped at
    ``max_step`` (m).

    :math:`E_r(1/l - 1/l_\text{safe})/l^2` along the unit vector from each obstacle's
    nearest point; ``inflate`` is subtracted from every distance: the repulsion felt by a
    disc of that radius centred at (x, y) (the formation as a whole, for the leader's
    steering). Compiled kernel, no checks.
    """
    fx = 0.0
    fy = 0.0
    for k in range(rects.shape[0] + circles.shape[0]):
        d, ux, uy = obstacle_distance(x, y, rects, circles, k)
        d -= inflate
        if d < l_safe:
            ell = max(d, 1e-9)  # inside an obstacle: push out along the nearest face
            mag = gain * (1.0 / ell - 1.0 / l_safe) / (ell * ell)
            fx += mag * ux
            fy += mag * uy
    return clip_norm(fx, fy, max_step)


@njit(cache=True)
def _clearance_batch(q, rects, circles, out):
    for b in range(q.shape[0]):
        out[b] = clearance_at(q[b, 0], q[b, 1], rects, circles)


def obstacle_clearance(positions: ArrayLike, obstacles: Obstacles) -> np.ndarray:
    """Signed distance from each point to the nearest obstacle (negative inside), m.

    Parameters
    ----------
    positions : array_like, shape (..., 2)
        Points, m.
    obstacles : Obstacles
        Rectangles and circles.

    Returns
    -------
    ndarray, shape (...)
        Clearance, m; ``+inf`` if there are no obstacles.
    """
    q = _v.location(positions, "positions")
    qb = np.ascontiguousarray(q).reshape(-1, 2)
    out = np.empty(qb.shape[0])
    obs = check_obstacles(obstacles)
    _clearance_batch(qb, obs.rectangles, obs.circles, out)
    return out.reshape(q.shape[:-1])
