"""Complete guidance and slot assignment (crlbswarm.planning) against independent references.

The references are written here from the geometry, without crlbswarm's code:

* the signed distance to the obstacles in NumPy (clamp for rectangles, radial for discs);
* the exact shortest route among the *true* inflated obstacles (rounded rectangles and
  discs): the tangent graph of the circles that bound them (the four corner circles of
  radius ``r`` of each rectangle, the discs of radius ``R + r``), with straight tangent
  segments and arcs, each checked free by dense sampling, and Dijkstra on a heap;
* brute force over all permutations for the slot assignment.

Bounds on the route length, both exact up to rounding and the reference's sampling: the
planner's route is feasible, so it is at least the optimum ``L*`` keeping ``r`` from the
obstacles; it is at most the shortest route among the circumscribing polygons whose
vertices are its nodes, and these polygons lie inside the obstacles inflated by
``rho sec(15 deg)`` (``rho`` = the inflated radius plus the node margin: rectangles inflated
by ``(r + margin) sec 15deg``, discs of radius ``(R + r + margin) sec 15deg``), so the route
is at most the optimum ``L+`` around those larger shapes. Both are computed by the same
reference.
"""

from __future__ import annotations

import heapq
import itertools
import math
import subprocess
import sys

import numpy as np
import pytest

from crlbswarm.errors import FieldError
from crlbswarm.obstacles import Obstacles
from crlbswarm.planning import (
    NODE_MARGIN,
    Roadmap,
    assign_slots,
    build_roadmap,
    next_waypoint,
    next_waypoints,
    plan_route,
    segment_clear,
)

SEC15 = 1.0 / math.cos(math.pi / 12)  # circumradius / inradius of the 30-degree polygons
SAMPLE = 0.05  # m, spacing of the reference's free-space sampling


# -- independent references ----------------------------------------------------------------
def ref_clearance(points, rects, circles, r_rect=0.0, r_disc=None) -> np.ndarray:
    """Signed distance from each point to the nearest obstacle (negative inside), less the
    distance required from it: ``r_rect`` from the rectangles, ``r_disc[i]`` from disc i."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    x, y = p[:, 0], p[:, 1]
    best = np.full(len(p), np.inf)
    for x0, x1, y0, y1 in np.asarray(rects, dtype=float).reshape(-1, 4):
        outside = np.hypot(np.maximum(np.maximum(x0 - x, x - x1), 0.0),
                           np.maximum(np.maximum(y0 - y, y - y1), 0.0))  # fmt: skip
        depth = np.minimum(np.minimum(x - x0, x1 - x), np.minimum(y - y0, y1 - y))
        best = np.minimum(best, np.where(outside > 0, outside, -depth) - r_rect)
    circles = np.asarray(circles, dtype=float).reshape(-1, 3)
    extra = np.zeros(len(circles)) if r_disc is None else r_disc
    for (cx, cy, r), e in zip(circles, extra, strict=True):
        best = np.minimum(best, np.hypot(x - cx, y - cy) - r - e)
    return best


def sample_polyline(points, step: float = SAMPLE) -> np.ndarray:
    """Points along a polyline, at most ``step`` apart, vertices included."""
    pts = np.asarray(points, dtype=float)
    out = [pts[:1]]
    for a, b in itertools.pairwise(pts):
        n = max(2, math.ceil(np.hypot(*(b - a)) / step) + 1)
        out.append(a + np.linspace(0.0, 1.0, n)[1:, None] * (b - a))
    return np.concatenate(out)


def route_length(route) -> float:
    return float(np.sum(np.hypot(*np.diff(np.asarray(route), axis=0).T)))


def ref_shortest(start, goal, rects, circles, r_rect: float, r_disc=None) -> float:
    """Exact length of the shortest route keeping ``r_rect`` from the rectangles and
    ``r_disc[i]`` (default ``r_rect``) from disc i: Dijkstra on the tangent graph of the
    circles bounding the forbidden regions (the corner circles of radius ``r_rect`` of each
    rectangle, and around each disc), made of tangent segments and arcs checked free."""
    rects = np.asarray(rects, dtype=float).reshape(-1, 4)
    circles = np.asarray(circles, dtype=float).reshape(-1, 3)
    r_disc = np.full(len(circles), r_rect) if r_disc is None else np.asarray(r_disc)
    discs = [(np.array([x, y]), r_rect)
             for x0, x1, y0, y1 in rects for x in (x0, x1) for y in (y0, y1)]  # fmt: skip
    discs += [(c[:2], c[2] + e) for c, e in zip(circles, r_disc, strict=True)]
    pts = [np.asarray(start, float), np.asarray(goal, float)]
    on: dict[int, list[tuple[float, int]]] = {}
    edges: dict[int, list[tuple[int, float]]] = {}

    def free(points) -> bool:
        return bool(np.all(ref_clearance(points, rects, circles, r_rect, r_disc) >= -1e-7))

    def point(p, disc) -> int:
        pts.append(p)
        c = discs[disc][0]
        on.setdefault(disc, []).append((math.atan2(p[1] - c[1], p[0] - c[0]), len(pts) - 1))
        return len(pts) - 1

    def link(i, j, length) -> None:
        edges.setdefault(i, []).append((j, length))
        edges.setdefault(j, []).append((i, length))

    def segment(p, q, dp=None, dq=None, ip=None, iq=None) -> None:
        if free([p, q]) and free(sample_polyline([p, q])):
            i = point(p, dp) if ip is None else ip
            j = point(q, dq) if iq is None else iq
            link(i, j, float(np.hypot(*(q - p))))

    segment(pts[0], pts[1], ip=0, iq=1)
    for k, (c, r) in enumerate(discs):
        for ip in (0, 1):  # tangents from the start and the goal
            off = pts[ip] - c
            d = np.hypot(*off)
            if d > r:
                for s in (-1, 1):
                    a = math.atan2(off[1], off[0]) + s * math.acos(r / d)
                    segment(pts[ip], c + r * np.array([math.cos(a), math.sin(a)]), dq=k, ip=ip)
    for (k, (c1, r1)), (m, (c2, r2)) in itertools.combinations(enumerate(discs), 2):
        d = np.hypot(*(c2 - c1))
        if d == 0:
            continue  # the same circle twice (a corner shared by two rectangles)
        base = math.atan2(*(c2 - c1)[::-1])
        for sign2, cosine in ((1, (r1 - r2) / d), (-1, (r1 + r2) / d)):  # outer, inner
            if abs(cosine) < 1:
                for s in (-1, 1):
                    a = base + s * math.acos(cosine)
                    n = np.array([math.cos(a), math.sin(a)])
                    segment(c1 + r1 * n, c2 + sign2 * r2 * n, dp=k, dq=m)
    for k, items in on.items():  # arcs between neighbouring tangent points of each circle
        c, r = discs[k]
        items.sort()
        for (a1, i), (a2, j) in zip(items, items[1:] + items[:1], strict=True):
            span = (a2 - a1) % (2 * math.pi)
            if len(items) < 2:
                continue
            ang = a1 + span * np.linspace(0, 1, max(3, math.ceil(r * span / SAMPLE) + 2))
            if free(np.stack([c[0] + r * np.cos(ang), c[1] + r * np.sin(ang)], axis=-1)):
                link(i, j, r * span)
    return _dijkstra(edges, 0, 1)


def _dijkstra(edges, source: int, target: int) -> float:
    best = {source: 0.0}
    heap = [(0.0, source)]
    done = set()
    while heap:
        d, i = heapq.heappop(heap)
        if i in done:
            continue
        done.add(i)
        if i == target:
            return d
        for j, length in edges.get(i, []):
            if j not in done and d + length < best.get(j, math.inf):
                best[j] = d + length
                heapq.heappush(heap, (d + length, j))
    return math.inf


# -- layouts -------------------------------------------------------------------------------
def random_discs(seed: int, n: int = 15, infl: float = 2.5):
    """Discs in [15, 85]^2 away from (0, 0) and (100, 100), overlapping or not; no gap
    between two is within 0.5 m of closing, for the route nor for the polygons (which
    grow a disc by at most (6 + 2.5) (sec 15deg - 1) = 0.3 m)."""
    rng = np.random.default_rng(seed)
    discs: list[list[float]] = []
    while len(discs) < n:
        c, r = rng.uniform(15, 85, 2), rng.uniform(2, 6)
        gaps = [np.hypot(*(c - d[:2])) - r - d[2] for d in discs]
        if any(2 * infl - 0.5 < g < 2 * (infl + 0.4) + 0.5 for g in gaps):
            continue
        if min(np.hypot(*c), np.hypot(*(c - 100))) - r > infl + 2:
            discs.append([*c, r])
    return Obstacles(circles=discs), (0.0, 0.0), (100.0, 100.0), infl


PAPER = [[30, 45, 0, 34], [30, 45, 54, 80]]
LAYOUTS = {
    "wall": (Obstacles(rectangles=[[40, 45, -30, 30]]), (0.0, 0.0), (90.0, 0.0), 5.0),
    "slalom": (
        Obstacles(rectangles=[[20, 25, -40, 10], [45, 50, -10, 40], [70, 75, -40, 10]]),
        (0.0, 0.0), (100.0, 0.0), 4.0,
    ),
    "u_trap": (
        Obstacles(rectangles=[[60, 65, -30, 30], [30, 65, 25, 30], [30, 65, -30, -25]]),
        (0.0, 0.0), (80.0, 0.0), 4.0,
    ),
    "u_trap_0": (
        Obstacles(rectangles=[[60, 65, -30, 30], [30, 65, 25, 30], [30, 65, -30, -25]]),
        (0.0, 0.0), (80.0, 0.0), 0.0,
    ),
    "paper_8": (Obstacles(rectangles=PAPER), (0.0, 0.0), (80.0, 90.0), 8.0),
    "paper_11": (Obstacles(rectangles=PAPER), (0.0, 0.0), (80.0, 90.0), 11.0),
    "mixed": (
        Obstacles(rectangles=[[20, 25, -40, 10], [60, 62, -5, 45]],
                  circles=[[40, -5, 6], [45, 25, 4], [80, 10, 5]]),
        (0.0, 0.0), (100.0, 10.0), 3.0,
    ),
    **{f"discs_{seed}": random_discs(seed) for seed in range(4)},
}  # fmt: skip


def _assert_clear(points, obstacles: Obstacles, infl: float, sampled: bool = True) -> None:
    pts = sample_polyline(points, 0.01) if sampled else np.asarray(points)
    clearance = ref_clearance(pts, obstacles.rectangles, obstacles.circles)
    assert clearance.min() >= infl - 1e-9


# -- routes --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(LAYOUTS))
def test_route_is_clear_and_as_short_as_the_exact_optimum_allows(name):
    obstacles, start, goal, infl = LAYOUTS[name]
    route = plan_route(start, goal, obstacles, infl)
    assert route.shape[1] == 2
    assert route.shape[0] >= 2
    np.testing.assert_array_equal(route[0], start)
    np.testing.assert_array_equal(route[-1], goal)
    _assert_clear(route, obstacles, infl)
    rects, circles = obstacles.rectangles, obstacles.circles
    exact = ref_shortest(start, goal, rects, circles, infl)
    rho = infl + NODE_MARGIN
    grown = ref_shortest(start, goal, rects, circles, rho * SEC15,
                         (circles[:, 2] + rho) * SEC15 - circles[:, 2])  # fmt: skip
    length = route_length(route)
    assert exact - 1e-6 <= length <= grown + 1e-6, (length, exact, grown)
    assert grown < exact * 1.01  # the polygons cost less than 1 % here


def test_layouts_make_the_planner_turn():
    """The references are not straight lines: each layout blocks the direct segment."""
    for name, (obstacles, start, goal, infl) in LAYOUTS.items():
        if name.startswith("discs"):
            continue
        line = sample_polyline([start, goal])
        assert ref_clearance(line, obstacles.rectangles, obstacles.circles).min() < infl, name
        assert len(plan_route(start, goal, obstacles, infl)) > 2, name


def _y_at(route: np.ndarray, x: float) -> list[float]:
    """The route's y where it crosses the vertical line at ``x``."""
    out = []
    for a, b in itertools.pairwise(route):
        if (a[0] - x) * (b[0] - x) <= 0 and a[0] != b[0]:
            out.append(a[1] + (x - a[0]) / (b[0] - a[0]) * (b[1] - a[1]))
    return out


def test_paper_passage_is_taken_at_8_m_and_avoided_at_11_m():
    obstacles, start, goal, _ = LAYOUTS["paper_8"]
    through = _y_at(plan_route(start, goal, obstacles, 8.0), 37.5)
    assert through
    assert all(34 + 8 - 1e-9 <= y <= 54 - 8 + 1e-9 for y in through)
    around = _y_at(plan_route(start, goal, obstacles, 11.0), 37.5)
    assert around
    assert all(y >= 80 + 11 - 1e-9 or y <= -11 + 1e-9 for y in around)


def test_without_obstacles_the_route_is_the_segment():
    route = plan_route((0.0, 0.0), (30.0, 40.0), Obstacles(), 5.0)
    np.testing.assert_array_equal(route, [[0.0, 0.0], [30.0, 40.0]])
    rm = build_roadmap(Obstacles(), (30.0, 40.0), 5.0)
    assert rm.nodes.shape == (1, 2)
    assert rm.edges.shape == (0, 2)


def test_start_closer_than_the_inflation_leaves_without_going_deeper():
    obstacles = Obstacles(rectangles=[[40, 45, -30, 30]])
    for start in ([38.0, 0.0], [37.0, 29.0], [46.0, -31.0]):
        route = plan_route(start, (90.0, 0.0), obstacles, 5.0)
        pts = sample_polyline(route[:2], 0.01)
        depth = ref_clearance(pts, obstacles.rectangles, obstacles.circles)
        assert depth.min() >= depth[0] - 1e-9
        _assert_clear(route[1:], obstacles, 5.0)


# -- navigation ----------------------------------------------------------------------------
def _follow(roadmap: Roadmap, start: np.ndarray, step: float = 0.5):
    rm = roadmap
    args = (rm.nodes, rm.dist_to_goal, rm.goal[0], rm.goal[1], rm.rects, rm.circles)
    p = np.array(start, dtype=float)
    path, togo, moved = [p.copy()], [], []
    for _ in range(2000):
        wx, wy, d = next_waypoint(p[0], p[1], *args, rm.inflation)
        togo.append(d)
        off = np.array([wx, wy]) - p
        dist = float(np.hypot(*off))
        p = np.array([wx, wy]) if dist <= step else p + step * off / dist
        moved.append(min(dist, step))
        path.append(p.copy())
        if np.array_equal(p, rm.goal):
            break
    return np.array(path), np.array(togo), np.array(moved)


@pytest.mark.parametrize("name", list(LAYOUTS))
def test_following_the_waypoints_reaches_the_goal_safely(name):
    obstacles, _, goal, infl = LAYOUTS[name]
    roadmap = build_roadmap(obstacles, goal, infl)
    rng = np.random.default_rng(7)
    starts = rng.uniform(-15, 115, (400, 2))
    starts = starts[ref_clearance(starts, obstacles.rectangles, obstacles.circles) >= infl][:25]
    for start in starts:
        path, togo, moved = _follow(roadmap, start)
        np.testing.assert_array_equal(path[-1], goal)
        assert np.all(np.isfinite(togo))
        # each step removes its own length from the distance to go
        assert np.all(togo[1:] <= togo[:-1] - moved[:-1] + 1e-6)
        _assert_clear(path, obstacles, infl)


def test_next_waypoint_moves_on_from_a_node_and_reports_no_route_as_inf():
    obstacles, _, goal, infl = LAYOUTS["u_trap"]
    rm = build_roadmap(obstacles, goal, infl)
    for k in np.flatnonzero(np.isfinite(rm.dist_to_goal[:-1])):
        x, y = rm.nodes[k]
        wx, wy, d = next_waypoint(x, y, rm.nodes, rm.dist_to_goal, *rm.goal, rm.rects,
                                  rm.circles, rm.inflation)  # fmt: skip
        assert (wx, wy) != (x, y)
        assert d == pytest.approx(rm.dist_to_goal[k], rel=1e-9)
    enclosed = Obstacles(rectangles=[[-10, 10, 8, 10], [-10, 10, -10, -8],
                                     [-10, -8, -10, 10], [8, 10, -10, 10]])  # fmt: skip
    rm = build_roadmap(enclosed, (50.0, 0.0), 1.0)
    w, d = next_waypoints(rm, [[0.0, 0.0], [30.0, 0.0]])
    np.testing.assert_array_equal(w, [[50.0, 0.0], [50.0, 0.0]])
    assert d[0] == np.inf
    assert d[1] == 20.0


def test_batched_waypoints_match_the_kernel_and_keep_the_shape():
    obstacles, _, goal, infl = LAYOUTS["slalom"]
    rm = build_roadmap(obstacles, goal, infl)
    pts = np.random.default_rng(3).uniform(-10, 110, (3, 4, 2))
    w, d = next_waypoints(rm, pts)
    assert w.shape == (3, 4, 2)
    assert d.shape == (3, 4)
    for idx in np.ndindex(3, 4):
        ref = next_waypoint(*pts[idx], rm.nodes, rm.dist_to_goal, *rm.goal, rm.rects,
                            rm.circles, rm.inflation)  # fmt: skip
        assert (w[idx][0], w[idx][1], d[idx]) == ref


def test_roadmap_is_read_only_and_consistent():
    obstacles, _, goal, infl = LAYOUTS["mixed"]
    rm = build_roadmap(obstacles, goal, infl)
    for arr in (rm.nodes, rm.dist_to_goal, rm.next_node, rm.edges, rm.goal):
        assert not arr.flags.writeable
    np.testing.assert_array_equal(rm.nodes[-1], goal)
    assert rm.dist_to_goal[-1] == 0
    assert rm.next_node[-1] == -1
    assert ref_clearance(rm.nodes, rm.rects, rm.circles).min() >= infl
    for k in np.flatnonzero(rm.next_node >= 0):  # the next node is one edge closer
        j = rm.next_node[k]
        step = np.hypot(*(rm.nodes[k] - rm.nodes[j]))
        assert rm.dist_to_goal[k] == pytest.approx(step + rm.dist_to_goal[j], rel=1e-12)
    for i, j in rm.edges:
        _assert_clear(rm.nodes[[i, j]], obstacles, infl)


def test_segment_clear_agrees_with_dense_sampling():
    rects = np.array([[0.0, 10.0, 0.0, 4.0], [20.0, 22.0, -5.0, 5.0]])
    circles = np.array([[10.0, 15.0, 3.0]])
    rng = np.random.default_rng(11)
    for _ in range(3000):
        a, b = rng.uniform(-10, 30, 2), rng.uniform(-10, 30, 2)
        infl = float(rng.choice([0.0, 0.5, 2.0, 4.0]))
        clear = segment_clear(*a, *b, rects, circles, infl)
        lowest = ref_clearance(sample_polyline([a, b], 0.005), rects, circles).min()
        if clear:
            assert lowest >= infl - 1e-9
        else:  # blocked: the true minimum is below infl, the samples at most 0.0025 above it
            assert lowest < infl + 0.0025 or (infl == 0 and lowest <= 0.0025)


def test_segment_clear_at_zero_inflation_allows_touching_not_entering():
    rects = np.array([[0.0, 10.0, 0.0, 4.0]])
    none = np.empty((0, 3))
    assert segment_clear(-5.0, 4.0, 15.0, 4.0, rects, none, 0.0)  # along the top face
    assert segment_clear(-5.0, -1.0, 1.0, 5.0, rects, none, 0.0)  # through the corner
    assert not segment_clear(-5.0, 3.9, 15.0, 3.9, rects, none, 0.0)
    assert not segment_clear(-5.0, 2.0, 15.0, 2.0, rects, none, 1e-3)


# -- errors --------------------------------------------------------------------------------
BOX = [[-1, 100, 58, 60], [98, 100, -60, 60], [-1, 100, -60, -58]]  # top, right, bottom


def test_enclosed_target_or_start_has_no_route():
    walls = Obstacles(rectangles=[[-1, 1, -60, 60], *BOX])
    with pytest.raises(FieldError, match="no route from the start to the target") as err:
        plan_route((-40.0, 30.0), (50.0, 0.0), walls, 2.0)
    assert err.value.field == "guidance"
    assert "lower" not in err.value.reason  # no advice on the size: no gap at all
    with pytest.raises(FieldError, match="no route from the start to the target"):
        plan_route((50.0, 0.0), (-40.0, 30.0), walls, 2.0, field="scene")


@pytest.mark.parametrize(
    ("lower", "names", "passage"),
    [
        ([-1, 1, -60, -5], ["walls[0]", "walls[1]", "top", "right", "bottom"],
         "between walls[0] and walls[1] is 10 m wide"),
        ([-1, 1, -60, -20], ["A", "B", "top", "right", "bottom", "D"],
         "between A and D is 10 m wide"),
    ],
)  # fmt: skip
def test_message_names_the_passage_that_closes_first(lower, names, passage):
    """The target is enclosed but for a 10 m gap in the left wall (between two rectangles,
    or a rectangle and the disc of radius 10 at (0, -15)): the route must use the gap."""
    circles = [[0.0, -15.0, 10.0]] if len(names) == 6 else []
    walls = Obstacles(rectangles=[[-1, 1, 5, 60], lower, *BOX], circles=circles)
    start, goal = (-40.0, 30.0), (50.0, 0.0)
    route = plan_route(start, goal, walls, 4.0, names=names)
    assert any(abs(y) <= 1 + 1e-9 for y in _y_at(route, 0.0))  # through the gap
    with pytest.raises(FieldError) as err:
        plan_route(start, goal, walls, 6.0, names=names, field="eta.minimum", hint="fix it")
    assert err.value.field == "eta.minimum"
    reason = err.value.reason
    assert passage in reason
    assert "the formation needs 2 x 6 = 12 m" in reason
    assert "up to an inflation of about 5 m" in reason
    assert reason.endswith("; fix it")
    assert "\n" not in reason


def test_target_too_close_to_an_obstacle_is_named():
    walls = Obstacles(rectangles=PAPER)
    with pytest.raises(FieldError, match=r"the target is 3 m from obstacles\[1\]") as err:
        plan_route((0.0, 0.0), (48.0, 60.0), walls, 8.0, names=["obstacles[0]", "obstacles[1]"])
    assert err.value.field == "guidance"
    with pytest.raises(FieldError, match=r"the target is inside rectangles\[0\]"):
        plan_route((0.0, 0.0), (40.0, 10.0), walls, 8.0)
    with pytest.raises(FieldError, match="inside rectangles") as err:
        build_roadmap(walls, (48.0, 60.0), 8.0)
    assert err.value.field == "goal_xy"


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda o: build_roadmap(o, (0, 0), -1.0), "inflation"),
        (lambda o: build_roadmap(o, (0, 0), float("nan")), "inflation"),
        (lambda o: build_roadmap(o, (0, np.inf), 1.0), "goal_xy"),
        (lambda o: build_roadmap(o, (0, 0, 0), 1.0), "goal_xy"),
        (lambda o: build_roadmap([[0, 1, 0, 1]], (5, 5), 1.0), "obstacles"),
        (lambda o: plan_route((0, 0, 1), (90, 0), o, 1.0), "start_xy"),
        (lambda o: plan_route((0, 0), "x", o, 1.0), "goal_xy"),
        (lambda o: plan_route((0, 0), (90, 0), o, [1.0, 2.0]), "inflation"),
        (lambda o: plan_route((0, 0), (90, 0), o, 1.0, names=["a", "b"]), "names"),
        (lambda o: next_waypoints("roadmap", (0, 0)), "roadmap"),
        (lambda o: next_waypoints(build_roadmap(o, (90, 0), 1.0), (0, 0, 0)), "points_xy"),
    ],
)
def test_invalid_arguments_are_named(call, field):
    with pytest.raises(FieldError) as err:
        call(Obstacles(rectangles=[[40, 45, -30, 30]]))
    assert err.value.field == field


def test_planning_does_not_import_networkx_or_scipy_optimize():
    probe = (
        "import sys, crlbswarm.planning\n"
        "print(any(m.startswith(('networkx', 'scipy.optimize')) for m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, timeout=120)  # fmt: skip
    assert out.stdout.strip() == "False"


# -- slot assignment -----------------------------------------------------------------------
def brute_force(start: np.ndarray, slots: np.ndarray, leader: int) -> tuple[float, list]:
    """Least total travel with the leader on its slot, and every assignment achieving it."""
    m = len(start)
    others = [i for i in range(m) if i != leader]
    costs = {}
    for perm in itertools.permutations(others):
        slot = np.empty(m, dtype=int)
        slot[leader] = leader
        slot[others] = perm
        costs[tuple(slot)] = float(np.sum(np.hypot(*(start - slots[slot]).T)))
    best = min(costs.values())
    return best, [s for s, c in costs.items() if c <= best + 1e-9]


@pytest.mark.parametrize("m", range(1, 8))
def test_slots_minimise_the_total_travel_like_brute_force(m):
    rng = np.random.default_rng(m)
    for _ in range(5):
        start, slots = rng.uniform(-50, 50, (m, 2)), rng.uniform(-50, 50, (m, 2))
        leader = int(rng.integers(m))
        slot = assign_slots(start, slots, leader)
        best, argbest = brute_force(start, slots, leader)
        assert slot.dtype == np.int64
        assert slot[leader] == leader
        assert sorted(slot) == list(range(m))
        assert np.sum(np.hypot(*(start - slots[slot]).T)) == pytest.approx(best, rel=1e-12)
        assert argbest == [tuple(slot)]  # generic positions: the optimum is unique


def test_slots_do_not_depend_on_the_followers_labels():
    rng = np.random.default_rng(5)
    for _ in range(20):
        start, slots = rng.uniform(-50, 50, (6, 2)), rng.uniform(-50, 50, (6, 2))
        slot = assign_slots(start, slots, leader=2)
        perm = np.arange(6)  # new UAV i is old UAV perm[i]; the leader keeps its label
        perm[[0, 1, 3, 4, 5]] = rng.permutation([0, 1, 3, 4, 5])
        relabelled = assign_slots(start[perm], slots, leader=2)
        np.testing.assert_array_equal(relabelled, slot[perm])
    # ties: deterministic, and every answer is optimal
    square = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    first = assign_slots(square, square[::-1], leader=0)
    np.testing.assert_array_equal(first, assign_slots(square, square[::-1], leader=0))
    assert tuple(first) in brute_force(square, square[::-1], 0)[1]


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (([[0, 0], [1, 1]], [[0, 0]], 0), "slots_xy"),
        (([[0, 0], [1, 1]], [[0, 0], [1, 1]], 2), "leader"),
        (([[0, 0], [1, 1]], [[0, 0], [1, 1]], -1), "leader"),
        (([[0, 0], [1, 1]], [[0, 0], [1, 1]], 1.0), "leader"),
        (([[0, np.nan], [1, 1]], [[0, 0], [1, 1]], 0), "start_xy"),
        (([[[0, 0], [1, 1]]], [[[0, 0], [1, 1]]], 0), "start_xy"),
    ],
)
def test_slot_arguments_are_checked(args, field):
    with pytest.raises(FieldError) as err:
        assign_slots(*args)
    assert err.value.field == field


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_assign_slots_keeps_each_uav_to_its_kind(seed):
    """With kinds, a UAV takes only a slot of its own kind (unequal UAVs), the leader keeps
    its own, and within a kind the travel is the least (checked by brute force)."""
    import itertools

    from crlbswarm.planning import assign_slots

    rng = np.random.default_rng(seed)
    start, slots = rng.uniform(-50, 50, (2, 7, 2))
    kinds = np.array([1.0, 2.0, 1.0, 2.0, 2.0, 1.0, 3.0])
    slot = assign_slots(start, slots, 0, kinds)
    assert sorted(slot) == list(range(7))
    assert slot[0] == 0
    assert np.array_equal(kinds[slot], kinds)
    for kind in (1.0, 2.0):
        uavs = [m for m in range(1, 7) if kinds[m] == kind]
        best = min(
            sum(np.hypot(*(start[m] - slots[p])) for m, p in zip(uavs, perm, strict=True))
            for perm in itertools.permutations(uavs)
        )
        got = sum(np.hypot(*(start[m] - slots[slot[m]])) for m in uavs)
        assert got == pytest.approx(best, rel=1e-12)
    assert slot[6] == 6  # alone in its kind
