r"""The compiled mission: one step of the distributed controller, equation by equation.

Every law is called from the module that owns it, never re-written here: the control laws
from :mod:`crlbswarm.control`, the obstacle clearance from :mod:`crlbswarm.obstacles`, the
smallest separation from :mod:`crlbswarm.spatial`, the range model from
:mod:`crlbswarm.estimation` and the filter from :mod:`crlbswarm.tracking`. Per step
:math:`k` (all UAVs in parallel, each using only its neighbours' information, except two
formation-wide quantities: the scaling factor :math:`\eta_k`, global in the paper too, and
the formation centroid that the leader uses to steer the formation off obstacles):

0. :func:`step_state`: the state of step :math:`k`, its centroid and its FIM (eq. (9)) at
   the true target; :func:`sense_target`: with sensing in the loop, every
   ``measure_every`` steps the UAVs measure their ranges (eq. (2)) and the iterated EKF
   fuses them; the formation's goal is then the estimate instead of the true target (not
   in the paper);
1. :func:`leader_step`: the leader computes its reference velocity :math:`\mathbf v^*_k`
   toward its slot of :math:`F^*` over the target
   (:func:`crlbswarm.control.reference_velocity`), with the target's (estimated) velocity
   as feedforward;
2. :func:`input_block`: each UAV's obstacle clearance and repulsion (one pass, eq. (18))
   and formation input (eq. (19)); :func:`step_motion`: each UAV moves by the motion model
   of eq. (3) (through :func:`safe_displacement`, the safety filter, when it is on), the
   cost of eq. (15) is recorded, the followers update their velocity estimates by the
   corrected consensus, eq. (14); :func:`next_eta`: :math:`\eta` steps toward the
   free-width rule at a limited rate;
3. the filter predicts the target state with its motion model.

With communication links (the scenario's ``[links]`` table, :mod:`crlbswarm.links`), step
1 is followed by the messages of the step (:func:`crlbswarm.links.exchange`), and the
formation input and the consensus of step 2 read each UAV's neighbours from what it has
received (the laws' tables, :func:`crlbswarm.control.formation_rows`), each UAV at the
:math:`\eta` it knows; without the table the link layer is not compiled.

The per-UAV work is done in blocks of :data:`UAV_BLOCK` UAVs (:func:`state_block`,
:func:`input_block`, :func:`motion_block`, :func:`update_block`), on all threads for one
large swarm. The driver, :func:`crlbswarm.simulate`, prepares the inputs and calls
:func:`run_mission` for one run or :func:`run_batch`, which runs the runs of a batch in
parallel threads; each run uses only its own inputs and draws (counter-based,
:mod:`crlbswarm.counter_rng`), so run :math:`b` is bit-identical to the single run with the
same seed.

Adding a control law: call it in the block where its inputs are ready
(:func:`input_block` for a law on the positions of step :math:`k`, :func:`update_block`
for one on the next positions); its gains come with the
:class:`~crlbswarm.control.ControlGains` tuple.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ._numba import leaf
from ._validation import MAX_COORDINATE
from .control import (
    consensus_rows,
    consensus_update,
    control_cost,
    cost_rows,
    eta_goal,
    eta_rate_limit,
    formation_rows,
    formation_update,
    motion_model,
    reference_velocity,
    route_eta_goal,
    route_point,
    travel_weight,
)
from .counter_rng import DISTURBANCE, RANGE_NOISE, normal_pair
from .estimation import noisy_range
from .fisher import fim_entries_at, inverse_figures_at
from .links import exchange, neighbour_tables
from .obstacles import field_of
from .planning import best_waypoint, segment_clear
from .safety import UNBLOCK_TURN, safety_step
from .spatial import min_separation, min_separation_parallel, pair_separation
from .tracking import filter_work, predict_into, update_into

__all__ = [
    "CARROT_BISECTIONS",
    "DIVERGENCE_LIMIT",
    "FILTER_ITERATIONS",
    "REPLAN_PERIOD",
    "UAV_BLOCK",
    "UNPLANNED",
    "GroupArrays",
    "GroupOutputs",
    "MissionConstants",
    "RunInputs",
    "RunOutputs",
    "SceneArrays",
    "block_minimum",
    "block_sum",
    "carrot_point",
    "hold_frozen",
    "input_block",
    "leader_goal",
    "leader_step",
    "motion_block",
    "next_eta",
    "obstacle_pass",
    "passed_nodes",
    "reference_step",
    "run_batch",
    "run_group_batch",
    "run_groups",
    "run_mission",
    "safe_displacement",
    "sense_target",
    "separation_of",
    "state_block",
    "steering_footprint",
    "step_inputs",
    "step_motion",
    "step_state",
    "update_block",
]

#: The route's node of a leader that has planned none yet (at the start of a mission or a
#: phase, or a new leader of ``crlbswarm fly``): it plans at once.
UNPLANNED = -3

#: A run whose UAV has a coordinate beyond this, m, or at NaN, diverged: it left the
#: model's range (every start and target lies inside it), where the CRLB is not computed.
DIVERGENCE_LIMIT = MAX_COORDINATE

#: Bisection steps of the carrot that would cut a corner (:func:`carrot_point`).
CARROT_BISECTIONS = 8

#: The route is re-planned from the formation's centre this often, s.
REPLAN_PERIOD = 0.5

#: Gauss-Newton iterations of the filter's range update.
FILTER_ITERATIONS = 3

#: UAVs per block of the per-UAV work of a step (:func:`run_mission`): the unit of work of
#: a thread for one large swarm, and the unit of the partial sums (added in block order,
#: so the result does not depend on the threads).
UAV_BLOCK = 256


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
    sigma : float
        Standard deviation of the motion disturbance per axis and step, m.
    first_step : int
        The mission's step of the kernel's step 0: 0 for a mission, the start of a phase
        of a mission with faults (:mod:`crlbswarm.faults`), so that the route's
        re-planning keeps its rhythm and the formation takes its goal's scale only at the
        mission's start.
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
    sigma: float
    first_step: int


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
    snr : ndarray, shape (M,)
        Each UAV's :math:`A_m` of the radar (the FIM of eq. (9)).
    keep : ndarray of int64, shape (K+1,)
        The row of each step in the kept trajectories, -1 for a step not kept (from
        :func:`crlbswarm.results.kept_rows`).
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
    snr: np.ndarray
    keep: np.ndarray


class RunInputs(NamedTuple):
    """The inputs of one run (drawn by the driver from the run's seed; the disturbance and
    the range noise are drawn inside the kernel, :mod:`crlbswarm.counter_rng`).

    Parameters
    ----------
    start : ndarray, shape (M, 2)
        Start positions, m.
    keys : ndarray of int64, shape (4,)
        The Philox keys of the run's disturbance and range noise,
        :func:`crlbswarm.counter_rng.stream_key` of (seed, DISTURBANCE) then (seed,
        RANGE_NOISE).
    target : ndarray, shape (K+1, 2)
        True target position, m.
    target_velocity : ndarray, shape (K+1, 2)
        True target velocity, m/s.
    x0 : ndarray, shape (n,)
        Prior mean of the filter.
    delta : ndarray, shape (M, 2)
        Each UAV's slot offset in :math:`F^*` from the formation's centre (the target for
        a regular polygon; ``MissionConstants.centre_x``), after the slot assignment, m.
    ids : ndarray of int64, shape (M,)
        Each UAV's index in the swarm (the UAV word of its draws' counters).
    velocity : ndarray, shape (M, 2)
        Start consensus velocities, m/s (zeros at a mission's start; the velocities of the
        step a phase of a mission with faults resumes from, :mod:`crlbswarm.faults`).
    """

    start: np.ndarray
    keys: np.ndarray
    target: np.ndarray
    target_velocity: np.ndarray
    x0: np.ndarray
    delta: np.ndarray
    ids: np.ndarray
    velocity: np.ndarray


class RunOutputs(NamedTuple):
    """The arrays one run writes. K+1 rows: steps 0 .. K; the trajectories keep the rows
    of :func:`crlbswarm.results.kept_rows`.

    Parameters
    ----------
    q : ndarray, shape (R, M, 2)
        Positions at the kept steps, m (R = 0 when the trajectories are not kept).
    v : ndarray, shape (R, M, 2)
        Consensus velocities at the kept steps, m/s (the leader's is its reference).
    v_ref : ndarray, shape (K+1, 2)
        Leader's reference velocity, m/s.
    eta : ndarray, shape (K+1,)
        Scaling factor (``eta[0]`` holds the start on entry).
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
    centroid : ndarray, shape (K+1, 2)
        Centroid of the UAVs, m.
    fim : ndarray, shape (K+1, 3)
        FIM of the target position at the true target, eq. (9): ``J_xx, J_yy, J_xy``.
    crlb : ndarray, shape (K+1,)
        CRLB of that FIM, eq. (10), m^2 (:func:`crlbswarm.fisher.inverse_figures_at`).
    centroid_error : ndarray, shape (K+1,)
        Distance from the centroid to the formation's centre over the true target, m
        (``MissionResult.centroid_error``).
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
    centroid: np.ndarray
    fim: np.ndarray
    crlb: np.ndarray
    centroid_error: np.ndarray


@leaf
def keep_state(row, q, v, out_q, out_v):
    """Copy the positions and velocities into row ``row`` of the kept trajectories (none if
    ``row`` is negative: ``SceneArrays.keep``)."""
    if row < 0:
        return
    for m in range(q.shape[0]):
        out_q[row, m, 0] = q[m, 0]
        out_q[row, m, 1] = q[m, 1]
        out_v[row, m, 0] = v[m, 0]
        out_v[row, m, 1] = v[m, 1]


@njit(cache=True)
def sense_target(k, q, s_true, ranges, keys, ids, x, p_cov, const, work):
    """Step 0: the UAVs measure their ranges to the true target (eq. (2), the range model
    of :func:`crlbswarm.estimation.noisy_range`, its standard normal the first of the pair
    of counter ``(k, ids[m], RANGE_NOISE, 0)``) and the filter fuses them in place
    (:func:`crlbswarm.tracking.update_into`, scratch ``work``). Returns ``(x, P)``."""
    h2 = const.altitude * const.altitude
    for m in range(q.shape[0]):
        dx = s_true[0] - q[m, 0]
        dy = s_true[1] - q[m, 1]
        z, _ = normal_pair(keys[2], keys[3], k, ids[m], RANGE_NOISE, 0)
        ranges[m] = noisy_range(dx * dx + dy * dy + h2, const.snr_constant, z)
    update_into(x, p_cov, q, ranges, const.altitude, const.snr_constant, FILTER_ITERATIONS, work)
    return x, p_cov


@leaf
def obstacle_pass(q, rep, clear, rects, circles, index, ctl, lo, hi):
    """One pass over the obstacles near each UAV ``lo .. hi - 1`` at ``q``
    (:func:`crlbswarm.obstacles.field_of` on the index, or on every obstacle when ``index``
    is None): its repulsion of eq. (18) (into ``rep``) and its clearance (into ``clear``);
    returns the smallest clearance."""
    smallest = math.inf
    for m in range(lo, hi):
        clear[m], rep[m, 0], rep[m, 1] = field_of(
            q[m, 0], q[m, 1], rects, circles, index, ctl.repulsion_gain, ctl.safety_radius,
            ctl.repulsion_max_step,
        )  # fmt: skip
        smallest = min(smallest, clear[m])
    return smallest


@njit(cache=True)
def safe_displacement(q, v, u, rep, d_work, rects, circles, const, a_work, b_work):
    """The safety filter (:func:`crlbswarm.safety.safety_step`, across all UAVs) on the
    nominal displacements: the formation input ``u`` (eq. (19)) plus the repulsion ``rep``
    (eq. (18)) plus the consensus velocity times dT; the safe displacements replace ``u``."""
    dt = const.dt
    for m in range(q.shape[0]):
        d_work[m, 0] = u[m, 0] + rep[m, 0] + v[m, 0] * dt
        d_work[m, 1] = u[m, 1] + rep[m, 1] + v[m, 1] * dt
    safety_step(
        q, d_work, u, rects, circles, const.min_separation, const.sensing_radius, const.decay,
        const.pair_margin, const.obstacle_margin, const.vmax_step, a_work, b_work,
        UNBLOCK_TURN,
    )  # fmt: skip


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


@leaf
def state_block(b, lo, hi, shift, q, q_next, v, v_next, tx, ty, altitude, snr, part):
    """Start of a step for the UAVs ``lo .. hi - 1`` (block ``b``): take the state of the
    step (``shift``: copy it from ``q_next``, ``v_next``), and write the block's sums of
    the positions and of the FIM terms at the true target (tx, ty) (eq. (9),
    :func:`crlbswarm.fisher.fim_entries_at`) into ``part[b, 0:5]``."""
    if shift:
        for m in range(lo, hi):
            q[m, 0] = q_next[m, 0]
            q[m, 1] = q_next[m, 1]
            v[m, 0] = v_next[m, 0]
            v[m, 1] = v_next[m, 1]
    cx = 0.0
    cy = 0.0
    for m in range(lo, hi):
        cx += q[m, 0]
        cy += q[m, 1]
    part[b, 0] = cx
    part[b, 1] = cy
    part[b, 2], part[b, 3], part[b, 4] = fim_entries_at(q[lo:hi], tx, ty, altitude, snr[lo:hi])


@leaf
def input_block(b, lo, hi, q, delta, eta, etas, u, rep, clear, rects, circles, index, indptr,
                indices, lookup, tab, ctl, part):  # fmt: skip
    """The inputs of the UAVs ``lo .. hi - 1`` (block ``b``): one pass over the obstacles
    for each (its repulsion of eq. (18) into ``rep``, its clearance into ``clear``, the
    block's smallest into ``part[b, 5]``) and the formation input of eq. (19) into ``u``,
    each UAV's neighbours (CSR ``indptr``, ``indices``) at the positions ``tab[lookup[j]]``
    (:func:`crlbswarm.control.formation_rows`), all at the scale ``eta``, or, with links
    (``etas`` not None), each UAV at the scale it knows, ``etas[m]``."""
    part[b, 5] = obstacle_pass(q, rep, clear, rects, circles, index, ctl, lo, hi)
    if etas is None:
        formation_rows(q, delta, eta, ctl.epsilon, tab, lookup, indptr, indices, u, lo, hi)
    else:
        formation_rows(q, delta, etas, ctl.epsilon, tab, lookup, indptr, indices, u, lo, hi)


@leaf
def motion_block(b, lo, hi, k, q, q_next, v, u, rep, keys, ids, const, filtered, part):
    """Eq. (3) for the UAVs ``lo .. hi - 1`` (block ``b``) from ``q`` (step k) to
    ``q_next``, with the disturbance ``sigma`` times the pair of counter ``(k, ids[m],
    DISTURBANCE, 0)``: the input ``u`` (eq. (19)) plus ``rep`` (eq. (18)) plus the
    consensus velocity, or, ``filtered``, the safety filter's displacement in ``u`` alone.
    ``part[b, 6]`` is 1 if a position ran away, else 0."""
    dt = const.dt
    sigma = const.sigma
    bad = 0.0
    for m in range(lo, hi):
        n0, n1 = normal_pair(keys[0], keys[1], k, ids[m], DISTURBANCE, 0)
        if filtered:
            q_next[m, 0] = motion_model(q[m, 0], u[m, 0], 0.0, 0.0, dt, sigma * n0)
            q_next[m, 1] = motion_model(q[m, 1], u[m, 1], 0.0, 0.0, dt, sigma * n1)
        else:
            q_next[m, 0] = motion_model(q[m, 0], u[m, 0], rep[m, 0], v[m, 0], dt, sigma * n0)
            q_next[m, 1] = motion_model(q[m, 1], u[m, 1], rep[m, 1], v[m, 1], dt, sigma * n1)
        if not (abs(q_next[m, 0]) <= DIVERGENCE_LIMIT
                and abs(q_next[m, 1]) <= DIVERGENCE_LIMIT):  # fmt: skip
            bad = 1.0
    part[b, 6] = bad


@leaf
def update_block(b, lo, hi, q, q_next, v, v_next, delta, vref, leader, indptr, indices, n_ptr,
                 lookup, tab, ctl, dt, part):  # fmt: skip
    """After the motion, for the UAVs ``lo .. hi - 1`` (block ``b``): their terms of the
    cost of eq. (15) into ``part[b, 7]`` (the true positions, the graph ``indptr``,
    ``indices``) and the consensus of eq. (14) into ``v_next``, each UAV's neighbours (row
    pointers ``n_ptr``) at the velocities ``tab[lookup[j]]``
    (:func:`crlbswarm.control.consensus_rows`)."""
    part[b, 7] = cost_rows(q, q_next, delta, vref, dt, indptr, indices, lo, hi)
    consensus_rows(v, vref, leader, tab, lookup, n_ptr, ctl.gamma, v_next, lo, hi)


@njit(cache=True, parallel=True)
def _state_blocks(n_uavs, shift, q, q_next, v, v_next, tx, ty, altitude, snr, part):
    for b in prange(part.shape[0]):
        lo = b * UAV_BLOCK
        state_block(b, lo, min(lo + UAV_BLOCK, n_uavs), shift, q, q_next, v, v_next, tx, ty,
                    altitude, snr, part)  # fmt: skip


@njit(cache=True, parallel=True)
def _input_blocks(n_uavs, q, delta, eta, etas, u, rep, clear, rects, circles, index, indptr,
                  indices, lookup, tab, ctl, part):  # fmt: skip
    for b in prange(part.shape[0]):
        lo = b * UAV_BLOCK
        input_block(b, lo, min(lo + UAV_BLOCK, n_uavs), q, delta, eta, etas, u, rep, clear,
                    rects, circles, index, indptr, indices, lookup, tab, ctl, part)  # fmt: skip


@njit(cache=True, parallel=True)
def _motion_blocks(n_uavs, k, q, q_next, v, u, rep, keys, ids, const, filtered, part):
    for b in prange(part.shape[0]):
        lo = b * UAV_BLOCK
        motion_block(b, lo, min(lo + UAV_BLOCK, n_uavs), k, q, q_next, v, u, rep, keys, ids,
                     const, filtered, part)  # fmt: skip


@njit(cache=True, parallel=True)
def _update_blocks(n_uavs, q, q_next, v, v_next, delta, vref, leader, indptr, indices, n_ptr,
                   lookup, tab, ctl, dt, part):  # fmt: skip
    for b in prange(part.shape[0]):
        lo = b * UAV_BLOCK
        update_block(b, lo, min(lo + UAV_BLOCK, n_uavs), q, q_next, v, v_next, delta, vref,
                     leader, indptr, indices, n_ptr, lookup, tab, ctl, dt, part)  # fmt: skip


@leaf
def leader_step(k, q, v, vref, cx, cy, sx, sy, tvx, tvy, eta, node, rects, circles, delta, scene,
                index, ctl, rule, const, out, route):  # fmt: skip
    """Step 1: the leader's reference velocity toward its slot over the goal (sx, sy)
    (moving at tvx, tvy), into ``vref``, ``out.v_ref[k]`` and the leader's row of ``v``;
    the distance to go into ``out.distance_to_go[k]``. With the route (``route`` not None)
    the goal is the point ahead on it (:func:`leader_goal`) and at step 0 the formation
    takes its goal's scale. Returns ``(eta, node)``."""
    leader = const.leader
    if route is not None:
        step = k + const.first_step  # (the mission's step)
        replan = node == UNPLANNED or step % const.replan_every == 0
        gx, gy, fvx, fvy, togo, node = leader_goal(
            cx, cy, sx, sy, tvx, tvy, scene, const, node, replan
        )  # fmt: skip
        out.distance_to_go[k] = togo
        if step == 0 and rule.enabled:  # the formation forms at its goal's scale (the paper's
            eta = route_eta_goal(  # rule starts at 1)
                cx, cy, sx, sy, node, scene.nodes, scene.next_node, const.radius, rects,
                circles, index,
                rule.margin, rule.lookahead, rule.samples, rule.minimum, True,
            )  # fmt: skip
            out.eta[0] = eta
    else:  # straight to the goal (the paper's guidance)
        gx, gy, fvx, fvy = sx, sy, tvx, tvy
        out.distance_to_go[k] = math.hypot(cx - sx, cy - sy)
    vref[0], vref[1] = reference_velocity(
        q[leader, 0], q[leader, 1], gx + eta * delta[leader, 0], gy + eta * delta[leader, 1],
        cx, cy, ctl.guidance_gain, ctl.cruise_speed, fvx, fvy, rects, circles,
        ctl.repulsion_gain, const.steer_radius,
        steering_footprint(eta, cx, cy, sx, sy, ctl, const.radius), const.dt,
    )  # fmt: skip
    out.v_ref[k, 0] = vref[0]
    out.v_ref[k, 1] = vref[1]
    v[leader, 0] = vref[0]
    v[leader, 1] = vref[1]
    return eta, node


@leaf
def next_eta(cx, cy, sx, sy, eta, node, rects, circles, index, scene, rule, const, route,
             frozen):  # fmt: skip
    """The next step's scaling factor: the eta rule's goal along the route (the straight
    line to the goal (sx, sy) without the planner), approached at the rule's rate; 1 with
    the rule off; ``eta`` itself while the leader, which computes it, is lost (``frozen``,
    :func:`run_mission`)."""
    if frozen is not None and frozen[const.leader] != 0:
        return eta
    if not rule.enabled:
        return 1.0
    if route is not None:
        goal = route_eta_goal(
            cx, cy, sx, sy, node, scene.nodes, scene.next_node, const.radius, rects, circles,
            index, rule.margin, rule.lookahead, rule.samples, rule.minimum, True,
        )  # fmt: skip
    else:
        goal = eta_goal(cx, cy, sx, sy, const.radius, rects, circles, index, rule.margin,
                        rule.lookahead, rule.samples, rule.minimum)  # fmt: skip
    return eta_rate_limit(eta, goal, rule.rate * const.dt)


@njit(cache=True)
def separation_of(q, wide, crowd):
    """The smallest distance between two UAVs: every pair (``crowd`` None: few UAVs; the
    cell list is then not compiled), the cell list (:func:`crlbswarm.spatial.min_separation`),
    or its search on all threads (``wide``)."""
    if wide is not None:
        return min_separation_parallel(q)
    if crowd is not None:
        return min_separation(q)
    return pair_separation(q)


@leaf
def block_sum(part, column):
    """The sum of ``part[:, column]`` in block order (the same bits whatever the threads)."""
    total = 0.0
    for b in range(part.shape[0]):
        total += part[b, column]
    return total


@leaf
def block_minimum(part, column):
    """The smallest value of ``part[:, column]`` (over the blocks)."""
    best = math.inf
    for b in range(part.shape[0]):
        best = min(best, part[b, column])
    return best


@njit(cache=True, inline="always")
def step_state(k, q, q_next, v, v_next, tx, ty, snr, part, const, out_centroid, out_fim,
               out_crlb, out_centroid_error, wide):  # fmt: skip
    """:func:`state_block` on every block (on all threads with ``wide``), then the blocks'
    sums in block order: the centroid (written to ``out_centroid[k]`` and returned) and the
    FIM (``out_fim[k]``); then the step's metrics: the CRLB of eq. (10) (``out_crlb[k]``)
    and the centroid's distance to the formation's centre over the true target
    (``out_centroid_error[k]``)."""
    altitude = const.altitude
    m_uavs = q.shape[0]
    n_blocks = part.shape[0]
    if wide is not None:
        _state_blocks(m_uavs, k > 0, q, q_next, v, v_next, tx, ty, altitude, snr, part)
    else:
        for b in range(n_blocks):
            lo = b * UAV_BLOCK
            state_block(b, lo, min(lo + UAV_BLOCK, m_uavs), k > 0, q, q_next, v, v_next, tx,
                        ty, altitude, snr, part)  # fmt: skip
    out_fim[k, 0] = block_sum(part, 2)
    out_fim[k, 1] = block_sum(part, 3)
    out_fim[k, 2] = block_sum(part, 4)
    cx = out_centroid[k, 0] = block_sum(part, 0) / m_uavs
    cy = out_centroid[k, 1] = block_sum(part, 1) / m_uavs
    out_crlb[k] = inverse_figures_at(out_fim[k, 0], out_fim[k, 1], out_fim[k, 2])[0]
    out_centroid_error[k] = math.hypot(cx - tx - const.centre_x, cy - ty - const.centre_y)
    return cx, cy


@njit(cache=True, inline="always")
def step_inputs(q, delta, eta, etas, u, rep, clear, rects, circles, index, indptr, indices,
                lookup, tab, ctl, part, wide):  # fmt: skip
    """:func:`input_block` on every block (on all threads with ``wide``); returns the
    smallest clearance of the step."""
    m_uavs = q.shape[0]
    if wide is not None:
        _input_blocks(m_uavs, q, delta, eta, etas, u, rep, clear, rects, circles, index, indptr,
                      indices, lookup, tab, ctl, part)  # fmt: skip
    else:
        for b in range(part.shape[0]):
            lo = b * UAV_BLOCK
            input_block(b, lo, min(lo + UAV_BLOCK, m_uavs), q, delta, eta, etas, u, rep, clear,
                        rects, circles, index, indptr, indices, lookup, tab, ctl,
                        part)  # fmt: skip
    return block_minimum(part, 5)


@njit(cache=True, inline="always")
def step_motion(k, q, q_next, v, v_next, u, rep, delta, vref, keys, ids, indptr, indices, n_ptr,
                lookup, v_tab, ctl, const, filtered, part, out_cost, wide):  # fmt: skip
    """:func:`motion_block` then :func:`update_block` (the consensus on the neighbours'
    velocities ``v_tab[lookup[j]]``, rows ``n_ptr``) on every block (on all threads with
    ``wide``), then the cost of eq. (15) (the blocks' sums in block order) into
    ``out_cost[k]``. Returns False if a position ran away."""
    m_uavs = q.shape[0]
    n_blocks = part.shape[0]
    dt = const.dt
    leader = const.leader
    if wide is not None:
        _motion_blocks(m_uavs, k, q, q_next, v, u, rep, keys, ids, const, filtered, part)
        _update_blocks(m_uavs, q, q_next, v, v_next, delta, vref, leader, indptr, indices,
                       n_ptr, lookup, v_tab, ctl, dt, part)  # fmt: skip
    else:
        for b in range(n_blocks):
            lo = b * UAV_BLOCK
            motion_block(b, lo, min(lo + UAV_BLOCK, m_uavs), k, q, q_next, v, u, rep, keys, ids,
                         const, filtered, part)  # fmt: skip
        for b in range(n_blocks):
            lo = b * UAV_BLOCK
            update_block(b, lo, min(lo + UAV_BLOCK, m_uavs), q, q_next, v, v_next, delta, vref,
                         leader, indptr, indices, n_ptr, lookup, v_tab, ctl, dt,
                         part)  # fmt: skip
    cost = 0.0
    for b in range(n_blocks):
        if part[b, 6] != 0.0:
            return False
        cost += part[b, 7]
    out_cost[k] = cost
    return True


@njit(cache=True)
def run_mission(out, inp, scene, index, ctl, rule, const, safe, route, track, wide, crowd, links,
                lio, frozen):  # fmt: skip
    """One run from ``inp.start`` for ``inp.target.shape[0] - 1`` steps; returns -1, or the
    step at which a position ran away (NaN or beyond :data:`DIVERGENCE_LIMIT`).

    ``index`` is the obstacles' index (:func:`crlbswarm.obstacles.obstacle_index`, reach
    ``control.safety_radius``; an argument of its own, not a field of ``scene``: Numba's
    parallel loops do not take a tuple of arrays inside a tuple): with it the obstacle work
    of a UAV or of a sample of the eta rule depends on the obstacles near it, not on their
    number; None for a few obstacles (a loop over them; the grid's code is not compiled).
    ``safe``, ``route`` and ``track`` switch the safety filter, the planner's route
    and the filter in the loop on (any array, e.g. ``np.empty(0)``) or off (``None``): Numba drops
    the code of a layer that is off, so a scenario compiles only what it uses (the paper's
    mission compiles none of the three). ``crowd`` (an array, or None for at most
    :data:`crlbswarm.spatial.SEPARATION_BRUTE_FORCE_MAX` UAVs) selects the cell list for
    the smallest separation instead of every pair. ``wide`` (an array, or None) runs the per-UAV
    work of each step on all threads, in blocks of :data:`UAV_BLOCK` UAVs (for one large
    swarm). The per-UAV work is done block by block either way and the blocks' partial
    sums are added in block order, so the results do not depend on ``wide`` or the
    threads, bit for bit.

    ``links`` is the link model (:class:`crlbswarm.links.LinkModel`) and ``lio`` the run's
    link inputs and outputs (its Philox key of the stream LINKS, shape (2,), and its
    :data:`crlbswarm.links.LINK_SERIES`, shape (K+1, 5)), or both None for perfect links:
    the laws then read the neighbours' states of the step itself, and the link layer is
    not compiled. With links, every step exchanges the messages
    (:func:`crlbswarm.links.exchange`) after the leader's step, and the laws read what
    each UAV received (:class:`crlbswarm.links.LinkState`), each UAV at its own eta.

    ``frozen`` (an int8 array, shape (M,), or None) marks the UAVs that are lost but not yet
    declared lost (:mod:`crlbswarm.faults`): a frozen UAV does not move (its position and
    velocity stay those ``inp`` starts from) and, when it is the leader, computes no
    reference (``vref`` and eta keep their last values). The driver also takes a frozen
    UAV out of the graph and of the FIM (``scene``), so its neighbours no longer hear it.

    The state of the step lives in work arrays of shape (M, 2); the trajectories are
    copied out at the kept steps only, so the memory does not grow with the mission's
    length. The arrays are taken out of their tuples once, before the loop, and no view is
    made in it but one per block: each costs atomic reference counts."""
    k_steps = inp.target.shape[0] - 1
    m_uavs = inp.start.shape[0]
    rects, circles, indptr, indices = scene.rects, scene.circles, scene.indptr, scene.indices
    snr, keep = scene.snr, scene.keep
    keys, ids, delta = inp.keys, inp.ids, inp.delta
    target, target_velocity = inp.target, inp.target_velocity
    out_q, out_v, out_eta, out_fim, out_cost = out.q, out.v, out.eta, out.fim, out.cost
    out_centroid, out_clear, out_sep = out.centroid, out.clearance, out.separation
    out_crlb, out_centroid_error = out.crlb, out.centroid_error
    q, v = inp.start.copy(), inp.velocity.copy()
    q_next, v_next, u = np.empty((m_uavs, 2)), np.empty((m_uavs, 2)), np.empty((m_uavs, 2))
    rep, d_work, clear = np.empty((m_uavs, 2)), np.empty((m_uavs, 2)), np.empty(m_uavs)
    n_blocks = (m_uavs + UAV_BLOCK - 1) // UAV_BLOCK
    part = np.zeros((n_blocks, 8))  # each block's partial sums (state_block, ...)
    n_rows = m_uavs - 1 + rects.shape[0] + circles.shape[0]
    a_work = np.empty((max(n_rows, 1), 2))  # rows of the safety filter's QP
    b_work = np.empty(max(n_rows, 1))
    vref = v[const.leader].copy()  # (a lost leader's last reference: where it resumes)
    ranges = np.empty(m_uavs)
    node = UNPLANNED  # the route's current node (re-planned every replan_every steps)
    x = inp.x0.copy()
    p_cov = scene.p0.copy()
    f_work = filter_work()
    moving = x.shape[0] == 4
    # The neighbours the laws read (CSR rows, senders, rows of the tables) and the tables:
    # the state of the step itself (perfect links), or what each UAV received.
    st, n_ptr, n_idx, n_look, q_tab, v_tab, etas, l_key0, l_key1, l_series = neighbour_tables(
        links, lio, m_uavs, indptr, indices, q, v
    )
    for k in range(k_steps + 1):
        eta = out_eta[k]
        # The state of step k, the centroid, the FIM at the true target (eq. (9)), the CRLB.
        tx, ty = target[k, 0], target[k, 1]
        cx, cy = step_state(k, q, q_next, v, v_next, tx, ty, snr, part, const, out_centroid,
                            out_fim, out_crlb, out_centroid_error, wide)  # fmt: skip
        # The formation's goal: the UAVs' own estimate of the target, or the truth.
        if track is not None:
            if k % const.measure_every == 0:
                x, p_cov = sense_target(k, q, target[k], ranges, keys, ids, x, p_cov, const,
                                        f_work)  # fmt: skip
            sx, sy = x[0], x[1]
            tvx, tvy = (x[2], x[3]) if moving else (0.0, 0.0)
            out.estimate[k, 0] = sx
            out.estimate[k, 1] = sy
            out.estimate_variance[k] = p_cov[0, 0] + p_cov[1, 1]
        else:
            sx, sy = tx, ty
            tvx, tvy = target_velocity[k, 0], target_velocity[k, 1]
        # The formation's centre over the goal (the target itself for a regular polygon).
        sx += const.centre_x
        sy += const.centre_y
        # Step 1: the leader's reference velocity toward its slot over the goal.
        eta, node = reference_step(k, q, v, vref, cx, cy, sx, sy, tvx, tvy, eta, node, rects,
                                   circles, delta, scene, index, ctl, rule, const, out, route,
                                   frozen)  # fmt: skip
        if links is not None:  # the messages of the step
            exchange(k, q, v, eta, const.leader, l_key0, l_key1, links, st, l_series)
        keep_state(keep[k], q, v, out_q, out_v)
        # One pass over the obstacles per UAV (its clearance and the repulsion of eq. (18))
        # and the formation input of eq. (19).
        out_clear[k] = step_inputs(q, delta, eta, etas, u, rep, clear, rects, circles, index,
                                   n_ptr, n_idx, n_look, q_tab, ctl, part, wide)  # fmt: skip
        out_sep[k] = separation_of(q, wide, crowd)
        if k == k_steps:
            break
        # Step 2: the motion of eq. (3) (through the safety filter when it is on), the cost
        # of eq. (15), the consensus of eq. (14), the next eta.
        if safe is not None:
            safe_displacement(q, v, u, rep, d_work, rects, circles, const, a_work, b_work)
        if not step_motion(k, q, q_next, v, v_next, u, rep, delta, vref, keys, ids, indptr,
                           indices, n_ptr, n_look, v_tab, ctl, const, safe is not None, part,
                           out_cost, wide):  # fmt: skip
            return k + 1
        hold_frozen(frozen, q, q_next, v, v_next)
        out_eta[k + 1] = next_eta(cx, cy, sx, sy, eta, node, rects, circles, index, scene, rule,
                                  const, route, frozen)  # fmt: skip
        if track is not None:  # Step 3: prediction with the target's motion model.
            predict_into(x, p_cov, scene.f_mat, scene.q_mat, f_work)
    return -1


@njit(cache=True, inline="always")
def reference_step(k, q, v, vref, cx, cy, sx, sy, tvx, tvy, eta, node, rects, circles, delta,
                   scene, index, ctl, rule, const, out, route, frozen):  # fmt: skip
    """Step 1: :func:`leader_step`, or, when the leader is lost (``frozen``,
    :func:`run_mission`), its last reference ``vref`` kept (into ``out.v_ref[k]``; the
    distance to go the straight line to the goal (sx, sy)). Returns ``(eta, node)``."""
    if frozen is not None and frozen[const.leader] != 0:
        out.v_ref[k, 0] = vref[0]
        out.v_ref[k, 1] = vref[1]
        out.distance_to_go[k] = math.hypot(cx - sx, cy - sy)
        return eta, node
    return leader_step(k, q, v, vref, cx, cy, sx, sy, tvx, tvy, eta, node, rects, circles,
                       delta, scene, index, ctl, rule, const, out, route)  # fmt: skip


@leaf
def hold_frozen(frozen, q, q_next, v, v_next):
    """A frozen UAV (``frozen[m] != 0``: lost, not yet declared lost) keeps its position
    and velocity: its rows of ``q_next`` and ``v_next`` are those of ``q`` and ``v``
    (nothing when ``frozen`` is None)."""
    if frozen is None:
        return
    for m in range(frozen.shape[0]):
        if frozen[m] != 0:
            q_next[m, 0], q_next[m, 1] = q[m, 0], q[m, 1]
            v_next[m, 0], v_next[m, 1] = v[m, 0], v[m, 1]


@njit(cache=True, parallel=True)
def run_batch(outs, inps, status, scene, index, ctl, rule, const, safe, route, track, crowd,
              links, link_io, frozen):  # fmt: skip
    """Run every run of a batch in parallel threads (``outs``/``inps``: tuples of arrays
    with a leading run axis, in the field order of :class:`RunOutputs`/:class:`RunInputs`;
    ``safe``, ``route``, ``track``: the layers' markers of :func:`run_mission`; ``links``
    its link model and ``link_io`` the runs' link keys (B, 2) and series (B, 5, K+1), or
    both None; ``frozen`` as there, the same for every run); ``status[b]`` receives
    :func:`run_mission`'s result."""
    for b in prange(status.shape[0]):
        out = RunOutputs(
            outs[0][b], outs[1][b], outs[2][b], outs[3][b], outs[4][b], outs[5][b],
            outs[6][b], outs[7][b], outs[8][b], outs[9][b], outs[10][b], outs[11][b],
            outs[12][b], outs[13][b],
        )  # fmt: skip
        inp = RunInputs(inps[0][b], inps[1][b], inps[2][b], inps[3][b], inps[4][b], inps[5][b],
                        inps[6][b], inps[7][b])  # fmt: skip
        if links is None:
            status[b] = run_mission(out, inp, scene, index, ctl, rule, const, safe, route,
                                    track, None, crowd, None, None, frozen)  # fmt: skip
        else:
            status[b] = run_mission(out, inp, scene, index, ctl, rule, const, safe, route,
                                    track, None, crowd, links,
                                    (link_io[0][b], link_io[1][b]), frozen)  # fmt: skip


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
def run_groups(out, inp, scene, index, ctl, rule, const, grp, safe):  # long: every group
    """One run of a swarm split into groups, each flying its own formation to its own static
    target with its own leader, as :func:`run_mission` flies one (the same laws, called per
    group on the group's UAVs and graph, without the planner and the filter), while the
    repulsion, the safety filter and the motion act on all UAVs at once (:func:`motion_block`),
    so the safety filter keeps UAVs of different groups apart too. Returns -1, or the step
    at which a position ran away."""
    k_steps = out.q.shape[0] - 1
    m_uavs = out.q.shape[1]
    n_groups = grp.leaders.shape[0]
    rects, circles, keys, ids = scene.rects, scene.circles, inp.keys, inp.ids
    u = np.empty((m_uavs, 2))
    rep = np.empty((m_uavs, 2))
    clear = np.empty(m_uavs)
    part = np.zeros((1, 8))  # (motion_block's flag)
    d_work = np.empty((m_uavs, 2))
    n_rows = m_uavs - 1 + scene.rects.shape[0] + scene.circles.shape[0]
    a_work = np.empty((max(n_rows, 1), 2))
    b_work = np.empty(max(n_rows, 1))
    vref = np.empty((n_groups, 2))
    centre = np.empty((n_groups, 2))
    delta = inp.delta
    for k in range(k_steps + 1):
        q = out.q[k]
        obstacle_pass(q, rep, clear, rects, circles, index, ctl, 0, m_uavs)  # all UAVs, one pass
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
                clearance = min(clearance, clear[m])
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
        if safe is not None:
            safe_displacement(q, out.v[k], u, rep, d_work, rects, circles, const, a_work,
                              b_work)  # fmt: skip
        motion_block(0, 0, m_uavs, k, q, q_next, out.v[k], u, rep, keys, ids, const,
                     safe is not None, part)  # fmt: skip
        if part[0, 6] != 0.0:
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
                    rects, circles, index, rule.margin, rule.lookahead, rule.samples, rule.minimum,
                )  # fmt: skip
                out.eta[k + 1, g] = eta_rate_limit(eta, goal, rule.rate * const.dt)
            else:
                out.eta[k + 1, g] = 1.0
    return -1


@njit(cache=True, parallel=True)
def run_group_batch(outs, inps, status, scene, index, ctl, rule, const, grp, safe):
    """:func:`run_groups` for every run of a batch in parallel threads (``outs``/``inps``:
    tuples of arrays with a leading run axis, in the field order of
    :class:`GroupOutputs`/:class:`RunInputs`)."""
    for b in prange(status.shape[0]):
        out = GroupOutputs(
            outs[0][b], outs[1][b], outs[2][b], outs[3][b], outs[4][b], outs[5][b],
            outs[6][b], outs[7][b],
        )  # fmt: skip
        inp = RunInputs(inps[0][b], inps[1][b], inps[2][b], inps[3][b], inps[4][b], inps[5][b],
                        inps[6][b], inps[7][b])  # fmt: skip
        status[b] = run_groups(out, inp, scene, index, ctl, rule, const, grp, safe)
