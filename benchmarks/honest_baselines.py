"""Two honest baselines of the paper mission, written from the paper and docs/control.md.

Neither calls crlbswarm's kernels: only numbers are read from the scenario (gains, slots,
obstacles, graph, radar constant). Both fly the laws of the built-in ``paper`` scenario:

* leader guidance (docs/control.md): ``v* = sat_vc(k_g (g - q_1) + u^r(c; rho) / dT)``,
  ``g`` the leader's slot over the target scaled by eta, ``u^r(c; rho)`` the repulsion of
  eq. (18) felt by the formation's disc of radius ``rho = eta r* beta(|c - s|)`` at its
  centroid ``c`` (``beta`` the smoothstep from r*/4 to r*);
* formation input, eq. (19): ``u_m = -eps sum_p a_mp (q_m - q_p - eta (delta_m - delta_p))``;
* repulsion, eq. (18): ``E_r (1/l - 1/l_safe) / l^2`` along the unit vector from each
  obstacle's nearest point within ``l_safe``, the sum capped at ``repulsion_max_step``;
* motion model, eq. (3): ``q_{k+1} = q_k + u_k + u^r_k + v_k dT + n_k``;
* corrected consensus, eq. (14): ``v_{m,k+1} = v_m - gamma sum_p a_mp (v_m - v_p)`` with
  the leader's velocity held at ``v*``;
* the eta rule (docs/control.md): 32 points from r* behind the centroid to the look-ahead
  toward the target; at each, the best clearance across the path within +-r* (9 points),
  the smallest of these is the free half-width ``w``; ``goal = clip((w - margin) / r*,
  eta_min, 1)``, blended to 1 near the target, and eta steps toward it by at most
  ``rate dT``. Like crlbswarm (docs/performance.md), the whole sampled segment, from r*
  behind the centroid to the look-ahead, is first tested against every obstacle (exact
  segment-to-rectangle and segment-to-disc distances): if it keeps ``r* + margin`` plus a
  pad of 1e-6 m, every sample would be skipped below and the rule returns at once; else a
  sample whose own clearance is at least ``r* + margin`` is not looked across, and the
  scan stops once ``w`` forces ``eta_min``: none of these changes the result;
* metrics per step: the CRLB, eq. (10), at the UAVs' positions; the smallest obstacle
  clearance; eta; the cost, eq. (15).

Random inputs follow the documented stream layout of ``crlbswarm.simulate`` (the start from
``SeedSequence(seed).spawn(4)[0]``, the disturbance from the counter-based generator of
``crlbswarm.counter_rng``, drawn up front here as an array), so the same seed gives the
same start and disturbance and the trajectories can be compared to crlbswarm's directly.

(a) :func:`plain_mission`: one run, loops over UAVs, neighbours, obstacles and samples,
``math`` only. (b) :func:`numpy_missions`: every run of a batch together, arrays
``(B, M, 2)``, one step for all runs at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crlbswarm.counter_rng import DISTURBANCE, standard_normals

LATERAL = 9  # points across the path in the eta rule
PATH_PAD = 1e-6  # m, by which the eta rule's segment must clear for its samples to be skipped
CLEAR_TOL = 1e-9  # m, the rounding tolerance of the segment test
HOVER_INNER, HOVER_OUTER = 0.25, 1.0  # the eta rule's and the steering's blend, in r*


@dataclass(frozen=True)
class Mission:
    """The numbers of a scenario the baselines need (read, never computed by crlbswarm)."""

    m: int
    steps: int
    dt: float
    leader: int
    target: tuple[float, float]
    altitude: float
    snr: float
    delta: np.ndarray  # (M, 2) slot offsets from the target
    neighbours: tuple[tuple[int, ...], ...]
    rects: tuple[tuple[float, float, float, float], ...]
    circles: tuple[tuple[float, float, float], ...]
    radius: float
    eps: float
    gamma: float
    k_g: float
    cruise: float
    l_safe: float
    e_r: float
    cap: float
    steering: bool
    eta_on: bool
    eta_min: float
    eta_rate: float
    lookahead: float
    margin: float
    samples: int
    sigma: float
    region: tuple[tuple[float, float], tuple[float, float]]

    @classmethod
    def from_scenario(cls, sc) -> Mission:
        adj = sc.adjacency
        nbrs = tuple(
            tuple(int(p) for p in adj.indices[adj.indptr[m] : adj.indptr[m + 1]])
            for m in range(sc.uavs.count)
        )
        target = np.asarray(sc.target, dtype=float)
        rule = sc.eta_rule
        g = sc.gains
        return cls(
            m=sc.uavs.count,
            steps=sc.time.steps,
            dt=sc.time.step,
            leader=sc.uavs.leader,
            target=(float(target[0]), float(target[1])),
            altitude=float(sc.altitude),
            snr=float(np.mean(sc.radar_model.snr_constant)),
            delta=np.asarray(sc.slots, dtype=float) - target,
            neighbours=nbrs,
            rects=tuple(tuple(map(float, r)) for r in sc.obstacle_set.rectangles),
            circles=tuple(tuple(map(float, c)) for c in sc.obstacle_set.circles),
            radius=float(sc.formation_radius),
            eps=float(g.epsilon),
            gamma=float(g.gamma),
            k_g=float(g.guidance_gain),
            cruise=float(g.cruise_speed),
            l_safe=float(g.safety_radius),
            e_r=float(g.repulsion_gain),
            cap=float(g.repulsion_max_step),
            steering=bool(g.formation_steering),
            eta_on=bool(rule.enabled),
            eta_min=float(rule.minimum),
            eta_rate=float(rule.rate),
            lookahead=float(rule.lookahead),
            margin=float(rule.margin_for(g)),
            samples=int(rule.samples),
            sigma=float(sc.disturbance.sigma),
            region=tuple(tuple(map(float, r)) for r in sc.uavs.start_region),
        )


def draw(mission: Mission, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Start (M, 2) and disturbance (K, M, 2) of the run with ``seed``: the draws of
    crlbswarm (the start from the first NumPy stream of the seed, the disturbance from the
    counter-based generator, :func:`crlbswarm.counter_rng.standard_normals`)."""
    start_ss = np.random.SeedSequence(seed).spawn(4)[0]
    (x0, x1), (y0, y1) = mission.region
    start = np.random.default_rng(start_ss).uniform((x0, y0), (x1, y1), size=(mission.m, 2))
    noise = standard_normals(seed, DISTURBANCE, mission.steps, mission.m)
    noise *= mission.sigma
    return start, noise


# ---------------------------------------------------------------------------------------
# (a) plain Python
# ---------------------------------------------------------------------------------------
def _smoothstep(t: float) -> float:
    if t >= 1.0:
        return 1.0
    return 0.0 if t <= 0.0 else t * t * (3.0 - 2.0 * t)


def _obstacle(x, y, ob, is_rect):
    """Signed distance from (x, y) to one obstacle and the outward unit vector."""
    if is_rect:
        xmin, xmax, ymin, ymax = ob
        dx = x - min(max(x, xmin), xmax)
        dy = y - min(max(y, ymin), ymax)
        d = math.sqrt(dx * dx + dy * dy)
        if d > 0.0:
            return d, dx / d, dy / d
        faces = ((x - xmin, -1.0, 0.0), (xmax - x, 1.0, 0.0), (y - ymin, 0.0, -1.0),
                 (ymax - y, 0.0, 1.0))  # fmt: skip
        best = min(faces, key=lambda f: f[0])
        return -best[0], best[1], best[2]
    cx, cy, r = ob
    dx, dy = x - cx, y - cy
    rho = math.sqrt(dx * dx + dy * dy)
    if rho > 0.0:
        return rho - r, dx / rho, dy / rho
    return -r, 1.0, 0.0


class _Counter:
    evaluations = 0
    eta_evaluations = 0
    samples = 0
    repulsion_terms = 0
    segment_tests = 0


def _clearance(x, y, mi: Mission, count: _Counter | None = None) -> float:
    best = math.inf
    for ob in mi.rects:
        best = min(best, _obstacle(x, y, ob, True)[0])
    for ob in mi.circles:
        best = min(best, _obstacle(x, y, ob, False)[0])
    if count is not None:
        count.evaluations += len(mi.rects) + len(mi.circles)
    return best


def _repulsion(x, y, mi: Mission, l_safe, cap, inflate=0.0, count=None):
    fx = fy = 0.0
    for obs, is_rect in ((mi.rects, True), (mi.circles, False)):
        for ob in obs:
            d, ux, uy = _obstacle(x, y, ob, is_rect)
            d -= inflate
            if d < l_safe:
                ell = max(d, 1e-9)
                mag = mi.e_r * (1.0 / ell - 1.0 / l_safe) / (ell * ell)
                fx += mag * ux
                fy += mag * uy
                if count is not None:
                    count.repulsion_terms += 1
    if count is not None:
        count.evaluations += len(mi.rects) + len(mi.circles)
    norm = math.sqrt(fx * fx + fy * fy)
    if norm > cap:
        fx, fy = fx * cap / norm, fy * cap / norm
    return fx, fy


def _segment_d2(px, py, ax, ay, dx, dy, den):
    """Squared distance from (px, py) to the segment from (ax, ay) to (ax + dx, ay + dy),
    ``den = dx^2 + dy^2``."""
    t = 0.0
    if den > 0.0:
        t = min(max(((px - ax) * dx + (py - ay) * dy) / den, 0.0), 1.0)
    ex = ax + t * dx - px
    ey = ay + t * dy - py
    return ex * ex + ey * ey


def _meets_box(ax, ay, dx, dy, xmin, xmax, ymin, ymax) -> bool:
    """Whether the segment from (ax, ay) to (ax + dx, ay + dy) meets the closed box
    (Liang-Barsky: the parameters t0 <= t1 of its part in the box)."""
    t0, t1 = 0.0, 1.0
    for p, q in ((-dx, ax - xmin), (dx, xmax - ax), (-dy, ay - ymin), (dy, ymax - ay)):
        if p == 0.0:
            if q < 0.0:
                return False  # parallel to this side and outside it
        elif p < 0.0:
            t0 = max(t0, q / p)
        else:
            t1 = min(t1, q / p)
        if t0 > t1:
            return False
    return True


def _segment_clear(ax, ay, bx, by, mi: Mission, keep, count=None) -> bool:
    """Whether every point of the segment from (ax, ay) to (bx, by) keeps at least ``keep -
    CLEAR_TOL`` from every obstacle (``keep > 0``), from the exact distances.

    A rectangle: the segment must not meet it (the clip) and, the two being disjoint convex
    polygons, their distance is the smallest of the endpoints' distances to the box and the
    corners' distances to the segment. A disc: its centre's distance to the segment, less
    the radius. Stops at the first obstacle too close; counts the obstacles tested.
    """
    keep -= CLEAR_TOL
    if keep <= 0.0:
        return False  # (not met by the rule: r* + margin > 0) let the samples decide
    k2 = keep * keep
    dx, dy = bx - ax, by - ay
    den = dx * dx + dy * dy
    for xmin, xmax, ymin, ymax in mi.rects:
        if count is not None:
            count.segment_tests += 1
        for px, py in ((ax, ay), (bx, by)):
            ex = px - min(max(px, xmin), xmax)
            ey = py - min(max(py, ymin), ymax)
            if ex * ex + ey * ey < k2:
                return False
        if _meets_box(ax, ay, dx, dy, xmin, xmax, ymin, ymax):
            return False
        for px, py in ((xmin, ymin), (xmin, ymax), (xmax, ymin), (xmax, ymax)):
            if _segment_d2(px, py, ax, ay, dx, dy, den) < k2:
                return False
    for px, py, rad in mi.circles:
        if count is not None:
            count.segment_tests += 1
        need = rad + keep
        if _segment_d2(px, py, ax, ay, dx, dy, den) < need * need:
            return False
    return True


def _eta_goal(cx, cy, mi: Mission, count=None) -> float:
    sx, sy = mi.target
    r = mi.radius
    hx, hy = sx - cx, sy - cy
    dist = math.sqrt(hx * hx + hy * hy)
    if dist > 0.0:
        hx, hy = hx / dist, hy / dist
    else:
        hx, hy = 1.0, 0.0
    ahead = min(mi.lookahead, dist)
    width = math.inf
    enough = r + mi.margin
    if not _segment_clear(cx - r * hx, cy - r * hy, cx + ahead * hx, cy + ahead * hy, mi,
                          enough + PATH_PAD, count):  # fmt: skip
        width = _path_width(cx, cy, hx, hy, ahead, mi, count)
    goal = min(1.0, max(mi.eta_min, (width - mi.margin) / r))
    w = _smoothstep((dist - HOVER_INNER * r) / ((HOVER_OUTER - HOVER_INNER) * r))
    return goal + (1.0 - goal) * (1.0 - w)


def _path_width(cx, cy, hx, hy, ahead, mi: Mission, count=None) -> float:
    """The eta rule's free half-width from its samples along (hx, hy) (the segment test
    failed: some sample may be closer than ``r* + margin``)."""
    r = mi.radius
    width = math.inf
    for i in range(mi.samples):
        t = -r + (ahead + r) * i / (mi.samples - 1)
        px, py = cx + t * hx, cy + t * hy
        if count is not None:
            count.samples += 1
        if _clearance(px, py, mi, count) >= r + mi.margin:
            continue  # looking across cannot lower the width below r + margin
        best = -math.inf
        for j in range(LATERAL):
            o = r * (2.0 * j / (LATERAL - 1) - 1.0)
            if count is not None:
                count.samples += 1
            best = max(best, _clearance(px - o * hy, py + o * hx, mi, count))
        width = min(width, best)
        if width <= mi.margin + mi.eta_min * r:
            break  # eta_min whatever follows
    return width


def _crlb(q, mi: Mission) -> float:
    sx, sy = mi.target
    h2 = mi.altitude * mi.altitude
    jxx = jxy = jyy = 0.0
    for x, y in q:
        dx, dy = sx - x, sy - y
        d2 = dx * dx + dy * dy + h2
        g = (mi.snr / (d2 * d2) + 8.0 / d2) / d2
        jxx += g * dx * dx
        jxy += g * dx * dy
        jyy += g * dy * dy
    det = jxx * jyy - jxy * jxy
    return (jxx + jyy) / det if det > 0.0 else math.inf


def plain_mission(mi: Mission, start, noise, count: _Counter | None = None) -> dict:
    """One run in plain Python: lists of tuples, loops, ``math``. ``start`` (M, 2) and
    ``noise`` (K, M, 2) as nested lists or arrays. Returns the final positions, the CRLB,
    eta, clearance and cost per step."""
    m_uavs, dt, leader = mi.m, mi.dt, mi.leader
    sx, sy = mi.target
    delta = [tuple(map(float, d)) for d in mi.delta]
    noise = noise.tolist() if hasattr(noise, "tolist") else noise
    q = [tuple(map(float, p)) for p in start]
    v = [(0.0, 0.0)] * m_uavs
    eta = 1.0
    crlb, etas, clear, cost = [], [], [], []
    for k in range(mi.steps + 1):
        cx = sum(p[0] for p in q) / m_uavs
        cy = sum(p[1] for p in q) / m_uavs
        # leader guidance (v*), with the formation's disc steered off obstacles
        ql = q[leader]
        wx = mi.k_g * (sx + eta * delta[leader][0] - ql[0])
        wy = mi.k_g * (sy + eta * delta[leader][1] - ql[1])
        dist = math.sqrt((cx - sx) ** 2 + (cy - sy) ** 2)
        rho = 0.0
        if mi.steering:
            t = (dist - HOVER_INNER * mi.radius) / ((HOVER_OUTER - HOVER_INNER) * mi.radius)
            rho = eta * mi.radius * _smoothstep(t)
        if rho > 0.0:
            rx, ry = _repulsion(cx, cy, mi, mi.l_safe, math.inf, rho, count)
            wx += rx / dt
            wy += ry / dt
        norm = math.sqrt(wx * wx + wy * wy)
        if norm > mi.cruise:
            wx, wy = wx * mi.cruise / norm, wy * mi.cruise / norm
        vref = (wx, wy)
        v[leader] = vref
        crlb.append(_crlb(q, mi))
        etas.append(eta)
        clear.append(min(_clearance(x, y, mi, count) for x, y in q))
        if k == mi.steps:
            break
        nk = noise[k]
        q_new, v_new = [None] * m_uavs, [None] * m_uavs
        total = 0.0
        for m in range(m_uavs):
            qm, dm, vm = q[m], delta[m], v[m]
            ux = uy = svx = svy = 0.0
            for p in mi.neighbours[m]:
                ex = qm[0] - q[p][0] - (dm[0] - delta[p][0])
                ey = qm[1] - q[p][1] - (dm[1] - delta[p][1])
                total += ex * ex + ey * ey
                ux += qm[0] - q[p][0] - eta * (dm[0] - delta[p][0])
                uy += qm[1] - q[p][1] - eta * (dm[1] - delta[p][1])
                svx += vm[0] - v[p][0]
                svy += vm[1] - v[p][1]
            rx, ry = _repulsion(qm[0], qm[1], mi, mi.l_safe, mi.cap, 0.0, count)
            nx = qm[0] - mi.eps * ux + rx + vm[0] * dt + nk[m][0]
            ny = qm[1] - mi.eps * uy + ry + vm[1] * dt + nk[m][1]
            q_new[m] = (nx, ny)
            wx, wy = (nx - qm[0]) / dt - vref[0], (ny - qm[1]) / dt - vref[1]
            total += wx * wx + wy * wy
            v_new[m] = vref if m == leader else (vm[0] - mi.gamma * svx, vm[1] - mi.gamma * svy)
        cost.append(total)
        if mi.eta_on:
            before = count.evaluations if count is not None else 0
            goal = _eta_goal(cx, cy, mi, count)
            if count is not None:
                count.eta_evaluations += count.evaluations - before
            step = mi.eta_rate * dt
            eta += min(step, max(-step, goal - eta))
        q, v = q_new, v_new
    return {"final": np.array(q), "crlb": np.array(crlb), "eta": np.array(etas),
            "clearance": np.array(clear), "cost": np.array(cost)}  # fmt: skip


def plain_missions(mi: Mission, seeds) -> list[dict]:
    """Plain runs, one after another, each with its own draws (timed with them)."""
    return [plain_mission(mi, *draw(mi, int(s))) for s in seeds]


def count_paper_work(mi: Mission, seed: int = 0) -> dict[str, float]:
    """The work of one step of the paper mission, counted on the instrumented plain
    baseline (the same algorithm as crlbswarm's kernel, docs/performance.md).

    Parameters
    ----------
    mi : Mission
        The mission.
    seed : int, optional
        The run counted (its draws, as :func:`draw`).

    Returns
    -------
    dict of str to float
        Per step, averaged over the run: ``evaluations``, the point-to-obstacle distance
        evaluations (all purposes); ``eta_evaluations``, those of the eta rule's samples
        (only in the steps where its segment test fails); ``samples``, the eta rule's
        sample points; ``repulsion_terms``, the obstacles within ``l_safe`` of a UAV or of
        the formation's disc; ``segment_tests``, the eta rule's segment-to-obstacle tests
        (one per obstacle and step, fewer where the test stops at an obstacle too close).
    """
    count = _Counter()
    plain_mission(mi, *draw(mi, seed), count=count)
    n = mi.steps
    return {
        "evaluations": count.evaluations / n,
        "eta_evaluations": count.eta_evaluations / n,
        "samples": count.samples / n,
        "repulsion_terms": count.repulsion_terms / n,
        "segment_tests": count.segment_tests / n,
    }


# ---------------------------------------------------------------------------------------
# (b) NumPy, vectorised over runs and UAVs
# ---------------------------------------------------------------------------------------
class _Arrays:
    def __init__(self, mi: Mission) -> None:
        self.rects = np.array(mi.rects, dtype=float).reshape(-1, 4)
        self.circles = np.array(mi.circles, dtype=float).reshape(-1, 3)
        xmin, xmax, ymin, ymax = self.rects.T
        # the rectangles' corners (4R,), for the segment test
        self.corner_x = np.concatenate((xmin, xmin, xmax, xmax))
        self.corner_y = np.concatenate((ymin, ymax, ymin, ymax))
        lap = np.zeros((mi.m, mi.m))
        for m, nb in enumerate(mi.neighbours):
            for p in nb:
                lap[m, p] -= 1.0
                lap[m, m] += 1.0
        self.lap = lap
        self.follower = np.ones((mi.m, 1))
        self.follower[mi.leader] = 0.0


def _rect_np(x, y, xmin, xmax, ymin, ymax, unit: bool):
    """Signed distance from points x, y (any shape) to one rectangle, and with ``unit`` the
    outward unit vector (inside: through the nearest face, negative distance). In place
    where possible: the temporaries dominate at these sizes."""
    dx = np.maximum(x, xmin)
    np.minimum(dx, xmax, out=dx)
    np.subtract(x, dx, out=dx)
    dy = np.maximum(y, ymin)
    np.minimum(dy, ymax, out=dy)
    np.subtract(y, dy, out=dy)
    d = dx * dx
    d += dy * dy
    np.sqrt(d, out=d)
    any_inside = not d.all()
    if any_inside:
        inside = d == 0.0
        left, right, down, up = x - xmin, xmax - x, y - ymin, ymax - y
        face = np.minimum(np.minimum(left, right), np.minimum(down, up))
        d = np.where(inside, -face, d)
    if not unit:
        return d, None, None
    safe = np.where(inside, 1.0, d) if any_inside else d
    ux, uy = dx / safe, dy / safe
    if any_inside:  # the first of left, right, down, up that attains the minimum
        fx = np.where(left == face, -1.0, np.where(right == face, 1.0, 0.0))
        fy = np.where((left == face) | (right == face), 0.0, np.where(down == face, -1.0, 1.0))
        ux = np.where(inside, fx, ux)
        uy = np.where(inside, fy, uy)
    return d, ux, uy


def _circle_np(x, y, cx, cy, r, unit: bool):
    dx, dy = x - cx, y - cy
    rho = np.sqrt(dx * dx + dy * dy)
    pos = rho > 0.0
    d = np.where(pos, rho - r, -r)
    if not unit:
        return d, None, None
    safe = np.where(pos, rho, 1.0)
    return d, np.where(pos, dx / safe, 1.0), np.where(pos, dy / safe, 0.0)


def _each_obstacle(x, y, arr: _Arrays, unit: bool):
    for xmin, xmax, ymin, ymax in arr.rects:
        yield _rect_np(x, y, xmin, xmax, ymin, ymax, unit)
    for cx, cy, r in arr.circles:
        yield _circle_np(x, y, cx, cy, r, unit)


def _clearance_np(x, y, arr: _Arrays):
    """Signed distance from points x, y to the nearest obstacle (one pass per obstacle)."""
    best = np.full(np.shape(x), np.inf)
    for d, _, _ in _each_obstacle(x, y, arr, False):
        np.minimum(best, d, out=best)
    return best


def _repulsion_np(x, y, arr, e_r, l_safe, cap, inflate=0.0):
    fx = np.zeros(np.shape(x))
    fy = np.zeros(np.shape(x))
    for d, ux, uy in _each_obstacle(x, y, arr, True):
        d = d - inflate
        near = d < l_safe
        if near.any():
            ell = np.maximum(d, 1e-9)
            mag = np.where(near, e_r * (1.0 / ell - 1.0 / l_safe) / (ell * ell), 0.0)
            fx += mag * ux
            fy += mag * uy
    if cap != math.inf:
        norm = np.sqrt(fx * fx + fy * fy)
        scale = np.where(norm > cap, cap / np.where(norm > 0, norm, 1.0), 1.0)
        fx, fy = fx * scale, fy * scale
    return fx, fy


def _smoothstep_np(t):
    return np.where(t >= 1.0, 1.0, np.where(t <= 0.0, 0.0, t * t * (3.0 - 2.0 * t)))


def _segment_d2_np(px, py, ax, ay, dx, dy, den):
    """Squared distances from the points (px, py) to the segments from (ax, ay) to (ax + dx,
    ay + dy), ``den = dx^2 + dy^2`` (broadcast)."""
    pos = den > 0.0
    t = ((px - ax) * dx + (py - ay) * dy) / np.where(pos, den, 1.0)
    t = np.where(pos, np.minimum(np.maximum(t, 0.0), 1.0), 0.0)
    ex = ax + t * dx - px
    ey = ay + t * dy - py
    return ex * ex + ey * ey


def _segment_clear_np(ax, ay, bx, by, arr: _Arrays, keep):
    """Whether each segment from (ax, ay) to (bx, by) (arrays (B,)) keeps at least ``keep -
    CLEAR_TOL`` from every obstacle (``keep > 0``): the test of :func:`_segment_clear` on all
    segments and all obstacles at once, arrays (B, R) and (B, C)."""
    clear = np.ones(np.shape(ax), dtype=bool)
    keep -= CLEAR_TOL
    if keep <= 0.0:
        return ~clear
    k2 = keep * keep
    dx, dy = bx - ax, by - ay
    den = dx * dx + dy * dy
    ax1, ay1, dx1, dy1, den1 = ax[:, None], ay[:, None], dx[:, None], dy[:, None], den[:, None]
    if arr.rects.shape[0]:
        xmin, xmax, ymin, ymax = arr.rects.T  # (R,)
        # the endpoints' distances to the boxes, (2, B, R)
        ex = np.stack((ax, bx))[..., None]
        ey = np.stack((ay, by))[..., None]
        ox = ex - np.minimum(np.maximum(ex, xmin), xmax)
        oy = ey - np.minimum(np.maximum(ey, ymin), ymax)
        near = (ox * ox + oy * oy < k2).any(axis=(0, 2))
        # Liang-Barsky on the four sides at once, (4, B, R): t0 only grows and t1 only
        # shrinks, so t0 <= t1 at the end is the sequential test
        side_p = np.stack((-dx1, dx1, -dy1, dy1))
        side_q = np.stack((ax1 - xmin, xmax - ax1, ay1 - ymin, ymax - ay1))
        zero = side_p == 0.0
        ratio = side_q / np.where(zero, 1.0, side_p)
        t0 = np.where(side_p < 0.0, ratio, 0.0).max(axis=0)
        t1 = np.where(side_p > 0.0, ratio, 1.0).min(axis=0)
        meets = (t0 <= t1) & ~(zero & (side_q < 0.0)).any(axis=0)  # (parallel and outside)
        near |= meets.any(axis=-1)
        # the corners' distances to the segments, (B, 4R)
        d2 = _segment_d2_np(arr.corner_x, arr.corner_y, ax1, ay1, dx1, dy1, den1)
        near |= (d2 < k2).any(axis=-1)
        clear &= ~near
    if arr.circles.shape[0]:
        px, py, rad = arr.circles.T  # (C,)
        need = rad + keep
        d2 = _segment_d2_np(px, py, ax1, ay1, dx1, dy1, den1)  # (B, C)
        clear &= (d2 >= need * need).all(axis=-1)
    return clear


def _eta_goal_np(cx, cy, mi: Mission, arr: _Arrays):
    """The eta rule for every run: the segment test of all runs at once; for the runs whose
    segment does not clear, the centre clearances of all samples at once, then the lateral
    scan only for the samples that need it (compacted)."""
    sx, sy = mi.target
    r = mi.radius
    hx, hy = sx - cx, sy - cy
    dist = np.sqrt(hx * hx + hy * hy)
    pos = dist > 0.0
    safe = np.where(pos, dist, 1.0)
    hx = np.where(pos, hx / safe, 1.0)
    hy = np.where(pos, hy / safe, 0.0)
    ahead = np.minimum(mi.lookahead, dist)
    enough = r + mi.margin
    clear = _segment_clear_np(
        cx - r * hx, cy - r * hy, cx + ahead * hx, cy + ahead * hy, arr, enough + PATH_PAD
    )
    w = np.full(cx.shape, np.inf)
    (rest,) = np.nonzero(~clear)
    if rest.size:
        w[rest] = _path_width_np(cx[rest], cy[rest], hx[rest], hy[rest], ahead[rest], mi, arr)
    goal = np.minimum(1.0, np.maximum(mi.eta_min, (w - mi.margin) / r))
    beta = _smoothstep_np((dist - HOVER_INNER * r) / ((HOVER_OUTER - HOVER_INNER) * r))
    return goal + (1.0 - goal) * (1.0 - beta)


def _path_width_np(cx, cy, hx, hy, ahead, mi: Mission, arr: _Arrays):
    """The eta rule's free half-width of each run from its samples (runs whose segment
    test failed)."""
    r = mi.radius
    frac = np.arange(mi.samples) / (mi.samples - 1)
    t = -r + (ahead + r)[:, None] * frac  # (B, S)
    px = cx[:, None] + t * hx[:, None]
    py = cy[:, None] + t * hy[:, None]
    width = np.full(px.shape, np.inf)
    need = _clearance_np(px, py, arr) < r + mi.margin
    b_idx, s_idx = np.nonzero(need)
    if b_idx.size:
        o = r * (2.0 * np.arange(LATERAL) / (LATERAL - 1) - 1.0)  # (L,)
        lx = px[b_idx, s_idx][:, None] - o * hy[b_idx][:, None]
        ly = py[b_idx, s_idx][:, None] + o * hx[b_idx][:, None]
        width[b_idx, s_idx] = _clearance_np(lx, ly, arr).max(-1)
    return width.min(-1)


def numpy_missions(mi: Mission, seeds, keep_trajectories: bool = False) -> dict:
    """Every run of ``seeds`` together, one vectorised step for all runs and UAVs (draws
    included). Returns final positions (B, M, 2), CRLB, eta, clearance (B, K+1), cost
    (B, K) and, with ``keep_trajectories``, the positions (B, K+1, M, 2)."""
    seeds = [int(s) for s in seeds]
    b_runs, m_uavs, k_steps = len(seeds), mi.m, mi.steps
    arr = _Arrays(mi)
    q = np.empty((b_runs, m_uavs, 2))
    noise = np.empty((b_runs, k_steps, m_uavs, 2))
    for i, s in enumerate(seeds):
        q[i], noise[i] = draw(mi, s)
    v = np.zeros_like(q)
    eta = np.ones(b_runs)
    delta = mi.delta
    sx, sy = mi.target
    s_vec = np.array(mi.target)
    h2 = mi.altitude**2
    dt, leader = mi.dt, mi.leader
    crlb = np.empty((b_runs, k_steps + 1))
    etas = np.empty((b_runs, k_steps + 1))
    clear = np.empty((b_runs, k_steps + 1))
    cost = np.empty((b_runs, k_steps))
    traj = np.empty((b_runs, k_steps + 1, m_uavs, 2)) if keep_trajectories else None
    lap = arr.lap
    lap_delta = lap @ delta  # sum_p a_mp (delta_m - delta_p)
    nominal = (lap_delta**2).sum()  # unused: the cost needs per-edge errors
    del nominal
    edges = [(m, p) for m, nb in enumerate(mi.neighbours) for p in nb]
    e_from = np.array([e[0] for e in edges])
    e_to = np.array([e[1] for e in edges])
    e_delta = delta[e_from] - delta[e_to]
    for k in range(k_steps + 1):
        c = q.mean(axis=1)  # (B, 2)
        cx, cy = c[:, 0], c[:, 1]
        goal_l = s_vec + eta[:, None] * delta[leader]
        w = mi.k_g * (goal_l - q[:, leader])
        dist = np.hypot(cx - sx, cy - sy)
        if mi.steering:
            rho = (
                eta
                * mi.radius
                * _smoothstep_np(
                    (dist - HOVER_INNER * mi.radius) / ((HOVER_OUTER - HOVER_INNER) * mi.radius)
                )
            )
            on = rho > 0.0
            if on.any():
                rx, ry = _repulsion_np(cx, cy, arr, mi.e_r, mi.l_safe, math.inf, rho)
                w[:, 0] += np.where(on, rx, 0.0) / dt
                w[:, 1] += np.where(on, ry, 0.0) / dt
        norm = np.sqrt((w * w).sum(-1))
        w *= np.where(norm > mi.cruise, mi.cruise / np.where(norm > 0, norm, 1.0), 1.0)[:, None]
        vref = w
        v[:, leader] = vref
        # metrics: CRLB (eq. (10)), clearance, eta
        dx = sx - q[..., 0]
        dy = sy - q[..., 1]
        d2 = dx * dx + dy * dy + h2
        g = (mi.snr / (d2 * d2) + 8.0 / d2) / d2
        jxx = (g * dx * dx).sum(-1)
        jxy = (g * dx * dy).sum(-1)
        jyy = (g * dy * dy).sum(-1)
        det = jxx * jyy - jxy * jxy
        crlb[:, k] = np.where(det > 0, (jxx + jyy) / np.where(det > 0, det, 1.0), np.inf)
        etas[:, k] = eta
        clear[:, k] = _clearance_np(q[..., 0], q[..., 1], arr).min(-1)
        if traj is not None:
            traj[:, k] = q
        if k == k_steps:
            break
        # eq. (19) formation input, eq. (18) repulsion, eq. (3) motion
        u = -mi.eps * (np.einsum("mn,bnd->bmd", lap, q) - eta[:, None, None] * lap_delta)
        rx, ry = _repulsion_np(q[..., 0], q[..., 1], arr, mi.e_r, mi.l_safe, mi.cap)
        q_next = q + u + v * dt + noise[:, k]
        q_next[..., 0] += rx
        q_next[..., 1] += ry
        # eq. (15) cost
        err = q[:, e_from] - q[:, e_to] - e_delta
        vel = (q_next - q) / dt - vref[:, None, :]
        cost[:, k] = (err * err).sum((-1, -2)) + (vel * vel).sum((-1, -2))
        # eq. (14) consensus (the leader's velocity is v* already)
        v = v - mi.gamma * arr.follower * np.einsum("mn,bnd->bmd", lap, v)
        if mi.eta_on:
            goal = _eta_goal_np(cx, cy, mi, arr)
            step = mi.eta_rate * dt
            eta = eta + np.clip(goal - eta, -step, step)
        q = q_next
    out = {"final": q, "crlb": crlb, "eta": etas, "clearance": clear, "cost": cost}
    if traj is not None:
        out["positions"] = traj
    return out
