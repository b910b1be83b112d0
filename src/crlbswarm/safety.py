r"""Distributed safety filter for the swarm: discrete-time control barrier functions.

Not in the paper. In the spirit of the barrier certificates of Wang, Ames and Egerstedt,
"Safety barrier certificates for collisions-free multirobot systems", *IEEE Transactions
on Robotics* 33(3), 2017 (and of the Robotarium's), but in discrete time and exact: each
UAV replaces its nominal displacement by the closest displacement that keeps every pair of
UAVs apart and every UAV out of every obstacle, using only the positions of the UAVs within
its sensing radius, and taking half of each pair's responsibility.

**Model.** UAV :math:`i` moves by :math:`\mathbf q_{i,k+1} = \mathbf q_{i,k} + \mathbf d_i
+ \mathbf n_{i,k}`: :math:`\mathbf d_i` is the commanded displacement of the step (m) and
:math:`\mathbf n_{i,k}` a Gaussian disturbance of standard deviation :math:`\sigma` per
axis and step. Everything below is computed from the positions at step :math:`k`.

**Pairs.** For each UAV :math:`j` with :math:`r = \lVert\mathbf p\rVert \le R` (the sensing
radius), :math:`\mathbf p = \mathbf q_i - \mathbf q_j`, let :math:`D = d_\text{min} +
m_p` (separation plus the pair margin) and :math:`h = r^2 - D^2`. UAV :math:`i` imposes

.. math::
    \hat{\mathbf p}\cdot\mathbf d_i \ge t(r), \qquad
    t(r) = \tfrac12\Bigl(\sqrt{r^2 - \gamma h} - r\Bigr)
         = \frac{-\gamma h}{2\bigl(\sqrt{r^2 - \gamma h} + r\bigr)},
    \qquad \hat{\mathbf p} = \mathbf p / r,

with the decay rate :math:`\gamma\in(0, 1]` (UAV :math:`j` imposes the mirror row on
:math:`\mathbf d_j`). With both rows, :math:`\hat{\mathbf p}\cdot(\mathbf d_i - \mathbf d_j)
\ge 2t = \sqrt{r^2 - \gamma h} - r`, so :math:`r + \hat{\mathbf p}\cdot(\mathbf d_i -
\mathbf d_j) \ge \sqrt{r^2 - \gamma h} \ge 0` and

.. math::
    h_{k+1} = \lVert\mathbf p + \mathbf d_i - \mathbf d_j\rVert^2 - D^2
    \ge \bigl(r + \hat{\mathbf p}\cdot(\mathbf d_i - \mathbf d_j)\bigr)^2 - D^2
    \ge r^2 - \gamma h - D^2 = (1 - \gamma)\,h,

the discrete-time barrier condition: exact, with no linearisation error (the dropped part of
:math:`\mathbf d_i - \mathbf d_j`, across :math:`\hat{\mathbf p}`, only adds a square).
The simpler row :math:`\mathbf p\cdot\mathbf d_i \ge -\gamma h/4` (from
:math:`h_{k+1} \ge h + 2\mathbf p\cdot(\mathbf d_i - \mathbf d_j)`), is the first-order
form of the row above: by concavity of the square root :math:`t(r) \le -\gamma h/(4r)`,
so the row above guarantees the same decay while allowing every move that row allows and
more; unlike that row it stays finite as :math:`r \to 0`: two UAVs at the same point
(:math:`r = 0`) are sent apart along :math:`\pm x` (the one with the larger index along
:math:`+x`) by :math:`t(0) = \sqrt\gamma D/2` each (this tie-break alone depends on the
order of the UAVs).

**Obstacles** (axis-aligned rectangles and discs, :mod:`crlbswarm.obstacles`). With the
signed distance :math:`c` of :math:`\mathbf q_i` and the unit vector :math:`\mathbf n`
from the obstacle's nearest point (:func:`~crlbswarm.obstacles.rectangle_distance`,
:func:`~crlbswarm.obstacles.circle_distance`), UAV :math:`i` imposes

.. math::
    \mathbf n\cdot\mathbf d_i \ge -\gamma\,(c - m_o),

with the obstacle margin :math:`m_o`. The signed distance to a convex set is convex
(inside too) and :math:`\mathbf n` is a subgradient of it, so :math:`c(\mathbf q +
\mathbf d) \ge c + \mathbf n\cdot\mathbf d`: then :math:`c_{k+1} - m_o \ge (1 - \gamma)
(c - m_o)`, again exactly. The obstacles are a map every UAV knows, so no sensing radius
applies to them.

**Speed.** :math:`\lVert\mathbf d_i\rVert \le v_\text{max}\Delta T`.

**The QP**, per UAV: minimise :math:`\lVert\mathbf d - \mathbf d^\text{nom}\rVert^2`
subject to the rows (unit normals :math:`\mathbf n_k\cdot\mathbf d \ge c_k`) and the
disc. A row that every point of the disc satisfies (:math:`c_k \le -v_\text{max}\Delta T`)
is left out, which changes nothing; the rows kept are the "active neighbours". The
problem is solved exactly in closed form (:func:`solve_qp2`): its solution is the
projection of :math:`\mathbf d^\text{nom}` onto a closed convex set of the plane, so it is
:math:`\mathbf d^\text{nom}` itself, or lies in the relative interior of one boundary
piece (the projection onto a line, or the radial projection onto the circle), or at a
point where two boundaries meet (two lines, or a line and the circle). Moreover at least
one of its active constraints is violated by :math:`\mathbf d^\text{nom}` (were all
satisfied, the projection onto them alone, which is the solution, would be
:math:`\mathbf d^\text{nom}`). So the candidates are: the radial projection (if
:math:`\mathbf d^\text{nom}` is outside the disc) and, on each line violated by
:math:`\mathbf d^\text{nom}` (on every line if it is outside the disc), the point of the
line's feasible segment (the line clipped by the disc and the other rows, :math:`O(m)`)
closest to :math:`\mathbf d^\text{nom}`: the projection onto the line clamped to the
segment, which is the projection itself or one of the segment's ends, a vertex with
another line or with the circle. Every candidate is feasible by construction; each is
checked anyway (to a relative tolerance of 1e-10, against rounding), and the closest to
:math:`\mathbf d^\text{nom}` is the solution. :math:`\mathbf d^\text{nom}` is checked
first, in :math:`O(m)` for :math:`m` rows; only when it is infeasible is the
:math:`O(m^2)` search done.

**Always feasible when safe.** If every sensed pair has :math:`h \ge 0` and every
clearance is at least :math:`m_o`, every row has :math:`c_k \le 0`, so :math:`\mathbf d =
0` is feasible; the filtered move then keeps the state safe, so a swarm that starts safe
stays safe without disturbance. A pair farther apart than :math:`R` (unseen) closes at
most :math:`2 v_\text{max}\Delta T` in a step, plus the disturbance: so
:func:`safety_filter` requires :math:`R \ge d_\text{min} + m_p + 2 v_\text{max}\Delta T`,
which leaves the pair margin for the disturbance.

**Fallback.** The disturbance can push a pair inside :math:`D` (or a UAV inside the
obstacle margin), and the rows may then have no common point in the disc. The filter then
returns the displacement that minimises the largest shortfall :math:`\max_k (c_k -
\mathbf n_k\cdot\mathbf d)` over the disc (a distance, m, since the normals are unit
vectors), and among those the closest to :math:`\mathbf d^\text{nom}`: the solution of the
QP with every :math:`c_k` lowered by the least common slack :math:`s` that makes it
feasible, found by bisection on :math:`s` (at :math:`s = \max_k c_k`, :math:`\mathbf d =
0` is feasible). It is finite, within the speed limit, equal to the QP's solution as soon
as the QP is feasible, and moves the worst-off pairs and obstacles apart as fast as the
others allow.

**Margins against the disturbance** (:func:`disturbance_margins`). Near the boundary,
with the rows active and feasible, the distance to it, :math:`e_k`, follows (to first
order in :math:`e_k`) :math:`e_{k+1} \ge (1 - \gamma)e_k + w_k`, :math:`w_k` the
disturbance projected on the normal (standard deviation :math:`\sqrt2\sigma` for a pair,
two UAVs; :math:`\sigma` for an obstacle). So
:math:`e_k` stays above the AR(1) process :math:`X_{k+1} = (1-\gamma)X_k + w_k`, whose
stationary standard deviation is :math:`\operatorname{sd}(w)/\sqrt{1 - (1-\gamma)^2}`;
margins of :math:`n_\sigma` such deviations are crossed with probability about
:math:`\Phi(-n_\sigma)` per step (about 1e-9 for the default 6).

**Deadlocks.** The filter alone can stop UAVs for good (two head-on, three pressed into
a triangle: every nominal points into a barrier). The mission kernel calls
:func:`safety_step` with ``turn`` = :data:`UNBLOCK_TURN`: a UAV whose safe move hardly
advances along its nominal one solves its QP again with the nominal turned to its right
(the right-hand rule), which is as safe (the same rows) and lets such UAVs slide past
each other. :func:`safety_filter` is the plain QP.

The law is written once per piece as a compiled kernel (:func:`solve_qp2`,
:func:`safe_displacement`, :func:`safety_step`, called by the mission kernel) and wrapped
by the public, validated, batched :func:`safety_filter`.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from pydantic import Field

from . import _validation as _v
from ._config import ConfigModel, PositiveFloat
from .errors import FieldError
from .geometry import clip_norm
from .obstacles import Obstacles, check_obstacles, obstacle_distance

#: A UAV is blocked when its safe displacement advances along its nominal one by less than
#: this fraction of what it could (the nominal's length, at most the step's speed limit)...
BLOCKED_FRACTION = 0.25

#: ... and its nominal displacement is at least this fraction of the step's speed limit.
BLOCKED_MOVING = 0.01

#: How far a blocked UAV turns its nominal displacement to the right, rad (the mission
#: kernel's ``turn`` of :func:`safety_step`).
UNBLOCK_TURN = math.pi / 4

__all__ = [
    "BLOCKED_FRACTION",
    "BLOCKED_MOVING",
    "UNBLOCK_TURN",
    "SafetyConfig",
    "disturbance_margins",
    "safe_displacement",
    "safety_filter",
    "safety_step",
    "solve_qp2",
]

# The kernels use NumPy's error model (no check for a division by zero, which makes them
# about twice as fast): every division below is guarded (a slope away from zero, a
# positive distance or norm; min_separation > 0), so the two models give the same results.

#: Relative feasibility tolerance of the closed-form QP (of the size of the problem).
_TOL = 1e-10
#: Two rows whose unit normals are closer to parallel than this are taken as parallel.
_DET_MIN = 1e-13
#: Bisection of the fallback's common slack: at most this many halvings ...
_BISECTION_STEPS = 64
#: ... stopping when the bracket is this small relative to the first one (at most
#: vmax wide): about 34 halvings.
_BISECTION_RTOL = 1e-10


# ---------------------------------------------------------------------------------------
# The closed-form QP in the plane (rows with unit normals: n_k . d >= b_k - slack)
# ---------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def _rows_hold(x, y, a, b, m, slack, size):
    """Whether (x, y) satisfies the first m rows, n_k . d >= b_k - slack, to the relative
    tolerance (``size``: of the problem and the point, m)."""
    for k in range(m):
        c = b[k] - slack
        if a[k, 0] * x + a[k, 1] * y - c < -_TOL * (size + abs(c)):
            return False
    return True


@njit(cache=True, inline="always", error_model="numpy")
def _feasible(x, y, a, b, m, vmax, slack, scale):
    """Whether (x, y) satisfies the first m rows and the disc, to the relative tolerance."""
    r2 = x * x + y * y
    if r2 > vmax * vmax * (1.0 + 4.0 * _TOL):
        return False
    return _rows_hold(x, y, a, b, m, slack, math.sqrt(r2) + scale)


@njit(cache=True, inline="always", error_model="numpy")
def _consider(x, y, d0x, d0y, a, b, m, vmax, slack, scale, best, bx, by):
    """Keep the candidate (x, y) if it is closer to d0 than the best so far and feasible."""
    dist = (x - d0x) * (x - d0x) + (y - d0y) * (y - d0y)
    if dist < best and _feasible(x, y, a, b, m, vmax, slack, scale):
        return dist, x, y
    return best, bx, by


@njit(cache=True, error_model="numpy")
def _segment_point(k, d0x, d0y, a, b, m, vmax, slack, size):
    """The point of row k's line closest to d0 among those in the disc and every other row
    (clamped to the line's feasible segment): ``(x, y, found)``; ``found`` False when the
    segment is empty. The point is d0's projection onto the line, or a vertex with another
    line or with the circle. Not checked for feasibility (rounding)."""
    nx = a[k, 0]
    ny = a[k, 1]
    ck = b[k] - slack
    fx = ck * nx  # the foot of the line; the line is foot + t (-ny, nx)
    fy = ck * ny
    lo = -math.inf
    hi = math.inf
    if vmax < math.inf:
        half2 = vmax * vmax - ck * ck
        if not half2 >= -4.0 * _TOL * size * size:
            return 0.0, 0.0, False  # the line misses the disc (or a NaN)
        hi = math.sqrt(max(half2, 0.0))
        lo = -hi
    for j in range(m):
        if j == k:
            continue
        slope = ny * a[j, 0] - nx * a[j, 1]  # -(row j's normal . the line's direction)
        gap = a[j, 0] * fx + a[j, 1] * fy - (b[j] - slack)  # row j: gap - slope t >= 0
        if abs(slope) < _DET_MIN:  # parallel: all of the line or none of it
            if gap < -_TOL * (size + abs(b[j] - slack)):
                return 0.0, 0.0, False
        elif slope > 0.0:
            hi = min(hi, gap / slope)
        else:
            lo = max(lo, gap / slope)
    t = min(max(-ny * d0x + nx * d0y, lo), hi) if lo <= hi else 0.5 * (lo + hi)
    return fx - t * ny, fy + t * nx, True


@njit(cache=True, error_model="numpy")
def _project(d0x, d0y, a, b, m, vmax, slack):
    """The projection of d0 onto {n_k . d >= b_k - slack, |d| <= vmax}, unit rows:
    ``(dx, dy, found)``; ``found`` False when no candidate is feasible (empty set)."""
    r0 = math.sqrt(d0x * d0x + d0y * d0y)
    scale = r0 + (vmax if vmax < math.inf else 0.0)
    if _feasible(d0x, d0y, a, b, m, vmax, slack, scale):
        return d0x, d0y, True
    best, bx, by = math.inf, 0.0, 0.0
    outside = r0 > vmax
    if outside:
        f = vmax / r0
        best, bx, by = _consider(
            d0x * f, d0y * f, d0x, d0y, a, b, m, vmax, slack, scale, best, bx, by
        )
    for k in range(m):
        ck = b[k] - slack
        # The solution lies on a line violated by d0, or on the circle (d0 outside it),
        # possibly where it meets another line: on that line's feasible segment.
        if outside or a[k, 0] * d0x + a[k, 1] * d0y < ck:
            x, y, found = _segment_point(k, d0x, d0y, a, b, m, vmax, slack, scale + abs(ck))
            if found:
                best, bx, by = _consider(x, y, d0x, d0y, a, b, m, vmax, slack, scale, best, bx, by)
    return bx, by, best < math.inf


@njit(cache=True, error_model="numpy")
def _least_violation(d0x, d0y, a, b, m, vmax):
    """The fallback: the QP with every b_k lowered by the least common slack that makes it
    feasible within the disc, by bisection between max(0, max_k b_k - vmax) (in the disc,
    no row can be met by more than vmax) and max_k b_k (where d = 0 is feasible)."""
    hi = 0.0
    for k in range(m):
        hi = max(hi, b[k])
    lo = max(0.0, hi - vmax)
    tol = _BISECTION_RTOL * (hi - lo)
    for _ in range(_BISECTION_STEPS):
        if hi - lo <= tol:
            break
        mid = 0.5 * (lo + hi)
        if _project(d0x, d0y, a, b, m, vmax, mid)[2]:
            hi = mid
        else:
            lo = mid
    dx, dy, found = _project(d0x, d0y, a, b, m, vmax, hi)
    if not found:  # rounding only: d = 0 is feasible at the first upper end
        return 0.0, 0.0
    return dx, dy


@njit(cache=True, inline="always", error_model="numpy")
def _solve_unit(d0x, d0y, a, b, m, vmax):
    """:func:`solve_qp2` on rows that already have unit (or zero, with b = -inf) normals.
    The common case first: d0 inside the disc and satisfying every row is the answer."""
    size = abs(d0x) + abs(d0y) + (vmax if vmax < math.inf else 0.0)
    if d0x * d0x + d0y * d0y <= vmax * vmax and _rows_hold(d0x, d0y, a, b, m, 0.0, size):
        return d0x, d0y, True
    dx, dy, feasible = _project(d0x, d0y, a, b, m, vmax, 0.0)
    if not feasible:
        dx, dy = _least_violation(d0x, d0y, a, b, m, vmax)
    dx, dy = clip_norm(dx, dy, vmax)
    return dx, dy, feasible


@njit(cache=True, error_model="numpy")
def solve_qp2(d0x, d0y, a, b, m, vmax):
    r"""The closest point to :math:`\mathbf d_0` under linear rows and a disc, exactly.

    .. math::
        \min_{\mathbf d\in\mathbb R^2} \lVert\mathbf d - \mathbf d_0\rVert^2
        \quad\text{s.t.}\quad \mathbf a_k\cdot\mathbf d \ge b_k\ (k < m),
        \qquad \lVert\mathbf d\rVert \le v_\text{max}

    Closed form by enumeration of the candidates (module docstring, "The QP"): ``d0`` if
    feasible, else the radial projection onto the circle and, on each line violated by
    ``d0`` (every line if ``d0`` is outside the disc), the projection of ``d0`` onto the
    line clamped to the line's feasible segment (which gives the line-line and
    line-circle vertices); the closest feasible candidate is the solution, in
    :math:`O(m^2)`. If none is feasible (empty set), the fallback of the module
    docstring: the point of the disc with the smallest largest shortfall of the rows,
    measured after the rows are scaled to unit normals. Compiled kernel, no checks,
    allocation-free.

    Parameters
    ----------
    d0x, d0y : float
        The point :math:`\mathbf d_0` to project.
    a : ndarray, shape (m_max, 2)
        Row normals :math:`\mathbf a_k` (any length; the first ``m`` rows are used).
        **Scratch:** the first ``m`` rows of ``a`` and ``b`` are scaled in place to unit
        normals, which leaves the constraint set unchanged; a zero row gets ``b = -inf``.
    b : ndarray, shape (m_max,)
        Right-hand sides :math:`b_k`.
    m : int
        Number of rows used.
    vmax : float
        Disc radius :math:`v_\text{max} \ge 0`; ``math.inf`` for no disc.

    Returns
    -------
    dx, dy : float
        The solution (the fallback point when infeasible); never NaN for finite inputs,
        and within the disc.
    feasible : bool
        Whether the constraints have a common point (to a relative tolerance of 1e-10); a
        zero row with :math:`b_k > 0` makes them infeasible, and is ignored otherwise.
    """
    hopeless = False
    for k in range(m):
        norm = math.hypot(a[k, 0], a[k, 1])
        if norm > 0.0:
            a[k, 0] /= norm
            a[k, 1] /= norm
            b[k] /= norm
        else:
            hopeless = hopeless or b[k] > 0.0
            b[k] = -math.inf
    dx, dy, feasible = _solve_unit(d0x, d0y, a, b, m, vmax)
    return dx, dy, feasible and not hopeless


# ---------------------------------------------------------------------------------------
# The safety law: each UAV's rows, and the whole swarm's step
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _pair_rows(i, q, reach, sensing_radius, decay, vmax, a, b):
    """UAV i's rows for the sensed pairs, the pair row of the module docstring (unit
    normals); returns their number."""
    m = 0
    xi = q[i, 0]
    yi = q[i, 1]
    r2_max = sensing_radius * sensing_radius
    for j in range(q.shape[0]):
        px = xi - q[j, 0]
        py = yi - q[j, 1]
        r2 = px * px + py * py
        if j == i or r2 > r2_max:
            continue
        u = decay * (reach * reach - r2)  # -decay h
        r = math.sqrt(r2)
        t = u / (2.0 * (math.sqrt(r2 + u) + r))
        if t <= -vmax:
            continue  # every displacement within the speed limit satisfies it
        if r > 0.0:
            a[m, 0] = px / r
            a[m, 1] = py / r
        else:  # coincident: apart along +-x, by index
            a[m, 0] = 1.0 if i > j else -1.0
            a[m, 1] = 0.0
        b[m] = t
        m += 1
    return m


@njit(cache=True, error_model="numpy")
def _obstacle_rows(x, y, rects, circles, decay, margin, vmax, a, b, m):
    """Rows for the obstacles a UAV at (x, y) could reach within the step, after row m;
    returns the new number of rows."""
    for k in range(rects.shape[0] + circles.shape[0]):
        dist, ux, uy = obstacle_distance(x, y, rects, circles, k)
        rhs = -decay * (dist - margin)
        if rhs <= -vmax:
            continue  # every displacement within the speed limit satisfies it
        a[m, 0] = ux
        a[m, 1] = uy
        b[m] = rhs
        m += 1
    return m


@njit(cache=True, error_model="numpy")
def safe_displacement(
    i, q, d_nom, rects, circles, min_separation, sensing_radius, decay, pair_margin,
    obstacle_margin, vmax_step, a_work, b_work,
):  # fmt: skip
    r"""UAV ``i``'s safe displacement: the solution of its QP (module docstring).

    .. math::
        \min_{\mathbf d} \lVert\mathbf d - \mathbf d_i^\text{nom}\rVert^2 \ \text{s.t.}\
        \hat{\mathbf p}_{ij}\cdot\mathbf d \ge t(r_{ij})\ (r_{ij} \le R),\
        \mathbf n_o\cdot\mathbf d \ge -\gamma(c_o - m_o),\
        \lVert\mathbf d\rVert \le v_\text{max}\Delta T

    Compiled kernel, no checks, allocation-free: builds the rows into ``a_work`` and
    ``b_work`` and solves in closed form; the fallback when the rows conflict.

    Parameters
    ----------
    i : int
        The UAV.
    q : ndarray, shape (M, 2)
        Positions at this step, m.
    d_nom : ndarray, shape (M, 2)
        Nominal displacements of the step, m (only row ``i`` is read).
    rects : ndarray, shape (R, 4)
        Rectangles ``[x_min, x_max, y_min, y_max]``, m.
    circles : ndarray, shape (C, 3)
        Circles ``[x_center, y_center, radius]``, m.
    min_separation : float
        :math:`d_\text{min} > 0`, m.
    sensing_radius : float
        :math:`R`, m (may be ``math.inf``); at least :math:`d_\text{min} + m_p + 2
        v_\text{max}\Delta T` (:func:`safety_filter`).
    decay : float
        :math:`\gamma \in (0, 1]`.
    pair_margin, obstacle_margin : float
        :math:`m_p` and :math:`m_o`, m (:func:`disturbance_margins`).
    vmax_step : float
        :math:`v_\text{max}\Delta T`, m (may be ``math.inf``).
    a_work : ndarray, shape (n_rows, 2)
        Scratch, ``n_rows >= M - 1 + R + C``.
    b_work : ndarray, shape (n_rows,)
        Scratch.

    Returns
    -------
    dx, dy : float
        The displacement, m.
    """
    m = _rows(i, q, rects, circles, min_separation, sensing_radius, decay, pair_margin,
              obstacle_margin, vmax_step, a_work, b_work)  # fmt: skip
    dx, dy, _ = _solve_unit(d_nom[i, 0], d_nom[i, 1], a_work, b_work, m, vmax_step)
    return dx, dy


@njit(cache=True, inline="always")
def _rows(i, q, rects, circles, min_separation, sensing_radius, decay, pair_margin,
          obstacle_margin, vmax_step, a_work, b_work):  # fmt: skip
    """UAV ``i``'s rows (pairs, then obstacles) in ``a_work``, ``b_work``; their number."""
    reach = min_separation + pair_margin
    m = _pair_rows(i, q, reach, sensing_radius, decay, vmax_step, a_work, b_work)
    return _obstacle_rows(
        q[i, 0], q[i, 1], rects, circles, decay, obstacle_margin, vmax_step, a_work, b_work, m
    )


@njit(cache=True, error_model="numpy")
def safety_step(
    q, d_nom, out, rects, circles, min_separation, sensing_radius, decay, pair_margin,
    obstacle_margin, vmax_step, a_work, b_work, turn=0.0,
):  # fmt: skip
    r"""Every UAV's :func:`safe_displacement`, written to ``out`` (M, 2), with an optional
    way out of deadlocks.

    With ``turn`` :math:`\theta \ne 0`, a UAV whose safe displacement is *blocked*
    (advances along a nominal displacement of at least :data:`BLOCKED_MOVING` of the step's
    speed limit by less than :data:`BLOCKED_FRACTION` of what it could, the nominal's
    length capped at the speed limit) solves its QP again with the nominal turned by
    :math:`\theta` clockwise, to its right, and moves by that solution if it is the longer
    move: the
    "right-hand rule" that lets two UAVs that meet head-on, or a cluster that jams, slide
    past each other instead of waiting for the disturbance to free them (for ever without
    it). The solution is safe either way (the same rows); only the nominal changes.
    ``turn = 0`` (the default) is the plain QP of :func:`safety_filter`.

    Compiled kernel, no checks, allocation-free; ``out`` may be ``d_nom`` itself (each UAV
    reads only its own nominal displacement). The other arguments are those of
    :func:`safe_displacement` (``a_work`` with at least ``M - 1 + R + C`` rows; scratch,
    so one pair of work arrays per thread).
    """
    c, s = math.cos(turn), math.sin(turn)
    moving2 = (BLOCKED_MOVING * vmax_step) ** 2
    for i in range(q.shape[0]):
        m = _rows(i, q, rects, circles, min_separation, sensing_radius, decay, pair_margin,
                  obstacle_margin, vmax_step, a_work, b_work)  # fmt: skip
        nx, ny = d_nom[i, 0], d_nom[i, 1]
        dx, dy, _ = _solve_unit(nx, ny, a_work, b_work, m, vmax_step)
        if turn != 0.0:
            nom2 = nx * nx + ny * ny
            reach = min(math.sqrt(nom2), vmax_step)  # what the step could advance at most
            if nom2 >= moving2 and dx * nx + dy * ny < BLOCKED_FRACTION * reach * math.sqrt(nom2):
                tx, ty, _ = _solve_unit(c * nx + s * ny, c * ny - s * nx, a_work, b_work, m,
                                        vmax_step)  # fmt: skip
                if tx * tx + ty * ty > dx * dx + dy * dy:  # it does get the UAV moving
                    dx, dy = tx, ty
        out[i, 0] = dx
        out[i, 1] = dy


@njit(cache=True, error_model="numpy")
def _filter_batch(q, d_nom, out, rects, circles, sep, radius, decay, m_p, m_o, vmax, a, b):
    for k in range(q.shape[0]):
        safety_step(q[k], d_nom[k], out[k], rects, circles, sep, radius, decay, m_p, m_o,
                    vmax, a, b)  # fmt: skip


# ---------------------------------------------------------------------------------------
# Public functions (validated, any batch shape, inputs never modified)
# ---------------------------------------------------------------------------------------
def _decay(value: object) -> float:
    rate = _v.scalar(value, "decay")
    if not MIN_DECAY <= rate <= 1.0:
        raise FieldError(
            "decay",
            f"must lie in [{MIN_DECAY:g}, 1] (below, 1 - (1 - decay)^2 rounds to 0), got {rate!r}",
        )
    return rate


#: Smallest barrier decay rate (the margins divide by 1 - (1 - decay)^2).
MIN_DECAY = 1e-12

#: Largest margin in standard deviations of the disturbance.
MAX_N_SIGMA = 1e3


def _flat(arr: np.ndarray, batch: tuple[int, ...], tail: tuple[int, ...]) -> np.ndarray:
    """Broadcast ``arr`` to ``batch + tail`` and flatten the batch: a C-contiguous copy."""
    return np.array(np.broadcast_to(arr, (*batch, *tail)), order="C").reshape(-1, *tail)


def disturbance_margins(sigma: float, decay: float, n_sigma: float = 6.0) -> tuple[float, float]:
    r"""Margins that keep the barrier's boundary away from the disturbance.

    .. math::
        m_p = n_\sigma\,\frac{\sqrt2\,\sigma}{\sqrt{1 - (1-\gamma)^2}}, \qquad
        m_o = n_\sigma\,\frac{\sigma}{\sqrt{1 - (1-\gamma)^2}}

    With its barrier row active, the distance :math:`e_k` of a pair (or a UAV) to the
    boundary obeys :math:`e_{k+1} \ge (1-\gamma)e_k + w_k`, where :math:`w_k` is the
    disturbance projected on the normal: the difference of two UAVs' disturbances for a
    pair (standard deviation :math:`\sqrt2\sigma`), one UAV's for an obstacle
    (:math:`\sigma`). So :math:`e_k` stays above the AR(1) process :math:`X_{k+1} =
    (1-\gamma)X_k + w_k`, of stationary variance :math:`\operatorname{var}(w)/(1 -
    (1-\gamma)^2)`; a margin of :math:`n_\sigma` of its standard deviations is crossed
    with probability about :math:`\Phi(-n_\sigma)` per step. With :math:`\gamma = 1`:
    :math:`m_p = \sqrt2 n_\sigma\sigma`, :math:`m_o = n_\sigma\sigma`. (The disturbance is
    Gaussian, unbounded: the margins are probabilistic.)

    Parameters
    ----------
    sigma : float
        Disturbance :math:`\sigma` per axis and step, m, >= 0.
    decay : float
        Barrier decay rate :math:`\gamma \in (0, 1]`.
    n_sigma : float, default 6
        Standard deviations of margin, >= 0 (0: no margin).

    Returns
    -------
    pair_margin, obstacle_margin : float
        :math:`m_p` and :math:`m_o`, m.

    Examples
    --------
    >>> from crlbswarm.safety import disturbance_margins
    >>> [round(x, 6) for x in disturbance_margins(0.1, 1.0, n_sigma=3.0)]
    [0.424264, 0.3]
    """
    s = _v.scalar(sigma, "sigma")
    if s < 0:
        raise FieldError("sigma", f"must be >= 0, got {s!r}")
    rate = _decay(decay)
    k = _v.in_range(n_sigma, "n_sigma", 0.0, MAX_N_SIGMA)
    spread = s / math.sqrt(1.0 - (1.0 - rate) ** 2)
    pair, obstacle = k * math.sqrt(2.0) * spread, k * spread
    if not math.isfinite(pair):
        raise FieldError("sigma", f"{s:g} m is so large that the margins overflow")
    return pair, obstacle


def _sensing_radius(value: object, least: float) -> float:
    radius = _v.as_float_array(value, "sensing_radius")
    if radius.ndim != 0 or not radius > 0:  # NaN fails too; +inf (sense everyone) is fine
        raise FieldError("sensing_radius", f"expected a single number > 0, got {_v.short(value)}")
    if radius < least:
        raise FieldError(
            "sensing_radius",
            f"must be >= min_separation + pair_margin + 2 max_speed dt = {least:g} m (a pair "
            f"farther apart, unseen, could close the gap within one step), got {float(radius)!r}",
        )
    return float(radius)


def safety_filter(
    positions: ArrayLike,
    displacements: ArrayLike,
    obstacles: Obstacles | None = None,
    *,
    min_separation: float,
    max_speed: float,
    dt: float,
    sensing_radius: float,
    decay: float = 0.5,
    sigma: float = 0.0,
) -> np.ndarray:
    r"""The safe displacements: each UAV's nominal displacement made safe (module docstring).

    .. math::
        \mathbf d_i = \arg\min_{\mathbf d} \lVert\mathbf d - \mathbf d_i^\text{nom}\rVert^2
        \ \text{s.t.}\ \hat{\mathbf p}_{ij}\cdot\mathbf d \ge t(r_{ij})\
        (r_{ij} \le R),\ \mathbf n_o\cdot\mathbf d \ge -\gamma(c_o - m_o),\
        \lVert\mathbf d\rVert \le v_\text{max}\Delta T

    Each UAV uses the positions of the UAVs within ``sensing_radius`` and takes half of
    each pair's responsibility; the pairs' :math:`h = r^2 - (d_\text{min} + m_p)^2` and
    the obstacles' :math:`c - m_o` then decay by at most the factor :math:`1 - \gamma` per
    step (without disturbance; so a swarm that starts safe stays safe). When the
    disturbance has left no common solution, the fallback of the module docstring.

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        UAV positions, m.
    displacements : array_like, shape (..., M, 2)
        Nominal displacements of the step, m (batch broadcast against ``positions``).
    obstacles : Obstacles, optional
        Rectangles and circles (none by default).
    min_separation : float
        Smallest distance between two UAVs, :math:`d_\text{min}`, m, > 0.
    max_speed : float
        Largest speed :math:`v_\text{max}`, m/s, > 0.
    dt : float
        Time step :math:`\Delta T`, s, > 0.
    sensing_radius : float
        :math:`R`, m: a UAV senses the UAVs within it. At least :math:`d_\text{min} + m_p +
        2 v_\text{max}\Delta T` (a pair farther apart, unseen, could otherwise close the
        gap within one step); ``inf`` senses every UAV.
    decay : float, default 0.5
        Barrier decay rate :math:`\gamma \in (0, 1]` (1: the boundary may be reached in
        one step).
    sigma : float, default 0
        Disturbance per axis and step, m; sets the margins :math:`m_p, m_o` by
        :func:`disturbance_margins` (6 standard deviations).

    Returns
    -------
    ndarray, shape (..., M, 2)
        Safe displacements, m, each of length at most :math:`v_\text{max}\Delta T`.

    Examples
    --------
    Two UAVs 3 m apart heading at each other at 1 m per step, kept 2 m apart:

    >>> import numpy as np
    >>> from crlbswarm.safety import safety_filter
    >>> d = safety_filter([[0.0, 0.0], [3.0, 0.0]], [[1.0, 0.0], [-1.0, 0.0]],
    ...                   min_separation=2.0, max_speed=10.0, dt=0.1, sensing_radius=10.0,
    ...                   decay=1.0)
    >>> np.round(d, 6)
    array([[ 0.5,  0. ],
           [-0.5,  0. ]])
    """
    q = _v.coordinates(positions, "positions")
    d = _v.positions(displacements, "displacements")
    _v.bounded(d, "displacements", -_v.MAX_DISTANCE, _v.MAX_DISTANCE, " m")
    if d.shape[-2:] != q.shape[-2:]:
        raise FieldError(
            "displacements",
            f"expected shape (..., {q.shape[-2]}, 2) like positions, got {d.shape}",
        )
    batch = _v.broadcast("displacements", q.shape[:-2], d.shape[:-2])
    obs = Obstacles() if obstacles is None else check_obstacles(obstacles)
    sep = float(_v.length(_v.scalar(min_separation, "min_separation"), "min_separation"))
    speed = _v.positive_scalar(max_speed, "max_speed")
    _v.in_range(speed, "max_speed", 0.0, _v.MAX_SPEED, " m/s")
    step = _v.positive_scalar(dt, "dt")
    _v.in_range(step, "dt", 0.0, _v.MAX_TIME_STEP, " s")
    vmax = speed * step
    rate = _decay(decay)
    m_p, m_o = disturbance_margins(sigma, rate)
    radius = _sensing_radius(sensing_radius, sep + m_p + 2.0 * vmax)
    tail = q.shape[-2:]
    size = float(np.prod(batch, dtype=float)) * tail[0]
    _v.check_elements(2.0 * size, "positions", f"{size:.3g} UAV rows", copies=3)
    qb = _flat(q, batch, tail)
    out = _flat(d, batch, tail)  # a fresh copy, overwritten in place
    rows = tail[0] - 1 + obs.count
    a_work = np.empty((max(rows, 1), 2))
    b_work = np.empty(max(rows, 1))
    _filter_batch(
        qb, out, out, obs.rectangles, obs.circles, sep, radius, rate, m_p, m_o, vmax,
        a_work, b_work,
    )  # fmt: skip
    return out.reshape(*batch, *tail)


class SafetyConfig(ConfigModel):
    """Inter-UAV safety (not in the paper): a distributed safety filter on each UAV's
    commanded motion (:mod:`crlbswarm.safety`), and the separation every run is judged by."""

    enabled: bool = Field(True, description="false: no safety filter (the paper's controller)")
    min_separation: PositiveFloat = Field(
        1.0, description="smallest distance between two UAVs, m (a closer pass is a collision)"
    )
    max_speed: PositiveFloat = Field(
        5.0, description="largest speed of every UAV, m/s (at least control.cruise_speed)"
    )
    sensing_radius: PositiveFloat | None = Field(
        None,
        description="a UAV avoids the UAVs within this distance, m (default: 2 min_separation "
        "+ max(min_separation, pair margin) + 2 max_speed time.step)",
    )
    decay: Annotated[float, Field(gt=0, le=1)] = Field(
        0.5, description="rate of the barrier, in (0, 1]: the allowed approach per step"
    )
    noise_sigmas: Annotated[float, Field(ge=0, le=20)] = Field(
        6.0, description="margin kept against the motion disturbance, in its standard deviations"
    )

    def radius_for(self, dt: float, pair_margin: float = 0.0) -> float:
        r"""The sensing radius: as given, or its default for the time step ``dt``,
        :math:`2d_{\min} + \max(d_{\min}, m_p) + 2v_{\max}\Delta T` (:math:`3d_{\min} +
        2v_{\max}\Delta T` unless the pair margin is larger than :math:`d_{\min}`).

        Parameters
        ----------
        dt : float
            Time step, s.
        pair_margin : float, default 0
            The pair margin :math:`m_p` against the disturbance, m.

        Returns
        -------
        float
            Sensing radius, m.
        """
        if self.sensing_radius is not None:
            return self.sensing_radius
        d_min = self.min_separation
        return 2.0 * d_min + max(d_min, pair_margin) + 2.0 * self.max_speed * dt
