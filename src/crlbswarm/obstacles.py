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

Many obstacles: :func:`obstacle_grid` builds an :class:`ObstacleGrid`, a uniform grid
over the obstacles' bounding boxes, and :func:`obstacle_field` returns the clearance and
the repulsion of one point in one pass, visiting only the obstacles near it; the results are
those of :func:`clearance_at` and :func:`repulsion_at` bit for bit.

Adding an obstacle shape: write its signed distance like :func:`rectangle_distance`, loop
over it in :func:`clearance_at` and :func:`repulsion_at`, give its bounding box to
:func:`obstacle_grid`, store its rows in :class:`Obstacles` and declare it in the scenario
schema.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from . import _validation as _v
from ._numba import leaf
from .errors import FieldError
from .geometry import clip_norm

__all__ = [
    "GRID_DIRECT_MAX",
    "GRID_MAX_CELLS",
    "ObstacleGrid",
    "Obstacles",
    "check_obstacles",
    "circle_distance",
    "clearance_at",
    "clearance_grid",
    "clearance_of",
    "field_of",
    "obstacle_clearance",
    "obstacle_distance",
    "obstacle_field",
    "obstacle_grid",
    "obstacle_index",
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


# ---------------------------------------------------------------------------------------
# Uniform-grid index: the obstacles near a point, and its clearance and repulsion in one pass
# ---------------------------------------------------------------------------------------
#: Obstacle count up to which :func:`obstacle_grid` builds no index: the queries loop over
#: every obstacle (the paper's scene has two). A loop over 64 obstacles costs about as much
#: as the grid's ring search for a point far from every obstacle (the clearance must find
#: the nearest one, however far), so below this count the index does not pay.
GRID_DIRECT_MAX = 64

#: Most cells an :class:`ObstacleGrid` ever has (whatever the obstacle count).
GRID_MAX_CELLS = 1 << 20

#: Relative rounding slack of the index: the obstacles' boxes are widened by this fraction
#: of the scene's coordinates, and the clearance search stops this much (relative to the
#: point's coordinates) before its lower bound, so rounding never drops an obstacle.
_GRID_SLACK = 1e-9
_SEARCH_SLACK = 1e-12


class ObstacleGrid(NamedTuple):
    """Uniform-grid index over rectangles and circles (build it with :func:`obstacle_grid`).

    Cell ``(i, j)`` (``0 <= i < nx``, ``0 <= j < ny``) is the square
    ``[x0 + i cell, x0 + (i+1) cell) x [y0 + j cell, y0 + (j+1) cell)``; it lists, in
    increasing obstacle number, every obstacle whose bounding box widened by ``reach``
    overlaps it. A compiled kernel takes it as one argument.

    Attributes
    ----------
    rects : ndarray, shape (R, 4)
        Rectangles, rows ``[x_min, x_max, y_min, y_max]``, m (read-only).
    circles : ndarray, shape (C, 3)
        Circles, rows ``[x_center, y_center, radius]``, m (read-only).
    x0 : float
        Left edge of the grid, m.
    y0 : float
        Bottom edge of the grid, m.
    cell : float
        Side of a cell, m.
    nx : int
        Number of cell columns.
    ny : int
        Number of cell rows.
    cell_start : ndarray of int64, shape (nx ny + 1,)
        CSR pointers: cell ``c = j nx + i`` lists ``cell_items[cell_start[c]:cell_start[c+1]]``.
    cell_items : ndarray of int64
        Obstacle numbers, rectangles first then circles (as :func:`obstacle_distance`),
        increasing within a cell.
    direct : bool
        True: no index (few obstacles); the queries loop over every obstacle.
    reach : float
        Distance within which every obstacle is listed in the point's cell, m.
    bounds : ndarray, shape (4,)
        Bounding box of all obstacles, ``[x_min, x_max, y_min, y_max]``, m.
    scale : float
        Largest coordinate magnitude of the grid, m (sets the search's rounding slack).
    """

    rects: np.ndarray
    circles: np.ndarray
    x0: float
    y0: float
    cell: float
    nx: int
    ny: int
    cell_start: np.ndarray
    cell_items: np.ndarray
    direct: bool
    reach: float
    bounds: np.ndarray
    scale: float


def _frozen(arr: np.ndarray, dtype: type) -> np.ndarray:
    out = np.ascontiguousarray(arr, dtype=dtype).copy()
    out.flags.writeable = False
    return out


def _bounding_boxes(rects: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """Rows ``[x_min, x_max, y_min, y_max]`` of every obstacle, in obstacle order."""
    cx, cy, r = circles[:, 0], circles[:, 1], circles[:, 2]
    discs = np.column_stack([cx - r, cx + r, cy - r, cy + r]).reshape(-1, 4)
    return np.concatenate([rects.reshape(-1, 4), discs])


def _cell_ranges(lo: np.ndarray, hi: np.ndarray, origin: float, cell: float, n: int):
    """First and last cell (clipped to ``[0, n)``) of each interval ``[lo, hi]``: the floor
    of ``(v - origin) / cell``, the very expression the queries evaluate."""
    first = np.clip(np.floor((lo - origin) / cell), 0, n - 1).astype(np.int64)
    last = np.clip(np.floor((hi - origin) / cell), 0, n - 1).astype(np.int64)
    return first, last


def _grid_layout(wide: np.ndarray, size: float):
    """Origin, cell side, shape and per-obstacle cell ranges for the widened boxes ``wide``.

    Start from ``size`` and coarsen by 1.5 until the grid has at most
    ``min(4 n + 256, GRID_MAX_CELLS)`` cells and the index at most ``16 n + 4096`` entries.
    """
    n = wide.shape[0]
    x0, y0 = float(wide[:, 0].min()), float(wide[:, 2].min())
    width, height = float(wide[:, 1].max()) - x0, float(wide[:, 3].max()) - y0
    max_cells = min(4 * n + 256, GRID_MAX_CELLS)
    max_items = 16 * n + 4096
    cell = max(size, math.sqrt(width * height / max_cells), max(width, height) / max_cells)
    while True:
        nx, ny = math.floor(width / cell) + 1, math.floor(height / cell) + 1
        if nx * ny <= max_cells:
            i0, i1 = _cell_ranges(wide[:, 0], wide[:, 1], x0, cell, nx)
            j0, j1 = _cell_ranges(wide[:, 2], wide[:, 3], y0, cell, ny)
            counts = (i1 - i0 + 1) * (j1 - j0 + 1)
            if int(counts.sum()) <= max_items:
                return x0, y0, cell, nx, ny, np.column_stack([i0, i1, j0, j1]), counts
        cell *= 1.5


def _cell_lists(ranges: np.ndarray, counts: np.ndarray, nx: int, ny: int):
    """CSR of the cells: each obstacle in every cell of its range, increasing within a cell
    (the entries are generated in obstacle order and sorted stably by cell)."""
    owner = np.repeat(np.arange(ranges.shape[0], dtype=np.int64), counts)
    local = np.arange(owner.size, dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    cols = (ranges[:, 1] - ranges[:, 0] + 1)[owner]
    cell_id = (ranges[owner, 2] + local // cols) * nx + ranges[owner, 0] + local % cols
    items = owner[np.argsort(cell_id, kind="stable")]
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell_id, minlength=nx * ny), out=start[1:])
    return start, items


def obstacle_grid(
    rects: ArrayLike, circles: ArrayLike, reach: float, *, direct: bool | None = None
) -> ObstacleGrid:
    """Build the uniform-grid index of :func:`obstacle_field` and :func:`clearance_grid`.

    Each obstacle is listed in every cell its bounding box, widened by ``reach`` (plus a
    rounding slack), overlaps, so the point's own cell lists every obstacle within
    ``reach`` of it. The cell side starts at ``max(reach, median obstacle size)`` (a few
    candidates per cell, each obstacle in a few cells) and is coarsened by 1.5 until the
    grid has at most ``min(4 n + 256, GRID_MAX_CELLS)`` cells and at most ``16 n + 4096``
    entries: memory is O(n) whatever the extent (clustered, huge or far-apart obstacles
    only give coarser cells).

    Parameters
    ----------
    rects : array_like, shape (R, 4)
        Rectangles, rows ``[x_min, x_max, y_min, y_max]``, m (as :class:`Obstacles`).
    circles : array_like, shape (C, 3)
        Circles, rows ``[x_center, y_center, radius]``, m.
    reach : float
        Largest distance at which a query needs every obstacle, m: the repulsion radius
        :math:`l_\\text{safe}` plus any ``inflate`` of :func:`obstacle_field`. A query with
        a larger radius stays exact but loops over every obstacle.
    direct : bool, optional
        Skip the index (True) or build it (False); default: skip it for at most
        :data:`GRID_DIRECT_MAX` obstacles. Without obstacles there is never an index.

    Returns
    -------
    ObstacleGrid
        The index (read-only arrays).
    """
    obs = Obstacles(rects, circles)
    reach = float(reach)
    if not (math.isfinite(reach) and 0.0 <= reach <= _v.MAX_DISTANCE):
        raise FieldError("reach", f"expected a finite distance >= 0 m, got {reach!r}")
    boxes = _bounding_boxes(obs.rectangles, obs.circles)
    n = boxes.shape[0]
    bounds = np.zeros(4)
    if n:
        bounds = np.array(
            [boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max()]
        )
    if n == 0 or (n <= GRID_DIRECT_MAX if direct is None else direct):
        return ObstacleGrid(
            obs.rectangles, obs.circles, 0.0, 0.0, 1.0, 1, 1, _frozen(np.zeros(2), np.int64),
            _frozen(np.zeros(0), np.int64), True, reach, _frozen(bounds, np.float64), 0.0,
        )  # fmt: skip
    pad = reach + _GRID_SLACK * (float(np.abs(bounds).max()) + reach) + 1e-9
    wide = boxes + np.array([-pad, pad, -pad, pad])
    size = float(np.median(np.maximum(boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2])))
    x0, y0, cell, nx, ny, ranges, counts = _grid_layout(wide, max(reach, size))
    start, items = _cell_lists(ranges, counts, nx, ny)
    scale = max(abs(x0), abs(y0), abs(x0 + nx * cell), abs(y0 + ny * cell))
    return ObstacleGrid(
        obs.rectangles, obs.circles, x0, y0, float(cell), nx, ny, _frozen(start, np.int64),
        _frozen(items, np.int64), False, reach, _frozen(bounds, np.float64), scale,
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def _quotient(a, b):
    """``a / b`` in IEEE arithmetic (no zero-division check; the same bits otherwise): a
    division's exception path in the inlined grid kernels would keep the index's arrays'
    reference counts alive on every call."""
    return a / b


@njit(cache=True, inline="always")
def _grid_cell(x, y, x0, y0, cell, nx, ny):
    """Cell (i, j) of (x, y), clamped to the grid (NaN: cell 0), by the floor that
    :func:`_cell_ranges` evaluates."""
    fx = _quotient(x - x0, cell)
    fy = _quotient(y - y0, cell)
    i = nx - 1 if fx >= nx else (int(fx) if fx >= 0.0 else 0)
    j = ny - 1 if fy >= ny else (int(fy) if fy >= 0.0 else 0)
    return i, j


@njit(cache=True, inline="always")
def _gap2(x, y, xmin, xmax, ymin, ymax):
    """Squared distance from (x, y) to a box (0 inside, +inf if the box is empty)."""
    gap = math.inf
    if xmin <= xmax and ymin <= ymax:
        dx = max(xmin - x, 0.0, x - xmax)
        dy = max(ymin - y, 0.0, y - ymax)
        gap = dx * dx + dy * dy
    return gap


@njit(cache=True, inline="always")
def _rings_left(x, y, best, slack, r, ci, cj, geometry, bounds):
    """Whether an obstacle listed in no cell within Chebyshev radius ``r`` of cell (ci, cj)
    could be nearer to (x, y) than ``best`` (``slack``: the rounding margin).

    Such an obstacle lies inside ``bounds`` (``(x_min, x_max, y_min, y_max)``) and more
    than ``reach`` beyond an edge of that block of cells where the grid goes on:
    the squared distance to these regions is the lower bound. ``geometry`` is
    ``(x0, y0, cell, nx, ny, reach)``.
    """
    x0, y0, cell, nx, ny, reach = geometry
    b0, b1, b2, b3 = bounds
    i0, i1, j0, j1 = max(ci - r, 0), min(ci + r, nx - 1), max(cj - r, 0), min(cj + r, ny - 1)
    west = x0 + i0 * cell - reach if i0 > 0 else -math.inf
    east = x0 + (i1 + 1) * cell + reach if i1 < nx - 1 else math.inf
    south = y0 + j0 * cell - reach if j0 > 0 else -math.inf
    north = y0 + (j1 + 1) * cell + reach if j1 < ny - 1 else math.inf
    lb = _gap2(x, y, b0, min(b1, west), b2, b3)
    lb = min(lb, _gap2(x, y, max(b0, east), b1, b2, b3))
    lb = min(lb, _gap2(x, y, b0, b1, b2, min(b3, south)))
    lb = min(lb, _gap2(x, y, b0, b1, max(b2, north), b3))
    stop = best + slack
    return stop > 0.0 and stop * stop > lb


@leaf
def obstacle_field(x, y, grid, gain, l_safe, max_step, inflate=0.0):  # long: one flat body
    r"""Clearance and eq. (18) repulsion at (x, y) in one pass over the nearby obstacles.

    The results equal ``clearance_at(x, y, rects, circles)`` and
    ``repulsion_at(x, y, rects, circles, gain, l_safe, max_step, inflate)`` bit for bit:
    the point's cell lists every obstacle within ``grid.reach`` in increasing number, so
    the repulsion adds the same terms in the same order. The clearance is a minimum: if the
    nearest obstacle of the cell is beyond ``reach``, rings of cells around it are searched
    until no obstacle listed in no visited cell can be nearer (each cell skipped if
    farther than the best distance less ``reach``). Its bits do not depend on the order:
    the only value with two bit patterns is zero, and an obstacle at distance zero (or
    within ``reach``) is in the point's cell, met in increasing number as by
    :func:`clearance_at`. Loops over every obstacle when ``grid.direct``, when
    ``l_safe + inflate`` exceeds ``grid.reach``, or for a non-finite point. Compiled
    kernel, no checks; ``l_safe > 0``.

    Compiled without reference counting (``_nrt=False``: it allocates nothing) and written
    as one flat body: otherwise every call would increment and decrement the reference
    counts of the index's arrays, which costs more than the query. It is not inlined
    (``inline="always"`` repeats the type inference of this large body at every call
    site: the first compile of a mission took 47 s).

    Parameters
    ----------
    x, y : float
        The point, m.
    grid : ObstacleGrid
        The obstacles' index (:func:`obstacle_grid`).
    gain : float
        :math:`E_r` of eq. (18).
    l_safe : float
        Repulsion radius :math:`l_\text{safe}`, m.
    max_step : float
        Cap on the repulsive step, m.
    inflate : float, default 0
        Subtracted from every distance of the repulsion (:func:`repulsion_at`), m.

    Returns
    -------
    clearance : float
        Signed distance to the nearest obstacle, m (+inf without obstacles).
    rx, ry : float
        The repulsive step, m.
    """
    rects, circles, start, items = grid.rects, grid.circles, grid.cell_start, grid.cell_items
    reach, nx, ny = grid.reach, grid.nx, grid.ny
    x0, y0, cell = grid.x0, grid.y0, grid.cell
    bounds = (grid.bounds[0], grid.bounds[1], grid.bounds[2], grid.bounds[3])
    finite = math.isfinite(x) and math.isfinite(y)
    direct = grid.direct or not (finite and l_safe + inflate <= reach)
    ci, cj = _grid_cell(x, y, x0, y0, cell, nx, ny)
    n_obs = rects.shape[0] + circles.shape[0]
    t0, t1 = (0, n_obs) if direct else (start[cj * nx + ci], start[cj * nx + ci + 1])
    best = math.inf
    fx = 0.0
    fy = 0.0
    for t in range(t0, t1):  # every obstacle, or those of the cell: increasing numbers
        k = t if direct else items[t]
        d, ux, uy = obstacle_distance(x, y, rects, circles, k)
        best = min(best, d)  # as clearance_at: a tie (+0 and -0) keeps the first
        d -= inflate
        if d < l_safe:  # repulsion_at's term, the same operations in the same order
            ell = max(d, 1e-9)  # inside an obstacle: push out along the nearest face
            mag = _quotient(gain * (_quotient(1.0, ell) - _quotient(1.0, l_safe)), ell * ell)
            fx += mag * ux
            fy += mag * uy
    # The cell lists every obstacle within reach; beyond it, rings of cells of radius r
    # until no obstacle listed in no visited cell can be nearer. (Loops without break or
    # continue: an early exit from a loop that reads the arrays defeats Numba's pruning of
    # their reference counts.)
    geometry = (x0, y0, cell, nx, ny, reach)
    slack = _SEARCH_SLACK * (abs(x) + abs(y) + grid.scale)
    searching = not direct and best > reach - slack
    searching = searching and _rings_left(x, y, best, slack, 0, ci, cj, geometry, bounds)
    r = 0
    while searching:
        r += 1
        for j in range(max(cj - r, 0), min(cj + r, ny - 1) + 1):
            edge = j == cj - r or j == cj + r  # the ring's bottom or top row, whole
            i_lo = max(ci - r, 0) if edge else ci - r  # else only the row's two ends
            for q in range(min(ci + r, nx - 1) - i_lo + 1 if edge else 2):
                i = i_lo + q if edge else ci - r + 2 * r * q
                # Skip a cell farther than best - reach: an obstacle first met in cell c is
                # reach beyond c (its cells are those within reach of its box, and c is
                # the one of them nearest to the point).
                need = best - reach + slack
                x_lo, y_lo = x0 + i * cell, y0 + j * cell
                near = 0 <= i < nx and need >= 0.0
                if near and _gap2(x, y, x_lo, x_lo + cell, y_lo, y_lo + cell) <= need * need:
                    for t in range(start[j * nx + i], start[j * nx + i + 1]):
                        d = obstacle_distance(x, y, rects, circles, items[t])[0]
                        best = min(best, d)  # (see below: any order gives the same bits)
        searching = _rings_left(x, y, best, slack, r, ci, cj, geometry, bounds)
    rx, ry = clip_norm(fx, fy, max_step)  # (last: a call while arrays are live adds counts)
    return best, rx, ry


@leaf
def clearance_grid(x, y, grid):
    """Signed distance from (x, y) to the nearest obstacle (+inf without obstacles), through
    the index: equal to ``clearance_at(x, y, rects, circles)`` bit for bit (it is
    :func:`obstacle_field` without repulsion; compiled likewise). Compiled kernel, no
    checks.

    Parameters
    ----------
    x, y : float
        The point, m.
    grid : ObstacleGrid
        The obstacles' index (:func:`obstacle_grid`).

    Returns
    -------
    float
        Clearance, m.
    """
    return obstacle_field(x, y, grid, 0.0, -math.inf, math.inf)[0]


# ---------------------------------------------------------------------------------------
# The index when it pays: the kernels take ``index`` None (few obstacles) or a grid
# ---------------------------------------------------------------------------------------
def obstacle_index(rects: ArrayLike, circles: ArrayLike, reach: float) -> ObstacleGrid | None:
    """The index a compiled caller takes (:func:`field_of`, :func:`clearance_of`): None up to
    :data:`GRID_DIRECT_MAX` obstacles (the caller then loops over them, and Numba compiles
    none of the grid's code for it), else :func:`obstacle_grid`.

    Parameters
    ----------
    rects : array_like, shape (R, 4)
        Rectangles, as in :class:`Obstacles`.
    circles : array_like, shape (C, 3)
        Circles.
    reach : float
        The largest distance at which a query needs exact per-obstacle terms, m.

    Returns
    -------
    ObstacleGrid or None
        The index, or None when it would not pay.
    """
    grid = obstacle_grid(rects, circles, reach)
    return None if grid.direct else grid


@leaf
def clearance_of(x, y, rects, circles, index):
    """Signed distance from (x, y) to the nearest obstacle: :func:`clearance_grid` on
    ``index``, or, with ``index`` None, :func:`clearance_at` over every obstacle (the same
    bits). Compiled kernel, no checks."""
    if index is not None:
        return clearance_grid(x, y, index)
    return clearance_at(x, y, rects, circles)


@leaf
def field_of(x, y, rects, circles, index, gain, l_safe, max_step):
    """``(clearance, rx, ry)`` at (x, y): :func:`obstacle_field` on ``index``, or, with
    ``index`` None, :func:`clearance_at` and :func:`repulsion_at` over every obstacle (the
    same bits). Compiled kernel, no checks."""
    if index is not None:
        return obstacle_field(x, y, index, gain, l_safe, max_step)
    rx, ry = repulsion_at(x, y, rects, circles, gain, l_safe, max_step)
    return clearance_at(x, y, rects, circles), rx, ry
