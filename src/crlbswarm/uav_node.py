r"""One UAV of ``crlbswarm fly``: the mission kernel's step, for one UAV, on what it receives.

:func:`crlbswarm.mission_kernel.run_mission` steps every UAV of a run in one process. Here
each UAV is a process (:func:`run_uav`) that runs the same compiled laws, called from the
mission kernel's blocks on its own row (``lo = m``, ``hi = m + 1``), on the states its
neighbours send it over Zenoh (:mod:`crlbswarm.flynet`). Per step :math:`k` (the order of
:func:`~crlbswarm.mission_kernel.run_mission`):

* a **follower** sends its state (position, consensus velocity and, with sensing in the
  loop, the range it measured); waits for its neighbours' states of step :math:`k` and the
  leader's (the leader's carries :math:`\eta_k` and :math:`\mathbf v^*_k`), or, with the
  safety filter on, every UAV's (the filter keeps a UAV clear of every UAV within its
  sensing radius: the positions it would sense are received); then computes its obstacle
  repulsion and formation input (:func:`crlbswarm.mission_kernel.input_block`), its safe
  displacement (:func:`crlbswarm.mission_kernel.safe_displacement`), its motion with its
  own disturbance (:func:`crlbswarm.mission_kernel.motion_block`: the pair of counter
  ``(k, m, DISTURBANCE, 0)`` under the run's keys) and its consensus velocity
  (:func:`crlbswarm.mission_kernel.update_block`);
* the **leader** waits for every follower's state of step :math:`k` (the two quantities the
  kernel takes over the whole formation: the centroid, and, with sensing, the ranges the
  filter fuses), computes the centroid and its reference
  (:func:`crlbswarm.mission_kernel.step_state`,
  :func:`crlbswarm.mission_kernel.leader_step`: the eta rule, the route, the goal), sends
  its state with :math:`\eta_k` and :math:`\mathbf v^*_k`, moves as a follower does, and
  computes :math:`\eta_{k+1}` (:func:`crlbswarm.mission_kernel.next_eta`); with sensing it
  runs the filter (:func:`crlbswarm.tracking.update_into`, ``predict_into``);
* every UAV sends its true state to the recorder (``LOG``).

Every process knows the scenario and the seed, so each computes the run's inputs itself
(:func:`fly_run`): the start positions (:func:`crlbswarm.simulation.start_positions`), the
slots, the target's trajectory and the keys of its draws
(:func:`crlbswarm.simulation.run_keys`); the states at take-off (the starts, velocities 0)
are known to all. With perfect links and the stepped mode each UAV acts on exactly the
numbers the kernel uses, so the flight is the simulation, bit for bit.

A UAV whose member is gone is **lost** (:class:`UavProcess`): the leader re-plans the
formation of the UAVs left with the simulator's rules (:func:`crlbswarm.faults.decide`,
:func:`crlbswarm.faults.phase_scenario`, :func:`crlbswarm.simulation.replanned_slots`) and
tells it in every message (:class:`crlbswarm.flynet.SwarmBlock`); each UAV then runs the
laws on its row of the members' arrays (:func:`phase_run`). A lost leader is replaced by
the member of lowest index left, which re-plans at its next step.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from . import _validation as _v
from .counter_rng import RANGE_NOISE, normal_pair
from .errors import FieldError
from .estimation import noisy_range
from .faults import decide, fault_step, phase_scenario, swarm_links
from .flynet import (
    DONE,
    LOG,
    MAX_DELAY,
    NO_STAMP,
    START_TIMEOUT,
    STATE,
    STATE_FIELDS,
    FlightError,
    FlightOptions,
    Inbox,
    Injection,
    Member,
    Packet,
    SwarmBlock,
    done_key,
    log_key,
    member_name,
    state_key,
)
from .graphs import auto_formation_step
from .mission_kernel import (
    FILTER_ITERATIONS,
    UNPLANNED,
    MissionConstants,
    RunOutputs,
    SceneArrays,
    input_block,
    leader_step,
    motion_block,
    next_eta,
    obstacle_pass,
    safe_displacement,
    step_state,
    update_block,
)
from .scenario import Scenario
from .simulation import (
    kernel_arguments,
    layer_markers,
    replanned_slots,
    run_keys,
    slot_offsets,
    start_positions,
    target_stream,
)
from .spatial import SEPARATION_BRUTE_FORCE_MAX
from .tracking import filter_work, predict_into, target_trajectories, update_into

__all__ = [
    "FlyRun",
    "UavProcess",
    "compile_laws",
    "delayed_gains",
    "fly_run",
    "kill_steps",
    "leader_reference",
    "measured_range",
    "phase_run",
    "run_uav",
    "uav_clearance",
    "uav_move",
    "wait_for_members",
]

_ON = np.empty(0)


@dataclass(frozen=True, eq=False)
class FlyRun:
    """What every process of a flight computes from the scenario and the seed: the compiled
    mission's arguments and the run's inputs, as :func:`crlbswarm.simulate` makes them.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    seed : int
        The seed.
    scene : SceneArrays
        The kernel's shared arrays (graph, obstacles, roadmap, filter matrices).
    index : object
        The obstacles' index (:func:`crlbswarm.obstacles.obstacle_index`), or None.
    ctl : tuple
        The gains (``ControlGains.kernel_tuple()``).
    rule : tuple
        The eta rule (``EtaRule.kernel_tuple(gains)``).
    const : MissionConstants
        The mission's constants.
    safe : ndarray or None
        The safety filter's marker (:func:`crlbswarm.simulation.layer_markers`).
    route : ndarray or None
        The planner's marker.
    track : ndarray or None
        The marker of sensing in the loop.
    crowd : ndarray or None
        The cell list's marker for the smallest separation.
    start : ndarray, shape (M, 2)
        Start positions, m.
    delta : ndarray, shape (M, 2)
        Each UAV's slot offset from the formation's centre, m.
    target : ndarray, shape (K+1, 2)
        The target's true position, m.
    target_velocity : ndarray, shape (K+1, 2)
        Its true velocity, m/s.
    x0 : ndarray, shape (n,)
        The filter's prior mean.
    keys : ndarray of int64, shape (4,)
        The keys of the run's disturbance and range noise.
    ids : ndarray of int64, shape (M,)
        The UAVs' indices (the UAV word of their draws).
    """

    scenario: Scenario
    seed: int
    scene: SceneArrays
    index: Any
    ctl: Any
    rule: Any
    const: MissionConstants
    safe: np.ndarray | None
    route: np.ndarray | None
    track: np.ndarray | None
    crowd: np.ndarray | None
    start: np.ndarray
    delta: np.ndarray
    target: np.ndarray
    target_velocity: np.ndarray
    x0: np.ndarray
    keys: np.ndarray
    ids: np.ndarray

    @property
    def m_uavs(self) -> int:
        """Number of UAVs M."""
        return int(self.start.shape[0])

    @property
    def k_steps(self) -> int:
        """Number of steps K."""
        return int(self.target.shape[0] - 1)

    @property
    def leader(self) -> int:
        """The leader's index."""
        return int(self.const.leader)

    def neighbours(self, m: int) -> list[int]:
        """UAV ``m``'s neighbours in the communication graph.

        Parameters
        ----------
        m : int
            The UAV.

        Returns
        -------
        list of int
            Its neighbours.
        """
        indptr, indices = self.scene.indptr, self.scene.indices
        return [int(p) for p in indices[indptr[m] : indptr[m + 1]]]


def fly_run(scenario: Scenario, seed: int, delay: int = 0) -> FlyRun:
    """The compiled mission's arguments and the inputs of the run with ``seed``, as
    :func:`crlbswarm.simulate` makes them: every process of a flight computes them itself.

    Parameters
    ----------
    scenario : Scenario
        The scenario (one target).
    seed : int
        The seed.
    delay : int, default 0
        The delay injected at the senders, steps: a ``"auto"`` formation gain is resolved
        for it (:func:`delayed_gains`), as the simulator resolves it for a ``[links]``
        table's delay.

    Returns
    -------
    FlyRun
        The run.

    Raises
    ------
    FieldError
        (field ``scenario``) For a scenario with several targets; (``links``) for one with
        a ``[links]`` table; (``faults.link_lost``) for links lost (UAVs lost are flown);
        (``seed``) for an invalid seed.
    """
    if not isinstance(scenario, Scenario):
        raise FieldError(
            "scenario", f"expected a crlbswarm.Scenario, got {type(scenario).__name__}"
        )
    if scenario.extra_targets:
        raise FieldError(
            "scenario", "has extra_targets (several targets): fly flies one formation"
        )
    if scenario.links is not None:
        raise FieldError(
            "links", "crlbswarm fly does not fly a [links] table (its network is the link): "
            "inject loss and delay at the sender with --loss and --delay, or remove it",
        )  # fmt: skip
    if scenario.faults is not None and scenario.faults.link_lost:
        raise FieldError(
            "faults.link_lost", "crlbswarm fly cannot cut a link yet (it flies the UAVs "
            "lost: their processes kill themselves at their times); remove the links lost",
        )  # fmt: skip
    seed = _v.seed(seed, "seed")
    sc = delayed_gains(scenario, _v.count(delay, "delay", 0, MAX_DELAY))
    scene, index, ctl, rule, const = kernel_arguments(sc, 0)
    start = start_positions(sc, seed)
    centre = np.asarray(sc.target, dtype=float) + sc.formation_design.centre_offset
    delta = slot_offsets(sc, start, centre)
    motion = sc.target_motion
    rng = target_stream(seed)
    truth = target_trajectories(
        np.asarray(sc.target, dtype=float), np.asarray(motion.velocity, dtype=float),
        motion.model, sc.time.step, sc.time.steps, [rng], motion.turn_rate,
        motion.acceleration_noise,
    )[0]  # fmt: skip
    x0 = np.zeros(scene.p0.shape[0])
    x0[:2] = truth[0, :2] + np.asarray(sc.estimation.prior_offset)
    safe, route, track = layer_markers(sc)
    m = sc.uavs.count
    return FlyRun(
        scenario=sc, seed=seed, scene=scene, index=index, ctl=ctl, rule=rule, const=const,
        safe=safe, route=route, track=track,
        crowd=_ON if m > SEPARATION_BRUTE_FORCE_MAX else None, start=start,
        delta=np.ascontiguousarray(delta), target=np.ascontiguousarray(truth[:, :2]),
        target_velocity=np.ascontiguousarray(truth[:, 2:]), x0=x0, keys=run_keys(seed),
        ids=np.arange(m, dtype=np.int64),
    )  # fmt: skip


def delayed_gains(scenario: Scenario, delay: int) -> Scenario:
    """The scenario flown with ``delay`` steps injected at the senders: its ``"auto"``
    formation gain resolved for that age of the neighbours' states
    (:func:`crlbswarm.graphs.auto_formation_step`, the rule of a ``[links]`` table in the
    simulator); the scenario itself without delay or with an explicit gain. A swarm that
    re-forms after a loss keeps that gain.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    delay : int
        Steps, >= 0.

    Returns
    -------
    Scenario
        The scenario, with ``control.epsilon`` a number when it was ``"auto"`` and
        ``delay > 0``.
    """
    if delay == 0 or scenario.control.epsilon != "auto":
        return scenario
    data = scenario.model_dump(exclude_none=True)
    data["control"]["epsilon"] = auto_formation_step(scenario.adjacency, delay)
    return Scenario.from_dict(data, source=f"{scenario.name} with {delay} steps of delay")


# ---------------------------------------------------------------------------------------
# The kernel's step on one UAV's row (compiled; every law called from its module)
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def uav_move(k, m, q, q_next, v, v_next, delta, eta, vref, u, rep, clear, d_work, a_work,
             b_work, part, scene, index, ctl, const, keys, ids, safe):  # fmt: skip
    """Step 2 of :func:`crlbswarm.mission_kernel.run_mission` for UAV ``m`` alone: its
    obstacle repulsion, clearance and formation input (eq. (19), ``input_block`` on row m),
    with ``safe`` its safe displacement (``safe_displacement``: each UAV's QP reads only its
    own nominal displacement and the positions ``q`` of all), its motion of eq. (3)
    (``motion_block``, its own disturbance) into ``q_next[m]`` and its consensus of eq. (14)
    (``update_block``) into ``v_next[m]``. Returns False if its position ran away."""
    input_block(0, m, m + 1, q, delta, eta, None, u, rep, clear, scene.rects, scene.circles,
                index, scene.indptr, scene.indices, scene.indices, q, ctl, part)  # fmt: skip
    if safe is not None:
        safe_displacement(q, v, u, rep, d_work, scene.rects, scene.circles, const, a_work,
                          b_work)  # fmt: skip
    motion_block(0, m, m + 1, k, q, q_next, v, u, rep, keys, ids, const, safe is not None, part)
    update_block(0, m, m + 1, q, q_next, v, v_next, delta, vref, const.leader, scene.indptr,
                 scene.indices, scene.indptr, scene.indices, v, ctl, const.dt,
                 part)  # fmt: skip
    return part[0, 6] == 0.0


@njit(cache=True)
def uav_clearance(m, q, rep, clear, scene, index, ctl):
    """UAV ``m``'s obstacle clearance at ``q[m]`` (the last step's obstacle pass,
    :func:`crlbswarm.mission_kernel.obstacle_pass`), m."""
    return obstacle_pass(q, rep, clear, scene.rects, scene.circles, index, ctl, m, m + 1)


@njit(cache=True)
def leader_reference(k, q, v, vref, delta, tx, ty, sx, sy, tvx, tvy, eta, node, part, scene,
                     index, ctl, rule, const, out, route):  # fmt: skip
    """Steps 0 and 1 of :func:`crlbswarm.mission_kernel.run_mission` at the leader, on the
    states it holds: the centroid (``step_state``, which also writes the FIM and CRLB of
    those states into ``out``) and the reference toward the goal ``(sx, sy)`` moving at
    ``(tvx, tvy)`` (``leader_step``: into ``vref``, ``v[leader]``, ``out``). Returns the
    centroid, the formation's centre over the goal, eta and the route's node."""
    cx, cy = step_state(k, q, q, v, v, tx, ty, scene.snr, part, const, out.centroid, out.fim,
                        out.crlb, out.centroid_error, None)  # fmt: skip
    sx += const.centre_x
    sy += const.centre_y
    eta, node = leader_step(k, q, v, vref, cx, cy, sx, sy, tvx, tvy, eta, node, scene.rects,
                            scene.circles, delta, scene, index, ctl, rule, const, out,
                            route)  # fmt: skip
    return cx, cy, sx, sy, eta, node


@njit(cache=True)
def measured_range(k, m, qx, qy, sx, sy, keys, const):
    """The range UAV ``m`` at ``(qx, qy)`` measures to the true target ``(sx, sy)`` at step
    ``k``, as :func:`crlbswarm.mission_kernel.sense_target` draws it for that UAV (eq. (2),
    :func:`crlbswarm.estimation.noisy_range`, its normal the first of the pair of counter
    ``(k, m, RANGE_NOISE, 0)``), m."""
    dx = sx - qx
    dy = sy - qy
    z, _ = normal_pair(keys[2], keys[3], k, m, RANGE_NOISE, 0)
    return noisy_range(dx * dx + dy * dy + const.altitude * const.altitude, const.snr_constant, z)


def _leader_outputs(k_steps: int) -> RunOutputs:
    """The per-step arrays the leader's kernel calls write (none of the trajectories)."""
    k1 = k_steps + 1
    return RunOutputs(
        q=np.empty((0, 1, 2)), v=np.empty((0, 1, 2)), v_ref=np.zeros((k1, 2)),
        eta=np.ones(k1), clearance=np.zeros(k1), separation=np.zeros(k1),
        cost=np.zeros(max(k_steps, 1)), estimate=np.zeros((k1, 2)),
        estimate_variance=np.zeros(k1), distance_to_go=np.zeros(k1),
        centroid=np.zeros((k1, 2)), fim=np.zeros((k1, 3)), crlb=np.zeros(k1),
        centroid_error=np.zeros(k1),
    )  # fmt: skip


def phase_run(base: FlyRun, block: SwarmBlock) -> FlyRun:
    """The run of the formation a re-planning made (``block``): the scenario of the UAVs
    that go on (:func:`crlbswarm.faults.phase_scenario`), its laws' arguments, the slots
    the block tells, the keys of the phase (:func:`crlbswarm.simulation.run_keys`) and the
    members' swarm indices as the UAV words of their draws.

    Parameters
    ----------
    base : FlyRun
        The flight's run (phase 0).
    block : SwarmBlock
        The formation (not hovering).

    Returns
    -------
    FlyRun
        The phase's run (``base`` itself for phase 0); its rows are the members'.
    """
    if block.phase == 0:
        return base
    members = block.members
    inside = set(members.tolist())
    pairs = [e for e in base.scenario.adjacency.edges.tolist() if set(e) <= inside]
    edges = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    sc = phase_scenario(base.scenario, members, block.leader, edges,
                        f"after the re-planning at step {block.step}")  # fmt: skip
    scene, index, ctl, rule, const = kernel_arguments(sc, 0)
    safe, route, track = layer_markers(sc)
    return FlyRun(
        scenario=sc, seed=base.seed, scene=scene, index=index, ctl=ctl, rule=rule, const=const,
        safe=safe, route=route, track=track, crowd=base.crowd, start=base.start[members],
        delta=np.ascontiguousarray(block.delta), target=base.target,
        target_velocity=base.target_velocity, x0=base.x0, keys=run_keys(base.seed, block.phase),
        ids=members.copy(),
    )  # fmt: skip


def compile_laws(run: FlyRun) -> None:
    """Compile (or load from Numba's cache) every law a UAV of ``run`` calls, by calling
    each once on scratch copies: the launcher does it before it starts the processes, which
    then load the compiled code instead of compiling it each.

    Parameters
    ----------
    run : FlyRun
        The run.
    """
    n, leader = run.m_uavs, run.leader
    q, (v, u, rep, d) = run.start.copy(), (np.zeros((n, 2)) for _ in range(4))
    q_next, v_next, clear, part = q.copy(), v.copy(), np.zeros(n), np.zeros((1, 8))
    rows = max(n - 1 + run.scene.rects.shape[0] + run.scene.circles.shape[0], 1)
    a_work, b_work, vref = np.empty((rows, 2)), np.empty(rows), np.zeros(2)
    out = _leader_outputs(run.k_steps)
    cx, cy, sx, sy, eta, node = leader_reference(
        0, q, v, vref, run.delta, run.target[0, 0], run.target[0, 1], run.target[0, 0],
        run.target[0, 1], 0.0, 0.0, 1.0, UNPLANNED, part, run.scene, run.index, run.ctl, run.rule,
        run.const, out, run.route,
    )  # fmt: skip
    uav_move(0, leader, q, q_next, v, v_next, run.delta, eta, vref, u, rep, clear, d, a_work,
             b_work, part, run.scene, run.index, run.ctl, run.const, run.keys, run.ids,
             run.safe)  # fmt: skip
    uav_clearance(leader, q, rep, clear, run.scene, run.index, run.ctl)
    next_eta(cx, cy, sx, sy, eta, node, run.scene.rects, run.scene.circles, run.index,
             run.scene, run.rule, run.const, run.route, None)  # fmt: skip
    if run.track is not None:
        x, p_cov, work = run.x0.copy(), run.scene.p0.copy(), filter_work()
        ranges = np.array([measured_range(0, p, q[p, 0], q[p, 1], run.target[0, 0],
                                          run.target[0, 1], run.keys, run.const)
                           for p in range(n)])  # fmt: skip
        update_into(x, p_cov, q, ranges, run.const.altitude, run.const.snr_constant,
                    FILTER_ITERATIONS, work)  # fmt: skip
        two, r2 = np.ascontiguousarray(q[:2]), np.ascontiguousarray(ranges[:2])  # (a subset)
        update_into(x, p_cov, two, r2, run.const.altitude, run.const.snr_constant,
                    FILTER_ITERATIONS, work)  # fmt: skip
        predict_into(x, p_cov, run.scene.f_mat, run.scene.q_mat, work)


# ---------------------------------------------------------------------------------------
# The process
# ---------------------------------------------------------------------------------------
def wait_for_members(member: Member, run: FlyRun, timeout: float = START_TIMEOUT) -> None:
    """Wait until every member of the flight (the M UAVs and the recorder) is alive.

    Parameters
    ----------
    member : Member
        This process's session (its subscriptions declared and its token announced).
    run : FlyRun
        The run.
    timeout : float, default START_TIMEOUT
        Longest wait, s.

    Raises
    ------
    FlightError
        Naming the members still missing after ``timeout``.
    """
    names = {member_name(m) for m in range(run.m_uavs)} | {member_name(None)}
    inbox = member.inbox
    if not inbox.wait(lambda: names <= inbox.alive, timeout):
        missing = sorted(names - inbox.alive)
        raise FlightError(
            f"{member.name}: after {timeout:g} s, still no sign of {', '.join(missing)} "
            f"under key {member.key!r} (check --connect/--listen and --key)"
        )


class UavProcess:
    """UAV ``m`` of a flight: its state, what it holds of the others', the formation it
    flies (:class:`crlbswarm.flynet.SwarmBlock`) and its step.

    Parameters
    ----------
    run : FlyRun
        The run.
    m : int
        The UAV.
    options : FlightOptions
        Mode, timeout, injected loss and delay.
    member : Member
        Its Zenoh session.
    """

    def __init__(self, run: FlyRun, m: int, options: FlightOptions, member: Member) -> None:
        n = run.m_uavs
        self.base, self.m, self.options, self.member = run, m, options, member
        self.q, self.v = run.start.copy(), np.zeros((n, 2))  # (the take-off states: known)
        self.q_next, self.v_next = self.q.copy(), self.v.copy()
        self.rep, self.clear = np.zeros((n, 2)), np.zeros(n)
        self.eta, self.vref = 1.0, np.zeros(2)
        # each UAV's last range, where it was measured, and whether it is fused yet
        self.ranges, self.range_q = np.full(n, np.nan), run.start.copy()
        self.unfused = np.zeros(n, dtype=bool)
        self.stamps = np.zeros(n, dtype=np.int64)  # the step of each UAV's state held
        self.heard = np.full(n, -1, dtype=np.int64)  # the step of each UAV's last message
        self.names = {p: member_name(p) for p in range(n)}
        self.base_links = swarm_links(run.scenario)  # (the graph decisions are made on)
        self.lost: set[int] = set()  # UAVs whose member is gone
        self.late = 0  # steps it went on without a state it waited for
        self.warned: set[int] = set()
        self.injection = Injection(run.seed, m, options.loss, options.delay)
        self.kill_steps, self.leader_kill = kill_steps(run, m, options)
        self.x, self.p_cov = run.x0.copy(), run.scene.p0.copy()
        self.f_work = filter_work()
        self.node = UNPLANNED
        self.out = _leader_outputs(run.k_steps)
        self.leader_x = np.empty(0)  # the last estimate the leader sent (a new leader's start)
        block = SwarmBlock(0, -1, False, run.leader, np.arange(n, dtype=np.int64),
                           run.delta.copy(), np.empty(0))  # fmt: skip
        self.block = block
        self.leading = False
        self._enter(block, run)

    # -- the formation flown -------------------------------------------------------------
    def _enter(self, block: SwarmBlock, prun: FlyRun | None) -> None:
        """Fly the formation of ``block`` (its run ``prun``; None: the UAVs hover)."""
        m = self.m
        takes_over = block.phase > 0 and block.leader == m and self.block.leader != m
        self.block, self.prun = block, prun
        self.hovering = prun is None or m not in block.members.tolist()
        self.leader = block.leader
        self.leading = not self.hovering and block.leader == m
        if self.hovering or prun is None:
            return
        k = block.members.shape[0]
        self.local = int(np.flatnonzero(block.members == m)[0])
        self.qc, self.vc = np.zeros((k, 2)), np.zeros((k, 2))
        self.qnc, self.vnc = np.zeros((k, 2)), np.zeros((k, 2))
        self.u, self.rep_c, self.clear_c = np.zeros((k, 2)), np.zeros((k, 2)), np.zeros(k)
        self.d_work = np.zeros((k, 2))
        rows = max(k - 1 + prun.scene.rects.shape[0] + prun.scene.circles.shape[0], 1)
        self.a_work, self.b_work = np.empty((rows, 2)), np.empty(rows)
        self.part = np.zeros((1, 8))
        if takes_over and self.leading:  # (a new leader: the filter from the last estimate
            self.node = UNPLANNED  # the old leader sent, with the prior's covariance)
            if self.leader_x.shape[0] == self.x.shape[0]:
                self.x = self.leader_x.copy()
            self.p_cov = self.base.scene.p0.copy()

    def _adopt(self, block: SwarmBlock) -> None:
        """Take a newer formation, told by the UAV that re-planned."""
        _say(f"uav {self.m}: re-planned at step {block.step}: UAVs {block.members.tolist()}, "
             f"leader {block.leader}{', hovering' if block.hover else ''}")  # fmt: skip
        self._enter(block, None if block.hover else phase_run(self.base, block))

    def _replan(self, k: int) -> None:
        """The leader's re-planning at step ``k`` when members are gone: the decision of
        :func:`crlbswarm.faults.decide`, the formation for the UAVs that go on
        (:func:`crlbswarm.faults.phase_scenario`) and their slots
        (:func:`crlbswarm.simulation.replanned_slots`), from the states it holds."""
        block, base = self.block, self.base
        members = block.members.tolist()
        gone = {p for p in members if p in self.lost}
        if not gone:
            return
        choice = decide(members, block.leader, self.base_links, gone)
        keep = np.array(choice.members, dtype=np.int64)
        hover = choice.outcome == "too_few"
        delta = np.zeros((keep.shape[0], 2))
        if not hover:
            sc = phase_scenario(base.scenario, keep, choice.leader, choice.edges,
                                f"after the re-planning at step {k}")  # fmt: skip
            delta = replanned_slots(sc, self.q[keep], base.target[k])
        estimate = self.x.copy() if base.track is not None else np.empty(0)
        new = SwarmBlock(block.phase + 1, k, hover, choice.leader, keep, delta, estimate)
        self._adopt(new)

    def senders(self) -> list[int]:
        """The UAVs whose states this UAV needs at a step: the leader needs every member
        (the centroid; the ranges with sensing in the loop); a follower its neighbours
        and the leader (eta and v*), or every member with the safety filter on.

        Returns
        -------
        list of int
            The senders (swarm indices), in order, lost ones left out.
        """
        m, prun = self.m, self.prun
        members = self.block.members.tolist()
        if self.hovering or prun is None:
            return []
        if self.leading or prun.safe is not None:
            wanted = set(members)
        else:
            ids = prun.ids
            wanted = {int(ids[p]) for p in prun.neighbours(self.local)} | {self.leader}
        return sorted(wanted - {m} - self.lost)

    # -- messages ----------------------------------------------------------------------
    def _send_state(self, k: int, measured: float) -> None:
        """Send the swarm state of step ``k`` through the injected loss and delay."""
        m = self.m
        eta = self.eta if self.leading else math.nan
        told = self.x if self.leading and self.base.track is not None else None
        values = np.concatenate([[self.q[m, 0], self.q[m, 1], self.v[m, 0], self.v[m, 1], eta,
                                  measured], self.block.values(told)])  # fmt: skip
        sent = self.injection.outgoing(k, values)
        stamp, carried = (NO_STAMP, np.empty(0)) if sent is None else sent
        self.member.publish(state_key(self.member.key, m), Packet(STATE, m, k, stamp, carried))

    def _absorb(self, packet: Packet) -> None:
        """Take a UAV's state (if newer than the one held), and the formation it tells if
        that is newer."""
        p, values = packet.sender, packet.values
        self.heard[p] = max(self.heard[p], packet.step)
        if packet.stamp == NO_STAMP or packet.stamp < self.stamps[p] or p == self.m:
            return
        self.stamps[p] = packet.stamp
        self.q[p] = values[0:2]
        self.v[p] = values[2:4]
        if p == self.leader and not math.isnan(values[4]):
            self.eta = float(values[4])
            self.vref[:] = values[2:4]
        if not math.isnan(values[5]):
            self.ranges[p], self.range_q[p], self.unfused[p] = values[5], values[0:2], True
        block = SwarmBlock.read(values, len(STATE_FIELDS))
        if block is None:
            return
        if p == self.leader and block.estimate.shape[0]:
            self.leader_x = block.estimate
        if block.newer_than(self.block):
            self._adopt(block)

    def _receive(self, k: int) -> None:
        """Stepped: wait for the senders' states of step ``k`` (at most the timeout) and take
        them; real time: take the newest state of each UAV. A member that is gone is lost:
        a lost leader is replaced by the member of lowest index left (which then leads:
        it re-plans at its next step)."""
        inbox = self.member.inbox
        if self.options.mode == "realtime":
            for p in range(self.base.m_uavs):
                packet = inbox.latest.get((STATE, p))
                if packet is not None:
                    self._absorb(packet)
            missing = {p for p in self.senders() if self.names[p] in inbox.gone}
        else:
            missing = self._wait_states(k)
        for p in sorted(missing):
            if self.names[p] in inbox.gone:
                if p not in self.lost:
                    self.lost.add(p)
                    _say(f"uav {self.m}: UAV {p} is gone (step {k})")
                continue
            self.late += 1
            if p not in self.warned:  # (said once; fly.json counts them)
                self.warned.add(p)
                _say(f"uav {self.m}: no state of UAV {p} for step {k} within "
                     f"{self.options.timeout:g} s; going on with the one of step "
                     f"{self.stamps[p]} (and so on whenever it is late: fly.json counts "
                     "the steps)")  # fmt: skip
        if self.leader in self.lost and not self.hovering:
            self._elect(k)

    def _elect(self, k: int) -> None:
        """The leader is gone: elect the one the re-planning will name
        (:func:`crlbswarm.faults.decide` over the members gone), and, stepped, take its
        state of step ``k``."""
        inbox, members = self.member.inbox, self.block.members.tolist()
        gone = {p for p in members if p in self.lost or self.names[p] in inbox.gone}
        self.leader = decide(members, self.leader, self.base_links, gone).leader
        self.leading = self.leader == self.m
        if not self.leading and self.options.mode == "stepped" and self.heard[self.leader] < k:
            inbox.wait_step(STATE, k, [self.leader], self.options.timeout, self.names)
            for packet in inbox.take(STATE, k):
                self._absorb(packet)

    def _wait_states(self, k: int) -> set[int]:
        """Stepped: wait for the senders' states of step ``k``, take every state received,
        and return the senders whose state did not come."""
        inbox, timeout = self.member.inbox, self.options.timeout
        wanted = self.senders()
        missing = inbox.wait_step(STATE, k, wanted, timeout, self.names)
        leader = self.leader
        if leader in missing:  # (the leader may itself have waited a timeout for a follower)
            missing = (missing - {leader}) | inbox.wait_step(
                STATE, k, [leader], timeout, self.names
            )
        for packet in inbox.take(STATE, k):
            self._absorb(packet)
        return missing

    def _send_log(self, k: int, extra: tuple[float, ...]) -> None:
        """Send the true state of step ``k`` (and the leader's metrics) to the recorder."""
        m = self.m
        values = np.concatenate([[self.q[m, 0], self.q[m, 1], self.v[m, 0], self.v[m, 1],
                                  self.clear[m], *extra, float(self.late)],
                                 self.block.values()])  # fmt: skip
        self.member.publish(log_key(self.member.key, m), Packet(LOG, m, k, k, values))

    # -- the step ----------------------------------------------------------------------
    def _measure(self, k: int) -> float:
        """The range measured at step ``k`` with sensing in the loop (NaN at other steps)."""
        run, m = self.base, self.m
        if run.track is None or k % run.const.measure_every or self.hovering:
            return math.nan
        r = measured_range(k, m, self.q[m, 0], self.q[m, 1], run.target[k, 0],
                           run.target[k, 1], run.keys, run.const)  # fmt: skip
        self.ranges[m], self.range_q[m], self.unfused[m] = r, self.q[m], True
        return float(r)

    def _gather(self) -> None:
        """The members' states held, in the formation's order (its kernel's rows)."""
        members = self.block.members
        self.qc[:] = self.q[members]
        self.vc[:] = self.v[members]

    def _move(self, k: int) -> None:
        """Step 2 for this UAV (``uav_move`` on its row of the formation's arrays), then
        its state of step ``k + 1``; a hovering UAV stays where it is."""
        m = self.m
        if self.hovering or self.prun is None:
            self.q_next[m], self.v_next[m] = self.q[m], 0.0
            return
        pr, row = self.prun, self.local
        self._gather()
        ok = uav_move(k, row, self.qc, self.qnc, self.vc, self.vnc, pr.delta, self.eta,
                      self.vref, self.u, self.rep_c, self.clear_c, self.d_work, self.a_work,
                      self.b_work, self.part, pr.scene, pr.index, pr.ctl, pr.const, pr.keys,
                      pr.ids, pr.safe)  # fmt: skip
        if not ok:
            raise FlightError(f"uav {m}: its position ran away at step {k + 1}")
        self.q_next[m], self.v_next[m] = self.qnc[row], self.vnc[row]
        self.clear[m] = self.clear_c[row]

    def _advance(self) -> None:
        """Take the state of the next step."""
        m = self.m
        self.q[m] = self.q_next[m]
        self.v[m] = self.v_next[m]

    def _follower_step(self, k: int) -> None:
        """A follower's (or a hovering UAV's) step ``k``: send, receive, move, log."""
        self._send_state(k, self._measure(k))
        if not self.hovering:
            self._receive(k)
        if k < self.base.k_steps:
            self._move(k)
        else:
            uav_clearance(self.m, self.q, self.rep, self.clear, self.base.scene,
                          self.base.index, self.base.ctl)  # fmt: skip
        nan = math.nan
        self._send_log(k, (nan,) * 5)

    def _fuse(self, k: int) -> tuple[float, float, float, float]:
        """The leader's goal: the filter's estimate after fusing the ranges measured at step
        ``k`` (sensing in the loop), or the true target; with its velocity."""
        run = self.base
        if run.track is None:
            tx, ty = run.target[k]
            tvx, tvy = run.target_velocity[k]
            return float(tx), float(ty), float(tvx), float(tvy)
        rows = np.flatnonzero(self.unfused)
        if k % run.const.measure_every == 0 and rows.size:  # each range fused once
            q, r = self.range_q, self.ranges
            if rows.size < run.m_uavs:
                q, r = np.ascontiguousarray(q[rows]), np.ascontiguousarray(r[rows])
            update_into(self.x, self.p_cov, q, r, run.const.altitude, run.const.snr_constant,
                        FILTER_ITERATIONS, self.f_work)  # fmt: skip
            self.unfused[:] = False
        moving = self.x.shape[0] == 4
        return (float(self.x[0]), float(self.x[1]), float(self.x[2]) if moving else 0.0,
                float(self.x[3]) if moving else 0.0)  # fmt: skip

    def _leader_step(self, k: int) -> None:
        """The leader's step ``k``: receive, re-plan if members are gone, centroid and
        reference, send, move, eta, log."""
        base = self.base
        measured = self._measure(k)
        self._receive(k)
        self._replan(k)
        if not self.leading or self.prun is None:  # (it handed the lead over, or hovers)
            self._send_state(k, measured)
            if k < base.k_steps:
                self._move(k)
            self._send_log(k, (math.nan,) * 5)
            return
        pr = self.prun
        sx, sy, tvx, tvy = self._fuse(k)
        self._gather()
        cx, cy, sx, sy, eta, self.node = leader_reference(
            k, self.qc, self.vc, self.vref, pr.delta, base.target[k, 0], base.target[k, 1], sx,
            sy, tvx, tvy, self.eta, self.node, self.part, pr.scene, pr.index, pr.ctl,
            pr.rule, pr.const, self.out, pr.route,
        )  # fmt: skip
        self.v[self.m] = self.vref
        self.eta = float(eta)
        self._send_state(k, measured)
        estimate = (math.nan,) * 3
        if base.track is not None:
            estimate = (float(self.x[0]), float(self.x[1]),
                        float(self.p_cov[0, 0] + self.p_cov[1, 1]))  # fmt: skip
        extra = (self.eta, float(self.out.distance_to_go[k]), *estimate)
        if k < base.k_steps:
            self._move(k)
            next_value = next_eta(cx, cy, sx, sy, self.eta, self.node, pr.scene.rects,
                                  pr.scene.circles, pr.index, pr.scene, pr.rule, pr.const,
                                  pr.route, None)  # fmt: skip
            if base.track is not None:
                predict_into(self.x, self.p_cov, base.scene.f_mat, base.scene.q_mat,
                             self.f_work)  # fmt: skip
        else:
            uav_clearance(self.m, self.q, self.rep, self.clear, base.scene, base.index, base.ctl)
        self._send_log(k, extra)
        if k < base.k_steps:
            self.eta = float(next_value)

    def fly(self) -> None:
        """Fly every step (on the wall clock in the real-time mode), then wait for the
        recorder's end of the flight (at most the timeout). At the time it is to be lost
        (:func:`kill_steps`) it kills itself (SIGKILL) instead."""
        run, realtime = self.base, self.options.mode == "realtime"
        dt = run.const.dt
        start = time.monotonic()
        for k in range(run.k_steps + 1):
            if k in self.kill_steps or (k == self.leader_kill and self.block.leader == self.m):
                os.kill(os.getpid(), signal.SIGKILL)
            if realtime:  # (a step that starts over a step late counts as late)
                self.member.inbox.check_parent()
                behind = time.monotonic() - (start + k * dt)
                self.late += int(behind > dt)
                time.sleep(max(0.0, -behind))
            if self.leading:
                self._leader_step(k)
            else:
                self._follower_step(k)
            if k < run.k_steps:
                self._advance()
        inbox = self.member.inbox
        inbox.wait(lambda: (DONE, run.k_steps) in inbox.by_step, self.options.timeout)


def kill_steps(run: FlyRun, m: int, options: FlightOptions) -> tuple[set[int], int]:
    """The steps at which UAV ``m``'s process kills itself (SIGKILL): a UAV lost, the
    scenario's ``faults.uav_lost`` naming it or ``--kill`` (``options.kill``), and the step
    of ``faults.leader_lost`` (at which the leader of the formation flown then, the one
    its last re-planning named, kills itself; -1: none).

    Parameters
    ----------
    run : FlyRun
        The run.
    m : int
        The UAV.
    options : FlightOptions
        The flight's options.

    Returns
    -------
    steps : set of int
        Its own steps.
    leader : int
        The step of the leader's loss.
    """
    dt, faults = run.const.dt, run.scenario.faults
    steps = set()
    if options.kill is not None and options.kill[0] == m:
        steps.add(round(options.kill[1] / dt))
    leader = -1
    if faults is not None:
        k_steps = run.k_steps
        steps |= {fault_step(loss.time, dt, k_steps) for loss in faults.uav_lost if loss.uav == m}
        if faults.leader_lost is not None:
            leader = fault_step(faults.leader_lost, dt, k_steps)
    return steps, leader


def _say(text: str) -> None:
    """One line of news from a member, on stderr."""
    print(f"crlbswarm fly: {text}", file=sys.stderr, flush=True)


def run_uav(run: FlyRun, m: int, options: FlightOptions) -> int:
    """Run UAV ``m`` of a flight in this process until the mission ends.

    Parameters
    ----------
    run : FlyRun
        The run (:func:`fly_run`).
    m : int
        The UAV, from 0.
    options : FlightOptions
        Key, endpoints, mode, timeout, injected loss and delay.

    Returns
    -------
    int
        Its late steps: stepped, the steps at which it went on without a state it waited
        for; real time, the steps it started over a step behind the wall clock.

    Raises
    ------
    FieldError
        (field ``uav``) For a UAV index out of range; (``listen``) if the session cannot
        open.
    FlightError
        If the members do not all appear within :data:`crlbswarm.flynet.START_TIMEOUT`, or
        the UAV's position runs away.
    """
    m = _v.count(m, "uav", 0, run.m_uavs - 1)
    compile_laws(run)  # (before it joins: a first step that compiles would hold up the others)
    inbox = Inbox(options.parent, stepped=options.mode == "stepped")
    member = Member(options.key, member_name(m), options.listen, options.connect, inbox)
    try:
        uav = UavProcess(run, m, options, member)
        member.subscribe(  # (every UAV's: any may become a neighbour or the leader)
            [state_key(options.key, p) for p in range(run.m_uavs)] + [done_key(options.key)]
        )
        member.announce()
        wait_for_members(member, run)
        uav.fly()
        return uav.late
    finally:
        member.close()
