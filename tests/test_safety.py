"""The safety filter (crlbswarm.safety) against references written in this file.

References, none of which calls crlbswarm:

* the QP by a general solver (qpsolvers with Clarabel, an interior-point method): to
  ~1e-10 for linear rows (solution within 1e-6 of the problem's size asserted); with the
  speed disc, the disc is replaced by regular 720-gons, one inscribed
  (a subset: an upper bound on the optimum) and one circumscribed (a superset: a lower
  bound), which sandwich the true optimum; SciPy's SLSQP on the exact disc is the tight
  second opinion;
* optimality certificates: the KKT conditions, with the multipliers found by non-negative
  least squares;
* the barrier guarantees checked directly on the positions after the step: every pair's
  ``h = r^2 - D^2`` and every obstacle's ``c - m_o`` (signed distances written here) decay
  at most by ``1 - decay``, and simulations of whole swarms pushed together and into
  obstacles, with and without disturbance;
* invariance to relabelling the UAVs and to moving the frame, and distributedness.
"""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings, strategies as st
from qpsolvers import solve_qp
from scipy.optimize import linprog, minimize, nnls
from scipy.stats import norm

import crlbswarm.safety as safety
from crlbswarm import FieldError, Obstacles
from crlbswarm.safety import (
    disturbance_margins,
    safe_displacement,
    safety_filter,
    safety_step,
    solve_qp2,
)

SEEDS = [0, 1, 2, 3, 4]

#: Sides of the polygons standing in for the disc in the reference QP. The inscribed one is
#: the disc shrunk by at most vmax (1 - cos(pi/N)) = 9.5e-6 vmax.
POLYGON_SIDES = 720

#: Clarabel's tolerances (tighter than its defaults, 1e-8).
CLARABEL = {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12}

#: The scene of the swarm tests: separation 2 m, 5 m/s, 0.1 s steps (0.5 m per step).
SEP = 2.0
SPEED = 5.0
DT = 0.1
VSTEP = SPEED * DT
RADIUS = 8.0

#: Obstacles of the swarm tests: rectangles [x_min, x_max, y_min, y_max] and circles
#: [x, y, radius], in an arena of about 40 m x 40 m.
RECTS = np.array([[-14.0, -8.0, -3.0, 9.0], [4.0, 16.0, -16.0, -11.0]])
CIRCLES = np.array([[9.0, 8.0, 3.0], [-6.0, -12.0, 2.5]])


# ---------------------------------------------------------------------------------------
# References
# ---------------------------------------------------------------------------------------
def qp_reference(d0, a, b, polygon=None):
    """argmin |d - d0|^2 s.t. a d >= b (and polygon rows ``(normals, offsets)``: n d <= o)
    by Clarabel; returns (d, objective). Clarabel is given the same problem with unit row
    normals, in units of the problem's size: so scaled, it is accurate to better than 1e-7
    of the size (unscaled, with rows of lengths 0.1 to 10, only to ~1e-5)."""
    a = np.asarray(a, dtype=float).reshape(-1, 2)
    norms = np.linalg.norm(a, axis=1)
    g = -a / norms[:, None]
    h = -np.asarray(b, dtype=float).reshape(-1) / norms
    if polygon is not None:
        g = np.vstack([g, polygon[0]])
        h = np.concatenate([h, polygon[1]])
    size = np.linalg.norm(d0) + np.max(np.abs(h))
    d = solve_qp(
        sp.csc_matrix(2.0 * np.eye(2)), -2.0 * np.asarray(d0) / size, sp.csc_matrix(g),
        h / size, solver="clarabel", **CLARABEL,
    )  # fmt: skip
    assert d is not None
    d = d * size
    return d, float(np.sum((d - d0) ** 2))


def polygon(vmax, inscribed, n=POLYGON_SIDES):
    """Rows of a regular n-gon around the disc of radius vmax: inscribed (edge at distance
    vmax cos(pi/n)) or circumscribed (edge at distance vmax)."""
    theta = (2.0 * np.arange(n) + 1.0) * np.pi / n
    normals = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    offset = vmax * (math.cos(math.pi / n) if inscribed else 1.0)
    return normals, np.full(n, offset)


def slsqp(d0, a, b, vmax, start):
    """The QP with the exact disc by SciPy's SLSQP, from ``start``, solved in units of the
    problem's size (SLSQP's stopping test is absolute)."""
    s = np.linalg.norm(d0) + vmax
    d0, b, vmax = d0 / s, b / s, vmax / s
    cons = [
        {"type": "ineq", "fun": lambda d: a @ d - b, "jac": lambda d: a},
        {"type": "ineq", "fun": lambda d: vmax**2 - d @ d, "jac": lambda d: -2.0 * d},
    ]
    res = minimize(
        lambda d: np.sum((d - d0) ** 2), start / s, jac=lambda d: 2.0 * (d - d0),
        constraints=cons, method="SLSQP", options={"ftol": 1e-15, "maxiter": 500},
    )  # fmt: skip
    return res.x * s


def unit_rows(a, b):
    """Rows scaled to unit normals (the scale of a shortfall is then metres)."""
    n = np.linalg.norm(a, axis=1)
    return a / n[:, None], b / n


def kkt_residual(d, d0, a, b, vmax):
    """Stationarity residual of d for min |d - d0|^2, a d >= b, |d| <= vmax, relative to
    the problem's size, with the multipliers of the active constraints fitted by NNLS."""
    n, c = unit_rows(a, b)
    size = np.linalg.norm(d0) + (vmax if np.isfinite(vmax) else 0.0) + np.max(np.abs(c))
    active = n @ d - c <= 1e-9 * size
    grads = list(n[active])
    if np.isfinite(vmax) and np.linalg.norm(d) >= vmax * (1 - 1e-9) and vmax > 0:
        grads.append(-d / np.linalg.norm(d))
    if not grads:
        return np.linalg.norm(d - d0) / size
    _, res = nnls(np.array(grads).T, d - d0)
    return res / size


def clearances(q, rects, circles):
    """Signed distance of each point to each obstacle, shape (..., n_obstacles), from the
    definitions: outside a rectangle the distance to its clamp, inside minus the distance
    to the nearest face; for a disc the distance to the centre less the radius."""
    x = q[..., 0, None]
    y = q[..., 1, None]
    xmin, xmax, ymin, ymax = rects.T
    ox = np.maximum(np.maximum(xmin - x, x - xmax), 0.0)
    oy = np.maximum(np.maximum(ymin - y, y - ymax), 0.0)
    inside = -np.minimum(np.minimum(x - xmin, xmax - x), np.minimum(y - ymin, ymax - y))
    rect = np.where((ox > 0) | (oy > 0), np.hypot(ox, oy), inside)
    circ = np.linalg.norm(q[..., None, :] - circles[:, :2], axis=-1) - circles[:, 2]
    return np.concatenate([rect, circ], axis=-1)


def outward_normals(p, rects, circles):
    """Unit vectors from each obstacle's nearest point to p (p outside every obstacle)."""
    clamp = np.stack([np.clip(p[0], rects[:, 0], rects[:, 1]),
                      np.clip(p[1], rects[:, 2], rects[:, 3])], axis=1)  # fmt: skip
    away = np.vstack([p - clamp, p - circles[:, :2]])
    return away / np.linalg.norm(away, axis=1)[:, None]


def pair_distances(q):
    """Distances between all pairs, (..., M, M), +inf on the diagonal."""
    r = np.linalg.norm(q[..., :, None, :] - q[..., None, :, :], axis=-1)
    idx = np.arange(q.shape[-2])
    r[..., idx, idx] = np.inf
    return r


def safe_state(rng, m, reach, margin, rects=RECTS, circles=CIRCLES, box=18.0, gap=0.0):
    """m positions in [-box, box]^2 with pairs >= reach + gap apart and clearances >=
    margin + gap (rejection sampling)."""
    q = []
    while len(q) < m:
        p = rng.uniform(-box, box, 2)
        if q and np.min(np.linalg.norm(np.array(q) - p, axis=1)) < reach + gap:
            continue
        if len(rects) + len(circles) and np.min(clearances(p, rects, circles)) < margin + gap:
            continue
        q.append(p)
    return np.array(q)


def kernel_step(q, d_nom, *, rects=RECTS, circles=CIRCLES, sep=SEP, radius=RADIUS,
                decay=0.5, m_p=0.0, m_o=0.0, vmax=VSTEP, turn=0.0):  # fmt: skip
    """One call of the compiled safety_step, with work arrays sized as documented."""
    rows = max(q.shape[0] - 1 + len(rects) + len(circles), 1)
    out = np.empty_like(d_nom)
    safety_step(
        q, d_nom, out, rects, circles, sep, radius, decay, m_p, m_o, vmax,
        np.empty((rows, 2)), np.empty(rows), turn,
    )  # fmt: skip
    return out


def random_qp(rng, m, bounded):
    """Rows with a known feasible point (in the disc when bounded), of random scales; some
    rows tight at that point; a nominal point anywhere. Returns (d0, a, b, vmax)."""
    scale = 10.0 ** rng.uniform(-2, 2)
    vmax = scale if bounded else math.inf
    rho = 0.95 * scale * math.sqrt(rng.random())
    phi = rng.uniform(0, 2 * np.pi)
    x_f = rho * np.array([math.cos(phi), math.sin(phi)])
    a = rng.normal(size=(m, 2)) * 10.0 ** rng.uniform(-1, 1, (m, 1))
    slack = rng.exponential(0.3 * scale, m) * (rng.random(m) < 0.6)
    b = a @ x_f - slack * np.linalg.norm(a, axis=1)
    d0 = rng.normal(size=2) * 2.0 * scale
    return d0, a, b, vmax


def solve(d0, a, b, vmax):
    """solve_qp2 on copies (it scales the rows in place)."""
    a2 = np.array(a, dtype=float).reshape(-1, 2)
    b2 = np.array(b, dtype=float).reshape(-1)
    dx, dy, ok = solve_qp2(float(d0[0]), float(d0[1]), a2, b2, len(b2), vmax)
    return np.array([dx, dy]), ok


# ---------------------------------------------------------------------------------------
# The closed-form QP
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_qp_with_linear_rows_matches_clarabel(seed):
    rng = np.random.default_rng(seed)
    for _ in range(150):
        d0, a, b, vmax = random_qp(rng, int(rng.integers(1, 12)), bounded=False)
        d, ok = solve(d0, a, b, vmax)
        ref, _ = qp_reference(d0, a, b)
        scale = np.linalg.norm(d0) + np.max(np.abs(unit_rows(a, b)[1]))
        assert ok
        assert np.linalg.norm(d - ref) <= 1e-6 * scale


@pytest.mark.parametrize("seed", SEEDS)
def test_qp_with_the_disc_is_sandwiched_by_polygons_and_matches_slsqp(seed):
    """Inscribed 720-gon P_in (a subset of the disc) and circumscribed P_out (a superset):
    f(P_out) <= f* <= f(P_in). The projection property gives, for the inscribed optimum y
    (feasible for the disc problem), |y - d*|^2 <= f(y) - f* <= f(P_in) - f(P_out): a bound
    of order sqrt(2 vmax (1 - cos(pi/720)) |d0 - d*|), up to 4e-3 vmax (2e-3 of the
    problem's size seen), so the tight comparison is with SLSQP on the exact disc (started
    at y), to 1e-6 of the problem's size (SLSQP's own error: below 2e-8 here)."""
    rng = np.random.default_rng(100 + seed)
    for _ in range(60):
        d0, a, b, vmax = random_qp(rng, int(rng.integers(0, 8)), bounded=True)
        d, ok = solve(d0, a, b, vmax)
        y, f_in = qp_reference(d0, a, b, polygon(vmax, inscribed=True))
        _, f_out = qp_reference(d0, a, b, polygon(vmax, inscribed=False))
        f = float(np.sum((d - d0) ** 2))
        size = np.linalg.norm(d0) + vmax
        assert ok
        assert np.linalg.norm(d) <= vmax * (1 + 1e-12)
        assert np.all(a @ d - b >= -1e-9 * size * np.linalg.norm(a, axis=1))
        # Clarabel's objective values are accurate to a few 1e-12 size^2.
        assert f_out - 1e-10 * size**2 <= f <= f_in + 1e-10 * size**2
        assert np.linalg.norm(d - y) <= math.sqrt(f_in - f_out + 1e-10 * size**2)
        if len(b):
            assert np.linalg.norm(d - slsqp(d0, a, b, vmax, y)) <= 1e-6 * size


@settings(max_examples=300)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(0, 10), bounded=st.booleans())
def test_qp_solution_satisfies_kkt(seed, m, bounded):
    """On every feasible problem: feasible, and the KKT conditions hold (a certificate of
    optimality for a convex problem)."""
    d0, a, b, vmax = random_qp(np.random.default_rng(seed), m, bounded)
    d, ok = solve(d0, a, b, vmax)
    assert ok
    assert np.all(np.isfinite(d))
    assert np.linalg.norm(d) <= vmax * (1 + 1e-12)
    if m:
        n, c = unit_rows(a, b)
        size = np.linalg.norm(d0) + np.max(np.abs(c)) + (vmax if bounded else 0.0)
        assert np.all(n @ d - c >= -1e-9 * size)
        assert kkt_residual(d, d0, a, b, vmax) <= 1e-8


@given(seed=st.integers(0, 2**32 - 1), m=st.integers(0, 6))
def test_qp_returns_d0_itself_when_feasible(seed, m):
    d0, a, b, _ = random_qp(np.random.default_rng(seed), m, bounded=False)
    b = np.minimum(b, a @ d0)  # now d0 is feasible
    d, ok = solve(d0, a, b, math.inf)
    assert ok
    assert np.array_equal(d, d0)


def max_shortfall_lp(a, b, poly=None):
    """min over d (in the polygon) of max_k (c_k - n_k d), unit rows, by linprog (-inf if
    unbounded)."""
    n, c = unit_rows(a, b)
    # variables (x, y, s): minimise s subject to -n d - s <= -c (and polygon rows).
    a_ub = np.hstack([-n, -np.ones((len(c), 1))])
    b_ub = -c
    if poly is not None:
        a_ub = np.vstack([a_ub, np.hstack([poly[0], np.zeros((len(poly[1]), 1))])])
        b_ub = np.concatenate([b_ub, poly[1]])
    res = linprog([0, 0, 1], A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * 3, method="highs")
    if res.status == 3:
        return -math.inf  # unbounded: the rows are feasible
    assert res.status == 0
    return res.fun


@pytest.mark.parametrize("seed", SEEDS)
def test_infeasible_qp_falls_back_to_the_least_largest_shortfall(seed):
    """Infeasible rows: flagged, finite, in the disc, and the largest shortfall is the LP's
    minimum (the disc sandwiched by the 720-gons: the shortfall's error is then below
    vmax (1 - cos(pi/720)))."""
    rng = np.random.default_rng(200 + seed)
    checked = 0
    while checked < 40:
        m = int(rng.integers(2, 9))
        scale = 10.0 ** rng.uniform(-1, 1)
        a = rng.normal(size=(m, 2))
        b = rng.uniform(0.2, 2.0, m) * scale * np.linalg.norm(a, axis=1)
        bounded = checked % 2 == 0
        vmax = scale if bounded else math.inf
        if bounded:
            lo = max_shortfall_lp(a, b, polygon(vmax, inscribed=False))
            hi = max_shortfall_lp(a, b, polygon(vmax, inscribed=True))
        else:
            lo = hi = max_shortfall_lp(a, b)
        if lo <= 1e-6 * scale:
            continue  # feasible after all
        d0 = rng.normal(size=2) * scale
        d, ok = solve(d0, a, b, vmax)
        n, c = unit_rows(a, b)
        worst = np.max(c - n @ d)
        assert not ok
        assert np.all(np.isfinite(d))
        assert np.linalg.norm(d) <= vmax * (1 + 1e-12)
        assert lo - 1e-9 * scale <= worst <= hi + 1e-9 * scale
        checked += 1


def test_degenerate_qps_give_finite_answers():
    inf = math.inf
    # Tangent: n . d >= vmax with the disc is the single point vmax n.
    d, ok = solve([0.3, 2.0], [[0.0, 1.0]], [1.0], 1.0)
    assert ok
    np.testing.assert_allclose(d, [0.0, 1.0], atol=1e-12)
    # Zero speed: only d = 0.
    d, ok = solve([1.0, 1.0], [[1.0, 1.0]], [-1.0], 0.0)
    assert ok
    assert np.array_equal(d, [0.0, 0.0])
    # A zero row: harmless with b <= 0, infeasible with b > 0 (and then ignored).
    d, ok = solve([1.0, 2.0], [[0.0, 0.0], [1.0, 0.0]], [0.0, 3.0], inf)
    assert ok
    np.testing.assert_allclose(d, [3.0, 2.0])
    d, ok = solve([1.0, 2.0], [[0.0, 0.0], [1.0, 0.0]], [1.0, 3.0], inf)
    assert not ok
    np.testing.assert_allclose(d, [3.0, 2.0])
    # Opposite half-planes x >= 1 and x <= -1: the fallback is the mid-line, nearest d0.
    d, ok = solve([5.0, 2.0], [[1.0, 0.0], [-1.0, 0.0]], [1.0, 1.0], inf)
    assert not ok
    np.testing.assert_allclose(d, [0.0, 2.0], atol=1e-9)
    # Duplicate and parallel rows, and x >= 1, y >= 1 outside the unit disc.
    d, ok = solve([0.0, 0.0], [[1.0, 0.0], [2.0, 0.0], [0.0, 1.0]], [1.0, 2.0, 1.0], inf)
    assert ok
    np.testing.assert_allclose(d, [1.0, 1.0])
    d, ok = solve([0.0, 0.0], [[1.0, 0.0], [0.0, 1.0]], [1.0, 1.0], 1.0)
    assert not ok
    np.testing.assert_allclose(d, [math.sqrt(0.5)] * 2, atol=1e-9)


def test_qp_scales_its_rows_in_place_without_changing_the_set():
    a = np.array([[3.0, 4.0], [0.0, -2.0]])
    b = np.array([5.0, -4.0])
    dx, dy, ok = solve_qp2(0.0, 0.0, a, b, 2, math.inf)
    assert ok
    np.testing.assert_allclose(a, [[0.6, 0.8], [0.0, -1.0]])
    np.testing.assert_allclose(b, [1.0, -2.0])
    np.testing.assert_allclose([dx, dy], [0.6, 0.8])
    again = solve_qp2(0.0, 0.0, a, b, 2, math.inf)
    np.testing.assert_allclose(again[:2], [dx, dy], rtol=1e-15)
    assert again[2]


# ---------------------------------------------------------------------------------------
# The law: rows against a reference QP, and the barrier guarantees
# ---------------------------------------------------------------------------------------
def reference_rows(i, q, rects, circles, reach, radius, decay, m_o):
    """UAV i's rows (unit normals, every sensed pair and every obstacle: no pruning); the
    state must be safe (every UAV outside every obstacle)."""
    a, b = [], []
    for j in range(q.shape[0]):
        p = q[i] - q[j]
        r = np.linalg.norm(p)
        if j == i or r > radius:
            continue
        # Both UAVs moving apart by t along p: (r + 2t)^2 - D^2 = (1 - decay) h.
        a.append(p / r)
        b.append((math.sqrt(r * r - decay * (r * r - reach * reach)) - r) / 2.0)
    normals = outward_normals(q[i], rects, circles)
    for n, c in zip(normals, clearances(q[i], rects, circles), strict=True):
        a.append(n)
        b.append(-decay * (c - m_o))
    return np.array(a).reshape(-1, 2), np.array(b)


@pytest.mark.parametrize("seed", SEEDS)
def test_each_uav_solves_the_qp_of_its_rows(seed):
    """safe_displacement against the reference rows solved by SLSQP and bounded by the
    polygon sandwich; safe states, so the QP is feasible."""
    rng = np.random.default_rng(300 + seed)
    m_p, m_o, decay = 0.3, 0.2, rng.uniform(0.2, 1.0)
    reach = SEP + m_p
    for _ in range(4):
        q = safe_state(rng, 12, reach, m_o, box=12.0, gap=0.05)
        d_nom = rng.normal(size=q.shape) * VSTEP * 1.5
        rows = q.shape[0] - 1 + len(RECTS) + len(CIRCLES)
        a_w, b_w = np.empty((rows, 2)), np.empty(rows)
        for i in range(q.shape[0]):
            d = np.array(safe_displacement(
                i, q, d_nom, RECTS, CIRCLES, SEP, RADIUS, decay, m_p, m_o, VSTEP, a_w, b_w
            ))  # fmt: skip
            a, b = reference_rows(i, q, RECTS, CIRCLES, reach, RADIUS, decay, m_o)
            y, f_in = qp_reference(d_nom[i], a, b, polygon(VSTEP, inscribed=True))
            _, f_out = qp_reference(d_nom[i], a, b, polygon(VSTEP, inscribed=False))
            f = np.sum((d - d_nom[i]) ** 2)
            size = np.linalg.norm(d_nom[i]) + VSTEP
            assert f_out - 1e-10 * size**2 <= f <= f_in + 1e-10 * size**2
            assert np.linalg.norm(d - slsqp(d_nom[i], a, b, VSTEP, y)) <= 1e-6 * size


def barrier_values(q, reach, m_o):
    """h = r^2 - D^2 of every pair (M, M) and c - m_o of every UAV and obstacle."""
    r = pair_distances(q)
    return r * r - reach * reach, clearances(q, RECTS, CIRCLES) - m_o


@settings(max_examples=60)
@given(
    seed=st.integers(0, 2**32 - 1),
    decay=st.floats(0.05, 1.0),
    m_p=st.floats(0.0, 1.0),
    m_o=st.floats(0.0, 1.0),
    push=st.floats(0.0, 3.0),
)
def test_barriers_decay_at_most_by_one_minus_decay(seed, decay, m_p, m_o, push):
    """From any safe state, for any nominal move: every sensed pair's h and every
    obstacle's c - m_o shrink at most by the factor 1 - decay; unsensed pairs stay apart;
    no UAV exceeds the speed limit; and d = 0 is feasible (returned for d_nom = 0)."""
    rng = np.random.default_rng(seed)
    reach = SEP + m_p
    radius = reach + 2 * VSTEP + rng.uniform(0, 4)
    q = safe_state(rng, 10, reach, m_o, box=10.0)
    toward = q.mean(axis=0) - q
    d_nom = push * VSTEP * (toward / np.linalg.norm(toward, axis=1)[:, None])
    d_nom += rng.normal(size=q.shape) * VSTEP
    d = kernel_step(q, d_nom, radius=radius, decay=decay, m_p=m_p, m_o=m_o)
    h0, c0 = barrier_values(q, reach, m_o)
    h1, c1 = barrier_values(q + d, reach, m_o)
    sensed = pair_distances(q) <= radius
    assert np.all(h1[sensed] >= (1 - decay) * h0[sensed] - 1e-9 * reach**2)
    assert np.all(pair_distances(q + d)[~sensed] >= reach)
    assert np.all(c1 >= (1 - decay) * c0 - 1e-9)
    assert np.all(np.linalg.norm(d, axis=1) <= VSTEP * (1 + 1e-12))
    zero = np.zeros_like(q)
    assert np.array_equal(kernel_step(q, zero, radius=radius, decay=decay, m_p=m_p, m_o=m_o), zero)


@settings(max_examples=60)
@given(seed=st.integers(0, 2**32 - 1), spread=st.floats(0.0, 20.0))
def test_any_state_gives_finite_moves_within_the_speed_limit(seed, spread):
    """Also crowded, overlapping, coincident and inside obstacles (the fallback)."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(9, 2)) * spread
    q[1] = q[0]  # two UAVs at the same point
    d_nom = rng.normal(size=q.shape) * 5 * VSTEP
    d = safety_filter(
        q, d_nom, Obstacles(RECTS, CIRCLES), min_separation=SEP, max_speed=SPEED, dt=DT,
        sensing_radius=RADIUS, sigma=0.05,
    )  # fmt: skip
    assert np.all(np.isfinite(d))
    assert np.all(np.linalg.norm(d, axis=1) <= VSTEP * (1 + 1e-12))


def test_coincident_uavs_are_sent_apart():
    q = np.array([[0.0, 0.0], [0.0, 0.0]])
    d = safety_filter(
        q, np.zeros_like(q), min_separation=SEP, max_speed=SPEED, dt=DT,
        sensing_radius=RADIUS, decay=1.0,
    )  # fmt: skip
    np.testing.assert_allclose(d, [[-VSTEP, 0.0], [VSTEP, 0.0]], atol=1e-9)


def test_safe_nominal_moves_pass_unchanged():
    rng = np.random.default_rng(7)
    q = safe_state(rng, 10, SEP + 3 * VSTEP, 2 * VSTEP, box=25.0)
    d_nom = rng.normal(size=q.shape) * VSTEP / 4
    d_nom *= np.minimum(1.0, VSTEP / np.linalg.norm(d_nom, axis=1))[:, None]
    d = safety_filter(
        q, d_nom, Obstacles(RECTS, CIRCLES), min_separation=SEP, max_speed=SPEED, dt=DT,
        sensing_radius=RADIUS, decay=1.0,
    )  # fmt: skip
    assert np.array_equal(d, d_nom)


# ---------------------------------------------------------------------------------------
# Whole swarms over many steps
# ---------------------------------------------------------------------------------------
def adversarial_moves(rng, q, rects, circles, vmax):
    """Nominal moves that push the swarm together and into obstacles: each UAV, at
    random, heads for the centroid, for another UAV, for the nearest obstacle's centre, or
    anywhere, at up to three times the speed limit."""
    batch, m = q.shape[:-2], q.shape[-2]
    centres = np.concatenate([np.stack([rects[:, :2].mean(1), rects[:, 2:].mean(1)], 1),
                              circles[:, :2]])  # fmt: skip
    other = np.take_along_axis(q, rng.integers(0, m, (*batch, m, 1)).repeat(2, -1), axis=-2)
    dist = np.linalg.norm(q[..., None, :] - centres, axis=-1)
    nearest = centres[np.argmin(dist, axis=-1)]
    goals = np.stack([q.mean(-2, keepdims=True).repeat(m, -2), other, nearest,
                      q + rng.normal(size=q.shape)], axis=-2)  # fmt: skip
    pick = rng.integers(0, 4, (*batch, m))
    goal = np.take_along_axis(goals, pick[..., None, None].repeat(2, -1), axis=-2)[..., 0, :]
    step = goal - q
    length = np.maximum(np.linalg.norm(step, axis=-1, keepdims=True), 1e-12)
    return step / length * vmax * rng.uniform(0, 3, (*batch, m, 1))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(("m_p", "m_o"), [(0.0, 0.0), (0.4, 0.3)])
def test_swarm_without_disturbance_stays_safe(seed, m_p, m_o):
    rng = np.random.default_rng(400 + seed)
    reach = SEP + m_p
    q = safe_state(rng, 10, reach, m_o, box=8.0)
    worst_pair, worst_clear = np.inf, np.inf
    for _ in range(600):
        d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
        q = q + kernel_step(q, d_nom, decay=rng.uniform(0.1, 1.0), m_p=m_p, m_o=m_o)
        worst_pair = min(worst_pair, np.min(pair_distances(q)))
        worst_clear = min(worst_clear, np.min(clearances(q, RECTS, CIRCLES)))
    assert worst_pair >= reach * (1 - 1e-9)
    assert worst_clear >= m_o - 1e-9


def margin_use(q, m_p, m_o):
    """The largest share of the pair and obstacle margins used: (D - r)/m_p, (m_o - c)/m_o
    (1 means the separation or the obstacle was reached)."""
    pair = (SEP + m_p - np.min(pair_distances(q))) / m_p
    obstacle = (m_o - np.min(clearances(q, RECTS, CIRCLES))) / m_o
    return max(pair, obstacle)


def test_swarm_with_disturbance_keeps_its_distance_with_the_margins():
    """20 runs x 2000 steps x 10 UAVs pushed together and into obstacles, disturbed by
    sigma = 0.04 m per axis and step, with the margins of disturbance_margins (6 sigma):
    no pair closer than min_separation, no UAV in an obstacle. Runs batched in one call."""
    sigma, decay, runs = 0.04, 0.5, 20
    m_p, m_o = disturbance_margins(sigma, decay)
    rng = np.random.default_rng(2024)
    q = np.stack([safe_state(rng, 10, SEP + m_p, m_o, box=8.0) for _ in range(runs)])
    obstacles = Obstacles(RECTS, CIRCLES)
    worst = -np.inf
    for _ in range(2000):
        d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
        d = safety_filter(
            q, d_nom, obstacles, min_separation=SEP, max_speed=SPEED, dt=DT,
            sensing_radius=RADIUS, decay=decay, sigma=sigma,
        )  # fmt: skip
        q = q + d + rng.normal(size=q.shape) * sigma
        worst = max(worst, margin_use(q, m_p, m_o))
    assert np.min(pair_distances(q)) > SEP
    assert worst < 1.0, f"largest share of a margin used: {worst:.3f}"


def test_margins_are_the_stationary_spread_of_the_distance_process():
    """The formula against the AR(1) series sum_k (1-decay)^(2k) var(w) and a simulation
    of the process X_{k+1} = (1-decay) X_k + w_k: it spends Phi(-n) of its time beyond n
    standard deviations."""
    sigma = 0.1
    for decay in (0.1, 0.5, 1.0):
        series = math.sqrt(sum((1 - decay) ** (2 * k) for k in range(2000)))
        m_p, m_o = disturbance_margins(sigma, decay, n_sigma=2.0)
        assert m_o == pytest.approx(2.0 * sigma * series, rel=1e-12)
        assert m_p == pytest.approx(2.0 * math.sqrt(2) * sigma * series, rel=1e-12)
        rng = np.random.default_rng(5)
        w = rng.normal(size=(200, 4000)) * sigma * math.sqrt(2)
        x = np.zeros(200)
        below = 0
        for k in range(4000):
            x = (1 - decay) * x + w[:, k]
            below += np.sum(x < -m_p) if k >= 100 else 0
        assert below / (200 * 3900) == pytest.approx(norm.cdf(-2.0), rel=0.1)
    assert disturbance_margins(0.2, 1.0) == pytest.approx((6 * math.sqrt(2) * 0.2, 1.2))
    assert disturbance_margins(0.0, 0.3) == (0.0, 0.0)


# ---------------------------------------------------------------------------------------
# Invariances, distributedness, batches
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_relabelling_the_uavs_relabels_the_moves(seed):
    rng = np.random.default_rng(500 + seed)
    q = safe_state(rng, 12, SEP, 0.0, box=9.0)
    d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
    perm = rng.permutation(12)
    base = kernel_step(q, d_nom)
    np.testing.assert_allclose(kernel_step(q[perm], d_nom[perm]), base[perm], atol=1e-12)


def rotate_rects(rects, quarter_turns):
    """Rectangles turned by a multiple of 90 degrees about the origin."""
    out = rects.copy()
    for _ in range(quarter_turns % 4):  # (x, y) -> (-y, x)
        out = np.stack([-out[:, 3], -out[:, 2], out[:, 0], out[:, 1]], axis=1)
    return out


@pytest.mark.parametrize("seed", SEEDS)
def test_moving_the_frame_moves_the_moves(seed):
    """Rotation (any angle with circles only; quarter turns with rectangles) then
    translation of everything rotates the filtered moves."""
    rng = np.random.default_rng(600 + seed)
    q = safe_state(rng, 10, SEP, 0.0, box=9.0)
    d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
    shift = rng.uniform(-50, 50, 2)
    for angle, rects in [(rng.uniform(0, 2 * np.pi), RECTS[:0]), (None, RECTS)]:
        turns = int(rng.integers(1, 4))
        theta = turns * np.pi / 2 if angle is None else angle
        rot = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
        circles = np.column_stack([CIRCLES[:, :2] @ rot.T + shift, CIRCLES[:, 2]])
        moved_rects = rotate_rects(rects, turns) + np.repeat(shift, 2)
        base = kernel_step(q, d_nom, rects=rects)
        moved = kernel_step(q @ rot.T + shift, d_nom @ rot.T, rects=moved_rects, circles=circles)
        np.testing.assert_allclose(moved, base @ rot.T, atol=1e-9 * VSTEP)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_uav_beyond_the_sensing_radius_changes_nothing(seed):
    rng = np.random.default_rng(700 + seed)
    q = safe_state(rng, 8, SEP, 0.0, box=6.0)
    d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
    base = kernel_step(q, d_nom)
    i = int(rng.integers(0, 8))
    # A stranger just beyond UAV i's sensing radius (possibly near the others).
    phi = rng.uniform(0, 2 * np.pi)
    stranger = q[i] + RADIUS * 1.001 * np.array([math.cos(phi), math.sin(phi)])
    q2 = np.vstack([q, stranger])
    d2 = np.vstack([d_nom, -d_nom[i]])
    assert np.array_equal(kernel_step(q2, d2)[i], base[i])


def test_batches_broadcast_and_match_the_kernel(make_readonly):
    rng = np.random.default_rng(8)
    q = make_readonly(np.stack([safe_state(rng, 6, SEP, 0.0, box=8.0) for _ in range(6)]))
    d_nom = make_readonly(adversarial_moves(rng, np.asarray(q), RECTS, CIRCLES, VSTEP))
    kwargs = dict(min_separation=SEP, max_speed=SPEED, dt=DT, sensing_radius=RADIUS)
    obs = Obstacles(RECTS, CIRCLES)
    out = safety_filter(q.reshape(2, 3, 6, 2), d_nom.reshape(2, 3, 6, 2), obs, **kwargs)
    assert out.shape == (2, 3, 6, 2)
    for k in range(6):
        np.testing.assert_array_equal(out.reshape(6, 6, 2)[k], kernel_step(q[k], d_nom[k]))
    # One formation with several nominal moves.
    out = safety_filter(q[0], d_nom, obs, **kwargs)
    for k in range(6):
        np.testing.assert_array_equal(out[k], kernel_step(q[0], d_nom[k]))


def test_the_kernel_may_write_over_the_nominal_moves():
    rng = np.random.default_rng(9)
    q = safe_state(rng, 10, SEP, 0.0, box=8.0)
    d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
    expected = kernel_step(q, d_nom)
    rows = 9 + len(RECTS) + len(CIRCLES)
    args = (RECTS, CIRCLES, SEP, RADIUS, 0.5, 0.0, 0.0, VSTEP)
    safety_step(q, d_nom, d_nom, *args, np.empty((rows, 2)), np.empty(rows))
    np.testing.assert_array_equal(d_nom, expected)


def test_docstring_examples_run():
    assert doctest.testmod(safety, optionflags=doctest.NORMALIZE_WHITESPACE).failed == 0


# ---------------------------------------------------------------------------------------
# Bad arguments
# ---------------------------------------------------------------------------------------
GOOD = dict(min_separation=SEP, max_speed=SPEED, dt=DT, sensing_radius=RADIUS)
Q2 = [[0.0, 0.0], [5.0, 0.0]]


@pytest.mark.parametrize(
    ("args", "changes", "field"),
    [
        ((Q2, Q2), {"min_separation": -1.0}, "min_separation"),
        ((Q2, Q2), {"min_separation": 0.0}, "min_separation"),
        ((Q2, Q2), {"decay": 0.0}, "decay"),
        ((Q2, Q2), {"decay": 1.5}, "decay"),
        ((Q2, Q2), {"decay": float("nan")}, "decay"),
        ((Q2, Q2), {"sensing_radius": SEP + 2 * VSTEP - 0.01}, "sensing_radius"),
        ((Q2, Q2), {"sensing_radius": 2.5, "sigma": 0.1}, "sensing_radius"),  # margin
        ((Q2, Q2), {"sensing_radius": -1.0}, "sensing_radius"),
        ((Q2, Q2), {"sensing_radius": float("nan")}, "sensing_radius"),
        ((Q2, Q2), {"max_speed": 0.0}, "max_speed"),
        ((Q2, Q2), {"dt": -0.1}, "dt"),
        ((Q2, Q2), {"sigma": -0.1}, "sigma"),
        (([[0.0, float("nan")], [5.0, 0.0]], Q2), {}, "positions"),
        ((Q2, [[0.0, 0.0]]), {}, "displacements"),
        (([Q2, Q2], [Q2, Q2, Q2]), {}, "displacements"),
        ((Q2, [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]), {}, "displacements"),
        ((Q2, Q2, "walls"), {}, "obstacles"),
        (([0.0, 0.0], Q2), {}, "positions"),
    ],
)
def test_bad_arguments_raise_one_field_error(args, changes, field):
    kwargs = {**GOOD, **changes}
    with pytest.raises(FieldError) as info:
        safety_filter(*args, **kwargs)
    assert info.value.field == field
    assert "\n" not in str(info.value)


def test_bad_margin_arguments_raise_one_field_error():
    for kwargs, field in [
        ({"sigma": -1.0, "decay": 0.5}, "sigma"),
        ({"sigma": 0.1, "decay": 0.0}, "decay"),
        ({"sigma": 0.1, "decay": 0.5, "n_sigma": -1.0}, "n_sigma"),
        ({"sigma": [0.1, 0.2], "decay": 0.5}, "sigma"),
    ]:
        with pytest.raises(FieldError) as info:
            disturbance_margins(**kwargs)
        assert info.value.field == field


def test_an_infinite_sensing_radius_senses_everyone():
    q = np.array([[0.0, 0.0], [2.6, 0.0]])
    d = safety_filter(q, [[1.0, 0.0], [-1.0, 0.0]], **{**GOOD, "sensing_radius": math.inf})
    assert d[0, 0] < VSTEP


# -- the way out of deadlocks (the mission kernel's turn) ----------------------------------------
def head_on(turn, steps=400):
    """Two UAVs that each want to reach the other's start, without disturbance: the pair's
    smallest distance and whether they swapped sides."""
    q = np.array([[0.0, 0.0], [6.0, 0.0]])
    goals = q[::-1].copy()
    none4, none3 = np.empty((0, 4)), np.empty((0, 3))
    closest = np.inf
    for _ in range(steps):
        d_nom = np.clip(goals - q, -VSTEP, VSTEP)
        q = q + kernel_step(q, d_nom, rects=none4, circles=none3, turn=turn)
        closest = min(closest, float(np.hypot(*(q[0] - q[1]))))
    return closest, bool(q[0, 0] > q[1, 0])


def test_head_on_uavs_wait_for_ever_without_the_turn_and_pass_with_it():
    """The plain QP stops a symmetric head-on pair for good (the nominal moves point straight
    into each other's barrier); turning a blocked UAV's nominal to its right lets both
    sidestep, pass and swap, still never closer than the separation."""
    closest, swapped = head_on(0.0)
    assert not swapped
    assert closest >= SEP * (1 - 1e-12)
    closest, swapped = head_on(safety.UNBLOCK_TURN)
    assert swapped
    assert closest >= SEP * (1 - 1e-12)


def test_the_turn_changes_only_blocked_uavs_and_stays_safe():
    """A UAV that is not blocked (its safe move advances along its nominal one by at least a
    quarter of what it could: the nominal's length, capped at the speed limit) moves exactly
    as with the plain QP; a blocked one takes the QP's solution for the turned nominal if
    that is the longer move, which satisfies the same rows."""
    c, s = math.cos(safety.UNBLOCK_TURN), math.sin(safety.UNBLOCK_TURN)
    counts = np.zeros(3, dtype=int)
    for seed in range(20):
        rng = np.random.default_rng(900 + seed)
        q = safe_state(rng, 10, SEP, 0.0, box=8.0)
        d_nom = adversarial_moves(rng, q, RECTS, CIRCLES, VSTEP)
        plain = kernel_step(q, d_nom)
        turned = kernel_step(q, d_nom, turn=safety.UNBLOCK_TURN)
        length = np.hypot(*d_nom.T)
        could = np.minimum(length, VSTEP)
        slow = np.sum(plain * d_nom, axis=1) < safety.BLOCKED_FRACTION * could * length
        blocked = slow & (length >= safety.BLOCKED_MOVING * VSTEP)
        assert np.array_equal(turned[~blocked], plain[~blocked])
        rotated = np.column_stack(
            [c * d_nom[:, 0] + s * d_nom[:, 1], c * d_nom[:, 1] - s * d_nom[:, 0]]
        )
        again = kernel_step(q, rotated)
        longer = np.hypot(*again.T) > np.hypot(*plain.T)
        expect = np.where((blocked & longer)[:, None], again, plain)
        assert np.allclose(turned, expect, rtol=0, atol=1e-12)
        counts += [(~blocked).sum(), (blocked & longer).sum(), (blocked & ~longer).sum()]
    assert counts[0] > 0  # unblocked UAVs occurred
    assert counts[1] > 0  # and UAVs the turn frees
