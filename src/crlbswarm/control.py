r"""Distributed formation control laws of the paper, Sec. IV, as pure functions.

Each law is written once, as a Numba-compiled kernel on one formation (arrays ``(M, 2)``),
and used both by the mission simulator (:mod:`crlbswarm.simulation`) and by the public
functions below, which accept any batch ``(..., M, 2)`` and never modify their inputs.

Laws and the choices the paper leaves open (each documented in ``docs/control.md``):

* **Velocity consensus**, eq. (14). The printed update has no :math:`\mathbf v_{m,k}` on the
  right and the wrong sign on the leader term, so it does not converge. crlbswarm uses the
  standard convergent form (Ren & Beard 2008)

  .. math::
      \mathbf v_{m,k+1} = \mathbf v_{m,k} - \gamma\Bigl[\sum_{p\in\mathcal N_m\setminus\{1\}}
      a_{mp}(\mathbf v_{m,k} - \mathbf v_{p,k}) + a_{m1}(\mathbf v_{m,k} - \mathbf v^*_k)\Bigr].

* **Leader guidance** (not in the paper; :func:`leader_guidance`): proportional guidance
  with gain :math:`k_g` toward the leader's slot of :math:`F^*` over the target (scaled by
  :math:`\eta_k`), plus the repulsion felt by the formation's disc of radius
  :math:`\eta_k r^*` (so the leader steers the formation to the middle of a passage),
  saturated at the cruise speed :math:`v_c`; it decays to zero as the formation settles.
* **Formation input**, eqs. (16) and (19):
  :math:`\mathbf u_{m,k} = -\varepsilon\sum_p a_{mp}(\mathbf q_{m,k} - \mathbf q_{p,k} -
  \eta_k\boldsymbol\delta_{pm}) + \mathbf u^r_{m,k}`, a position increment per step (m).
* **Repulsion**, eq. (18), summed over every obstacle within :math:`l_\text{safe}`:
  :math:`E_r(1/l - 1/l_\text{safe})/l^2` along the unit vector from the nearest obstacle point
  to the UAV; the nearest point of a rectangle is the clamp of the paper, that of a circle
  the radial projection. Not in the paper: the step is capped at ``max_step`` metres, since
  :math:`1/l^3` is unbounded and a discrete-time step would otherwise jump.
* **Scaling factor** :math:`\eta_k` (rule not in the paper): see :func:`eta_target`.
* **Cost** :math:`\mathcal L_\text{tot}`, eq. (15) summed over UAVs: see
  :func:`formation_cost`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from . import _validation as _v
from .errors import FieldError
from .graphs import Adjacency

__all__ = [
    "Obstacles",
    "consensus_step",
    "eta_target",
    "eta_update",
    "formation_cost",
    "formation_input",
    "leader_guidance",
    "obstacle_clearance",
    "repulsion",
]


# ---------------------------------------------------------------------------------------
# Obstacles
# ---------------------------------------------------------------------------------------
def _rows(value: object, name: str, width: int) -> np.ndarray:
    """A finite ``(n, width)`` array; an empty input gives ``(0, width)``."""
    arr = _v.as_float_array(value, name)
    if arr.size == 0:
        return np.empty((0, width))
    if arr.ndim != 2 or arr.shape[1] != width:
        raise FieldError(name, f"expected shape (n, {width}), got {arr.shape}")
    return _v.check_finite(arr, name)


def _check_obstacles(obstacles: object) -> Obstacles:
    if not isinstance(obstacles, Obstacles):
        raise FieldError(
            "obstacles", f"expected a crlbswarm.Obstacles, got {type(obstacles).__name__}"
        )
    return obstacles


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

    def __init__(self, rectangles: object = (), circles: object = ()) -> None:
        rects = _rows(rectangles, "rectangles", 4)
        circs = _rows(circles, "circles", 3)
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


#: Points sampled across the path (odd, so the path itself is one) by the eta rule.
_LATERAL_SAMPLES = 9


# ---------------------------------------------------------------------------------------
# Kernels on one formation (Numba)
# ---------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _rect_distance(x, y, xmin, xmax, ymin, ymax):
    """Signed distance to a rectangle and the unit vector from its nearest point to (x, y)."""
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
def _circle_distance(x, y, cx, cy, r):
    dx = x - cx
    dy = y - cy
    rho = math.sqrt(dx * dx + dy * dy)
    if rho > 0.0:
        return rho - r, dx / rho, dy / rho
    return -r, 1.0, 0.0


@njit(cache=True)
def _clearance_point(x, y, rects, circles):
    """Signed distance from (x, y) to the nearest obstacle (+inf without obstacles)."""
    best = math.inf
    for i in range(rects.shape[0]):
        d, _, _ = _rect_distance(x, y, rects[i, 0], rects[i, 1], rects[i, 2], rects[i, 3])
        best = min(best, d)
    for i in range(circles.shape[0]):
        d, _, _ = _circle_distance(x, y, circles[i, 0], circles[i, 1], circles[i, 2])
        best = min(best, d)
    return best


@njit(cache=True)
def _repulsion_point(x, y, rects, circles, gain, l_safe, max_step, inflate=0.0):
    """Eq. (18) summed over the obstacles within l_safe, capped at max_step.

    ``inflate`` is subtracted from every distance: the repulsion felt by a disc of that
    radius centred at (x, y) (used for the formation as a whole by the leader guidance).
    """
    fx = 0.0
    fy = 0.0
    n_r = rects.shape[0]
    for i in range(n_r + circles.shape[0]):
        if i < n_r:
            d, ux, uy = _rect_distance(x, y, rects[i, 0], rects[i, 1], rects[i, 2], rects[i, 3])
        else:
            j = i - n_r
            d, ux, uy = _circle_distance(x, y, circles[j, 0], circles[j, 1], circles[j, 2])
        d -= inflate
        if d < l_safe:
            ell = max(d, 1e-9)  # inside an obstacle: push out along the nearest face
            mag = gain * (1.0 / ell - 1.0 / l_safe) / (ell * ell)
            fx += mag * ux
            fy += mag * uy
    norm = math.sqrt(fx * fx + fy * fy)
    if norm > max_step:
        fx *= max_step / norm
        fy *= max_step / norm
    return fx, fy


@njit(cache=True)
def _consensus(v, v_ref, leader, indptr, indices, gamma, out):
    """Corrected eq. (14): followers step toward their neighbours; the leader holds v_ref."""
    for m in range(v.shape[0]):
        if m == leader:
            out[m, 0] = v_ref[0]
            out[m, 1] = v_ref[1]
            continue
        sx = 0.0
        sy = 0.0
        for j in range(indptr[m], indptr[m + 1]):
            p = indices[j]
            if p == leader:
                px, py = v_ref[0], v_ref[1]
            else:
                px, py = v[p, 0], v[p, 1]
            sx += v[m, 0] - px
            sy += v[m, 1] - py
        out[m, 0] = v[m, 0] - gamma * sx
        out[m, 1] = v[m, 1] - gamma * sy


@njit(cache=True)
def _formation(q, delta, eta, eps, indptr, indices, out):
    """Eq. (19) without repulsion: -eps sum_p a_mp (q_m - q_p - eta (delta_m - delta_p))."""
    for m in range(q.shape[0]):
        sx = 0.0
        sy = 0.0
        for j in range(indptr[m], indptr[m + 1]):
            p = indices[j]
            sx += q[m, 0] - q[p, 0] - eta * (delta[m, 0] - delta[p, 0])
            sy += q[m, 1] - q[p, 1] - eta * (delta[m, 1] - delta[p, 1])
        out[m, 0] = -eps * sx
        out[m, 1] = -eps * sy


@njit(cache=True)
def _reference(
    qx, qy, gx, gy, cx, cy, gain, cruise, tvx, tvy, rects, circles, e_r, l_safe, footprint, dt
):
    """Leader reference velocity (not in the paper): the goal's velocity plus proportional
    guidance to the goal plus, if ``footprint > 0``, the repulsion felt by the formation's
    disc, saturated at cruise."""
    wx = tvx + gain * (gx - qx)
    wy = tvy + gain * (gy - qy)
    if footprint > 0.0:
        rx, ry = _repulsion_point(cx, cy, rects, circles, e_r, l_safe, math.inf, footprint)
        wx += rx / dt
        wy += ry / dt
    speed = math.sqrt(wx * wx + wy * wy)
    if speed > cruise:
        wx *= cruise / speed
        wy *= cruise / speed
    return wx, wy


@njit(cache=True)
def _eta_goal(cx, cy, sx, sy, radius, rects, circles, margin, lookahead, n_samples, eta_min):
    """Free half-width of the corridor ahead of the formation -> scale in [eta_min, 1]."""
    if rects.shape[0] + circles.shape[0] == 0:
        return 1.0
    hx = sx - cx
    hy = sy - cy
    dist = math.sqrt(hx * hx + hy * hy)
    if dist > 0.0:
        hx /= dist
        hy /= dist
    else:
        hx, hy = 1.0, 0.0
    ahead = min(lookahead, dist)
    width = math.inf
    enough = radius + margin  # a half-width this large allows eta = 1
    floor = margin + eta_min * radius  # a half-width this small forces eta = eta_min
    for i in range(n_samples):
        t = -radius + (ahead + radius) * i / (n_samples - 1)
        px = cx + t * hx
        py = cy + t * hy
        if _clearance_point(px, py, rects, circles) >= enough:
            continue  # the lateral best is at least as large: no effect on the result
        # Half-width of the corridor's cross-section: the best clearance the centre could
        # have within +-radius of the straight path (the repulsion centres the formation).
        best = -math.inf
        for j in range(_LATERAL_SAMPLES):
            o = radius * (2.0 * j / (_LATERAL_SAMPLES - 1) - 1.0)
            best = max(best, _clearance_point(px - o * hy, py + o * hx, rects, circles))
        width = min(width, best)
        if width <= floor:
            break  # clipped at eta_min whatever the remaining samples say
    scale = (width - margin) / radius
    return min(1.0, max(eta_min, scale))


@njit(cache=True)
def _cost(q, q_next, delta, v_ref, dt, indptr, indices):
    """Eq. (15) summed over UAVs with the nominal displacements delta_pm = delta_m - delta_p."""
    total = 0.0
    for m in range(q.shape[0]):
        for j in range(indptr[m], indptr[m + 1]):
            p = indices[j]
            ex = q[m, 0] - q[p, 0] - (delta[m, 0] - delta[p, 0])
            ey = q[m, 1] - q[p, 1] - (delta[m, 1] - delta[p, 1])
            total += ex * ex + ey * ey
        wx = (q_next[m, 0] - q[m, 0]) / dt - v_ref[0]
        wy = (q_next[m, 1] - q[m, 1]) / dt - v_ref[1]
        total += wx * wx + wy * wy
    return total


# Batched drivers: loop over the flattened batch, one formation at a time.
@njit(cache=True)
def _consensus_batch(v, v_ref, leader, indptr, indices, gamma, out):
    for b in range(v.shape[0]):
        _consensus(v[b], v_ref[b], leader, indptr, indices, gamma, out[b])


@njit(cache=True)
def _formation_batch(q, delta, eta, eps, indptr, indices, out):
    for b in range(q.shape[0]):
        _formation(q[b], delta, eta[b], eps, indptr, indices, out[b])


@njit(cache=True)
def _repulsion_batch(q, rects, circles, gain, l_safe, max_step, out):
    for b in range(q.shape[0]):
        fx, fy = _repulsion_point(q[b, 0], q[b, 1], rects, circles, gain, l_safe, max_step)
        out[b, 0] = fx
        out[b, 1] = fy


@njit(cache=True)
def _clearance_batch(q, rects, circles, out):
    for b in range(q.shape[0]):
        out[b] = _clearance_point(q[b, 0], q[b, 1], rects, circles)


@njit(cache=True)
def _reference_batch(
    q, goal, c, tv, gain, cruise, rects, circles, e_r, l_safe, footprint, dt, out
):
    for b in range(q.shape[0]):
        vx, vy = _reference(
            q[b, 0], q[b, 1], goal[b, 0], goal[b, 1], c[b, 0], c[b, 1], gain, cruise,
            tv[b, 0], tv[b, 1], rects, circles, e_r, l_safe, footprint, dt,
        )  # fmt: skip
        out[b, 0] = vx
        out[b, 1] = vy


@njit(cache=True)
def _eta_goal_batch(c, s, radius, rects, circles, margin, lookahead, n_samples, eta_min, out):
    for b in range(c.shape[0]):
        out[b] = _eta_goal(
            c[b, 0], c[b, 1], s[b, 0], s[b, 1], radius, rects, circles,
            margin, lookahead, n_samples, eta_min,
        )  # fmt: skip


@njit(cache=True)
def _cost_batch(q, q_next, delta, v_ref, dt, indptr, indices, out):
    for b in range(q.shape[0]):
        out[b] = _cost(q[b], q_next[b], delta, v_ref[b], dt, indptr, indices)


# ---------------------------------------------------------------------------------------
# Public pure functions (any batch shape, inputs never modified)
# ---------------------------------------------------------------------------------------
def _flat(arr: np.ndarray, batch: tuple[int, ...], tail: tuple[int, ...]) -> np.ndarray:
    """Broadcast ``arr`` to ``batch + tail`` and flatten the batch: a C-contiguous copy."""
    return np.ascontiguousarray(np.broadcast_to(arr, (*batch, *tail))).reshape(-1, *tail)


def _formation_arrays(q: object, name: str, adjacency: Adjacency) -> np.ndarray:
    if not isinstance(adjacency, Adjacency):
        raise FieldError(
            "adjacency", f"expected a crlbswarm.Adjacency, got {type(adjacency).__name__}"
        )
    arr = _v.positions(q, name)
    if arr.shape[-2] != adjacency.n_nodes:
        raise FieldError(
            f"{name}", f"has {arr.shape[-2]} UAVs but the graph has {adjacency.n_nodes} nodes"
        )
    return arr


def _slot_offsets(delta: object, adjacency: Adjacency) -> np.ndarray:
    d = _formation_arrays(delta, "delta", adjacency)
    if d.ndim != 2:
        raise FieldError("delta", f"expected shape (M, 2), got {d.shape}")
    return np.ascontiguousarray(d)


def _scale(eta: object, name: str) -> np.ndarray:
    e = _v.finite(eta, name)
    if np.any((e <= 0) | (e > 1)):
        raise FieldError(name, f"must lie in (0, 1], got {eta!r}")
    return e


def _is_inf(value: object) -> bool:
    return isinstance(value, float | int | np.floating) and value == math.inf


def _check_leader(leader: int, n: int) -> int:
    lead = _v.count(leader, "leader", 0)
    if lead >= n:
        raise FieldError("leader", f"must be a UAV index below {n}, got {lead}")
    return lead


def consensus_step(
    velocities: object, v_ref: object, adjacency: Adjacency, leader: int, gamma: float
) -> np.ndarray:
    r"""One step of the corrected leader-follower velocity consensus, eq. (14).

    .. math::
        \mathbf v_{m,k+1} = \mathbf v_{m,k} - \gamma\Bigl[\sum_{p\in\mathcal N_m\setminus\{1\}}
        a_{mp}(\mathbf v_{m,k} - \mathbf v_{p,k}) + a_{m1}(\mathbf v_{m,k} - \mathbf v^*_k)\Bigr]

    The paper's printed update lacks :math:`\mathbf v_{m,k}` on the right and flips the sign
    of the leader term; this is the standard convergent form.

    Parameters
    ----------
    velocities : array_like, shape (..., M, 2)
        Velocity estimates :math:`\mathbf v_{m,k}`, m/s. The leader's row is ignored.
    v_ref : array_like, shape (..., 2)
        Leader's reference velocity :math:`\mathbf v^*_k`, m/s.
    adjacency : Adjacency
        Communication graph.
    leader : int
        Index of the leader.
    gamma : float
        Consensus step, > 0 (stable iff below :func:`crlbswarm.consensus_step_limit`).

    Returns
    -------
    ndarray, shape (..., M, 2)
        :math:`\mathbf v_{m,k+1}`; the leader's row is :math:`\mathbf v^*_k`.
    """
    v = _formation_arrays(velocities, "velocities", adjacency)
    ref = _v.point(v_ref, "v_ref")
    lead = _check_leader(leader, adjacency.n_nodes)
    g = float(_v.positive(gamma, "gamma"))
    shape = _v.broadcast("v_ref", v.shape[:-2], ref.shape[:-1])
    vb = _flat(v, shape, v.shape[-2:])
    rb = _flat(ref, shape, (2,))
    out = np.empty_like(vb)
    _consensus_batch(vb, rb, lead, adjacency.indptr, adjacency.indices, g, out)
    return out.reshape(*shape, *v.shape[-2:])


def leader_guidance(
    leader_xy: object,
    goal_xy: object,
    gain: float,
    cruise_speed: float,
    *,
    center_xy: object = None,
    goal_velocity: object = (0.0, 0.0),
    footprint: float = 0.0,
    obstacles: Obstacles | None = None,
    repulsion_gain: float = 2.0,
    safety_radius: float = 5.0,
    dt: float = 0.1,
) -> np.ndarray:
    r"""Leader's reference velocity :math:`\mathbf v^*_k` (not in the paper).

    .. math::
        \mathbf v^* = \operatorname{sat}_{v_c}\bigl(\dot{\mathbf g} + k_g(\mathbf g -
        \mathbf q_1) + \mathbf u^r(\mathbf c;\, \rho)/\Delta T\bigr),
        \qquad \operatorname{sat}_{v_c}(\mathbf w) = \mathbf w\,\min(1, v_c/\lVert\mathbf w
        \rVert)

    Proportional guidance toward the goal :math:`\mathbf g` (the leader's slot over the
    target) with the goal's own velocity :math:`\dot{\mathbf g}` as feedforward (zero for a
    static target), saturated at the cruise speed, so that it decays to zero as the
    formation settles over a static target. With ``footprint`` :math:`\rho > 0` the leader
    also steers the whole formation: :math:`\mathbf u^r(\mathbf c; \rho)` is the repulsion
    of eq. (18) felt by a disc of radius :math:`\rho` (the formation, :math:`\eta_k r^*`)
    centred at the formation centre :math:`\mathbf c`, i.e. eq. (18) with every distance
    reduced by :math:`\rho`. This keeps the formation centred in a passage instead of
    letting the walls squeeze it.

    Parameters
    ----------
    leader_xy : array_like, shape (..., 2)
        Leader position :math:`\mathbf q_1`, m.
    goal_xy : array_like, shape (..., 2)
        Goal :math:`\mathbf g`, m.
    gain : float
        Proportional gain :math:`k_g`, 1/s.
    cruise_speed : float
        Saturation speed :math:`v_c`, m/s.
    center_xy : array_like, shape (..., 2), optional
        Formation centre :math:`\mathbf c` (needed when ``footprint > 0``), m.
    goal_velocity : array_like, shape (..., 2), default (0, 0)
        Velocity of the goal :math:`\dot{\mathbf g}` (the target's), m/s.
    footprint : float, default 0
        Radius :math:`\rho` of the formation's disc, m; 0 turns steering off.
    obstacles : Obstacles, optional
        Obstacles for the steering term.
    repulsion_gain : float, default 2
        :math:`E_r` of the steering term, m^4 per step (the paper scenario's value).
    safety_radius : float, default 5
        :math:`l_\text{safe}` of the steering term, m (the paper's value).
    dt : float, default 0.1
        Time step :math:`\Delta T`, s (turns the repulsive step into a velocity).

    Returns
    -------
    ndarray, shape (..., 2)
        :math:`\mathbf v^*`, m/s.
    """
    q = _v.point(leader_xy, "leader_xy")
    goal = _v.point(goal_xy, "goal_xy")
    k = float(_v.positive(gain, "gain"))
    vc = float(_v.positive(cruise_speed, "cruise_speed"))
    rho = float(_v.finite(footprint, "footprint"))
    if rho < 0:
        raise FieldError("footprint", f"must be >= 0, got {footprint!r}")
    obs = _check_obstacles(obstacles) if obstacles is not None else Obstacles()
    c = q if center_xy is None else _v.point(center_xy, "center_xy")
    if rho > 0 and (center_xy is None or obstacles is None):
        raise FieldError("footprint", "steering needs center_xy and obstacles")
    e_r = float(_v.positive(repulsion_gain, "repulsion_gain"))
    l_safe = float(_v.positive(safety_radius, "safety_radius"))
    step = float(_v.positive(dt, "dt"))
    tv = _v.point(goal_velocity, "goal_velocity")
    shape = _v.broadcast("goal_xy", q.shape, goal.shape)
    shape = _v.broadcast("center_xy", shape, c.shape)
    shape = _v.broadcast("goal_velocity", shape, tv.shape)
    out = np.empty((int(np.prod(shape[:-1], dtype=int)), 2))
    _reference_batch(
        _flat(q, shape[:-1], (2,)), _flat(goal, shape[:-1], (2,)), _flat(c, shape[:-1], (2,)),
        _flat(tv, shape[:-1], (2,)), k, vc, obs.rectangles, obs.circles, e_r, l_safe, rho,
        step, out,
    )  # fmt: skip
    return out.reshape(shape)


def formation_input(
    positions: object, delta: object, eta: object, adjacency: Adjacency, epsilon: float
) -> np.ndarray:
    r"""Displacement-based formation input without repulsion, eqs. (16) and (19).

    .. math::
        \mathbf u_{m,k} = -\varepsilon \sum_p a_{mp}
        (\mathbf q_{m,k} - \mathbf q_{p,k} - \eta_k \boldsymbol\delta_{pm}),
        \qquad \boldsymbol\delta_{pm} = \boldsymbol\delta_m - \boldsymbol\delta_p

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        UAV positions :math:`\mathbf q_{m,k}`, m.
    delta : array_like, shape (M, 2)
        Slot offsets :math:`\boldsymbol\delta_m` of the desired formation (for example
        :math:`F^*` minus its centre), m.
    eta : float or array_like, shape (...)
        Scaling factor :math:`\eta_k \in (0, 1]`.
    adjacency : Adjacency
        Communication graph.
    epsilon : float
        Per-step gain :math:`\varepsilon > 0` (stable iff below
        :func:`crlbswarm.formation_step_limit`).

    Returns
    -------
    ndarray, shape (..., M, 2)
        Position increment per step, m.
    """
    q = _formation_arrays(positions, "positions", adjacency)
    d = _slot_offsets(delta, adjacency)
    e = _scale(eta, "eta")
    eps = float(_v.positive(epsilon, "epsilon"))
    shape = _v.broadcast("eta", q.shape[:-2], e.shape)
    qb = _flat(q, shape, q.shape[-2:])
    eb = _flat(e, shape, ())
    out = np.empty_like(qb)
    _formation_batch(
        qb, np.ascontiguousarray(d), eb, eps, adjacency.indptr, adjacency.indices, out
    )
    return out.reshape(*shape, *q.shape[-2:])


def obstacle_clearance(positions: object, obstacles: Obstacles) -> np.ndarray:
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
    q = _v.point(positions, "positions")
    qb = np.ascontiguousarray(q).reshape(-1, 2)
    out = np.empty(qb.shape[0])
    obs = _check_obstacles(obstacles)
    _clearance_batch(qb, obs.rectangles, obs.circles, out)
    return out.reshape(q.shape[:-1])


def repulsion(
    positions: object,
    obstacles: Obstacles,
    gain: float,
    safety_radius: float,
    max_step: float = math.inf,
) -> np.ndarray:
    r"""Repulsive input :math:`\mathbf u^r`, eq. (18), summed over nearby obstacles.

    .. math::
        \mathbf u^r = \sum_{o:\, l_o < l_\text{safe}} E_r \Bigl(\frac{1}{l_o} -
        \frac{1}{l_\text{safe}}\Bigr) \frac{1}{l_o^2}\, \frac{\vec{\mathbf l}_o}{l_o}

    with :math:`\vec{\mathbf l}_o` from the nearest point of obstacle :math:`o` to the UAV.
    Not in the paper: the sum is capped at ``max_step`` metres.

    Parameters
    ----------
    positions : array_like, shape (..., 2)
        UAV positions, m.
    obstacles : Obstacles
        Rectangles and circles.
    gain : float
        Repulsion gain :math:`E_r`, m^4 per step (so that :math:`\mathbf u^r` is in metres).
    safety_radius : float
        :math:`l_\text{safe}`, m.
    max_step : float, default inf
        Cap on the length of :math:`\mathbf u^r`, m.

    Returns
    -------
    ndarray, shape (..., 2)
        Position increment per step, m.
    """
    q = _v.point(positions, "positions")
    e_r = float(_v.positive(gain, "gain"))
    l_safe = float(_v.positive(safety_radius, "safety_radius"))
    cap = _v.scalar(max_step, "max_step") if not _is_inf(max_step) else math.inf
    if not cap > 0:
        raise FieldError("max_step", f"must be > 0 (inf for no cap), got {max_step!r}")
    qb = np.ascontiguousarray(q).reshape(-1, 2)
    out = np.empty_like(qb)
    obs = _check_obstacles(obstacles)
    _repulsion_batch(qb, obs.rectangles, obs.circles, e_r, l_safe, cap, out)
    return out.reshape(q.shape)


def eta_target(
    center_xy: object,
    target_xy: object,
    obstacles: Obstacles,
    radius: float,
    margin: float,
    lookahead: float,
    eta_min: float,
    n_samples: int = 32,
) -> np.ndarray:
    r"""Desired scaling factor from the free width ahead of the formation (not in the paper).

    The paper says only that :math:`\eta_k` "is adaptively reduced when the formation centre
    approaches spatial bottlenecks". crlbswarm samples ``n_samples`` points on the segment
    from ``radius`` behind the formation centre :math:`\mathbf c` to ``lookahead`` ahead of it,
    toward the target. At each point it takes the largest obstacle clearance across the path
    within :math:`\pm R` (9 points, spacing :math:`R/4`): the half-width of the corridor's
    cross-section there, since the repulsion and the leader's steering centre the formation
    in a passage (the sampling errs on the safe side: it can miss the widest point by up to
    :math:`R/8`, so the formation shrinks slightly more than needed). The
    smallest of these along the path is the free half-width :math:`w` of the corridor the
    formation is about to use, and the rule asks for the scale at which a formation of
    nominal radius :math:`R` keeps ``margin`` from every obstacle:

    .. math:: \eta^\text{goal} = \operatorname{clip}\bigl((w - \text{margin})/R,\;
              \eta_\min,\; 1\bigr).

    Looking behind keeps :math:`\eta` low until the rear of the formation has cleared the
    bottleneck; looking ahead lets the shape (time constant :math:`1/(\varepsilon\lambda_2)`)
    shrink before the centre arrives. The result is continuous in :math:`\mathbf c`;
    :func:`eta_update` rate-limits it.

    Parameters
    ----------
    center_xy : array_like, shape (..., 2)
        Formation centre, m.
    target_xy : array_like, shape (..., 2)
        Target (the direction of travel), m.
    obstacles : Obstacles
        Rectangles and circles.
    radius : float
        Nominal formation radius :math:`R` (at :math:`\eta = 1`), m.
    margin : float
        Clearance to keep, m (the safety radius by default in scenarios).
    lookahead : float
        How far ahead to look, m.
    eta_min : float
        Smallest scale, in (0, 1].
    n_samples : int, default 32
        Points sampled along the segment (at least 2).

    Returns
    -------
    ndarray, shape (...)
        :math:`\eta^\text{goal} \in [\eta_\min, 1]`.
    """
    c = _v.point(center_xy, "center_xy")
    s = _v.point(target_xy, "target_xy")
    shape = _v.broadcast("target_xy", c.shape, s.shape)
    r = float(_v.positive(radius, "radius"))
    mrg = float(_v.finite(margin, "margin"))
    look = float(_v.positive(lookahead, "lookahead"))
    lo = float(_v.positive(eta_min, "eta_min"))
    if lo > 1.0:
        raise FieldError("eta_min", f"must lie in (0, 1], got {eta_min!r}")
    n = _v.count(n_samples, "n_samples", 2)
    cb = _flat(c, shape[:-1], (2,))
    sb = _flat(s, shape[:-1], (2,))
    out = np.empty(cb.shape[0])
    obs = _check_obstacles(obstacles)
    _eta_goal_batch(cb, sb, r, obs.rectangles, obs.circles, mrg, look, n, lo, out)
    return out.reshape(shape[:-1])


def eta_update(eta: object, goal: object, rate: float, dt: float) -> np.ndarray:
    r"""Rate-limited step of :math:`\eta` toward its goal (not in the paper).

    :math:`\eta_{k+1} = \eta_k + \operatorname{clip}(\eta^\text{goal}_k - \eta_k,
    -\rho\,\Delta T, \rho\,\Delta T)`: smooth, and back to 1 after the bottleneck.

    Parameters
    ----------
    eta : float or array_like
        Current scale :math:`\eta_k`.
    goal : float or array_like
        Desired scale from :func:`eta_target`.
    rate : float
        Largest change per second :math:`\rho`, 1/s.
    dt : float
        Time step :math:`\Delta T`, s.

    Returns
    -------
    ndarray
        :math:`\eta_{k+1}`.
    """
    e = _scale(eta, "eta")
    g = _scale(goal, "goal")
    step = float(_v.positive(rate, "rate")) * float(_v.positive(dt, "dt"))
    return e + np.clip(g - e, -step, step)


def formation_cost(
    positions: object,
    next_positions: object,
    delta: object,
    v_ref: object,
    adjacency: Adjacency,
    dt: float,
) -> np.ndarray:
    r"""Total control cost :math:`\mathcal L_\text{tot} = \sum_m \mathcal L_m`, eq. (15).

    .. math::
        \mathcal L_\text{tot} = \sum_m \Bigl[\sum_p a_{mp}\lVert \mathbf q_{m,k} -
        \mathbf q_{p,k} - \boldsymbol\delta_{pm}\rVert^2 + \Bigl\lVert
        \frac{\mathbf q_{m,k+1} - \mathbf q_{m,k}}{\Delta T} - \mathbf v^*_k\Bigr\rVert^2\Bigr]

    The displacements are the nominal ones (:math:`\eta = 1`), as printed: shrinking the
    formation in a passage is a deviation from :math:`\mathbb F` and raises the cost.

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        :math:`\mathbf q_{m,k}`, m.
    next_positions : array_like, shape (..., M, 2)
        :math:`\mathbf q_{m,k+1}`, m.
    delta : array_like, shape (M, 2)
        Slot offsets :math:`\boldsymbol\delta_m`, m.
    v_ref : array_like, shape (..., 2)
        Leader's reference velocity :math:`\mathbf v^*_k`, m/s.
    adjacency : Adjacency
        Communication graph.
    dt : float
        Time step, s.

    Returns
    -------
    ndarray, shape (...)
        :math:`\mathcal L_\text{tot}` (m^2 + m^2/s^2, summed as printed).
    """
    q = _formation_arrays(positions, "positions", adjacency)
    qn = _formation_arrays(next_positions, "next_positions", adjacency)
    d = _slot_offsets(delta, adjacency)
    ref = _v.point(v_ref, "v_ref")
    step = float(_v.positive(dt, "dt"))
    shape = _v.broadcast("next_positions", q.shape[:-2], qn.shape[:-2], ref.shape[:-1])
    mshape = q.shape[-2:]
    qb = _flat(q, shape, mshape)
    qnb = _flat(qn, shape, mshape)
    rb = _flat(ref, shape, (2,))
    out = np.empty(qb.shape[0])
    _cost_batch(
        qb, qnb, np.ascontiguousarray(d), rb, step, adjacency.indptr, adjacency.indices, out
    )
    return out.reshape(shape)
