r"""The compiled mission: one step of the distributed controller, equation by equation.

Every law is called from the module that owns it, never re-written here: the control laws
from :mod:`crlbswarm.control`, the obstacle clearance from :mod:`crlbswarm.obstacles`, the
smallest separation from :mod:`crlbswarm.spatial`, the range model from
:mod:`crlbswarm.estimation` and the filter from :mod:`crlbswarm.tracking`. Per step
:math:`k` (all UAVs in parallel, each using only its neighbours' information, except two
formation-wide quantities: the scaling factor :math:`\eta_k`, global in the paper too, and
the formation centroid that the leader uses to steer the formation off obstacles):

0. :func:`sense_target`: with sensing in the loop, every ``measure_every`` steps the UAVs
   measure their ranges (eq. (2)) and the iterated EKF fuses them; the formation's goal is
   then the estimate instead of the true target (not in the paper);
1. the leader computes its reference velocity :math:`\mathbf v^*_k` toward its slot of
   :math:`F^*` over the target (:func:`crlbswarm.control.reference_velocity`), with the
   target's (estimated) velocity as feedforward;
2. :func:`control_step`: each UAV computes its formation input and obstacle repulsion,
   eqs. (18)-(19), and moves by the motion model of eq. (3); the cost of eq. (15) is
   recorded; the followers update their velocity estimates by the corrected consensus,
   eq. (14); :math:`\eta` steps toward the free-width rule at a limited rate;
3. the filter predicts the target state with its motion model.

The driver, :func:`crlbswarm.simulate`, prepares the arrays and calls :func:`run_batch`,
which runs the runs of a batch in parallel threads; each run uses only its own inputs, so
run :math:`b` is bit-identical to the single run with the same seed.

Adding a control law: call it in :func:`control_step`; its gains come with the
:class:`~crlbswarm.control.ControlGains` tuple.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ._validation import MAX_COORDINATE
from .control import (
    consensus_update,
    control_cost,
    eta_goal,
    eta_rate_limit,
    formation_update,
    motion_model,
    reference_velocity,
    route_eta_goal,
    route_point,
    travel_weight,
)
from .estimation import noisy_range
from .obstacles import clearance_at, repulsion_at
from .planning import best_waypoint, segment_clear
from .safety import UNBLOCK_TURN, safety_step
from .spatial import min_separation
from .tracking import filter_work, predict_into, update_into

__all__ = [
    "CARROT_BISECTIONS",
    "DIVERGENCE_LIMIT",
    "FILTER_ITERATIONS",
    "REPLAN_PERIOD",
    "GroupArrays",
    "GroupOutputs",
    "MissionConstants",
    "RunInputs",
    "RunOutputs",
    "SceneArrays",
    "carrot_point",
    "control_step",
    "leader_goal",
    "move_uavs",
    "passed_nodes",
    "run_batch",
    "run_group_batch",
    "run_groups",
    "run_mission",
    "sense_target",
    "steering_footprint",
]

#: A run whose UAV has a coordinate beyond this, m, or at NaN, diverged: it left the
#: model's range (every start and target lies inside it), where the CRLB is not computed.
DIVERGENCE_LIMIT = MAX_COORDINATE

#: Bisection steps of the carrot that would cut a corner (:func:`carrot_point`).
CARROT_BISECTIONS = 8

#: The route is re-planned from the formation's centre this often, s.
REPLAN_PERIOD = 0.5

#: Gauss-Newton iterations of the filter's range update.
FILTER_ITERATIONS = 3


class MissionConstants(NamedTuple):
    """Scalars of a mission derived from its scenario (the gains come separately).

    Parameters
    ----------
    dt : float
        Time step :math:`\\Delta T`, s.
    leader : int
        Index of the leader.
    radius : float
        Radius of :math:`F^*` around the target, m.
    altitude : float
        Flight altitude, m.
    snr_constant : float
        :math:`A` of the radar.
    measure_every : int
        Ranges are measured every this many steps.
    min_separation : float
        Its smallest distance between two UAVs, m.
    sensing_radius : float
        Its sensing radius, m.
    decay : float
        Its barrier rate.
    pair_margin : float
        Its margin between two UAVs against the disturbance, m.
    obstacle_margin : float
        Its margin from obstacles, m.
    vmax_step : float
        Largest displacement per step, ``max_speed * dt``, m.
    inflation : float
        The route's clearance from every obstacle, m.
    route_x : float
        The route's goal, x, m.
    route_y : float
        The route's goal, y, m.
    carrot : float
        How far ahead along the route the leader aims, m.
    replan_every : int
        The route is re-planned from the centre every this many steps.
    steer_radius : float
        :math:`l_\text{safe}` of the leader's steering (the repulsion felt by the
        formation's disc), m: ``Scenario.steering_radius``.
    centre_x : float
        Offset of the formation's centre (the mean of its slots) from the target, x, m:
        0 for a regular polygon; the slot offsets ``RunInputs.delta`` are taken from it.
    centre_y : float
        The same, y, m.
    """

    dt: float
    leader: int
    radius: float
    altitude: float
    snr_constant: float
    measure_every: int
    min_separation: float
    sensing_radius: float
    decay: float
    pair_margin: float
    obstacle_margin: float
    vmax_step: float
    inflation: float
    route_x: float
    route_y: float
    carrot: float
    replan_every: int
    steer_radius: float
    centre_x: float
    centre_y: float


class SceneArrays(NamedTuple):
    """Arrays shared by every run of a batch.

    Parameters
    ----------
    indptr : ndarray of int64, shape (M+1,)
        CSR row pointers of the communication graph.
    indices : ndarray of int64
        CSR neighbour indices.
    rects : ndarray, shape (R, 4)
        Rectangles.
    circles : ndarray, shape (C, 3)
        Circles.
    f_mat : ndarray, shape (n, n)
        Transition matrix of the target's motion model (n = 2 static, 4 moving).
    q_mat : ndarray, shape (n, n)
        Its process-noise covariance.
    p0 : ndarray, shape (n, n)
        Prior covariance of the filter.
    nodes : ndarray, shape (N, 2)
        Nodes of the route's roadmap, m (empty without the planner).
    node_dist : ndarray, shape (N,)
        Their distance to the route's goal along the roadmap, m.
    next_node : ndarray of int64, shape (N,)
        The next node toward the goal (-1 for the goal).
    """

    indptr: np.ndarray
    indices: np.ndarray
    rects: np.ndarray
    circles: np.ndarray
    f_mat: np.ndarray
    q_mat: np.ndarray
    p0: np.ndarray
    nodes: np.ndarray
    node_dist: np.ndarray
    next_node: np.ndarray


class RunInputs(NamedTuple):
    """The random inputs of one run (drawn by the driver from the run's seed).

    Parameters
    ----------
    noise : ndarray, shape (K, M, 2)
        Motion disturbance :math:`\\mathbf n_{m,k}`, m.
    range_noise : ndarray, shape (K+1, M)
        Standard normal draws of the range noise.
    target : ndarray, shape (K+1, 2)
        True target position, m.
    target_velocity : ndarray, shape (K+1, 2)
        True target velocity, m/s.
    x0 : ndarray, shape (n,)
        Prior mean of the filter.
    delta : ndarray, shape (M, 2)
        Each UAV's slot offset in :math:`F^*` from the formation's centre (the target for
        a regular polygon; ``MissionConstants.centre_x``), after the slot assignment, m.
    """

    noise: np.ndarray
    range_noise: np.ndarray
    target: np.ndarray
    target_velocity: np.ndarray
    x0: np.ndarray
    delta: np.ndarray


class RunOutputs(NamedTuple):
    """The arrays one run writes (``q[0]`` and ``eta[0]`` hold the start on entry).

    Parameters
    ----------
    q : ndarray, shape (K+1, M, 2)
        Positions, m.
    v : ndarray, shape (K+1, M, 2)
        Consensus velocities, m/s (``v[0]`` zero on entry).
    v_ref : ndarray, shape (K+1, 2)
        Leader's reference velocity, m/s.
    eta : ndarray, shape (K+1,)
        Scaling factor.
    clearance : ndarray, shape (K+1,)
        Smallest obstacle clearance, m.
    separation : ndarray, shape (K+1,)
        Smallest distance between two UAVs, m.
    cost : ndarray, shape (K,)
        Cost of eq. (15).
    estimate : ndarray, shape (K+1, 2)
        Filter estimate (sensing in the loop).
    estimate_variance : ndarray, shape (K+1,)
        Trace of its position covariance, m^2.
    distance_to_go : ndarray, shape (K+1,)
        Distance from the centroid to the target along the route, m.
    """

    q: np.ndarray
    v: np.ndarray
    v_ref: np.ndarray
    eta: np.ndarray
    clearance: np.ndarray
    separation: np.ndarray
    cost: np.ndarray
    estimate: np.ndarray
    estimate_variance: np.ndarray
    distance_to_go: np.ndarray


@njit(cache=True)
def sense_target(q, s_true, z, x, p_cov, ranges, const, work):
    """Step 0: the UAVs measure their ranges to the true target (eq. (2), the range model
    of :func:`crlbswarm.estimation.noisy_range`) and the filter fuses them in place
    (:func:`crlbswarm.tracking.update_into`, scratch ``work``). Returns ``(x, P)``."""
    h2 = const.altitude * const.altitude
    for m in range(q.shape[0]):
        dx = s_true[0] - q[m, 0]
        dy = s_true[1] - q[m, 1]
        ranges[m] = noisy_range(dx * dx + dy * dy + h2, const.snr_constant, z[m])
    update_into(x, p_cov, q, ranges, const.altitude, const.snr_constant, FILTER_ITERATIONS, work)
    return x, p_cov


@njit(cache=True)
def move_uavs(k, q, q_next, v, u, d_work, inp, scene, ctl, const, a_work, b_work, safe):
    """Step 2's motion, for every UAV of every group: the obstacle repulsion (eq. (18)) added
    to the formation input in ``u`` (eq. (19)), through the safety filter when it is on
    (across all UAVs), then the motion model of eq. (3) from ``q`` (step k) to ``q_next``.
    ``safe``: None without the safety filter (its code is then not compiled), else any
    array. Returns False if a position ran away."""
    dt = const.dt
    noise = inp.noise[k]
    for m in range(q.shape[0]):
        rx, ry = repulsion_at(
            q[m, 0], q[m, 1], scene.rects, scene.circles, ctl.repulsion_gain,
            ctl.safety_radius, ctl.repulsion_max_step,
        )  # fmt: skip
        if safe is not None:  # the nominal displacement, filtered below
            d_work[m, 0] = u[m, 0] + rx + v[m, 0] * dt
            d_work[m, 1] = u[m, 1] + ry + v[m, 1] * dt
        else:
            q_next[m, 0] = motion_model(q[m, 0], u[m, 0], rx, v[m, 0], dt, noise[m, 0])
            q_next[m, 1] = motion_model(q[m, 1], u[m, 1], ry, v[m, 1], dt, noise[m, 1])
    if safe is not None:
        safety_step(
            q, d_work, u, scene.rects, scene.circles, const.min_separation,
            const.sensing_radius, const.decay, const.pair_margin, const.obstacle_margin,
            const.vmax_step, a_work, b_work, UNBLOCK_TURN,
        )  # fmt: skip
        for m in range(q.shape[0]):  # eq. (3) with the safe displacement (in u) as the input
            q_next[m, 0] = motion_model(q[m, 0], u[m, 0], 0.0, 0.0, dt, noise[m, 0])
            q_next[m, 1] = motion_model(q[m, 1], u[m, 1], 0.0, 0.0, dt, noise[m, 1])
    for m in range(q.shape[0]):
        if not (abs(q_next[m, 0]) <= DIVERGENCE_LIMIT
                and abs(q_next[m, 1]) <= DIVERGENCE_LIMIT):  # fmt: skip
            return False
    return True


@njit(cache=True)
def control_step(k, q, q_next, v, v_next, vref, eta, u, d_work, cx, cy, sx, sy, node, out, inp,
                 scene, ctl, rule, const, a_work, b_work, safe, route):  # fmt: skip
    """Step 2 from ``q`` (step k) to ``q_next``: eqs. (19), (18) and (3) (through the safety
    filter when it is on, :func:`move_uavs`), the cost (15), the consensus (14) and the next
    eta (``safe``, ``route``: the feature markers of :func:`run_mission`). Returns False if
    a position ran away."""
    delta = inp.delta
    formation_update(q, delta, eta, ctl.epsilon, scene.indptr, scene.indices, u)
    if not move_uavs(k, q, q_next, v, u, d_work, inp, scene, ctl, const, a_work, b_work,
                     safe):  # fmt: skip
        return False
    out.cost[k] = control_cost(q, q_next, delta, vref, const.dt, scene.indptr, scene.indices)
    consensus_update(v, vref, const.leader, scene.indptr, scene.indices, ctl.gamma, v_next)
    if rule.enabled:  # along the route (the straight line to the target off the planner)
        if route is not None:
            goal = route_eta_goal(
                cx, cy, sx, sy, node, scene.nodes, scene.next_node, const.radius, scene.rects,
                scene.circles, rule.margin, rule.lookahead, rule.samples, rule.minimum, True,
            )  # fmt: skip
        else:
            goal = eta_goal(cx, cy, sx, sy, const.radius, scene.rects, scene.circles,
                            rule.margin, rule.lookahead, rule.samples, rule.minimum)  # fmt: skip
        out.eta[k + 1] = eta_rate_limit(eta, goal, rule.rate * const.dt)
    else:
        out.eta[k + 1] = 1.0
    return True


@njit(cache=True, inline="always")
def steering_footprint(eta, cx, cy, sx, sy, ctl, radius):
    """Radius of the formation's disc that the leader steers off obstacles: eta r* (``radius``
    r*) while travelling, fading to 0 over the target (:func:`crlbswarm.control.travel_weight`),
    so a formation whose slots are clear hovers exactly over the target; 0 without
    steering."""
    if not ctl.formation_steering:
        return 0.0
    return eta * radius * travel_weight(math.hypot(cx - sx, cy - sy), radius)


@njit(cache=True)
def leader_goal(cx, cy, sx, sy, tvx, tvy, scene, const, node, replan):
    """Step 1's goal for the formation's centre with the planner (without it the goal is the
    target itself, :func:`run_mission`): the target (``sx, sy``, moving at ``tvx, tvy``) in
    sight, or, while it is out of sight, the point ``const.carrot``
    ahead of the centre along the route (no feedforward; a carrot, so that the formation
    keeps moving when its centre cannot reach a node exactly). Returns ``(gx, gy, vx, vy,
    distance to go, node)``, node -1 on the last leg
    (:func:`crlbswarm.planning.best_waypoint`). The route is re-planned from the centre when
    ``replan`` (every ``const.replan_every`` steps); in between, the last ``node`` is kept."""
    if replan:
        k, togo = best_waypoint(
            cx, cy, scene.nodes, scene.node_dist, const.route_x, const.route_y, scene.rects,
            scene.circles, const.inflation,
        )  # fmt: skip
    else:
        k = node
        if k >= 0:
            togo = math.hypot(scene.nodes[k, 0] - cx, scene.nodes[k, 1] - cy)
            togo += scene.node_dist[k]
        else:
            togo = math.hypot(const.route_x - cx, const.route_y - cy)
    if k < 0 or togo <= const.carrot:  # the goal in sight or near: the last leg
        togo = togo if k >= -1 else math.hypot(cx - sx, cy - sy)  # (-2: no route, unexpected)
        return sx, sy, tvx, tvy, togo, -1
    k = passed_nodes(cx, cy, k, scene.nodes, scene.next_node, const.carrot)
    gx, gy = carrot_point(cx, cy, k, scene, const)
    return gx, gy, 0.0, 0.0, togo, k


@njit(cache=True)
def carrot_point(cx, cy, k, scene, const):
    """The point ``const.carrot`` ahead of the centre along the route through ``nodes[k]``,
    or, if the straight segment to it would pass within half the route's inflation of an
    obstacle (the carrot cutting a corner), the farthest point before it that does not
    (bisection, :data:`CARROT_BISECTIONS` steps): the leader never aims across a corner."""
    gx, gy, _, _ = route_point(cx, cy, k, scene.nodes, scene.next_node, const.carrot)
    keep = 0.5 * const.inflation
    if segment_clear(cx, cy, gx, gy, scene.rects, scene.circles, keep):
        return gx, gy
    lo, hi = 0.0, const.carrot
    for _ in range(CARROT_BISECTIONS):
        mid = 0.5 * (lo + hi)
        px, py, _, _ = route_point(cx, cy, k, scene.nodes, scene.next_node, mid)
        if segment_clear(cx, cy, px, py, scene.rects, scene.circles, keep):
            lo = mid
        else:
            hi = mid
    gx, gy, _, _ = route_point(cx, cy, k, scene.nodes, scene.next_node, lo)
    return gx, gy


@njit(cache=True)
def passed_nodes(cx, cy, k, nodes, next_node, reach):
    """The first node of the route from ``k`` on that the centre (cx, cy) has not passed: a
    node is passed when it lies within ``reach`` of the centre and behind it along the leg
    that leaves it (``(node - c) . (next - node) <= 0``). The route re-planned from a centre
    that hugs an inflated corner can start at the corner's node just behind it (the next
    node is not in sight at the full inflation); aiming through it would pull the centre
    back."""
    while next_node[k] >= 0:
        j = next_node[k]
        ax, ay = nodes[k, 0] - cx, nodes[k, 1] - cy
        if ax * ax + ay * ay > reach * reach:
            break
        if ax * (nodes[j, 0] - nodes[k, 0]) + ay * (nodes[j, 1] - nodes[k, 1]) > 0.0:
            break
        k = j
    return k


@njit(cache=True)
def run_mission(out, inp, scene, ctl, rule, const, safe, route, track):
    """One run from ``out.q[0]`` to the end of ``inp.noise``; returns -1, or the step at
    which a position ran away (NaN or beyond :data:`DIVERGENCE_LIMIT`).

    ``safe``, ``route`` and ``track`` switch the safety filter, the planner's route and the
    filter in the loop on (any array, e.g. ``np.empty(0)``) or off (``None``): Numba drops
    the code of a layer that is off, so a scenario compiles only what it uses (the paper's
    mission compiles none of the three)."""
    k_steps = inp.noise.shape[0]
    m_uavs = out.q.shape[1]
    leader = const.leader
    u = np.empty((m_uavs, 2))
    d_work = np.empty((m_uavs, 2))
    n_rows = m_uavs - 1 + scene.rects.shape[0] + scene.circles.shape[0]
    a_work = np.empty((max(n_rows, 1), 2))  # rows of the safety filter's QP
    b_work = np.empty(max(n_rows, 1))
    vref = np.empty(2)
    ranges = np.empty(m_uavs)
    node = -1  # the route's current node (re-planned every replan_every steps)
    x = inp.x0.copy()
    p_cov = scene.p0.copy()
    f_work = filter_work()
    moving = x.shape[0] == 4
    for k in range(k_steps + 1):
        q = out.q[k]
        eta = out.eta[k]
        # The formation's goal: the UAVs' own estimate of the target, or the truth.
        if track is not None:
            if k % const.measure_every == 0:
                x, p_cov = sense_target(q, inp.target[k], inp.range_noise[k], x, p_cov, ranges,
                                        const, f_work)  # fmt: skip
            sx, sy = x[0], x[1]
            tvx, tvy = (x[2], x[3]) if moving else (0.0, 0.0)
            out.estimate[k, 0] = sx
            out.estimate[k, 1] = sy
            out.estimate_variance[k] = p_cov[0, 0] + p_cov[1, 1]
        else:
            sx, sy = inp.target[k, 0], inp.target[k, 1]
            tvx, tvy = inp.target_velocity[k, 0], inp.target_velocity[k, 1]
        # The formation's centre over the goal (the target itself for a regular polygon).
        sx += const.centre_x
        sy += const.centre_y
        cx = 0.0
        cy = 0.0
        for m in range(m_uavs):
            cx += q[m, 0]
            cy += q[m, 1]
        cx /= m_uavs
        cy /= m_uavs
        # Step 1: the leader's reference velocity toward its slot over the goal.
        if route is not None:
            gx, gy, fvx, fvy, out.distance_to_go[k], node = leader_goal(
                cx, cy, sx, sy, tvx, tvy, scene, const, node, k % const.replan_every == 0
            )
            if k == 0 and rule.enabled:  # the formation forms at its goal's scale (the
                eta = route_eta_goal(  # paper's rule starts at 1)
                    cx, cy, sx, sy, node, scene.nodes, scene.next_node, const.radius,
                    scene.rects, scene.circles, rule.margin, rule.lookahead, rule.samples,
                    rule.minimum, True,
                )  # fmt: skip
                out.eta[0] = eta
        else:  # straight to the goal (the paper's guidance)
            gx, gy, fvx, fvy = sx, sy, tvx, tvy
            out.distance_to_go[k] = math.hypot(cx - sx, cy - sy)
        vref[0], vref[1] = reference_velocity(
            q[leader, 0], q[leader, 1], gx + eta * inp.delta[leader, 0],
            gy + eta * inp.delta[leader, 1], cx, cy, ctl.guidance_gain, ctl.cruise_speed,
            fvx, fvy, scene.rects, scene.circles, ctl.repulsion_gain, const.steer_radius,
            steering_footprint(eta, cx, cy, sx, sy, ctl, const.radius), const.dt,
        )  # fmt: skip
        out.v_ref[k, 0] = vref[0]
        out.v_ref[k, 1] = vref[1]
        out.v[k, leader, 0] = vref[0]
        out.v[k, leader, 1] = vref[1]
        clearance = math.inf
        for m in range(m_uavs):
            clearance = min(clearance, clearance_at(q[m, 0], q[m, 1], scene.rects, scene.circles))
        out.clearance[k] = clearance
        out.separation[k] = min_separation(q)
        if k == k_steps:
            break
        if not control_step(k, q, out.q[k + 1], out.v[k], out.v[k + 1], vref, eta, u, d_work,
                            cx, cy, sx, sy, node, out, inp, scene, ctl, rule, const, a_work,
                            b_work, safe, route):  # fmt: skip
            return k + 1
        if track is not None:  # Step 3: prediction with the target's motion model.
            predict_into(x, p_cov, scene.f_mat, scene.q_mat, f_work)
    return -1


@njit(cache=True, parallel=True)
def run_batch(outs, inps, status, scene, ctl, rule, const, safe, route, track):
    """Run every run of a batch in parallel threads (``outs``/``inps``: tuples of arrays
    with a leading run axis, in the field order of :class:`RunOutputs`/:class:`RunInputs`;
    ``safe``, ``route``, ``track``: the layers' markers of :func:`run_mission`);
    ``status[b]`` receives :func:`run_mission`'s result."""
    for b in prange(status.shape[0]):
        out = RunOutputs(
            outs[0][b], outs[1][b], outs[2][b], outs[3][b], outs[4][b], outs[5][b],
            outs[6][b], outs[7][b], outs[8][b], outs[9][b],
        )  # fmt: skip
        inp = RunInputs(inps[0][b], inps[1][b], inps[2][b], inps[3][b], inps[4][b], inps[5][b])
        status[b] = run_mission(out, inp, scene, ctl, rule, const, safe, route, track)


# ---------------------------------------------------------------------------------------
# Several targets: one formation per group, one motion step for all (issue 11, item 4)
# ---------------------------------------------------------------------------------------
class GroupArrays(NamedTuple):
    """The groups of a mission with several targets (:func:`crlbswarm.simulate_groups`): the UAVs
    are ordered so that group g is ``bounds[g] .. bounds[g+1] - 1``.

    Parameters
    ----------
    bounds : ndarray of int64, shape (G+1,)
        First UAV of each group, and M.
    leaders : ndarray of int64, shape (G,)
        Each group's leader, an index within the group.
    goals : ndarray, shape (G, 2)
        Each group's formation centre over its (static) target, m.
    radius : ndarray, shape (G,)
        Each group's formation radius about its centre, m.
    indptr : ndarray of int64
        The groups' CSR row pointers, each group's with local values from 0, concatenated.
    indices : ndarray of int64
        Their neighbour indices (local to each group), concatenated.
    ptr_off : ndarray of int64, shape (G+1,)
        Where each group's row pointers start in ``indptr``.
    idx_off : ndarray of int64, shape (G+1,)
        Where each group's neighbours start in ``indices``.
    """

    bounds: np.ndarray
    leaders: np.ndarray
    goals: np.ndarray
    radius: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    ptr_off: np.ndarray
    idx_off: np.ndarray


class GroupOutputs(NamedTuple):
    """The arrays one run with several groups writes (``q[0]`` and ``eta[0]`` hold the start
    on entry; ``v[0]`` zero).

    Parameters
    ----------
    q : ndarray, shape (K+1, M, 2)
        Positions, m (the UAVs in group order).
    v : ndarray, shape (K+1, M, 2)
        Consensus velocities, m/s.
    v_ref : ndarray, shape (K+1, G, 2)
        Each leader's reference velocity, m/s.
    eta : ndarray, shape (K+1, G)
        Each group's scaling factor.
    clearance : ndarray, shape (K+1, G)
        Each group's smallest obstacle clearance, m.
    separation : ndarray, shape (K+1,)
        Smallest distance between two UAVs of the swarm (all groups), m.
    cost : ndarray, shape (K, G)
        Each group's cost of eq. (15).
    distance_to_go : ndarray, shape (K+1, G)
        Distance from each group's centroid to its centre over the target, m.
    """

    q: np.ndarray
    v: np.ndarray
    v_ref: np.ndarray
    eta: np.ndarray
    clearance: np.ndarray
    separation: np.ndarray
    cost: np.ndarray
    distance_to_go: np.ndarray


@njit(cache=True)
def run_groups(out, inp, scene, ctl, rule, const, grp, safe):
    """One run of a swarm split into groups, each flying its own formation to its own static
    target with its own leader, as :func:`run_mission` flies one (the same laws, called per
    group on the group's UAVs and graph, without the planner and the filter), while the
    repulsion, the safety filter and the motion act on all UAVs at once (:func:`move_uavs`),
    so the safety filter keeps UAVs of different groups apart too. Returns -1, or the step
    at which a position ran away."""
    k_steps = inp.noise.shape[0]
    m_uavs = out.q.shape[1]
    n_groups = grp.leaders.shape[0]
    u = np.empty((m_uavs, 2))
    d_work = np.empty((m_uavs, 2))
    n_rows = m_uavs - 1 + scene.rects.shape[0] + scene.circles.shape[0]
    a_work = np.empty((max(n_rows, 1), 2))
    b_work = np.empty(max(n_rows, 1))
    vref = np.empty((n_groups, 2))
    centre = np.empty((n_groups, 2))
    delta = inp.delta
    for k in range(k_steps + 1):
        q = out.q[k]
        for g in range(n_groups):  # Step 1 per group: the leader's reference velocity.
            lo, hi = grp.bounds[g], grp.bounds[g + 1]
            cx = 0.0
            cy = 0.0
            for m in range(lo, hi):
                cx += q[m, 0]
                cy += q[m, 1]
            cx /= hi - lo
            cy /= hi - lo
            centre[g, 0] = cx
            centre[g, 1] = cy
            sx, sy = grp.goals[g, 0], grp.goals[g, 1]
            eta = out.eta[k, g]
            ld = lo + grp.leaders[g]
            out.distance_to_go[k, g] = math.hypot(cx - sx, cy - sy)
            vref[g, 0], vref[g, 1] = reference_velocity(
                q[ld, 0], q[ld, 1], sx + eta * delta[ld, 0], sy + eta * delta[ld, 1], cx, cy,
                ctl.guidance_gain, ctl.cruise_speed, 0.0, 0.0, scene.rects, scene.circles,
                ctl.repulsion_gain, const.steer_radius,
                steering_footprint(eta, cx, cy, sx, sy, ctl, grp.radius[g]), const.dt,
            )  # fmt: skip
            out.v_ref[k, g, 0] = vref[g, 0]
            out.v_ref[k, g, 1] = vref[g, 1]
            out.v[k, ld, 0] = vref[g, 0]
            out.v[k, ld, 1] = vref[g, 1]
            clearance = math.inf
            for m in range(lo, hi):
                clearance = min(
                    clearance, clearance_at(q[m, 0], q[m, 1], scene.rects, scene.circles)
                )
            out.clearance[k, g] = clearance
        out.separation[k] = min_separation(q)
        if k == k_steps:
            break
        for g in range(n_groups):  # eq. (19) per group, on its own graph
            lo, hi = grp.bounds[g], grp.bounds[g + 1]
            ip = grp.indptr[grp.ptr_off[g] : grp.ptr_off[g + 1]]
            ix = grp.indices[grp.idx_off[g] : grp.idx_off[g + 1]]
            formation_update(q[lo:hi], delta[lo:hi], out.eta[k, g], ctl.epsilon, ip, ix,
                             u[lo:hi])  # fmt: skip
        q_next = out.q[k + 1]
        if not move_uavs(k, q, q_next, out.v[k], u, d_work, inp, scene, ctl, const, a_work,
                         b_work, safe):  # fmt: skip
            return k + 1
        for g in range(n_groups):  # eqs. (15) and (14) and the next eta, per group
            lo, hi = grp.bounds[g], grp.bounds[g + 1]
            ip = grp.indptr[grp.ptr_off[g] : grp.ptr_off[g + 1]]
            ix = grp.indices[grp.idx_off[g] : grp.idx_off[g + 1]]
            out.cost[k, g] = control_cost(q[lo:hi], q_next[lo:hi], delta[lo:hi], vref[g],
                                          const.dt, ip, ix)  # fmt: skip
            consensus_update(out.v[k][lo:hi], vref[g], grp.leaders[g], ip, ix, ctl.gamma,
                             out.v[k + 1][lo:hi])  # fmt: skip
            eta = out.eta[k, g]
            if rule.enabled:
                goal = eta_goal(
                    centre[g, 0], centre[g, 1], grp.goals[g, 0], grp.goals[g, 1], grp.radius[g],
                    scene.rects, scene.circles, rule.margin, rule.lookahead, rule.samples,
                    rule.minimum,
                )  # fmt: skip
                out.eta[k + 1, g] = eta_rate_limit(eta, goal, rule.rate * const.dt)
            else:
                out.eta[k + 1, g] = 1.0
    return -1


@njit(cache=True, parallel=True)
def run_group_batch(outs, inps, status, scene, ctl, rule, const, grp, safe):
    """:func:`run_groups` for every run of a batch in parallel threads (``outs``/``inps``:
    tuples of arrays with a leading run axis, in the field order of
    :class:`GroupOutputs`/:class:`RunInputs`)."""
    for b in prange(status.shape[0]):
        out = GroupOutputs(
            outs[0][b], outs[1][b], outs[2][b], outs[3][b], outs[4][b], outs[5][b],
            outs[6][b], outs[7][b],
        )  # fmt: skip
        inp = RunInputs(inps[0][b], inps[1][b], inps[2][b], inps[3][b], inps[4][b], inps[5][b])
        status[b] = run_groups(out, inp, scene, ctl, rule, const, grp, safe)
