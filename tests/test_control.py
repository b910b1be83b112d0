"""Control laws of Sec. IV (crlbswarm.control) against references written in this file.

The references below use plain Python loops over a dense adjacency matrix built from an
edge list; they follow docs/control.md (secs. 4, 6, 7 and 10: the corrected eq. (14), eqs.
(19), (18) and (15)) and never call crlbswarm. Beside them: small examples whose expected
numbers were worked out by hand, the closed-form solutions of the two linear laws (matrix
powers of ``I - gamma L_ff`` and ``I - eps L``), invariance to relabelling the followers,
batches against loops, and checks that no input array is ever written to. The laws take
their gains from one ``ControlGains`` (and the eta rule from one ``EtaRule``); the gains
used repeatedly are the module constants below.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from crlbswarm import (
    Adjacency,
    ControlGains,
    EtaRule,
    FieldError,
    Obstacles,
    communication_graph,
    consensus_step,
    consensus_step_limit,
    eta_target,
    eta_update,
    formation_cost,
    formation_input,
    formation_step_limit,
    leader_guidance,
    obstacle_clearance,
    repulsion,
)

SEEDS = [0, 1, 2, 3]

#: A repulsion cap too large ever to bind, for the uncapped examples (the gains must be
#: finite, so the cap cannot be infinity).
NO_CAP = 1e300


def repulsion_gains(
    gain: float = 2.0, l_safe: float = 5.0, max_step: float = NO_CAP
) -> ControlGains:
    """Gains with E_r = ``gain`` and l_safe = ``l_safe``, uncapped unless ``max_step``."""
    return ControlGains(repulsion_gain=gain, safety_radius=l_safe, repulsion_max_step=max_step)


def guidance_gains(gain: float, cruise: float) -> ControlGains:
    """Gains with k_g = ``gain``, v_c = ``cruise`` and, for the steering term, E_r = 2 and
    l_safe = 5."""
    return ControlGains(
        guidance_gain=gain, cruise_speed=cruise, repulsion_gain=2.0, safety_radius=5.0
    )


#: E_r = 2, l_safe = 5 (the paper's), no cap: the repulsion of the hand-computed examples.
REPULSION = repulsion_gains()

#: Gains of the batch, broadcasting, relabelling and read-only tests: gamma = 0.2,
#: eps = 0.05, and for the guidance and repulsion k_g = 0.5, v_c = 2, E_r = 2, l_safe = 5
#: with the repulsion capped at 1 m per step.
GAINS = ControlGains(
    gamma=0.2,
    epsilon=0.05,
    guidance_gain=0.5,
    cruise_speed=2.0,
    repulsion_gain=2.0,
    safety_radius=5.0,
    repulsion_max_step=1.0,
)

#: Gains of the closed-loop mission: the paper scenario's defaults (docs/control.md sec.
#: 12.1), written out.
MISSION_GAINS = ControlGains(
    epsilon=0.01,
    gamma=0.25,
    guidance_gain=0.5,
    cruise_speed=2.0,
    repulsion_gain=2.0,
    safety_radius=5.0,
    repulsion_max_step=1.0,
)

#: Connected graphs of 10 UAVs for the convergence tests (random_geometric seeds 0, 2, 3 and
#: radius 0.55 give connected graphs).
GRAPHS = {
    "ring": lambda: communication_graph("ring", 10),
    "path": lambda: communication_graph("path", 10),
    "star": lambda: communication_graph("star", 10, center=4),
    "complete": lambda: communication_graph("complete", 10),
    "rgg0": lambda: communication_graph("random_geometric", 10, radius=0.55, seed=0),
    "rgg2": lambda: communication_graph("random_geometric", 10, radius=0.55, seed=2),
    "rgg3": lambda: communication_graph("random_geometric", 10, radius=0.55, seed=3),
}


# =============================================================================================
# Independent references (plain loops; nothing from crlbswarm)
# =============================================================================================
def adjacency_matrix(n: int, edges) -> list[list[float]]:
    """Binary symmetric adjacency a_mp from an edge list."""
    a = [[0.0] * n for _ in range(n)]
    for m, p in edges:
        a[m][p] = a[p][m] = 1.0
    return a


def laplacian(n: int, edges) -> np.ndarray:
    a = adjacency_matrix(n, edges)
    return np.array([[(sum(a[m]) if m == p else -a[m][p]) for p in range(n)] for m in range(n)])


def consensus_ref(v, v_ref, a, leader, gamma):
    """Corrected eq. (14): v_m - gamma [sum_{p != leader} a_mp (v_m - v_p)
    + a_m,leader (v_m - v_ref)]; the leader's row is v_ref."""
    n = len(a)
    out = np.zeros((n, 2))
    for m in range(n):
        if m == leader:
            out[m] = v_ref
            continue
        for c in range(2):
            s = 0.0
            for p in range(n):
                if p != leader:
                    s += a[m][p] * (v[m][c] - v[p][c])
            s += a[m][leader] * (v[m][c] - v_ref[c])
            out[m, c] = v[m][c] - gamma * s
    return out


def formation_ref(q, delta, eta, a, eps):
    """Eq. (19) without repulsion: -eps sum_p a_mp (q_m - q_p - eta (delta_m - delta_p))."""
    n = len(a)
    out = np.zeros((n, 2))
    for m in range(n):
        for c in range(2):
            s = 0.0
            for p in range(n):
                s += a[m][p] * (q[m][c] - q[p][c] - eta * (delta[m][c] - delta[p][c]))
            out[m, c] = -eps * s
    return out


def cost_ref(q, q_next, delta, v_ref, a, dt):
    """Eq. (15) summed over m, nominal displacements delta_pm = delta_m - delta_p."""
    n = len(a)
    total = 0.0
    for m in range(n):
        for p in range(n):
            ex = q[m][0] - q[p][0] - (delta[m][0] - delta[p][0])
            ey = q[m][1] - q[p][1] - (delta[m][1] - delta[p][1])
            total += a[m][p] * (ex * ex + ey * ey)
        wx = (q_next[m][0] - q[m][0]) / dt - v_ref[0]
        wy = (q_next[m][1] - q[m][1]) / dt - v_ref[1]
        total += wx * wx + wy * wy
    return total


def nearest_points(x, y, rects, circles):
    """Nearest point of every obstacle to the (outside) point (x, y): the clamp for a
    rectangle, the radial projection for a circle."""
    out = []
    for xmin, xmax, ymin, ymax in rects:
        out.append((max(xmin, min(x, xmax)), max(ymin, min(y, ymax))))
    for cx, cy, r in circles:
        rho = math.hypot(x - cx, y - cy)
        out.append((cx + r * (x - cx) / rho, cy + r * (y - cy) / rho))
    return out


def repulsion_ref(x, y, rects, circles, gain, l_safe, max_step=math.inf, inflate=0.0):
    """Eq. (18) summed over obstacles within l_safe (distances reduced by ``inflate``),
    then the sum capped at max_step. For points outside every obstacle."""
    fx = fy = 0.0
    for nx_, ny_ in nearest_points(x, y, rects, circles):
        dist = math.hypot(x - nx_, y - ny_)
        ell = dist - inflate
        if ell < l_safe:
            mag = gain * (1.0 / ell - 1.0 / l_safe) / ell**2
            fx += mag * (x - nx_) / dist
            fy += mag * (y - ny_) / dist
    norm = math.hypot(fx, fy)
    if norm > max_step:
        fx, fy = fx * max_step / norm, fy * max_step / norm
    return np.array([fx, fy])


def clearance_ref(x, y, rects, circles):
    """Signed distance to the nearest obstacle, negative inside."""
    best = math.inf
    for xmin, xmax, ymin, ymax in rects:
        if xmin <= x <= xmax and ymin <= y <= ymax:
            d = -min(x - xmin, xmax - x, y - ymin, ymax - y)
        else:
            d = math.hypot(x - max(xmin, min(x, xmax)), y - max(ymin, min(y, ymax)))
        best = min(best, d)
    for cx, cy, r in circles:
        best = min(best, math.hypot(x - cx, y - cy) - r)
    return best


def guidance_ref(
    q,
    goal,
    gain,
    cruise,
    center=None,
    footprint=0.0,
    rects=(),
    circles=(),
    e_r=1.0,
    l_safe=1.0,
    dt=1.0,
):
    """sat_vc(k_g (g - q) + u^r(c; footprint) / dt)."""
    w = gain * (np.asarray(goal, float) - np.asarray(q, float))
    if footprint > 0:
        w = w + repulsion_ref(*center, rects, circles, e_r, l_safe, math.inf, footprint) / dt
    speed = math.hypot(*w)
    return w * cruise / speed if speed > cruise else w


def adj_of(n: int, edges) -> Adjacency:
    return Adjacency.from_graph(communication_graph("edges", n, edges=[list(e) for e in edges]))


def random_connected_edges(rng: np.random.Generator, n: int, extra: int) -> list[tuple]:
    """Random spanning tree plus ``extra`` random edges."""
    order = rng.permutation(n)
    edges = {tuple(sorted((int(order[i]), int(order[rng.integers(i)])))) for i in range(1, n)}
    for _ in range(extra):
        m, p = rng.choice(n, size=2, replace=False)
        edges.add((min(int(m), int(p)), max(int(m), int(p))))
    return sorted(edges)


# =============================================================================================
# Hand-computed steps
# =============================================================================================
def test_consensus_hand_computed():
    """Path 0-1-2, leader 0, gamma = 1/2, v = [[7,7],[1,0],[3,2]], v_ref = (2, 1):
    UAV 1: (v1 - v2) + (v1 - v_ref) = (-2,-2) + (-1,-1) -> v1 + 1.5 = (2.5, 1.5);
    UAV 2: v2 - v1 = (2, 2) -> (2, 1); the leader's row (7, 7) is replaced by v_ref."""
    adj = adj_of(3, [(0, 1), (1, 2)])
    v = [[7.0, 7.0], [1.0, 0.0], [3.0, 2.0]]
    out = consensus_step(v, [2.0, 1.0], adj, 0, ControlGains(gamma=0.5))
    np.testing.assert_allclose(out, [[2.0, 1.0], [2.5, 1.5], [2.0, 1.0]], rtol=0, atol=1e-15)


def test_consensus_hand_computed_leader_not_zero():
    """Same path, leader 1 in the middle, gamma = 1/4, v_ref = (4, 0):
    UAV 0: v0 - v_ref = (-3, 2) -> (1.75, 1.5); UAV 2: v2 - v_ref = (-1, 2) -> (3.25, 1.5)."""
    adj = adj_of(3, [(0, 1), (1, 2)])
    v = [[1.0, 2.0], [9.0, 9.0], [3.0, 2.0]]
    out = consensus_step(v, [4.0, 0.0], adj, 1, ControlGains(gamma=0.25))
    np.testing.assert_allclose(out, [[1.75, 1.5], [4.0, 0.0], [3.25, 1.5]], rtol=0, atol=1e-15)


def test_formation_input_hand_computed():
    """Triangle (complete), eps = 0.1, eta = 1/2, q = [[0,0],[4,0],[0,2]],
    delta = [[0,0],[2,0],[0,2]]: with e_m = q_m - eta delta_m = (0,0), (3,0), (0,1),
    u_m = -eps sum_p (e_m - e_p) = (0.3, 0.1), (-0.6, 0.1), (0.3, -0.2)."""
    adj = adj_of(3, [(0, 1), (1, 2), (0, 2)])
    q = [[0.0, 0.0], [4.0, 0.0], [0.0, 2.0]]
    delta = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]
    out = formation_input(q, delta, 0.5, adj, ControlGains(epsilon=0.1))
    np.testing.assert_allclose(out, [[0.3, 0.1], [-0.6, 0.1], [0.3, -0.2]], rtol=0, atol=1e-15)


def test_formation_cost_hand_computed():
    """Same triangle, eta not involved: e_m = q_m - delta_m = (0,0), (2,0), (0,0); ordered
    pairs give 2 (4 + 0 + 4) = 16. Steps (1,0), (0,0), (0,1) over dt = 0.5 minus
    v_ref = (2, 0): (0,0), (-2,0), (-2,2) -> 0 + 4 + 8 = 12. Total 28."""
    adj = adj_of(3, [(0, 1), (1, 2), (0, 2)])
    q = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 2.0]])
    q_next = q + np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    delta = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]
    assert formation_cost(q, q_next, delta, [2.0, 0.0], adj, 0.5) == pytest.approx(28.0, 1e-14)


RECT = [0.0, 1.0, 0.0, 1.0]
CIRCLE = [3.0, -3.0, 1.0]


def test_repulsion_hand_computed():
    """E_r = 2, l_safe = 5. Point (3, 0.5): the unit square's clamp is (1, 0.5), l = 2,
    2 (1/2 - 1/5) / 4 = 0.15 along +x; the circle at (3, -3), r = 1: l = 2.5,
    2 (0.4 - 0.2) / 6.25 = 0.064 along +y. (4, 5): l = 5 from (1, 1), not < l_safe: 0."""
    obstacles = Obstacles([RECT], [CIRCLE])
    out = repulsion([[3.0, 0.5], [4.0, 5.0], [30.0, 30.0]], obstacles, REPULSION)
    np.testing.assert_allclose(out, [[0.15, 0.064], [0.0, 0.0], [0.0, 0.0]], rtol=0, atol=1e-15)
    only_rect = repulsion([3.0, 0.5], Obstacles([RECT]), REPULSION)
    np.testing.assert_allclose(only_rect, [0.15, 0.0], rtol=0, atol=1e-15)


def test_repulsion_corner_and_cap_hand_computed():
    """Point (2, 2): nearest point of the square is the corner (1, 1), l = sqrt 2,
    magnitude 2 (1/sqrt2 - 1/5) / 2 = 1/sqrt2 - 0.2 along (1, 1)/sqrt2. Capped at 0.1, the
    same direction with length 0.1."""
    obstacles = Obstacles([RECT])
    mag = 1.0 / math.sqrt(2.0) - 0.2
    expected = mag * np.array([1.0, 1.0]) / math.sqrt(2.0)
    np.testing.assert_allclose(repulsion([2.0, 2.0], obstacles, REPULSION), expected, 1e-14)
    capped = repulsion([2.0, 2.0], obstacles, repulsion_gains(max_step=0.1))
    np.testing.assert_allclose(capped, 0.1 * np.array([1.0, 1.0]) / math.sqrt(2.0), 1e-14)


def test_repulsion_cap_applies_to_the_sum():
    """Between two equal circles the pushes cancel: the sum (zero) is capped, not each
    push (which would also give zero here, but with unequal distances the capped sum
    differs from the sum of capped pushes)."""
    obstacles = Obstacles(circles=[[-2.0, 0.0, 1.0], [2.5, 0.0, 1.0]])
    # l = 1 to the left circle, 1.5 to the right one; E_r = 2, l_safe = 5.
    left = 2.0 * (1.0 - 0.2) / 1.0  # 1.6 along +x
    right = 2.0 * (1.0 / 1.5 - 0.2) / 2.25  # along -x
    total = left - right
    np.testing.assert_allclose(
        repulsion([0.0, 0.0], obstacles, REPULSION), [total, 0.0], rtol=1e-14, atol=0
    )
    np.testing.assert_allclose(
        repulsion([0.0, 0.0], obstacles, repulsion_gains(max_step=0.5)), [0.5, 0.0], 1e-14
    )
    # Summing capped pushes would give 0.5 - 0.5 = 0.
    np.testing.assert_allclose(
        repulsion([0.0, 0.0], obstacles, repulsion_gains(max_step=1.0)), [1.0, 0.0], 1e-14
    )


def test_repulsion_inside_pushes_out_through_the_nearest_face():
    """Inside a rectangle the UAV is pushed out through the closest face, at the cap."""
    obstacles = Obstacles([[0.0, 10.0, 0.0, 4.0]])
    points = [[9.5, 2.0], [0.2, 2.0], [5.0, 0.3], [5.0, 3.9]]
    expected = [[1.0, 0.0], [-1.0, 0.0], [0.0, -1.0], [0.0, 1.0]]
    out = repulsion(points, obstacles, repulsion_gains(max_step=0.7))
    np.testing.assert_allclose(out, 0.7 * np.array(expected), rtol=1e-14, atol=1e-14)


def test_obstacle_clearance_hand_computed():
    obstacles = Obstacles([RECT], [CIRCLE])
    points = [[3.0, 0.5], [0.9, 0.5], [0.5, 0.5], [4.0, 5.0], [3.0, -3.5], [1.0, 0.5]]
    # (3, 0.5): 2 to the square, 2.5 to the circle; inside the square 0.1 and 0.5 from the
    # nearest face; (4, 5): 5 from the corner (1, 1); (3, -3.5) inside the circle (-0.5);
    # on the square's face: 0.
    expected = [2.0, -0.1, -0.5, 5.0, -0.5, 0.0]
    np.testing.assert_allclose(obstacle_clearance(points, obstacles), expected, 1e-14, 1e-15)


def test_obstacle_clearance_without_obstacles_is_inf():
    out = obstacle_clearance(np.zeros((3, 4, 2)), Obstacles())
    assert out.shape == (3, 4)
    assert np.all(np.isposinf(out))


def test_leader_guidance_hand_computed():
    """k_g = 0.5, v_c = 2 from (0, 0): to (3, 4) k_g (g - q) = (1.5, 2), |.| = 2.5 > 2, so
    (1.2, 1.6); to (0.6, 0.8): (0.3, 0.4), unsaturated."""
    gains = guidance_gains(0.5, 2.0)
    out = leader_guidance([[0.0, 0.0], [0.0, 0.0]], [[3.0, 4.0], [0.6, 0.8]], gains)
    np.testing.assert_allclose(out, [[1.2, 1.6], [0.3, 0.4]], rtol=1e-15, atol=1e-15)


def test_leader_guidance_footprint_hand_computed():
    """Centre (10, 0.5), unit square, footprint 6: l = 9 - 6 = 3, E_r = 2, l_safe = 5:
    2 (1/3 - 1/5) / 9 = 4/135 along +x, over dt = 0.1: 40/135. Added to (0.3, 0.4) it is
    (0.3 + 40/135, 0.4) below v_c = 2; with v_c = 0.5 it is scaled down to 0.5."""
    kwargs = {
        "center_xy": [10.0, 0.5],
        "footprint": 6.0,
        "obstacles": Obstacles([RECT]),
        "dt": 0.1,
    }
    w = np.array([0.3 + 40.0 / 135.0, 0.4])
    out = leader_guidance([0.0, 0.0], [0.6, 0.8], guidance_gains(0.5, 2.0), **kwargs)
    np.testing.assert_allclose(out, w, rtol=1e-14)
    slow = leader_guidance([0.0, 0.0], [0.6, 0.8], guidance_gains(0.5, 0.5), **kwargs)
    np.testing.assert_allclose(slow, w * 0.5 / np.hypot(*w), rtol=1e-14)
    # Without a footprint the obstacles are ignored.
    bare = leader_guidance(
        [0.0, 0.0], [0.6, 0.8], guidance_gains(0.5, 2.0), **{**kwargs, "footprint": 0.0}
    )
    np.testing.assert_allclose(bare, [0.3, 0.4], rtol=1e-15)


def test_leader_guidance_footprint_needs_center_and_obstacles():
    with pytest.raises(ValueError, match=r"^footprint"):
        leader_guidance([0.0, 0.0], [1.0, 1.0], guidance_gains(0.5, 2.0), footprint=3.0)
    with pytest.raises(ValueError, match=r"^footprint"):
        leader_guidance([0.0, 0.0], [1.0, 1.0], guidance_gains(0.5, 2.0), footprint=-1.0)


def test_eta_update_hand_computed():
    """Rate 0.1 /s, dt 0.1 s: at most 0.01 per step."""
    out = eta_update([1.0, 0.5, 0.3, 0.7], [0.3, 0.505, 1.0, 0.7], EtaRule(rate=0.1), 0.1)
    np.testing.assert_allclose(out, [0.99, 0.505, 0.31, 0.7], rtol=0, atol=1e-15)


# =============================================================================================
# Against the loop references, random inputs
# =============================================================================================
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("n", [3, 6, 9])
def test_consensus_and_formation_match_reference(seed, n):
    rng = np.random.default_rng([seed, n])
    edges = random_connected_edges(rng, n, extra=n // 2)
    adj, a = adj_of(n, edges), adjacency_matrix(n, edges)
    v = rng.normal(size=(n, 2))
    v_ref = rng.normal(size=2)
    q = rng.uniform(-50, 50, size=(n, 2))
    delta = rng.uniform(-15, 15, size=(n, 2))
    eta = rng.uniform(0.3, 1.0)
    for leader in range(n):
        np.testing.assert_allclose(
            consensus_step(v, v_ref, adj, leader, GAINS),
            consensus_ref(v, v_ref, a, leader, GAINS.gamma),
            rtol=1e-13,
            atol=1e-13,
        )
    np.testing.assert_allclose(
        formation_input(q, delta, eta, adj, ControlGains(epsilon=0.03)),
        formation_ref(q, delta, eta, a, 0.03),
        rtol=1e-12,
        atol=1e-12,
    )
    q_next = q + rng.normal(size=(n, 2))
    assert formation_cost(q, q_next, delta, v_ref, adj, 0.1) == pytest.approx(
        cost_ref(q, q_next, delta, v_ref, a, 0.1), rel=1e-12
    )


SCENE_RECTS = [[30.0, 45.0, 0.0, 34.0], [30.0, 45.0, 54.0, 80.0], [-5.0, 0.0, -20.0, -12.0]]
SCENE_CIRCLES = [[60.0, 40.0, 4.0], [10.0, 60.0, 2.5]]
SCENE = Obstacles(SCENE_RECTS, SCENE_CIRCLES)

coords = st.floats(-30.0, 110.0, allow_nan=False)


def assert_vector_close(got, expected, rel: float) -> None:
    """|got - expected| <= rel |expected| (relative to the vector's length, not to each
    component: a small component of a long vector carries the long one's rounding)."""
    err = float(np.hypot(*(np.asarray(got) - expected)))
    assert err <= rel * float(np.hypot(*expected)) + 1e-300, (got, expected)


@settings(max_examples=300)
@given(coords, coords)
def test_clearance_matches_reference(x, y):
    got = float(obstacle_clearance([x, y], SCENE))
    assert got == pytest.approx(clearance_ref(x, y, SCENE_RECTS, SCENE_CIRCLES), abs=1e-12)


@settings(max_examples=300)
@given(coords, coords, st.floats(0.5, 20.0), st.floats(1.0, 10.0))
def test_repulsion_matches_reference_outside(x, y, gain, l_safe):
    """Outside the obstacles (by at least 1 cm), eq. (18) summed over near obstacles."""
    if clearance_ref(x, y, SCENE_RECTS, SCENE_CIRCLES) < 0.01:
        return
    expected = repulsion_ref(x, y, SCENE_RECTS, SCENE_CIRCLES, gain, l_safe)
    got = repulsion([x, y], SCENE, repulsion_gains(gain, l_safe))
    assert_vector_close(got, expected, 1e-12)
    capped = repulsion([x, y], SCENE, repulsion_gains(gain, l_safe, max_step=0.5))
    assert_vector_close(
        capped, repulsion_ref(x, y, SCENE_RECTS, SCENE_CIRCLES, gain, l_safe, 0.5), 1e-12
    )
    assert np.hypot(*capped) <= 0.5 * (1 + 1e-12)


def test_repulsion_zero_beyond_safety_radius():
    """Every point with clearance >= l_safe gets exactly zero."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(-30, 110, size=(20000, 2))
    far = np.array([clearance_ref(x, y, SCENE_RECTS, SCENE_CIRCLES) >= 5.0 for x, y in pts])
    out = repulsion(pts, SCENE, REPULSION)
    assert far.sum() > 1000
    assert np.all(out[far] == 0.0)
    assert np.all(np.any(out[~far] != 0.0, axis=1))


def test_repulsion_points_away_from_nearest_point_and_decreases():
    """Along the outward normal of a face the push is outward and decreasing in l."""
    obstacles = Obstacles([[0.0, 10.0, 0.0, 10.0]])
    ells = np.linspace(0.2, 4.9, 50)
    pts = np.stack([10.0 + ells, np.full_like(ells, 5.0)], axis=-1)
    out = repulsion(pts, obstacles, REPULSION)
    assert np.all(out[:, 1] == 0.0)
    assert np.all(out[:, 0] > 0.0)
    assert np.all(np.diff(out[:, 0]) < 0.0)


@settings(max_examples=200)
@given(
    st.floats(-40.0, 120.0),
    st.floats(-40.0, 120.0),
    st.floats(0.1, 3.0),
    st.floats(0.1, 5.0),
    st.floats(0.0, 8.0),
)
def test_leader_guidance_matches_reference(cx, cy, gain, cruise, footprint):
    """Saturated proportional guidance plus the disc repulsion (distances minus the
    footprint, no cap), over dt, for centres whose disc stays outside every obstacle."""
    if clearance_ref(cx, cy, SCENE_RECTS, SCENE_CIRCLES) - footprint < 0.05:
        return
    q, goal = [cx + 3.0, cy - 2.0], [80.0, 90.0]
    expected = guidance_ref(
        q, goal, gain, cruise, (cx, cy), footprint, SCENE_RECTS, SCENE_CIRCLES, 2.0, 5.0, 0.1
    )
    got = leader_guidance(
        q,
        goal,
        guidance_gains(gain, cruise),
        center_xy=[cx, cy],
        footprint=footprint,
        obstacles=SCENE,
        dt=0.1,
    )
    assert_vector_close(got, expected, 1e-12)
    assert np.hypot(*got) <= cruise * (1 + 1e-12)


# =============================================================================================
# eta rule
# =============================================================================================
#: Nominal formation radius R of the eta tests, m.
RADIUS = 14.0

#: The eta rule of the eta tests: margin 5 m (l_safe), lookahead 40 m, eta_min 0.3, rate
#: 0.1 /s, 32 samples along the path.
ETA_RULE = EtaRule(margin=5.0, lookahead=40.0, minimum=0.3, rate=0.1, samples=32)


def test_eta_target_is_one_without_obstacles():
    rng = np.random.default_rng(0)
    c = rng.uniform(-100, 100, size=(4, 5, 2))
    out = eta_target(c, [80.0, 90.0], Obstacles(), RADIUS, ETA_RULE)
    assert out.shape == (4, 5)
    assert np.all(out == 1.0)


def test_eta_target_is_one_far_from_obstacles():
    """Obstacles far off the corridor (and the target closer than any of them)."""
    obstacles = Obstacles([[0.0, 10.0, 500.0, 600.0]], [[-300.0, 0.0, 5.0]])
    c = np.stack([np.linspace(-50, 50, 11), np.zeros(11)], axis=-1)
    assert np.all(eta_target(c, [100.0, 0.0], obstacles, RADIUS, ETA_RULE) == 1.0)


def test_eta_target_is_eta_min_when_blocked():
    """A wall across the whole path ahead: no free width, eta_min."""
    wall = Obstacles([[10.0, 20.0, -1000.0, 1000.0]])
    out = eta_target([[0.0, 0.0], [-5.0, 3.0], [15.0, 0.0]], [100.0, 0.0], wall, RADIUS, ETA_RULE)
    np.testing.assert_array_equal(out, 0.3)
    low_floor = EtaRule(margin=5.0, lookahead=40.0, minimum=0.05, rate=0.1, samples=32)
    out = eta_target([0.0, 0.0], [100.0, 0.0], wall, RADIUS, low_floor)
    assert float(out) == 0.05


def test_eta_target_in_a_straight_corridor():
    """Walls at y = +-10 along the path: the free half-width is 10 (at the corridor's
    middle), so eta = (10 - margin) / R = 5/14; a wider corridor gives 1."""
    walls = Obstacles([[-100.0, 200.0, 10.0, 50.0], [-100.0, 200.0, -50.0, -10.0]])
    out = eta_target(
        [[0.0, 0.0], [-20.0, 0.0], [50.0, 0.0]], [150.0, 0.0], walls, RADIUS, ETA_RULE
    )
    np.testing.assert_allclose(out, 5.0 / 14.0, rtol=1e-14)
    wide = Obstacles([[-100.0, 200.0, 20.0, 50.0], [-100.0, 200.0, -50.0, -20.0]])
    assert float(eta_target([0.0, 0.0], [150.0, 0.0], wide, RADIUS, ETA_RULE)) == 1.0


def test_eta_target_looks_ahead_and_behind():
    """A wall across the path at distance D beyond the lookahead leaves D - 40 of clearance
    at the farthest sample: eta = (D - 40 - 5)/14, clipped. A corridor just left behind
    (within R) still counts; once the rear sample (R behind) is margin + R clear of its
    walls it no longer does."""
    for dist, expected in [(50.0, 5.0 / 14.0), (52.0, 7.0 / 14.0), (59.0, 1.0), (80.0, 1.0)]:
        wall = Obstacles([[dist, dist + 10.0, -1000.0, 1000.0]])
        got = float(eta_target([0.0, 0.0], [500.0, 0.0], wall, RADIUS, ETA_RULE))
        assert got == pytest.approx(expected, rel=1e-13)
    corridor = Obstacles([[-100.0, 0.0, 10.0, 50.0], [-100.0, 0.0, -50.0, -10.0]])
    inside = float(eta_target([7.0, 0.0], [150.0, 0.0], corridor, RADIUS, ETA_RULE))
    assert inside == pytest.approx(5.0 / 14.0, rel=1e-13)
    # Centre at x = 31: rear sample at x = 17, clearance hypot(17, 10) > 19 = margin + R.
    assert float(eta_target([31.0, 0.0], [150.0, 0.0], corridor, RADIUS, ETA_RULE)) == 1.0
    assert float(eta_target([20.0, 0.0], [150.0, 0.0], corridor, RADIUS, ETA_RULE)) < 1.0


def test_eta_target_does_not_look_past_the_target():
    """The segment stops at the target: a wall just beyond a near target is not seen."""
    wall = Obstacles([[45.0, 55.0, -1000.0, 1000.0]])
    assert float(eta_target([0.0, 0.0], [20.0, 0.0], wall, RADIUS, ETA_RULE)) == 1.0
    assert float(eta_target([0.0, 0.0], [500.0, 0.0], wall, RADIUS, ETA_RULE)) == 0.3


PAPER_OBSTACLES = Obstacles([[30.0, 45.0, 0.0, 34.0], [30.0, 45.0, 54.0, 80.0]])


@settings(max_examples=200)
@given(
    st.floats(-20.0, 120.0),
    st.floats(-20.0, 120.0),
    st.floats(0.0, 2.0 * math.pi),
    st.floats(1e-6, 1e-2),
)
def test_eta_target_range_and_continuity(cx, cy, angle, step):
    """eta in [eta_min, 1]; moving the centre by |dc| changes eta by at most
    (2 + (lookahead + R)/dist) |dc| / R: the clearance is 1-Lipschitz, the sample points
    move by |dc| (translation), |d ahead| <= |dc| (spacing) and sqrt(t^2 + o^2) |dc| / dist
    (the heading turns by at most |dc|/dist); min and max keep the constant."""
    target = np.array([80.0, 90.0])
    c = np.array([cx, cy])
    dist = float(np.hypot(*(target - c)))
    if dist < 20.0:
        return
    dc = step * np.array([math.cos(angle), math.sin(angle)])
    a, b = eta_target(np.stack([c, c + dc]), target, PAPER_OBSTACLES, RADIUS, ETA_RULE)
    assert 0.3 <= a <= 1.0
    bound = (2.0 + (40.0 + 14.0) / (dist - step)) * step / 14.0
    assert abs(a - b) <= 1.01 * bound + 1e-12


def test_eta_target_paper_path_shrinks_and_recovers():
    """Along the straight line from the start to the target the rule dips below 1 near the
    gap and is 1 at both ends; the sampled profile has no jumps."""
    t = np.linspace(0.0, 1.0, 2001)[:, None]
    c = (1 - t) * np.array([-40.0, -45.0]) + t * np.array([80.0, 90.0])
    out = eta_target(c, [80.0, 90.0], PAPER_OBSTACLES, RADIUS, ETA_RULE)
    assert out[0] == 1.0
    assert out[-1] == 1.0
    assert out.min() < 0.6
    spacing = float(np.hypot(120.0, 135.0) / 2000)
    assert np.max(np.abs(np.diff(out))) < 0.5 * spacing  # far below a jump


@settings(max_examples=200)
@given(st.floats(1e-6, 1.0), st.floats(1e-6, 1.0), st.floats(0.01, 1.0), st.floats(0.01, 0.5))
def test_eta_update_rate_limit(eta, goal, rate, dt):
    new = float(eta_update(eta, goal, EtaRule(rate=rate), dt))
    assert abs(new - eta) <= rate * dt * (1 + 1e-12)
    assert min(eta, goal) - 1e-15 <= new <= max(eta, goal) + 1e-15
    if abs(goal - eta) <= rate * dt:
        assert new == pytest.approx(goal, abs=1e-15)
    else:
        assert abs(new - eta) == pytest.approx(rate * dt, rel=1e-12)


# =============================================================================================
# Closed-form solutions of the linear laws
# =============================================================================================
def follower_block(lap: np.ndarray, leader: int) -> np.ndarray:
    keep = [i for i in range(lap.shape[0]) if i != leader]
    return lap[np.ix_(keep, keep)]


@pytest.mark.parametrize("leader", [0, 7])
@pytest.mark.parametrize("name", list(GRAPHS))
def test_consensus_converges_below_limit_and_matches_matrix_power(name, leader):
    """With a constant v_ref the followers' error e = v_f - v_ref obeys
    e_k = (I - gamma L_ff)^k e_0 (L built by networkx); at gamma = 0.9 * limit every
    velocity reaches v_ref. The limit itself is checked against numpy's eigenvalues."""
    graph = GRAPHS[name]()
    adj = Adjacency.from_graph(graph)
    n = adj.n_nodes
    lap = nx.laplacian_matrix(graph, nodelist=range(n)).toarray().astype(float)
    l_ff = follower_block(lap, leader)
    eig = np.linalg.eigvalsh(l_ff)
    limit = consensus_step_limit(adj, leader)
    assert limit == pytest.approx(2.0 / eig[-1], rel=1e-12)
    gamma = 0.9 * limit
    rng = np.random.default_rng(n + leader)
    v0 = rng.normal(size=(5, n, 2)) * 3.0  # 5 initial conditions at once (a batch)
    v_ref = np.array([1.5, -0.5])
    followers = [i for i in range(n) if i != leader]
    rho = max(abs(1 - gamma * eig[0]), abs(1 - gamma * eig[-1]))
    steps = math.ceil(math.log(1e-11) / math.log(rho))
    v = v0
    for k in range(1, steps + 1):
        v = consensus_step(v, v_ref, adj, leader, ControlGains(gamma=gamma))
        if k == 40:
            power = np.linalg.matrix_power(np.eye(n - 1) - gamma * l_ff, 40)
            expected = np.einsum("ij,bjc->bic", power, v0[:, followers] - v_ref) + v_ref
            np.testing.assert_allclose(v[:, followers], expected, rtol=0, atol=1e-11)
            np.testing.assert_array_equal(v[:, leader], np.broadcast_to(v_ref, (5, 2)))
    assert np.max(np.abs(v - v_ref)) < 1e-9


@pytest.mark.parametrize("name", list(GRAPHS))
def test_consensus_diverges_above_limit(name):
    """At gamma = 1.1 * limit the error grows like (1.2)^k along the top eigenvector."""
    graph = GRAPHS[name]()
    adj = Adjacency.from_graph(graph)
    gains = ControlGains(gamma=1.1 * consensus_step_limit(adj, 0))
    rng = np.random.default_rng(0)
    v = rng.normal(size=(adj.n_nodes, 2))
    start = np.max(np.abs(v[1:]))
    for _ in range(200):
        v = consensus_step(v, [0.0, 0.0], adj, 0, gains)
    assert np.max(np.abs(v)) > 1e6 * start


@pytest.mark.parametrize("factor", [0.5, 0.99, 1.02])
@pytest.mark.parametrize("name", list(GRAPHS))
def test_formation_matches_closed_form(name, factor):
    """Without obstacles, noise or velocities, q_k - eta delta = (I - eps L)^k (q_0 - eta
    delta) per coordinate (L from networkx); below the limit the shape converges
    (every q_m - eta delta_m to a common point), above it the error explodes."""
    graph = GRAPHS[name]()
    adj = Adjacency.from_graph(graph)
    n = adj.n_nodes
    lap = nx.laplacian_matrix(graph, nodelist=range(n)).toarray().astype(float)
    lam = np.linalg.eigvalsh(lap)
    assert formation_step_limit(adj) == pytest.approx(2.0 / lam[-1], rel=1e-12)
    eps = factor * formation_step_limit(adj)
    rng = np.random.default_rng(n)
    q0 = rng.uniform(-20.0, 20.0, size=(n, 2))
    delta = rng.uniform(-10.0, 10.0, size=(n, 2))
    eta = 0.7
    q = q0
    steps = 300
    for _ in range(steps):
        q = q + formation_input(q, delta, eta, adj, ControlGains(epsilon=eps))
    power = np.linalg.matrix_power(np.eye(n) - eps * lap, steps)
    expected = power @ (q0 - eta * delta) + eta * delta
    scale = max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(q, expected, rtol=0, atol=1e-10 * scale)
    # Shape error: q - eta delta minus its centroid; it obeys the same recursion on the
    # subspace orthogonal to 1, where |I - eps L| = rho (Frobenius norm over both columns).
    shape_error = q - eta * delta - (q - eta * delta).mean(axis=0)
    initial = q0 - eta * delta - (q0 - eta * delta).mean(axis=0)
    rho = max(abs(1 - eps * lam[1]), abs(1 - eps * lam[-1]))
    if factor < 1:
        assert np.linalg.norm(shape_error) <= rho**steps * np.linalg.norm(initial) + 1e-9
        # The centroid of q - eta delta never moves: sum_m u_m = 0 (L symmetric).
        np.testing.assert_allclose(
            (q - eta * delta).mean(axis=0), (q0 - eta * delta).mean(axis=0), atol=1e-10
        )
    else:
        assert np.linalg.norm(shape_error) > 100.0 * np.linalg.norm(initial)


# =============================================================================================
# Invariance to relabelling the followers
# =============================================================================================
def relabel(edges, perm):
    """New index i is old index perm[i]: old edge (m, p) becomes (inv[m], inv[p])."""
    inv = np.argsort(perm)
    return [(int(inv[m]), int(inv[p])) for m, p in edges]


def closed_loop(q0, delta, edges, leader, steps, eta=0.8):
    """A small mission composed of the public laws: guidance, formation input + repulsion,
    motion (eq. 3) and consensus; returns positions (steps+1, M, 2) and velocities."""
    n = q0.shape[0]
    adj = adj_of(n, edges)
    target = np.array([80.0, 90.0])
    q, v = q0.copy(), np.zeros_like(q0)
    qs, vs = [q], [v]
    for _ in range(steps):
        c = q.mean(axis=0)
        v_ref = leader_guidance(
            q[leader],
            target + eta * delta[leader],
            MISSION_GAINS,
            center_xy=c,
            footprint=eta * 14.0,
            obstacles=PAPER_OBSTACLES,
            dt=0.1,
        )
        v = v.copy()
        v[leader] = v_ref
        u = formation_input(q, delta, eta, adj, MISSION_GAINS) + repulsion(
            q, PAPER_OBSTACLES, MISSION_GAINS
        )
        q = q + u + 0.1 * v
        v = consensus_step(v, v_ref, adj, leader, MISSION_GAINS)
        qs.append(q)
        vs.append(v)
    return np.array(qs), np.array(vs)


@pytest.mark.parametrize("seed", SEEDS)
def test_closed_loop_invariant_to_relabelling_followers(seed):
    """Permuting the followers (leader fixed) together with the graph, the start positions
    and the formation slots gives the same trajectories, permuted. The simulator ties the
    slot of UAV m in F* to the index m, so this is checked here on a closed loop composed of
    the public laws, where the slots delta can be permuted with the UAVs (see
    tests/test_simulation.py for the relabellings the simulator admits)."""
    rng = np.random.default_rng(seed)
    n, leader = 6, int(rng.integers(6))
    edges = random_connected_edges(rng, n, extra=2)
    perm = np.arange(n)
    followers = [i for i in range(n) if i != leader]
    perm[followers] = rng.permutation(followers)
    assert perm[leader] == leader
    assert not np.array_equal(perm, np.arange(n))
    q0 = rng.uniform(-10.0, 10.0, size=(n, 2))
    delta = 14.0 * np.stack(
        [np.cos(2 * np.pi * np.arange(n) / n), np.sin(2 * np.pi * np.arange(n) / n)], axis=-1
    )
    qa, va = closed_loop(q0, delta, edges, leader, 300)
    qb, vb = closed_loop(q0[perm], delta[perm], relabel(edges, perm), leader, 300)
    np.testing.assert_allclose(qb, qa[:, perm], rtol=0, atol=1e-9)
    np.testing.assert_allclose(vb, va[:, perm], rtol=0, atol=1e-9)


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1), st.integers(3, 9))
def test_laws_are_equivariant_under_relabelling(seed, n):
    """Each law on relabelled inputs = the law's output relabelled; the cost is invariant."""
    rng = np.random.default_rng(seed)
    leader = int(rng.integers(n))
    edges = random_connected_edges(rng, n, extra=int(rng.integers(0, n)))
    perm = np.arange(n)
    followers = [i for i in range(n) if i != leader]
    perm[followers] = rng.permutation(followers)
    adj, adj_p = adj_of(n, edges), adj_of(n, relabel(edges, perm))
    q, qn, delta, v = (rng.normal(scale=10.0, size=(n, 2)) for _ in range(4))
    v_ref = rng.normal(size=2)
    np.testing.assert_allclose(
        formation_input(q[perm], delta[perm], 0.6, adj_p, GAINS),
        formation_input(q, delta, 0.6, adj, GAINS)[perm],
        rtol=1e-12,
        atol=1e-12,
    )
    np.testing.assert_allclose(
        consensus_step(v[perm], v_ref, adj_p, leader, GAINS),
        consensus_step(v, v_ref, adj, leader, GAINS)[perm],
        rtol=1e-12,
        atol=1e-12,
    )
    assert formation_cost(q[perm], qn[perm], delta[perm], v_ref, adj_p, 0.1) == pytest.approx(
        formation_cost(q, qn, delta, v_ref, adj, 0.1), rel=1e-12
    )


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1))
def test_formation_input_invariant_to_translation_and_rotation(seed):
    """u is equivariant under rotating the frame (q and delta rotated alike) and invariant
    under translating q; the formation input sums to zero."""
    rng = np.random.default_rng(seed)
    n = 6
    adj = adj_of(n, random_connected_edges(rng, n, extra=3))
    q, delta = rng.normal(scale=10.0, size=(n, 2)), rng.normal(scale=10.0, size=(n, 2))
    theta = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    u = formation_input(q, delta, 0.9, adj, GAINS)
    np.testing.assert_allclose(
        formation_input(q @ rot.T, delta @ rot.T, 0.9, adj, GAINS), u @ rot.T, atol=1e-12
    )
    np.testing.assert_allclose(
        formation_input(q + rng.normal(scale=100.0, size=2), delta, 0.9, adj, GAINS),
        u,
        atol=1e-11,
    )
    np.testing.assert_allclose(u.sum(axis=0), 0.0, atol=1e-12)


def test_cost_is_zero_on_the_formation_moving_at_v_ref():
    """Displacements equal to delta and every UAV moving by v_ref dT: zero cost; the
    nominal displacements are used, so a shrunk formation (eta < 1) costs something."""
    adj = Adjacency.from_graph(communication_graph("ring", 6))
    angles = 2 * np.pi * np.arange(6) / 6
    delta = 14.0 * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    q = delta + np.array([80.0, 90.0])
    v_ref = np.array([1.0, -2.0])
    assert float(formation_cost(q, q + 0.1 * v_ref, delta, v_ref, adj, 0.1)) < 1e-20
    shrunk = 0.5 * delta + np.array([80.0, 90.0])
    expected = sum(
        2 * 0.25 * np.sum((delta[m] - delta[(m + 1) % 6]) ** 2) for m in range(6)
    )  # each ring edge twice, error = -(1 - 0.5)(delta_m - delta_p)
    got = float(formation_cost(shrunk, shrunk, delta, [0.0, 0.0], adj, 0.1))
    assert got == pytest.approx(expected, rel=1e-12)


# =============================================================================================
# Batches, broadcasting and read-only inputs
# =============================================================================================
@pytest.fixture(scope="module")
def batch_case():
    rng = np.random.default_rng(42)
    n = 5
    adj = adj_of(n, [(0, 1), (1, 2), (2, 3), (3, 4), (4, 0), (1, 3)])
    return {
        "adj": adj,
        "q": rng.uniform(20.0, 60.0, size=(2, 3, n, 2)),
        "qn": rng.uniform(20.0, 60.0, size=(2, 3, n, 2)),
        "v": rng.normal(size=(2, 3, n, 2)),
        "v_ref": rng.normal(size=(2, 3, 2)),
        "delta": rng.normal(scale=10.0, size=(n, 2)),
        "eta": rng.uniform(0.3, 1.0, size=(2, 3)),
        "pts": rng.uniform(20.0, 60.0, size=(2, 3, 2)),
    }


def test_batches_equal_loops(batch_case):
    """Every law on a (2, 3, ...) batch = the law applied to each element."""
    b = batch_case
    adj = b["adj"]
    cons = consensus_step(b["v"], b["v_ref"], adj, 2, GAINS)
    form = formation_input(b["q"], b["delta"], b["eta"], adj, GAINS)
    cost = formation_cost(b["q"], b["qn"], b["delta"], b["v_ref"], adj, 0.1)
    rep = repulsion(b["pts"], SCENE, GAINS)
    clear = obstacle_clearance(b["pts"], SCENE)
    guide_kw = {"footprint": 2.0, "obstacles": SCENE, "dt": 0.1}
    guide = leader_guidance(b["pts"], [80.0, 90.0], GAINS, center_xy=b["pts"] + 1.0, **guide_kw)
    eta_goal = eta_target(b["pts"], [80.0, 90.0], PAPER_OBSTACLES, RADIUS, ETA_RULE)
    upd = eta_update(b["eta"], eta_goal, ETA_RULE, 0.1)
    assert cons.shape == form.shape == (2, 3, 5, 2)
    assert cost.shape == clear.shape == eta_goal.shape == upd.shape == (2, 3)
    assert rep.shape == guide.shape == (2, 3, 2)
    for i in range(2):
        for j in range(3):
            np.testing.assert_array_equal(
                cons[i, j], consensus_step(b["v"][i, j], b["v_ref"][i, j], adj, 2, GAINS)
            )
            np.testing.assert_array_equal(
                form[i, j], formation_input(b["q"][i, j], b["delta"], b["eta"][i, j], adj, GAINS)
            )
            assert cost[i, j] == formation_cost(
                b["q"][i, j], b["qn"][i, j], b["delta"], b["v_ref"][i, j], adj, 0.1
            )
            p = b["pts"][i, j]
            np.testing.assert_array_equal(rep[i, j], repulsion(p, SCENE, GAINS))
            assert clear[i, j] == obstacle_clearance(p, SCENE)
            np.testing.assert_array_equal(
                guide[i, j],
                leader_guidance(p, [80.0, 90.0], GAINS, center_xy=p + 1.0, **guide_kw),
            )
            assert eta_goal[i, j] == eta_target(p, [80.0, 90.0], PAPER_OBSTACLES, RADIUS, ETA_RULE)
            assert upd[i, j] == eta_update(b["eta"][i, j], eta_goal[i, j], ETA_RULE, 0.1)


def test_broadcasting(batch_case):
    """Leading shapes broadcast: one formation against a batch of references, a batch of
    formations against one scale, (3, M, 2) against (4, 1, 2) -> (4, 3)."""
    b = batch_case
    adj = b["adj"]
    v = b["v"][0]  # (3, M, 2)
    refs = np.random.default_rng(1).normal(size=(4, 1, 2))
    out = consensus_step(v, refs, adj, 0, GAINS)
    assert out.shape == (4, 3, 5, 2)
    for i in range(4):
        for j in range(3):
            np.testing.assert_array_equal(
                out[i, j], consensus_step(v[j], refs[i, 0], adj, 0, GAINS)
            )
    one = consensus_step(v[0], refs[:, 0], adj, 0, GAINS)
    assert one.shape == (4, 5, 2)
    form = formation_input(b["q"], b["delta"], 0.5, adj, GAINS)
    np.testing.assert_array_equal(
        form[1, 2], formation_input(b["q"][1, 2], b["delta"], 0.5, adj, GAINS)
    )
    etas = np.array([0.3, 0.6, 0.9])
    form = formation_input(b["q"][0, 0], b["delta"], etas, adj, GAINS)
    assert form.shape == (3, 5, 2)
    for i, e in enumerate(etas):
        np.testing.assert_array_equal(
            form[i], formation_input(b["q"][0, 0], b["delta"], e, adj, GAINS)
        )
    cost = formation_cost(b["q"][0], b["qn"][0, 0], b["delta"], [0.0, 1.0], adj, 0.1)
    assert cost.shape == (3,)
    goals = np.array([[10.0, 0.0], [0.0, 10.0], [-10.0, 0.0]])
    guide = leader_guidance([0.0, 0.0], goals, guidance_gains(0.1, 2.0))
    np.testing.assert_allclose(guide, 0.1 * goals)
    targets = np.array([[80.0, 90.0], [-100.0, 40.0]])
    eta_goal = eta_target([-10.0, 40.0], targets, PAPER_OBSTACLES, RADIUS, ETA_RULE)
    assert eta_goal.shape == (2,)
    assert eta_goal[1] == 1.0


def test_shapes_that_do_not_broadcast_are_rejected(batch_case):
    b = batch_case
    with pytest.raises(ValueError, match=r"^v_ref"):
        consensus_step(b["v"], np.zeros((4, 2)), b["adj"], 0, GAINS)
    with pytest.raises(ValueError, match=r"^eta"):
        formation_input(b["q"], b["delta"], np.ones(4), b["adj"], GAINS)
    with pytest.raises(ValueError, match=r"^velocities"):
        consensus_step(np.zeros((4, 2)), [0.0, 0.0], b["adj"], 0, GAINS)
    with pytest.raises(ValueError, match=r"^delta"):
        formation_input(b["q"], np.zeros((2, 5, 2)), 0.5, b["adj"], GAINS)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda a: consensus_step(np.zeros((5, 2)), [0, 0], a, 5, GAINS), "leader"),
        (lambda a: consensus_step(np.zeros((5, 2)), [0, np.nan], a, 0, GAINS), "v_ref"),
        (lambda a: formation_input(np.zeros((5, 2)), np.zeros((5, 2)), 0.0, a, GAINS), "eta"),
        (lambda a: formation_input(np.zeros((5, 2)), np.zeros((4, 2)), 1.0, a, GAINS), "delta"),
        (
            lambda a: formation_cost(
                np.zeros((5, 2)), np.zeros((5, 2)), np.zeros((5, 2)), [0, 0], a, 0.0
            ),
            "dt",
        ),
    ],
)
def test_invalid_arguments_name_the_argument(batch_case, call, field):
    with pytest.raises(FieldError, match=rf"^{field}:") as info:
        call(batch_case["adj"])
    assert info.value.field == field


@pytest.mark.parametrize(
    ("model", "field", "value"),
    [
        (ControlGains, "gamma", 0.0),
        (ControlGains, "epsilon", -1.0),
        (ControlGains, "repulsion_gain", -1.0),
        (ControlGains, "safety_radius", 0.0),
        (ControlGains, "repulsion_max_step", 0.0),
        (ControlGains, "repulsion_max_step", -1.0),
        (ControlGains, "repulsion_max_step", math.nan),
        (ControlGains, "repulsion_max_step", math.inf),
        (ControlGains, "cruise_speed", 0.0),
        (EtaRule, "minimum", 1.5),
        (EtaRule, "rate", 0.0),
    ],
)
def test_invalid_gains_name_the_field(model, field, value):
    """A gain out of range is refused where the gains are declared: one FieldError line (a
    ValueError) naming the field."""
    with pytest.raises(FieldError, match=rf"^{field}: ") as info:
        model(**{field: value})
    assert info.value.field == field
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda a: consensus_step(np.zeros((5, 2)), [0, 0], a, 0, 0.2), "gains"),
        (lambda a: formation_input(np.zeros((5, 2)), np.zeros((5, 2)), 1.0, a, 0.1), "gains"),
        (lambda a: repulsion([0.0, 0.0], SCENE, {"repulsion_gain": 2.0}), "gains"),
        (lambda a: leader_guidance([0, 0], [1, 1], 0.5), "gains"),
        (lambda a: eta_target([0, 0], [1, 1], SCENE, 14.0, ETA_RULE, 5.0), "gains"),
        (lambda a: eta_target([0, 0], [1, 1], SCENE, 14.0, GAINS), "rule"),
        (lambda a: eta_update(1.0, 0.5, 0.1, 0.1), "rule"),
    ],
)
def test_gains_of_another_type_are_refused(batch_case, call, field):
    """A law given loose numbers (the old signatures) or the wrong model instead of its
    ControlGains or EtaRule raises a FieldError naming the argument."""
    with pytest.raises(FieldError, match=rf"^{field}:") as info:
        call(batch_case["adj"])
    assert info.value.field == field


def test_obstacles_validation_and_copy():
    with pytest.raises(ValueError, match=r"^rectangles"):
        Obstacles([[1.0, 0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match=r"^circles"):
        Obstacles(circles=[[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"^rectangles"):
        Obstacles([[0.0, np.inf, 0.0, 1.0]])
    rects = np.array([[0.0, 1.0, 0.0, 1.0]])
    obstacles = Obstacles(rects)
    rects[0, 1] = 50.0  # the caller's array is copied, not kept
    assert obstacles.rectangles[0, 1] == 1.0
    assert obstacles.count == 1
    assert not obstacles.rectangles.flags.writeable


def test_inputs_are_never_modified(batch_case, make_readonly):
    """Read-only inputs are accepted (a write would raise) and writable inputs are unchanged;
    no output shares memory with an input."""
    b = batch_case
    adj = b["adj"]
    ro = {k: make_readonly(v) for k, v in b.items() if k != "adj"}
    ctl = {k: v.copy() for k, v in b.items() if k != "adj"}
    calls = [
        (consensus_step, (ro["v"], ro["v_ref"], adj, 1, GAINS)),
        (formation_input, (ro["q"], ro["delta"], ro["eta"], adj, GAINS)),
        (formation_cost, (ro["q"], ro["qn"], ro["delta"], ro["v_ref"], adj, 0.1)),
        (repulsion, (ro["pts"], SCENE, GAINS)),
        (obstacle_clearance, (ro["pts"], SCENE)),
        (
            eta_target,
            (ro["pts"], make_readonly([80.0, 90.0]), PAPER_OBSTACLES, RADIUS, ETA_RULE),
        ),
        (eta_update, (ro["eta"], make_readonly(np.full((2, 3), 0.5)), ETA_RULE, 0.1)),
    ]
    # Single formation (no batch): the fast paths must not write either.
    calls += [
        (consensus_step, (ro["v"][0, 0], ro["v_ref"][0, 0], adj, 1, GAINS)),
        (formation_input, (ro["q"][0, 0], ro["delta"], 0.5, adj, GAINS)),
        (repulsion, (ro["pts"][0, 0], SCENE, REPULSION)),
    ]
    for func, args in calls:
        out = func(*args)
        for arg in args:
            if isinstance(arg, np.ndarray):
                assert not np.shares_memory(out, arg), func.__name__
    out = leader_guidance(
        ro["pts"],
        make_readonly([80.0, 90.0]),
        GAINS,
        center_xy=ro["pts"],
        footprint=3.0,
        obstacles=SCENE,
        dt=0.1,
    )
    assert not np.shares_memory(out, ro["pts"])
    # Writable inputs: unchanged after every law.
    w = {k: v.copy() for k, v in b.items() if k != "adj"}
    consensus_step(w["v"], w["v_ref"], adj, 1, GAINS)
    formation_input(w["q"], w["delta"], w["eta"], adj, GAINS)
    formation_cost(w["q"], w["qn"], w["delta"], w["v_ref"], adj, 0.1)
    repulsion(w["pts"], SCENE, GAINS)
    obstacle_clearance(w["pts"], SCENE)
    eta_target(w["pts"], [80.0, 90.0], PAPER_OBSTACLES, RADIUS, ETA_RULE)
    eta_update(w["eta"], w["eta"] * 0.5, ETA_RULE, 0.1)
    leader_guidance(
        w["pts"],
        [80.0, 90.0],
        GAINS,
        center_xy=w["pts"],
        footprint=3.0,
        obstacles=SCENE,
        dt=0.1,
    )
    for key in w:
        np.testing.assert_array_equal(w[key], ctl[key])


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: Obstacles([[0.0, 1.0], [0.0, 1.0]]), "rectangles"),
        (lambda: Obstacles(circles=[[0.0, 0.0, 1.0, 2.0]]), "circles"),
        (lambda: obstacle_clearance([0.0, 0.0], [[0.0, 1.0, 0.0, 1.0]]), "obstacles"),
        (lambda: eta_update(0.5, 5.0, EtaRule(rate=1.0), 0.1), "goal"),
        (lambda: eta_update(0.0, 0.5, EtaRule(rate=1.0), 0.1), "eta"),
    ],
)
def test_bad_arguments_name_themselves(call, name):
    """Wrong types, shapes and out-of-range values raise a FieldError (a ValueError) naming
    the argument. (A bad repulsion cap is refused by ControlGains itself:
    test_invalid_gains_name_the_field.)"""
    with pytest.raises(FieldError, match=rf"^{name}") as info:
        call()
    assert info.value.field == name
