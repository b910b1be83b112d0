r"""Complete guidance and slot assignment (not in the paper).

A local potential field stops in front of a wall or in a U-shaped trap. The leader of the
formation instead follows a collision-free route for the formation's centre, planned for the
formation's smallest footprint: the centre must keep a distance ``inflation`` (the smallest
formation radius plus a clearance margin, m) from every obstacle, i.e. stay out of every
obstacle *inflated* by ``inflation`` (a rectangle becomes a rounded rectangle, a disc of
radius :math:`R` a disc of radius :math:`R + r`).

**Roadmap** (:func:`build_roadmap`). The nodes are the vertices of a polygon circumscribing
each inflated obstacle, pushed out by :data:`NODE_MARGIN` so that they are free: at each
corner of a rectangle :data:`CORNER_VERTICES` vertices on the circumscribed polygon of its
rounded quarter (radius :math:`r/\cos(\pi/(4n))`), around a disc a circumscribed regular
polygon of :data:`DISC_VERTICES` sides (circumradius :math:`(R + r)/\cos(\pi/K)`); the edges
of these polygons lie outside the inflated shapes. Nodes inside another inflated obstacle
are dropped, the goal is added as the last node, and two nodes are joined when the segment
between them is clear of every inflated obstacle (:func:`segment_clear`, exact). Dijkstra
(networkx) from the goal gives each node its distance to the goal and the next node toward
it. Coincident vertices (a corner shared by two rectangles) give one node.

The route is feasible for the true inflated shapes, so it is at least the exact shortest
route; it is at most the shortest route around the circumscribing polygons, which lie inside
the shapes grown by the factor :math:`\sec 15^\circ \approx 1.035` (a rectangle inflated by
:math:`1.035\,r`, a disc of radius :math:`1.035(R + r)`): roughly
:math:`0.035\rho` longer per radian turned around an obstacle of inflated radius
:math:`\rho` (under 1 % on the test layouts). A passage narrower than the polygons but
wider than the inflated shapes may be missed.

**Navigation** (:func:`next_waypoint`, compiled, called by the mission kernel every step):
from a point, the goal if it is visible, else the visible node minimising the distance to
it plus the node's distance to the goal. Moving toward it along the straight segment
decreases the distance to go by the length moved. A point closer than ``inflation`` to an
obstacle may move away from it or along it, not closer.

**Route check** (:func:`plan_route`): the waypoints from a start to the goal, or one
:class:`~crlbswarm.errors.FieldError` line saying why there is none: the target too close to
an obstacle, the start or target enclosed, or the passage that closes first (found by
bisection on the inflation) with its width and the width the formation needs.

**Slots** (:func:`assign_slots`): the leader keeps its slot; the followers take the others
so as to minimise the total straight-line travel (Hungarian algorithm, scipy).

networkx and scipy are imported by the functions that use them, not with this module.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from pydantic import Field

from . import _validation as _v
from ._config import ConfigModel, PositiveFloat
from ._numba import leaf
from .errors import FieldError
from .obstacles import (
    Obstacles,
    check_obstacles,
    circle_distance,
    obstacle_clearance,
    obstacle_distance,
    rectangle_distance,
)

__all__ = [
    "BISECTION_STEPS",
    "CLEAR_TOL",
    "CORNER_VERTICES",
    "DEFAULT_HINT",
    "DISC_VERTICES",
    "MAX_ROADMAP_OBSTACLES",
    "MAX_SCENARIO_STARTS",
    "MIN_MAX_RADIUS",
    "NODE_MARGIN",
    "FormationConfig",
    "GuidanceConfig",
    "Roadmap",
    "assign_slots",
    "best_waypoint",
    "build_roadmap",
    "check_roadmap_size",
    "next_waypoint",
    "next_waypoints",
    "plan_route",
    "segment_clear",
]

#: Vertices of the roadmap on each rounded corner of an inflated rectangle (steps of 30°).
CORNER_VERTICES = 3
#: Sides of the polygon circumscribing an inflated disc (steps of 30°).
DISC_VERTICES = 12
#: How far the polygons are pushed out beyond the inflated shapes, m, so that their
#: vertices and edges are free by much more than :data:`CLEAR_TOL`.
NODE_MARGIN = 1e-6
#: Rounding tolerance of the clearance test, m: a segment is clear when it keeps at least
#: ``inflation - CLEAR_TOL`` from every obstacle.
CLEAR_TOL = 1e-9
#: Bisection steps on the inflation when :func:`plan_route` looks for the closing passage.
BISECTION_STEPS = 12

#: Smallest ``formation.max_radius``, m.
MIN_MAX_RADIUS = 1e-3

#: Most starts of a scenario's constrained design (``formation.starts``): each costs about
#: :math:`M^3` and the design is made when the scenario is validated.
MAX_SCENARIO_STARTS = 1000

#: Advice that ends the message of :func:`plan_route` by default.
DEFAULT_HINT = "lower the inflation or widen the passage"


# ---------------------------------------------------------------------------------------
# Compiled kernels: exact segment clearance and the navigation step
# ---------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _point_segment_d2(px, py, ax, ay, bx, by):
    """Squared distance from (px, py) to the segment ab."""
    dx = bx - ax
    dy = by - ay
    den = dx * dx + dy * dy
    t = 0.0
    if den > 0.0:
        t = min(max(((px - ax) * dx + (py - ay) * dy) / den, 0.0), 1.0)
    ex = ax + t * dx - px
    ey = ay + t * dy - py
    return ex * ex + ey * ey


@njit(cache=True, inline="always")
def _point_box_d2(px, py, xmin, xmax, ymin, ymax):
    """Squared distance from (px, py) to the closed box (0 inside)."""
    ex = px - min(max(px, xmin), xmax)
    ey = py - min(max(py, ymin), ymax)
    return ex * ex + ey * ey


@njit(cache=True)
def _clip_box(ax, ay, bx, by, xmin, xmax, ymin, ymax):
    """Liang-Barsky: the parameters ``t0 <= t1`` of the part of ab in the closed box, or
    ``t0 > t1`` when the segment misses it."""
    t0 = 0.0
    t1 = 1.0
    dx = bx - ax
    dy = by - ay
    for k in range(4):
        if k == 0:
            p, q = -dx, ax - xmin
        elif k == 1:
            p, q = dx, xmax - ax
        elif k == 2:
            p, q = -dy, ay - ymin
        else:
            p, q = dy, ymax - ay
        if p == 0.0:
            if q < 0.0:
                return 1.0, 0.0
        elif p < 0.0:
            t0 = max(t0, q / p)
        else:
            t1 = min(t1, q / p)
        if t0 > t1:
            return t0, t1
    return t0, t1


@njit(cache=True)
def _segment_rect_clear(ax, ay, bx, by, xmin, xmax, ymin, ymax, delta):
    """Whether every point of ab has signed distance >= ``delta`` from the rectangle.

    ``delta > 0``: the distance between the segment and the box (0 if they meet) is the
    smallest of the endpoints' distances to the box and the corners' distances to the
    segment (two disjoint convex polygons). ``delta <= 0``: the segment must not enter the
    open box shrunk by ``-delta``.
    """
    if delta <= 0.0:
        xmin, xmax, ymin, ymax = xmin - delta, xmax + delta, ymin - delta, ymax + delta
        if xmin >= xmax or ymin >= ymax:
            return True
        t0, t1 = _clip_box(ax, ay, bx, by, xmin, xmax, ymin, ymax)
        if t0 > t1:
            return True
        t = 0.5 * (t0 + t1)  # a chord of a convex set: its midpoint is inside if any point is
        mx = ax + t * (bx - ax)
        my = ay + t * (by - ay)
        return not (xmin < mx < xmax and ymin < my < ymax)
    d2 = delta * delta
    if _point_box_d2(ax, ay, xmin, xmax, ymin, ymax) < d2:
        return False
    if _point_box_d2(bx, by, xmin, xmax, ymin, ymax) < d2:
        return False
    t0, t1 = _clip_box(ax, ay, bx, by, xmin, xmax, ymin, ymax)
    if t0 <= t1:
        return False
    for cx, cy in ((xmin, ymin), (xmin, ymax), (xmax, ymin), (xmax, ymax)):
        if _point_segment_d2(cx, cy, ax, ay, bx, by) < d2:
            return False
    return True


@leaf
def _clear_from(ax, ay, bx, by, rects, circles, inflation, relax):
    """Segment clearance; with ``relax``, an obstacle whose inflated region contains ``a``
    only forbids going deeper than ``a`` (and is ignored if ``a`` is inside the obstacle)."""
    delta = inflation - CLEAR_TOL
    lox, hix = min(ax, bx), max(ax, bx)
    loy, hiy = min(ay, by), max(ay, by)
    for i in range(rects.shape[0]):
        xmin, xmax, ymin, ymax = rects[i, 0], rects[i, 1], rects[i, 2], rects[i, 3]
        if hix <= xmin - delta or lox >= xmax + delta or hiy <= ymin - delta:
            continue  # the segment's box is beyond reach (any threshold <= delta)
        if loy >= ymax + delta:
            continue
        thr = delta
        if relax:
            da, _, _ = rectangle_distance(ax, ay, xmin, xmax, ymin, ymax)
            if da <= 0.0:
                continue
            thr = min(thr, da - CLEAR_TOL)
        if not _segment_rect_clear(ax, ay, bx, by, xmin, xmax, ymin, ymax, thr):
            return False
    for j in range(circles.shape[0]):
        cx, cy, rad = circles[j, 0], circles[j, 1], circles[j, 2]
        reach = rad + delta
        if hix <= cx - reach or lox >= cx + reach or hiy <= cy - reach or loy >= cy + reach:
            continue
        thr = delta
        if relax:
            da, _, _ = circle_distance(ax, ay, cx, cy, rad)
            if da <= 0.0:
                continue
            thr = min(thr, da - CLEAR_TOL)
        need = rad + thr
        if need > 0.0 and _point_segment_d2(cx, cy, ax, ay, bx, by) < need * need:
            return False
    return True


@leaf
def segment_clear(ax, ay, bx, by, rects, circles, inflation):
    """Whether the segment from (ax, ay) to (bx, by) keeps at least ``inflation`` (m, less
    :data:`CLEAR_TOL`) from every obstacle: exact segment-to-rectangle and segment-to-disc
    distances. With ``inflation`` 0 the segment may touch an obstacle but not enter it.

    Compiled kernel, no checks; ``rects`` (R, 4) and ``circles`` (C, 3) as in
    :class:`~crlbswarm.obstacles.Obstacles`.
    """
    return _clear_from(ax, ay, bx, by, rects, circles, inflation, False)


@njit(cache=True)
def best_waypoint(px, py, nodes, dist_to_goal, gx, gy, rects, circles, inflation):
    """:func:`next_waypoint` as an index: ``(k, total)``, with ``k`` the node to fly to, -1 if
    the goal is in sight, -2 if no visible node leads to the goal (``total`` the distance
    to go, +inf then). Compiled kernel, no checks."""
    if _clear_from(px, py, gx, gy, rects, circles, inflation, True):
        return -1, math.sqrt((gx - px) ** 2 + (gy - py) ** 2)
    best = math.inf
    best_d = math.inf
    best_k = -2
    for k in range(nodes.shape[0]):
        d = dist_to_goal[k]
        if not d > 0.0 or d == math.inf:  # the goal (tested above) or unreachable
            continue
        total = math.sqrt((nodes[k, 0] - px) ** 2 + (nodes[k, 1] - py) ** 2) + d
        tie = 1e-9 * (1.0 + total)
        if total > best + tie:
            continue
        if total >= best - tie and d >= best_d:
            continue  # ties go to the node nearer the goal (never the node at p itself)
        if not _clear_from(px, py, nodes[k, 0], nodes[k, 1], rects, circles, inflation, True):
            continue
        best, best_d, best_k = total, d, k
    return best_k, best


@njit(cache=True)
def next_waypoint(px, py, nodes, dist_to_goal, gx, gy, rects, circles, inflation):
    """The point to fly straight to from (px, py), and the distance to go through it, m.

    The goal (gx, gy) and its distance if the segment to it is clear
    (:func:`segment_clear`); else the visible node ``k`` minimising
    ``|p - nodes[k]| + dist_to_goal[k]``, and that sum (on a tie, within 1e-9 relative, the
    node nearer the goal, so that a point standing on a node moves on). With no visible node
    that leads to the goal: the goal and ``+inf``.

    The point may be closer than ``inflation`` to an obstacle (the formation's centre at
    the start, or pushed by a disturbance): the segments from it are then only forbidden to
    come closer to *that* obstacle than the point already is, and an obstacle containing
    the point itself is ignored. Allocation-free, ``O(nodes x obstacles)``, with early
    exits (bounding boxes, nodes that cannot beat the best so far).

    Compiled kernel, no checks: ``nodes``, ``dist_to_goal``, ``rects``, ``circles`` and
    ``inflation`` are the fields of a :class:`Roadmap` (:func:`build_roadmap`).
    """
    k, total = best_waypoint(px, py, nodes, dist_to_goal, gx, gy, rects, circles, inflation)
    if k >= 0:
        return nodes[k, 0], nodes[k, 1], total
    if k == -1:
        return gx, gy, total
    return gx, gy, math.inf


@njit(cache=True)
def _next_waypoint_batch(p, nodes, dist, gx, gy, rects, circles, inflation, out, togo):
    for b in range(p.shape[0]):
        wx, wy, d = next_waypoint(p[b, 0], p[b, 1], nodes, dist, gx, gy, rects, circles, inflation)
        out[b, 0] = wx
        out[b, 1] = wy
        togo[b] = d


@njit(cache=True)
def _visibility_edges(nodes, rects, circles, inflation):
    """The node pairs ``(i, j)``, ``i < j``, joined by a clear segment, and its length."""
    n = nodes.shape[0]
    m = n * (n - 1) // 2
    ei = np.empty(m, np.int64)
    ej = np.empty(m, np.int64)
    w = np.empty(m)
    c = 0
    for i in range(n):
        for j in range(i + 1, n):
            ax, ay, bx, by = nodes[i, 0], nodes[i, 1], nodes[j, 0], nodes[j, 1]
            if segment_clear(ax, ay, bx, by, rects, circles, inflation):
                ei[c] = i
                ej[c] = j
                w[c] = math.sqrt((bx - ax) ** 2 + (by - ay) ** 2)
                c += 1
    return ei[:c], ej[:c], w[:c]


@njit(cache=True)
def _obstacle_distances(x, y, rects, circles, out):
    """Signed distance from (x, y) to each obstacle, rectangles first."""
    for k in range(rects.shape[0] + circles.shape[0]):
        out[k] = obstacle_distance(x, y, rects, circles, k)[0]


# ---------------------------------------------------------------------------------------
# The roadmap
# ---------------------------------------------------------------------------------------
def _readonly(arr: np.ndarray) -> np.ndarray:
    out = np.ascontiguousarray(arr).copy()
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class Roadmap:
    """A visibility roadmap toward one goal among inflated obstacles (read-only arrays).

    Built by :func:`build_roadmap`; its fields are the arguments of :func:`next_waypoint`.

    Parameters
    ----------
    nodes : ndarray, shape (N, 2)
        Node positions, m; the last node is the goal.
    dist_to_goal : ndarray, shape (N,)
        Length of the shortest roadmap path from each node to the goal, m (``inf`` where
        the goal cannot be reached).
    next_node : ndarray of int64, shape (N,)
        Index of the next node toward the goal (-1 for the goal and unreachable nodes).
    edges : ndarray of int64, shape (E, 2)
        The node pairs joined by a clear segment (for plots and checks).
    rects : ndarray, shape (R, 4)
        The rectangles, as in :class:`~crlbswarm.obstacles.Obstacles`.
    circles : ndarray, shape (C, 3)
        The discs, as in :class:`~crlbswarm.obstacles.Obstacles`.
    inflation : float
        Distance the route keeps from every obstacle, m.
    goal : ndarray, shape (2,)
        The goal, m.
    """

    nodes: np.ndarray
    dist_to_goal: np.ndarray
    next_node: np.ndarray
    edges: np.ndarray
    rects: np.ndarray
    circles: np.ndarray
    inflation: float
    goal: np.ndarray


def _obstacle_nodes(rects: np.ndarray, circles: np.ndarray, inflation: float) -> np.ndarray:
    """Vertices of the polygons circumscribing the inflated obstacles, pushed out."""
    rho = inflation + NODE_MARGIN
    n = CORNER_VERTICES
    step = 0.5 * np.pi / n
    # Corners (xmax, ymax), (xmin, ymax), (xmin, ymin), (xmax, ymin): quarters from 0, 90, ...
    cx = rects[:, [1, 0, 0, 1]]
    cy = rects[:, [3, 3, 2, 2]]
    ang = 0.5 * np.pi * np.arange(4)[:, None] + step * (np.arange(n) + 0.5)  # (4, n)
    radius = rho / math.cos(0.5 * step)
    rx = cx[:, :, None] + radius * np.cos(ang)
    ry = cy[:, :, None] + radius * np.sin(ang)
    k = DISC_VERTICES
    theta = 2.0 * np.pi * (np.arange(k) + 0.5) / k
    big = (circles[:, 2:3] + rho) / math.cos(np.pi / k)
    dx = circles[:, 0:1] + big * np.cos(theta)
    dy = circles[:, 1:2] + big * np.sin(theta)
    x = np.concatenate([rx.reshape(-1), dx.reshape(-1)])
    y = np.concatenate([ry.reshape(-1), dy.reshape(-1)])
    return np.stack([x, y], axis=-1)


def _check_inflation(inflation: object) -> float:
    return _v.in_range(inflation, "inflation", 0.0, _v.MAX_DISTANCE, " m")


def _goal_point(goal_xy: ArrayLike, name: str) -> np.ndarray:
    goal = _v.location(goal_xy, name)
    if goal.shape != (2,):
        raise FieldError(name, f"expected shape (2,), got {goal.shape}")
    return goal


def _default_names(obstacles: Obstacles) -> list[str]:
    n_r = obstacles.rectangles.shape[0]
    return [f"rectangles[{i}]" for i in range(n_r)] + [
        f"circles[{j}]" for j in range(obstacles.circles.shape[0])
    ]


def _nearest_obstacle(point: np.ndarray, obstacles: Obstacles) -> tuple[int, float]:
    """Index (rectangles first) of the obstacle nearest ``point`` and its signed distance."""
    out = np.empty(obstacles.count)
    if out.size == 0:
        return -1, math.inf
    _obstacle_distances(point[0], point[1], obstacles.rectangles, obstacles.circles, out)
    i = int(np.argmin(out))
    return i, float(out[i])


#: Most obstacles a roadmap is built over: its nodes grow with the obstacles and its edges
#: are checked against every obstacle, so the work grows with the cube of their number
#: (256 obstacles: about a second; 1600: more than a minute).
MAX_ROADMAP_OBSTACLES = 256


def check_roadmap_size(obstacles: Obstacles, field: str) -> Obstacles:
    """Refuse a roadmap over more than :data:`MAX_ROADMAP_OBSTACLES` obstacles.

    Parameters
    ----------
    obstacles : Obstacles
        The obstacles.
    field : str
        What to name in the error.

    Returns
    -------
    Obstacles
        The same obstacles.

    Raises
    ------
    FieldError
        If there are too many.
    """
    if obstacles.count > MAX_ROADMAP_OBSTACLES:
        raise FieldError(
            field,
            f"a route planned over {obstacles.count} obstacles would take too long (the work "
            f"grows with the cube of their number); at most {MAX_ROADMAP_OBSTACLES}",
        )
    return obstacles


def build_roadmap(obstacles: Obstacles, goal_xy: ArrayLike, inflation: float) -> Roadmap:
    """The visibility roadmap toward ``goal_xy`` around the obstacles inflated by ``inflation``.

    Nodes: the vertices of the polygons circumscribing the inflated obstacles (see the
    module's docstring), less those inside another inflated obstacle, then the goal. Edges:
    the node pairs whose segment is clear (:func:`segment_clear`). Each node's distance to
    the goal and next node come from Dijkstra's algorithm (networkx) run from the goal.

    Parameters
    ----------
    obstacles : Obstacles
        Rectangles and discs.
    goal_xy : array_like, shape (2,)
        The goal, m; at least ``inflation`` from every obstacle.
    inflation : float
        Distance to keep from every obstacle, m, >= 0.

    Returns
    -------
    Roadmap
        Nodes, distances to the goal, next nodes, edges, obstacles and goal.

    Raises
    ------
    FieldError
        On an invalid argument, or ``goal_xy`` closer than ``inflation`` to an obstacle.
    """
    import networkx as nx

    obs = check_roadmap_size(check_obstacles(obstacles), "obstacles")
    goal = _goal_point(goal_xy, "goal_xy")
    infl = _check_inflation(inflation)
    i, d = _nearest_obstacle(goal, obs)
    if d < infl - CLEAR_TOL:
        raise FieldError(
            "goal_xy",
            f"is inside {_default_names(obs)[i]} inflated by {infl:.3g} m "
            f"(its distance is {d:.3g} m)",
        )
    cand = _obstacle_nodes(obs.rectangles, obs.circles, infl)
    if cand.shape[0]:  # free vertices; shared corners give one node
        cand = np.unique(cand[obstacle_clearance(cand, obs) >= infl], axis=0)
    nodes = np.concatenate([cand, goal[None, :]])
    ei, ej, w = _visibility_edges(nodes, obs.rectangles, obs.circles, infl)
    graph = nx.Graph()
    graph.add_nodes_from(range(nodes.shape[0]))
    graph.add_weighted_edges_from(zip(ei.tolist(), ej.tolist(), w.tolist(), strict=True))
    target = nodes.shape[0] - 1
    dist, paths = nx.single_source_dijkstra(graph, target)  # a tree: no cycle, deterministic
    dist_to_goal = np.full(nodes.shape[0], np.inf)
    next_node = np.full(nodes.shape[0], -1, dtype=np.int64)
    for k, value in dist.items():
        dist_to_goal[k] = value
        if k != target:
            next_node[k] = paths[k][-2]
    return Roadmap(
        nodes=_readonly(nodes),
        dist_to_goal=_readonly(dist_to_goal),
        next_node=_readonly(next_node),
        edges=_readonly(np.stack([ei, ej], axis=-1)),
        rects=obs.rectangles,
        circles=obs.circles,
        inflation=infl,
        goal=_readonly(goal),
    )


def next_waypoints(roadmap: Roadmap, points_xy: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """:func:`next_waypoint` for a batch of points.

    Parameters
    ----------
    roadmap : Roadmap
        From :func:`build_roadmap`.
    points_xy : array_like, shape (..., 2)
        Points, m (e.g. formation centres).

    Returns
    -------
    waypoints : ndarray, shape (..., 2)
        Where to fly straight to from each point, m.
    distance_to_go : ndarray, shape (...)
        Length of the route through that waypoint to the goal, m (``inf``: no route).
    """
    if not isinstance(roadmap, Roadmap):
        raise FieldError("roadmap", f"expected a Roadmap, got {type(roadmap).__name__}")
    p = _v.point(points_xy, "points_xy")
    pb = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 2)
    out = np.empty_like(pb)
    togo = np.empty(pb.shape[0])
    rm = roadmap
    gx, gy = float(rm.goal[0]), float(rm.goal[1])
    _next_waypoint_batch(
        pb, rm.nodes, rm.dist_to_goal, gx, gy, rm.rects, rm.circles, rm.inflation, out, togo
    )
    return out.reshape(p.shape), togo.reshape(p.shape[:-1])


# ---------------------------------------------------------------------------------------
# Route check with a diagnosis
# ---------------------------------------------------------------------------------------
def _route(roadmap: Roadmap, start: np.ndarray) -> np.ndarray | None:
    """The waypoints from ``start`` (first) to the goal (last), or None."""
    rm = roadmap
    k, total = best_waypoint(
        start[0], start[1], rm.nodes, rm.dist_to_goal, rm.goal[0], rm.goal[1],
        rm.rects, rm.circles, rm.inflation,
    )  # fmt: skip
    if k == -2 or not math.isfinite(total):
        return None
    points = [start]
    if k == -1:
        points.append(rm.goal)
    for _ in range(rm.nodes.shape[0]):  # the next nodes form a tree rooted at the goal
        if k < 0:
            break
        points.append(rm.nodes[k])
        k = int(rm.next_node[k])
    return np.array(points, dtype=float)


def _gap(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Distance between two obstacles (rows of 4: rectangle, 3: disc) and a pair of nearest
    points (for two boxes overlapping along an axis, the middle of the overlap)."""
    if a.size == 3 and b.size == 4:
        d, pb, pa = _gap(b, a)
        return d, pa, pb
    if a.size == 4 and b.size == 4:
        pa, pb = np.empty(2), np.empty(2)
        for ax in range(2):
            lo_a, hi_a, lo_b, hi_b = a[2 * ax], a[2 * ax + 1], b[2 * ax], b[2 * ax + 1]
            if hi_a < lo_b:
                pa[ax], pb[ax] = hi_a, lo_b
            elif hi_b < lo_a:
                pa[ax], pb[ax] = lo_a, hi_b
            else:
                pa[ax] = pb[ax] = 0.5 * (max(lo_a, lo_b) + min(hi_a, hi_b))
        return float(np.hypot(*(pb - pa))), pa, pb
    cb, rb = b[:2], b[2]
    if a.size == 4:
        pa = np.array([min(max(cb[0], a[0]), a[1]), min(max(cb[1], a[2]), a[3])])
        ra = 0.0
    else:
        pa, ra = a[:2], a[2]
    off = cb - pa
    norm = float(np.hypot(*off))
    if norm == 0.0:
        return -math.inf, pa, pa
    u = off / norm
    return norm - ra - rb, pa + ra * u, cb - rb * u


def _crosses(p: np.ndarray, q: np.ndarray, route: np.ndarray) -> bool:
    """Whether the segment pq meets the polyline ``route``."""

    def orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
        return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                       - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))  # fmt: skip

    a, b = route[:-1], route[1:]
    o1, o2 = orient(p, q, a), orient(p, q, b)
    o3, o4 = orient(a, b, p), orient(a, b, q)
    return bool(np.any((o1 * o2 <= 0) & (o3 * o4 <= 0)))


def _closing_passage(
    route: np.ndarray, obstacles: Obstacles, wide: float
) -> tuple[int, int, float] | None:
    """The narrowest gap between two obstacles that ``route`` passes through, if it is at
    most ``wide`` m wide: ``(i, j, width)`` (indices rectangles first)."""
    rows = [*obstacles.rectangles, *obstacles.circles]
    best = None
    for i in range(len(rows)):
        for j in range(i + 1, len(rows)):
            width, pa, pb = _gap(rows[i], rows[j])
            narrower = best is None or width < best[2]
            if 0.0 < width <= wide and narrower and _crosses(pa, pb, route):
                best = (i, j, width)
    return best


def _m(value: float) -> str:
    return f"{value:.3g}"


def _no_route_reason(
    start: np.ndarray, goal: np.ndarray, obs: Obstacles, infl: float, names: Sequence[str]
) -> str | None:
    """Why there is no route at ``infl``, or None when there is none even at inflation 0
    (a smaller formation would not help)."""
    lo, hi = 0.0, infl
    route = _route(build_roadmap(obs, goal, 0.0), start)
    if route is None:
        return None
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        found = _route(build_roadmap(obs, goal, mid), start)
        if found is None:
            hi = mid
        else:
            lo, route = mid, found
    up_to = f"routes exist up to an inflation of about {_m(lo)} m"
    passage = _closing_passage(route, obs, 2.0 * hi + NODE_MARGIN)
    if passage is None:
        return f"no route keeps {_m(infl)} m from every obstacle ({up_to})"
    i, j, width = passage
    return (
        f"the passage between {names[i]} and {names[j]} is {_m(width)} m wide; the formation "
        f"needs 2 x {_m(infl)} = {_m(2.0 * infl)} m ({up_to})"
    )


def _check_names(names: Sequence[str] | None, obstacles: Obstacles) -> list[str]:
    if names is None:
        return _default_names(obstacles)
    labels = list(names) if not isinstance(names, str) else [names]
    if len(labels) != obstacles.count or not all(isinstance(s, str) for s in labels):
        raise FieldError(
            "names", f"expected {obstacles.count} labels (rectangles first, then circles)"
        )
    return labels


def plan_route(
    start_xy: ArrayLike,
    goal_xy: ArrayLike,
    obstacles: Obstacles,
    inflation: float,
    *,
    names: Sequence[str] | None = None,
    field: str = "guidance",
    hint: str = DEFAULT_HINT,
    goal_name: str = "the target",
) -> np.ndarray:
    """The roadmap route from ``start_xy`` to ``goal_xy`` keeping ``inflation`` from every
    obstacle, or one error line saying why there is none.

    The first segment follows the rule of :func:`next_waypoint` (a start closer than
    ``inflation`` to an obstacle may leave it, not go deeper). Without a route, the
    diagnosis is: the target closer than ``inflation`` to an obstacle; no route even at
    inflation 0 (``"no route from the start to the target, even for a point"``: the start
    or the target is enclosed, and ``hint`` is left out); else the largest inflation with a
    route is found by bisection (:data:`BISECTION_STEPS` steps) and the narrowest passage
    between two obstacles that the route at that inflation goes through is named, with its
    width and the width the formation needs, ``2 x inflation``.

    Parameters
    ----------
    start_xy : array_like, shape (2,)
        Start of the formation's centre, m.
    goal_xy : array_like, shape (2,)
        Goal of the formation's centre (over the target), m.
    obstacles : Obstacles
        Rectangles and discs.
    inflation : float
        Distance the centre keeps from every obstacle, m, >= 0 (the formation's smallest
        radius plus a clearance margin).
    names : sequence of str, optional
        A label for each obstacle, rectangles first then circles, as they should appear in
        the message (default ``"rectangles[i]"``, ``"circles[j]"``).
    field : str, default "guidance"
        The ``field`` of the :class:`~crlbswarm.errors.FieldError` raised when there is no
        route (the scenario names its own).
    hint : str, default "lower the inflation or widen the passage"
        Advice appended to that message, after ``"; "``.
    goal_name : str, default "the target"
        What the goal is called in the message.

    Returns
    -------
    ndarray, shape (W, 2)
        The waypoints, m: the start first, the goal last (``W >= 2``).

    Raises
    ------
    FieldError
        On an invalid argument (named), or, with ``field``, when there is no route.

    Examples
    --------
    >>> from crlbswarm.obstacles import Obstacles
    >>> walls = Obstacles(rectangles=[[30, 45, 0, 34], [30, 45, 54, 80]])
    >>> plan_route([0, 0], [80, 90], walls, 8.0).shape[1]
    2
    """
    start = _goal_point(start_xy, "start_xy")
    goal = _goal_point(goal_xy, "goal_xy")
    obs = check_roadmap_size(check_obstacles(obstacles), "obstacles")
    infl = _check_inflation(inflation)
    labels = _check_names(names, obs)
    for name, text in (("field", field), ("hint", hint), ("goal_name", goal_name)):
        if not isinstance(text, str):
            raise FieldError(name, "expected a str")
    tail = f"; {hint}" if hint else ""
    i, d = _nearest_obstacle(goal, obs)
    if d < infl - CLEAR_TOL:
        where = f"inside {labels[i]}" if d <= 0 else f"{_m(d)} m from {labels[i]}"
        raise FieldError(
            field, f"{goal_name} is {where}; the formation needs {_m(infl)} m around it{tail}"
        )
    route = _route(build_roadmap(obs, goal, infl), start)
    if route is None:
        reason = _no_route_reason(start, goal, obs, infl, labels)
        if reason is None:  # no advice about the formation's size can help
            raise FieldError(
                field,
                "no route from the start to the target, even for a point: obstacles enclose "
                "one of them",
            )
        raise FieldError(field, reason + tail)
    return route


# ---------------------------------------------------------------------------------------
# Slot assignment
# ---------------------------------------------------------------------------------------
def assign_slots(
    start_xy: ArrayLike, slots_xy: ArrayLike, leader: int, kinds: ArrayLike | None = None
) -> np.ndarray:
    """Which slot each UAV takes: the leader keeps its own, the followers take the others
    so as to minimise the total straight-line travel.

    With ``kinds``, a UAV takes only a slot made for a UAV of its own kind (unequal UAVs:
    each slot of the unequal-UAV optimum is at its UAV's own elevation, so only a UAV with
    the same radar may take it); the assignment is then solved per kind.

    The followers' problem is a linear assignment on the Euclidean distances, solved by
    :func:`scipy.optimize.linear_sum_assignment`. Ties (several assignments of equal total
    travel) are broken deterministically: the same inputs always give the same answer,
    the one that function returns for the distance matrix with the followers and the free
    slots in increasing index order.

    Parameters
    ----------
    start_xy : array_like, shape (M, 2)
        The UAVs' positions, m.
    slots_xy : array_like, shape (M, 2)
        The slots' positions, m.
    leader : int
        Index of the leader (UAV ``leader`` takes slot ``leader``).
    kinds : array_like, shape (M,), optional
        A label per UAV (for example its :attr:`crlbswarm.Radar.snr_constant`); UAV ``m``
        takes only slots ``j`` with ``kinds[j] == kinds[m]`` (default: all one kind).

    Returns
    -------
    ndarray of int64, shape (M,)
        ``slot[m]``, the slot of UAV ``m`` (a permutation of ``0 .. M-1``).

    Examples
    --------
    >>> assign_slots([[0, 0], [10, 0], [0, 10]], [[0, 0], [0, 10], [10, 0]], leader=0)
    array([0, 2, 1])
    """
    from scipy.optimize import linear_sum_assignment

    start = _v.coordinates(start_xy, "start_xy")
    slots = _v.coordinates(slots_xy, "slots_xy")
    if start.ndim != 2:
        raise FieldError("start_xy", f"expected shape (M, 2), got {start.shape}")
    if slots.shape != start.shape:
        raise FieldError("slots_xy", f"expected shape {start.shape}, got {slots.shape}")
    n = start.shape[0]
    _v.check_elements(float(n) * n, "start_xy", f"a {n} x {n} assignment", copies=3)
    lead = _v.count(leader, "leader", 0)
    if lead >= n:
        raise FieldError("leader", f"must be a UAV index below {n}, got {lead}")
    if kinds is None:
        label = np.zeros(n)
    else:
        label = _v.finite(kinds, "kinds")
        if label.shape != (n,):
            raise FieldError("kinds", f"expected shape ({n},), got {label.shape}")
    out = np.empty(n, dtype=np.int64)
    out[lead] = lead
    for kind in np.unique(label):
        others = np.flatnonzero((label == kind) & (np.arange(n) != lead))
        if others.size:
            diff = start[others, None, :] - slots[None, others, :]
            rows, cols = linear_sum_assignment(np.hypot(*diff.transpose(2, 0, 1)))
            out[others[rows]] = others[cols]
    return out


class GuidanceConfig(ConfigModel):
    """Complete guidance (not in the paper): the leader follows a route for the formation's
    centre, planned around the obstacles for its smallest footprint (:mod:`crlbswarm.planning`)."""

    planner: bool = Field(True, description="false: straight to the target (the paper's guidance)")
    clearance: PositiveFloat | None = Field(
        None,
        description="clearance of the formation's smallest disc from every obstacle along the "
        "route, m (default: control.safety_radius)",
    )


class FormationConfig(ConfigModel):
    """The formation flown over the target and which UAV takes which slot (not in the
    paper): F* in closed form, or the best formation that fits when F* is blocked
    (:func:`crlbswarm.constrained_design`, ``docs/constrained-design.md``)."""

    assignment: Literal["optimal", "index"] = Field(
        "optimal",
        description="optimal: the followers take the slots that minimise the total travel "
        "from the start (Hungarian); index: UAV m takes slot m (the paper)",
    )
    design: Literal["auto", "closed_form"] = Field(
        "auto",
        description="auto: F* in closed form, or, if F* is blocked (a slot within "
        "control.safety_radius of an obstacle, beyond max_radius, or two slots too close), the "
        "best formation that fits (constrained design); closed_form: F* only, a blocked F* is "
        "refused (the paper)",
    )
    criterion: Literal["A", "D", "E"] = Field(
        "A",
        description="criterion of the constrained design: A (CRLB, the paper's), D or E",
    )
    max_radius: (
        Annotated[float, Field(ge=MIN_MAX_RADIUS, le=_v.MAX_DISTANCE, allow_inf_nan=False)] | None
    ) = Field(
        None,
        description=f"largest distance from the target to a slot, m ({MIN_MAX_RADIUS:g} to "
        f"{_v.MAX_DISTANCE:g}; none by default)",
    )
    starts: int | None = Field(
        None,
        ge=1,
        le=MAX_SCENARIO_STARTS,
        description=f"starts of the constrained design (1 to {MAX_SCENARIO_STARTS}; default "
        "64 up to 16 UAVs, then fewer)",
    )
    seed: int = Field(
        0, ge=0, le=2**63 - 1, description="seed of the constrained design's random starts"
    )
    objective: Literal["sum", "max"] = Field(
        "sum",
        description="with extra_targets: the UAVs are split between the targets to minimise "
        "the sum or the largest of their CRLBs",
    )
