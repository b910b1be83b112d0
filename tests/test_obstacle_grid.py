"""The uniform-grid obstacle index (crlbswarm.obstacles.obstacle_grid, obstacle_field,
clearance_grid) against the loops over every obstacle (clearance_at, repulsion_at).

The reference is the library's own brute-force kernels, which the mission kernel uses
today: the index must give their results bit for bit (compared as int64 bit patterns, so
even the sign of a zero counts), for random scenes of 0 to 2000 rectangles and circles,
spread or clustered, at points inside obstacles, on their boundaries, on cell boundaries
and far outside the grid, in direct and grid mode, and for degenerate scenes (everything
in one cell, one huge obstacle, obstacles 2e6 m apart). No timing here: see
benchmarks/bench_obstacles.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st
from numba import njit

from crlbswarm import FieldError
from crlbswarm.obstacles import (
    GRID_DIRECT_MAX,
    GRID_MAX_CELLS,
    ObstacleGrid,
    clearance_at,
    clearance_grid,
    obstacle_field,
    obstacle_grid,
    repulsion_at,
)

SEEDS = [0, 1, 2]
COUNTS = [0, 1, 5, 17, 200, 2000]
L_SAFE = 5.0
GAIN = 2.0


@njit
def grid_batch(points, grid, gain, l_safe, max_step, inflate):
    """obstacle_field and clearance_grid at every point: columns clearance, rx, ry and the
    clearance again (clearance_grid)."""
    out = np.empty((points.shape[0], 4))
    for b in range(points.shape[0]):
        x, y = points[b, 0], points[b, 1]
        out[b, 0], out[b, 1], out[b, 2] = obstacle_field(
            x, y, grid, gain, l_safe, max_step, inflate
        )
        out[b, 3] = clearance_grid(x, y, grid)
    return out


@njit
def loop_batch(points, rects, circles, gain, l_safe, max_step, inflate):
    """The same columns from the loops over every obstacle."""
    out = np.empty((points.shape[0], 4))
    for b in range(points.shape[0]):
        x, y = points[b, 0], points[b, 1]
        out[b, 0] = clearance_at(x, y, rects, circles)
        out[b, 1], out[b, 2] = repulsion_at(x, y, rects, circles, gain, l_safe, max_step, inflate)
        out[b, 3] = out[b, 0]
    return out


def assert_bitwise(grid: ObstacleGrid, points: np.ndarray, **kw: float) -> np.ndarray:
    """obstacle_field / clearance_grid equal the loops bit for bit at ``points``."""
    args = (kw.get("gain", GAIN), kw.get("l_safe", L_SAFE), kw.get("max_step", 1.0),
            kw.get("inflate", 0.0))  # fmt: skip
    pts = np.ascontiguousarray(points, dtype=float)
    got = grid_batch(pts, grid, *args)
    ref = loop_batch(pts, grid.rects, grid.circles, *args)
    bad = np.flatnonzero((got.view(np.int64) != ref.view(np.int64)).any(axis=1))
    assert bad.size == 0, (pts[bad[:5]], got[bad[:5]], ref[bad[:5]])
    return got


# -- scenes and points -----------------------------------------------------------------
def scene(n: int, rng: np.random.Generator, layout: str) -> tuple[np.ndarray, np.ndarray]:
    """``n`` obstacles (about half rectangles): spread over 1 km, or in a few tight
    clusters (overlapping), or a mix of sizes from 0.01 m to 100 m."""
    n_r = n // 2 + n % 2
    n_c = n - n_r
    if layout == "spread":
        lo = rng.uniform(0.0, 1000.0, (n_r, 2))
        size = rng.uniform(0.5, 20.0, (n_r, 2))
        centres = rng.uniform(0.0, 1000.0, (n_c, 2))
        radii = rng.uniform(0.5, 10.0, n_c)
    elif layout == "clustered":
        hubs = rng.uniform(0.0, 1000.0, (4, 2))
        lo = hubs[rng.integers(0, 4, n_r)] + rng.normal(0.0, 8.0, (n_r, 2))
        size = rng.uniform(0.5, 6.0, (n_r, 2))
        centres = hubs[rng.integers(0, 4, n_c)] + rng.normal(0.0, 8.0, (n_c, 2))
        radii = rng.uniform(0.5, 4.0, n_c)
    else:  # "sizes"
        lo = rng.uniform(-500.0, 500.0, (n_r, 2))
        size = 10.0 ** rng.uniform(-2.0, 2.0, (n_r, 2))
        centres = rng.uniform(-500.0, 500.0, (n_c, 2))
        radii = 10.0 ** rng.uniform(-2.0, 2.0, n_c)
    rects = np.column_stack([lo[:, 0], lo[:, 0] + size[:, 0], lo[:, 1], lo[:, 1] + size[:, 1]])
    return rects.reshape(-1, 4), np.column_stack([centres, radii]).reshape(-1, 3)


def probe_points(grid: ObstacleGrid, rng: np.random.Generator, n_free: int = 400) -> np.ndarray:
    """Free points over (and beyond) the scene, obstacle centres, corners, edge points and
    circle boundary points, cell corners and edges, and points far outside the grid."""
    rects, circles = grid.rects, grid.circles
    if rects.size + circles.size:
        lo = min(
            rects[:, 0].min(initial=np.inf), (circles[:, 0] - circles[:, 2]).min(initial=np.inf)
        )
        hi = max(
            rects[:, 1].max(initial=-np.inf), (circles[:, 0] + circles[:, 2]).max(initial=-np.inf)
        )
        blo = min(
            rects[:, 2].min(initial=np.inf), (circles[:, 1] - circles[:, 2]).min(initial=np.inf)
        )
        bhi = max(
            rects[:, 3].max(initial=-np.inf), (circles[:, 1] + circles[:, 2]).max(initial=-np.inf)
        )
    else:
        lo, hi, blo, bhi = -10.0, 10.0, -10.0, 10.0
    wx, wy = max(hi - lo, 1.0), max(bhi - blo, 1.0)
    pts = [
        np.column_stack([rng.uniform(lo - 0.2 * wx, hi + 0.2 * wx, n_free),
                         rng.uniform(blo - 0.2 * wy, bhi + 0.2 * wy, n_free)]),
        circles[:, :2],  # centres (the radial direction is undefined there)
        circles[:, :2] + circles[:, 2:3] * np.array([1.0, 0.0]),  # on the boundary
        circles[:, :2] + circles[:, 2:3] * np.array([0.6, 0.8]),
        np.column_stack([(rects[:, 0] + rects[:, 1]) / 2, (rects[:, 2] + rects[:, 3]) / 2]),
        rects[:, [0, 2]], rects[:, [1, 3]],  # corners
        np.column_stack([rects[:, 0], (rects[:, 2] + rects[:, 3]) / 2]),  # on an edge
        np.column_stack([rects[:, 1] + L_SAFE, rects[:, 3]]),  # exactly l_safe away
        np.column_stack([rects[:, 0] - L_SAFE * 0.999999, rects[:, 2]]),
        np.array([[1e6, 1e6], [-1e6, 3.0], [2e6, -2e6], [lo - 1e5, blo], [hi + 1e5, bhi]]),
    ]  # fmt: skip
    if not grid.direct:
        i = rng.integers(0, grid.nx + 1, 50)
        j = rng.integers(0, grid.ny + 1, 50)
        corners = np.column_stack([grid.x0 + i * grid.cell, grid.y0 + j * grid.cell])
        pts += [corners, corners + np.array([0.5 * grid.cell, 0.0])]
    return np.concatenate([p.reshape(-1, 2) for p in pts])


# -- bit for bit against the loops --------------------------------------------------------
@pytest.mark.parametrize("direct", [None, True, False])
@pytest.mark.parametrize("layout", ["spread", "clustered", "sizes"])
@pytest.mark.parametrize("n", COUNTS)
@pytest.mark.parametrize("seed", SEEDS)
def test_field_is_the_loop_bit_for_bit(seed, n, layout, direct):
    rng = np.random.default_rng([seed, n, len(layout)])
    rects, circles = scene(n, rng, layout)
    grid = obstacle_grid(rects, circles, L_SAFE, direct=direct)
    assert grid.direct == (n == 0 or (n <= GRID_DIRECT_MAX if direct is None else direct))
    got = assert_bitwise(grid, probe_points(grid, rng))
    assert np.all(got[:, 0] == got[:, 3])
    if n == 0:
        assert np.all(got[:, 0] == np.inf)
        assert np.all(got[:, 1:3] == 0.0)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(
    ("reach", "l_safe", "inflate", "max_step"),
    [(5.0, 5.0, 0.0, math.inf), (12.0, 5.0, 7.0, 1.0), (12.0, 3.0, 2.0, 0.05),
     (5.0, 20.0, 0.0, 1.0), (0.0, 5.0, 0.0, 1.0), (5.0, 5.0, -3.0, 1.0)],
)  # fmt: skip
def test_inflation_and_radii_beyond_reach(seed, reach, l_safe, inflate, max_step):
    """The leader's inflated repulsion within reach uses the cell; a radius beyond reach
    (or reach 0) falls back to the loop: exact either way."""
    rng = np.random.default_rng(seed)
    rects, circles = scene(300, rng, "clustered")
    grid = obstacle_grid(rects, circles, reach, direct=False)
    assert_bitwise(grid, probe_points(grid, rng), l_safe=l_safe, inflate=inflate,
                   max_step=max_step, gain=50.0)  # fmt: skip


def test_default_mode_switches_above_the_direct_count():
    rng = np.random.default_rng(0)
    for n, direct in [(GRID_DIRECT_MAX, True), (GRID_DIRECT_MAX + 1, False)]:
        rects, circles = scene(n, rng, "spread")
        assert obstacle_grid(rects, circles, L_SAFE).direct is direct


def test_non_finite_points_give_the_loop():
    rng = np.random.default_rng(1)
    rects, circles = scene(200, rng, "spread")
    grid = obstacle_grid(rects, circles, L_SAFE)
    pts = np.array([[np.nan, 1.0], [1.0, np.nan], [np.inf, 0.0], [-np.inf, -np.inf]])
    with np.errstate(invalid="ignore"):
        got = grid_batch(pts, grid, GAIN, L_SAFE, 1.0, 0.0)
        ref = loop_batch(pts, grid.rects, grid.circles, GAIN, L_SAFE, 1.0, 0.0)
    np.testing.assert_array_equal(got, ref)


# -- degenerate scenes ----------------------------------------------------------------------
def degenerate(name: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    if name == "one_cell":  # 300 obstacles within a 1 m square
        c = rng.uniform(0.0, 1.0, (150, 2))
        rects = np.column_stack([c[:, 0], c[:, 0] + 0.01, c[:, 1], c[:, 1] + 0.02])
        return rects, np.column_stack([rng.uniform(0.0, 1.0, (150, 2)), np.full(150, 0.005)])
    if name == "one_huge":  # a 1e5 m rectangle among 200 small ones
        rects, circles = scene(200, rng, "spread")
        return np.vstack([rects, [[-5e4, 5e4, -2e4, 3e4]]]), circles
    if name == "many_huge":  # 2000 overlapping 1e5 m rectangles: coarse cells, bounded index
        lo = rng.uniform(-1e3, 1e3, (2000, 2))
        return np.column_stack([lo[:, 0], lo[:, 0] + 1e5, lo[:, 1], lo[:, 1] + 1e5]), ()
    if name == "far_apart":  # two clusters 2e6 m apart
        rects, circles = scene(100, rng, "clustered")
        shift, move = np.array([1e6, 1e6, -1e6, -1e6]), np.array([1e6, -1e6, 0.0])
        return np.vstack([rects + shift, rects - shift]), np.vstack(
            [circles + move, circles - move]
        )
    if name == "line":  # 2000 circles along a 2e6 m line: an elongated grid
        x = np.linspace(-1e6, 1e6, 2000)
        return (), np.column_stack([x, np.zeros_like(x), np.full_like(x, 3.0)])
    raise AssertionError(name)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", ["one_cell", "one_huge", "many_huge", "far_apart", "line"])
def test_degenerate_scenes(seed, name):
    rng = np.random.default_rng(seed)
    rects, circles = degenerate(name, rng)
    grid = obstacle_grid(rects, circles, L_SAFE)
    n = grid.rects.shape[0] + grid.circles.shape[0]
    assert grid.nx * grid.ny <= min(4 * n + 256, GRID_MAX_CELLS)
    assert grid.cell_items.size <= 16 * n + 4096
    pts = probe_points(grid, rng)
    near = np.concatenate([grid.rects[:, [0, 2]], grid.circles[:, :2]])
    pts = np.vstack([pts, near + rng.normal(0.0, 3.0, near.shape)])
    assert_bitwise(grid, pts)


# -- the index itself -------------------------------------------------------------------------
@pytest.mark.parametrize("layout", ["spread", "clustered", "sizes"])
def test_index_lists_each_obstacle_in_the_cells_of_its_widened_box(layout):
    rng = np.random.default_rng(7)
    rects, circles = scene(500, rng, layout)
    grid = obstacle_grid(rects, circles, L_SAFE)
    cx, cy, cr = grid.circles.T
    boxes = np.concatenate([grid.rects, np.column_stack([cx - cr, cx + cr, cy - cr, cy + cr])])
    assert grid.cell_start.shape == (grid.nx * grid.ny + 1,)
    assert grid.cell_start[0] == 0
    assert grid.cell_start[-1] == grid.cell_items.size
    assert np.all(np.diff(grid.cell_start) >= 0)
    for c in range(grid.nx * grid.ny):
        listed = grid.cell_items[grid.cell_start[c] : grid.cell_start[c + 1]]
        assert np.all(np.diff(listed) > 0)  # increasing, each obstacle once
        i, j = c % grid.nx, c // grid.nx
        x_lo, y_lo = grid.x0 + i * grid.cell, grid.y0 + j * grid.cell
        gap_x = np.maximum(np.maximum(boxes[:, 0] - (x_lo + grid.cell), x_lo - boxes[:, 1]), 0.0)
        gap_y = np.maximum(np.maximum(boxes[:, 2] - (y_lo + grid.cell), y_lo - boxes[:, 3]), 0.0)
        must = np.flatnonzero(np.maximum(gap_x, gap_y) < L_SAFE * (1 - 1e-9))
        assert set(must) <= set(listed)
        assert np.all(np.maximum(gap_x, gap_y)[listed] <= L_SAFE * (1 + 1e-6) + 1e-6)
    for arr in (grid.rects, grid.circles, grid.cell_start, grid.cell_items, grid.bounds):
        assert not arr.flags.writeable


def test_cell_count_and_entries_stay_linear():
    """Whatever the extent and the sizes, at most 4 n + 256 cells and 16 n + 4096 entries."""
    rng = np.random.default_rng(3)
    for n in (1, 17, 1000, 20000):
        lo = rng.uniform(-1e6, 1e6, (n, 2))
        size = 10.0 ** rng.uniform(-3.0, 5.0, (n, 2))
        rects = np.column_stack([lo[:, 0], lo[:, 0] + size[:, 0], lo[:, 1], lo[:, 1] + size[:, 1]])
        grid = obstacle_grid(rects, (), 5.0, direct=False)
        assert grid.nx * grid.ny <= 4 * n + 256
        assert grid.cell_items.size <= 16 * n + 4096


@pytest.mark.parametrize("reach", [-1.0, math.nan, math.inf])
def test_reach_must_be_a_distance(reach):
    with pytest.raises(FieldError, match="reach"):
        obstacle_grid([[0.0, 1.0, 0.0, 1.0]], (), reach)


def test_obstacles_are_checked_as_in_obstacles():
    with pytest.raises(FieldError, match="rectangles"):
        obstacle_grid([[1.0, 0.0, 0.0, 1.0]], (), 5.0)
    with pytest.raises(FieldError, match="circles"):
        obstacle_grid((), [[0.0, 0.0, -1.0]], 5.0)


# -- property: any small scene -------------------------------------------------------------
coordinate = st.floats(-50.0, 50.0)
extent = st.floats(0.001, 30.0)


@given(
    rects=st.lists(st.tuples(coordinate, coordinate, extent, extent), max_size=30),
    circles=st.lists(st.tuples(coordinate, coordinate, extent), max_size=30),
    points=st.lists(st.tuples(coordinate, coordinate), min_size=1, max_size=20),
    reach=st.floats(0.0, 20.0),
    l_safe=st.floats(0.1, 20.0),
)
def test_any_scene(rects, circles, points, reach, l_safe):
    r = np.array([[x, x + w, y, y + h] for x, y, w, h in rects]).reshape(-1, 4)
    c = np.array(circles, dtype=float).reshape(-1, 3)
    grid = obstacle_grid(r, c, reach, direct=False)
    pts = np.array(points, dtype=float)
    # the obstacles' own corners and centres too: boundaries and interiors
    pts = np.vstack([pts, r[:, [0, 2]], r[:, [1, 3]], c[:, :2], c[:, :2] + c[:, 2:] * [1, 0]])
    assert_bitwise(grid, pts, l_safe=l_safe)
    assert_bitwise(grid, pts, l_safe=max(min(l_safe, reach), 0.1))


@pytest.mark.parametrize("reach", [0.0, 5.0])
def test_signed_zeros_of_touching_obstacles(reach):
    """On a rectangle's edge that touches a disc the distances are -0.0 (the rectangle's
    inside branch) and +0.0 (the disc): the clearance keeps the first in obstacle order,
    as clearance_at does, whichever cell the obstacles are listed in."""
    rects = np.array([[10.0 * k + 3.0, 10.0 * k + 5.0, 0.0, 2.0] for k in range(20)])
    circles = np.array([[10.0 * k + 2.0, 1.0, 1.0] for k in range(20)])
    grid = obstacle_grid(rects, circles, reach, direct=False)
    pts = np.column_stack([rects[:, 0], np.ones(20)])  # on both boundaries
    got = assert_bitwise(grid, pts, l_safe=max(reach, 0.1))
    assert np.all(np.signbit(got[:, 0]))
