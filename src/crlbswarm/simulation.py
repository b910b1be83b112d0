r"""The mission driver: run a scenario for one seed or a batch of seeds.

:func:`simulate` validates the seeds, sizes the batch against the machine's memory, draws
every run's random inputs from its own seed, and hands the runs, in chunks, to the compiled
mission (:mod:`crlbswarm.mission_kernel`, the controller of Sec. IV equation by equation);
it then computes the CRLB along the trajectories and, with sensing in the loop, the
posterior CRLB, and returns a :class:`~crlbswarm.results.MissionResult`.

Random numbers: for seed :math:`s`, ``SeedSequence(s).spawn(4)`` gives the NumPy streams of
the start positions (child 0) and the target's acceleration noise (child 3); the motion
disturbance and the range noise are drawn inside the kernel, each number from the
counter-based generator of :mod:`crlbswarm.counter_rng` keyed by (seed, stream) and
counted by (step, UAV), so no array of them is ever held and the memory of a run does not
grow with its length; so are the messages' losses and delays of a scenario with links
(stream LINKS, :mod:`crlbswarm.links`). Run :math:`b` of a batch is therefore
bit-identical to the single run with the same seed, whatever the batch, the chunk or the
thread.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from typing import Any, NamedTuple

import numba
import numpy as np

from . import _validation as _v
from .counter_rng import DISTURBANCE, LINKS, PHASE_STREAMS, RANGE_NOISE, stream_key
from .errors import FieldError, SimulationDivergedError
from .faults import FaultPlan, Phase
from .fisher import crlb
from .geometry import fitted_turn
from .graphs import Adjacency
from .links import LINK_SERIES, LinkModel, link_model, link_state_bytes
from .mission_kernel import (
    DIVERGENCE_LIMIT,
    REPLAN_PERIOD,
    GroupArrays,
    GroupOutputs,
    MissionConstants,
    RunInputs,
    RunOutputs,
    SceneArrays,
    run_batch,
    run_group_batch,
    run_mission,
)
from .obstacles import obstacle_index
from .planning import assign_slots
from .results import GroupMissionResult, MissionResult, kept_rows, result_nbytes
from .scenario import Scenario
from .spatial import SEPARATION_BRUTE_FORCE_MAX
from .tracking import motion_matrices, posterior_crlb, target_trajectories

__all__ = [
    "MAX_ITERATED_SEEDS",
    "MAX_SEED",
    "WIDE_UAVS",
    "check_memory",
    "kernel_arguments",
    "layer_markers",
    "link_arguments",
    "phase_scene",
    "replanned_slots",
    "run_keys",
    "simulate",
    "simulate_groups",
    "slot_offsets",
    "start_positions",
    "target_stream",
]

#: Largest number of runs simulated per chunk.
CHUNK_RUNS = 256

#: Memory budget of the per-chunk work buffers (FIM per step, inputs and state), bytes.
CHUNK_BYTES = 64 * 2**20

#: Most seeds taken from an iterator other than a ``range`` (which is checked without
#: being expanded): the batch's memory is checked once they are counted.
MAX_ITERATED_SEEDS = 1_000_000

#: Largest seed (seeds are stored as int64).
MAX_SEED = _v.MAX_SEED

#: A single run of at least this many UAVs does the per-UAV work of each step on all of
#: Numba's threads (:func:`crlbswarm.mission_kernel.run_mission`, ``wide``); a batch runs
#: its runs in parallel instead. The results are the same bits either way.
WIDE_UAVS = 2048

#: The marker of a kernel layer that is on (:func:`layer_markers`).
_ON = np.empty(0)


#: The children of ``SeedSequence(seed).spawn(4)`` that the driver draws from: the start
#: positions and the target's acceleration noise (children 1 and 2, the disturbance and the
#: range noise of earlier versions, are now counter-based draws inside the kernel).
_START_STREAM, _TARGET_STREAM = 0, 3


def _streams(seed: int, *children: int) -> list[np.random.Generator]:
    """The NumPy streams ``children`` of the seed (``SeedSequence(seed).spawn(4)``; a
    child depends only on its index), only those asked for."""
    spawned = np.random.SeedSequence(seed).spawn(4)
    return [np.random.default_rng(spawned[c]) for c in children]


#: Draws per UAV before the start region is declared too crowded (the scenario checks leave
#: room for about four times the area the UAVs need, so this is never reached in practice).
START_ATTEMPTS = 10_000


def _start(scenario: Scenario, rng: np.random.Generator) -> np.ndarray:
    """Start positions: explicit, or uniform in the start region; with the safety filter on,
    each UAV is redrawn until it is ``scenario.start_separation`` from those before it."""
    if scenario.uavs.start is not None or scenario.uavs.start_region is None:
        return np.array(scenario.uavs.start, dtype=float)  # (exactly one of the two is set)
    (x0, x1), (y0, y1) = scenario.uavs.start_region
    m_uavs = scenario.uavs.count
    if not scenario.safety.enabled:
        return rng.uniform((x0, y0), (x1, y1), size=(m_uavs, 2))
    need = scenario.start_separation
    out = np.empty((m_uavs, 2))
    for m in range(m_uavs):
        for _ in range(START_ATTEMPTS):
            out[m] = rng.uniform((x0, y0), (x1, y1))
            if m == 0 or np.min(np.hypot(*(out[:m] - out[m]).T)) >= need:
                break
        else:
            raise FieldError(
                "uavs.start_region", f"no room for UAV {m} at {need:g} m from the others"
            )
    return out


def start_positions(scenario: Scenario, seed: int) -> np.ndarray:
    """Start positions of the run with ``seed``: explicit, or uniform in the start region.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    seed : int
        Seed of the run.

    Returns
    -------
    ndarray, shape (M, 2)
        Start positions, m.
    """
    return _start(scenario, _streams(_v.seed(seed, "seed"), _START_STREAM)[0])


def _seed_list(seed: int | None, seeds: Iterable[int] | None, m_uavs: int, k_steps: int,
               keep: bool, stride: int = 1, link_bytes: int = 0) -> np.ndarray:  # fmt: skip
    """The seeds as an int64 array, checked; a ``range`` is checked (values and the memory
    of its runs) before it is materialised."""
    if seed is not None and seeds is not None:
        raise FieldError("seeds", "give either seed or seeds, not both")
    name = "seeds" if seeds is not None else "seed"
    if isinstance(seeds, range):
        if len(seeds) == 0:
            raise FieldError("seeds", "need at least one seed")
        _v.seed(seeds[0], name)
        _v.seed(seeds[-1], name)  # a range's values lie between its ends
        check_memory(len(seeds), k_steps, m_uavs, keep, stride, link_bytes)
        return np.arange(seeds.start, seeds.stop, seeds.step, dtype=np.int64)
    if seeds is None:
        values = [0 if seed is None else seed]
    else:
        if isinstance(seeds, str | bytes) or not isinstance(seeds, Iterable):
            raise FieldError("seeds", f"expected an iterable of integers, got {seeds!r}")
        values = list(itertools.islice(seeds, MAX_ITERATED_SEEDS + 1))
        if len(values) > MAX_ITERATED_SEEDS:
            raise FieldError(
                "seeds",
                f"more than {MAX_ITERATED_SEEDS:,} seeds from an iterator; pass a range "
                "(checked before it is expanded) or split the batch",
            )
    if not values:
        raise FieldError("seeds", "need at least one seed")
    for s in values:
        _v.seed(s, name)
    check_memory(len(values), k_steps, m_uavs, keep, stride, link_bytes)
    return np.array(values, dtype=np.int64)


#: Work values per run of a chunk: the FIM along the run (3 per step) and the run's own
#: inputs and state (start, slots, the kernel's work arrays: about 20 per UAV).
CHUNK_VALUES_PER_STEP = 3
CHUNK_VALUES_PER_UAV = 20


def _chunk_runs(n_runs: int, k_steps: int, m_uavs: int, link_bytes: int = 0) -> int:
    """Runs per chunk: at most CHUNK_RUNS runs or CHUNK_BYTES of work arrays (``link_bytes``
    more per run with links), and at least ~20 chunks for long batches so that progress is
    reported often."""
    per_run = 8 * (k_steps * CHUNK_VALUES_PER_STEP + m_uavs * CHUNK_VALUES_PER_UAV) + link_bytes
    return max(1, min(CHUNK_RUNS, CHUNK_BYTES // per_run, -(-n_runs // 20), n_runs))


def check_memory(
    n_runs: int, k_steps: int, m_uavs: int, keep: bool, stride: int = 1, link_bytes: int = 0
) -> None:
    """Refuse, before allocating, a batch whose arrays could not fit in memory.

    Parameters
    ----------
    n_runs : int
        Runs of the batch.
    k_steps : int
        Steps per run.
    m_uavs : int
        UAVs.
    keep : bool
        Whether the trajectories are kept.
    stride : int, default 1
        They are kept every this many steps (:func:`crlbswarm.results.kept_rows`).
    link_bytes : int, default 0
        Bytes of one run's link state (:func:`crlbswarm.links.link_state_bytes`; 0 without
        links), whose series add 5 values per step and run.

    Raises
    ------
    FieldError
        With the memory needed and the memory the process may take: field ``seeds`` for a
        batch, ``scenario`` when one run is already too large.
    """
    fixes = ["fewer runs per call"] if n_runs > 1 else []
    if keep:
        fixes.append("keep_trajectories=False (--no-trajectories) or a trajectory stride")
    fixes.append("fewer UAVs or steps (uavs.count, time.duration)")
    chunk = _chunk_runs(n_runs, k_steps, m_uavs, link_bytes)
    work = chunk * 8 * ((k_steps + 1) * CHUNK_VALUES_PER_STEP + m_uavs * CHUNK_VALUES_PER_UAV)
    work += chunk * link_bytes
    series = n_runs * (k_steps + 1) * len(LINK_SERIES) * 8 if link_bytes else 0
    _v.check_memory(
        result_nbytes(n_runs, k_steps, m_uavs, keep, stride) + work + series,
        "seeds" if n_runs > 1 else "scenario",
        f"{n_runs} run{'s' * (n_runs != 1)} of {k_steps} steps with {m_uavs} UAVs",
        "use " + ", or ".join(fixes),
    )


def layer_markers(sc: Scenario) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """The markers of the kernel's optional layers for ``sc``
    (:func:`crlbswarm.mission_kernel.run_mission`): the safety filter, the planner's route,
    the filter in the loop; each an empty array when on, None when off, so that the
    compiled mission holds only the layers the scenario uses.

    Parameters
    ----------
    sc : Scenario
        The scenario.

    Returns
    -------
    tuple
        ``(safe, route, track)``.
    """
    return (
        _ON if sc.safety.enabled else None,
        _ON if sc.planner_on else None,
        _ON if sc.estimation.enabled else None,
    )


def link_arguments(sc: Scenario) -> LinkModel | None:
    """The compiled mission's link model of ``sc`` (:func:`crlbswarm.links.link_model`), or
    None without a ``[links]`` table: the marker of the link layer, so that a mission with
    perfect links compiles none of it.

    Parameters
    ----------
    sc : Scenario
        The scenario.

    Returns
    -------
    LinkModel or None
        The model.
    """
    if sc.links is None:
        return None
    return link_model(sc.links, sc.adjacency, sc.uavs.leader, sc.time.step)


def _crowd(sc: Scenario) -> np.ndarray | None:
    """The kernel's marker of a swarm whose smallest separation needs the cell list."""
    return _ON if sc.uavs.count > SEPARATION_BRUTE_FORCE_MAX else None


def _keep_rows(k_steps: int, stride: int) -> np.ndarray:
    """Each step's row in the kept trajectories, -1 if not kept (``SceneArrays.keep``)."""
    keep = np.full(k_steps + 1, -1, dtype=np.int64)
    rows = kept_rows(k_steps, stride)
    keep[rows] = np.arange(rows.size)
    return keep


def kernel_arguments(sc: Scenario, stride: int = 1, first_step: int = 0
                     ) -> tuple[SceneArrays, Any, Any, Any, MissionConstants]:  # fmt: skip
    """The compiled mission's shared arguments for a scenario.

    Parameters
    ----------
    sc : Scenario
        The scenario.
    stride : int, default 1
        The trajectories are kept every ``stride`` steps and at the last (0: not kept).
    first_step : int, default 0
        The mission's step of the kernel's step 0 (``MissionConstants.first_step``: the
        start of a phase of a mission with faults).

    Returns
    -------
    tuple
        ``(scene, index, gains, eta_rule, constants)``: the shared arrays
        (:class:`crlbswarm.mission_kernel.SceneArrays`), the obstacle grid, the gains' and
        the eta rule's kernel tuples, the :class:`crlbswarm.mission_kernel.MissionConstants`.
    """
    motion, est, safety = sc.target_motion, sc.estimation, sc.safety
    f_mat, q_mat, n = motion_matrices(
        motion.model, sc.time.step, motion.turn_rate, motion.acceleration_noise
    )
    p0 = np.diag([est.prior_std**2] * 2 + [est.velocity_prior_std**2] * 2)
    roadmap = sc.roadmap
    if roadmap is not None:
        nodes, node_dist, next_node = roadmap.nodes, roadmap.dist_to_goal, roadmap.next_node
    else:
        nodes, node_dist, next_node = np.empty((0, 2)), np.empty(0), np.empty(0, np.int64)
    scene = SceneArrays(
        indptr=sc.adjacency.indptr,
        indices=sc.adjacency.indices,
        rects=sc.obstacle_set.rectangles,
        circles=sc.obstacle_set.circles,
        f_mat=np.ascontiguousarray(f_mat[:n, :n]),
        q_mat=np.ascontiguousarray(q_mat[:n, :n]),
        p0=np.ascontiguousarray(p0[:n, :n]),
        nodes=nodes,
        node_dist=node_dist,
        next_node=next_node,
        keep=_keep_rows(sc.time.steps, stride),
        snr=np.ascontiguousarray(
            np.broadcast_to(np.asarray(sc.radar_model.snr_constant, dtype=float), (sc.uavs.count,))
        ),
    )
    pair_margin, obstacle_margin = sc.safety_margins
    const = MissionConstants(
        dt=sc.time.step,
        leader=sc.uavs.leader,
        radius=sc.formation_radius,
        altitude=sc.altitude,
        # (the filter in the loop's A: equal UAVs only, which the scenario checks ensure)
        snr_constant=float(np.mean(sc.radar_model.snr_constant)),
        measure_every=est.measure_every,
        min_separation=safety.min_separation,
        sensing_radius=safety.radius_for(sc.time.step, sc.safety_margins[0]),
        decay=safety.decay,
        pair_margin=pair_margin,
        obstacle_margin=obstacle_margin,
        vmax_step=safety.max_speed * sc.time.step,
        inflation=sc.route_inflation,
        route_x=float(sc.route_goal[0]),
        route_y=float(sc.route_goal[1]),
        carrot=sc.route_carrot,
        replan_every=max(1, round(REPLAN_PERIOD / sc.time.step)),
        steer_radius=sc.steering_radius,
        centre_x=float(sc.formation_design.centre_offset[0]),
        centre_y=float(sc.formation_design.centre_offset[1]),
        sigma=float(sc.disturbance.sigma),
        first_step=int(first_step),
    )
    index = obstacle_index(
        sc.obstacle_set.rectangles, sc.obstacle_set.circles, float(sc.gains.safety_radius)
    )
    return scene, index, sc.gains.kernel_tuple(), sc.eta_rule.kernel_tuple(sc.gains), const


class _Batch:
    """The arrays of a whole batch (B runs), filled chunk by chunk."""

    def __init__(self, sc: Scenario, n_runs: int, rows: int) -> None:
        k1, m = sc.time.steps + 1, sc.uavs.count
        traj = (n_runs, rows, m, 2)
        self.positions = np.empty(traj)
        self.velocities = np.empty(traj)
        self.vref, self.centroid, self.target = (np.empty((n_runs, k1, 2)) for _ in range(3))
        self.eta, self.crlb, self.clearance, self.separation, self.distance_to_go = (
            np.empty((n_runs, k1)) for _ in range(5)
        )
        self.centroid_error = np.empty((n_runs, k1))
        self.cost = np.empty((n_runs, k1 - 1))
        est = sc.estimation.enabled
        self.estimate = np.full((n_runs, k1, 2), np.nan) if est else None
        self.estimate_variance = np.full((n_runs, k1), np.nan) if est else None
        self.fim_sum = np.zeros((k1, 2, 2))
        self.links = None if sc.links is None else np.empty((n_runs, len(LINK_SERIES), k1))


class _ChunkBuffers:
    """Work arrays of one chunk of runs, reused across chunks (page faults of fresh arrays
    cost as much as the work)."""

    def __init__(self, sc: Scenario, chunk_runs: int, n_state: int) -> None:
        k, m = sc.time.steps, sc.uavs.count
        self.start = np.empty((chunk_runs, m, 2))
        self.keys = np.empty((chunk_runs, 4), dtype=np.int64)
        self.ids = np.broadcast_to(np.arange(m, dtype=np.int64), (chunk_runs, m)).copy()
        self.estimate = np.zeros((chunk_runs, k + 1, 2))
        self.estimate_variance = np.zeros((chunk_runs, k + 1))
        self.fim = np.empty((chunk_runs, k + 1, 3))
        self.x0 = np.zeros((chunk_runs, n_state))
        self.delta = np.empty((chunk_runs, m, 2))
        self.velocity = np.zeros((chunk_runs, m, 2))  # (a mission starts at rest)
        # (no UAV frozen: a mission without faults passes the marker of a phase with
        # none, so that faults compile no other mission, :func:`_run_phase`)
        self.frozen = np.zeros(m, dtype=np.int8)
        self.status = np.empty(chunk_runs, dtype=np.int64)
        self.link_keys = np.empty((chunk_runs, 2), dtype=np.int64)


def run_keys(seed: int, phase: int = 0) -> np.ndarray:
    """The Philox keys of a run's disturbance and range noise (``RunInputs.keys``).

    Parameters
    ----------
    seed : int
        The run's seed.
    phase : int, default 0
        The phase of a mission with faults (:mod:`crlbswarm.faults`): its streams are
        those plus ``phase *`` :data:`crlbswarm.counter_rng.PHASE_STREAMS`.

    Returns
    -------
    ndarray of int64, shape (4,)
        :func:`crlbswarm.counter_rng.stream_key` of (seed, DISTURBANCE), then of (seed,
        RANGE_NOISE) (each stream shifted by the phase).
    """
    shift = phase * PHASE_STREAMS
    return np.array(
        stream_key(seed, DISTURBANCE + shift) + stream_key(seed, RANGE_NOISE + shift), np.int64
    )


def target_stream(seed: int) -> np.random.Generator:
    """The NumPy stream of the target's acceleration noise of the run with ``seed``.

    Parameters
    ----------
    seed : int
        The run's seed.

    Returns
    -------
    numpy.random.Generator
        The stream (a child of ``SeedSequence(seed)``, the same as :func:`simulate`'s).
    """
    return _streams(seed, _TARGET_STREAM)[0]


def _draw_run(sc: Scenario, seed: int, keys: np.ndarray) -> tuple[np.ndarray, np.random.Generator]:
    """One run's random inputs: the start (returned), the keys of the kernel's draws (into
    ``keys``), and the stream of the target's motion (returned)."""
    start_rng, motion_rng = _streams(seed, _START_STREAM, _TARGET_STREAM)
    keys[:] = run_keys(seed)
    return _start(sc, start_rng), motion_rng


def slot_offsets(sc: Scenario, start: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Each UAV's slot offset from the formation's centre, after the slot assignment.

    Unequal UAVs: a slot is made for its UAV's radar, so only a UAV of the same kind takes
    it.

    Parameters
    ----------
    sc : Scenario
        The scenario.
    start : ndarray, shape (M, 2)
        The start positions the slots are assigned from, m.
    centre : ndarray, shape (2,)
        The formation's centre, m.

    Returns
    -------
    ndarray, shape (M, 2)
        Each UAV's offset, m.
    """
    offsets = sc.slots - centre
    if sc.formation.assignment != "optimal":
        return offsets
    kinds = sc.radar_model.snr_constant if sc.radar_model.per_uav else None
    return offsets[assign_slots(start, sc.slots, sc.uavs.leader, kinds)]


def _diverged(sc: Scenario, run: int, seed: int, step: int) -> SimulationDivergedError:
    """The error of a run that ran away."""
    return SimulationDivergedError(
        f"run {run} (seed {seed}) diverged at step {step} (t = {step * sc.time.step:g} s): "
        f"NaN or a UAV beyond the model's range (coordinates within +-{DIVERGENCE_LIMIT:g} "
        "m); check the gains and the disturbance of the scenario"
    )


def _draw_inputs(sc: Scenario, seeds: np.ndarray, buf: _ChunkBuffers) -> Any:
    """Each run's start (into ``buf.start``) and keys from its own seed, the slots of F*
    (into ``buf.delta``), and the true target trajectories; returns the target states
    (B, K+1, 4)."""
    motion_rngs = []
    centre = np.asarray(sc.target) + sc.formation_design.centre_offset
    for i, s in enumerate(seeds):
        buf.start[i], motion_rng = _draw_run(sc, int(s), buf.keys[i])
        buf.delta[i] = slot_offsets(sc, buf.start[i], centre)
        motion_rngs.append(motion_rng)
    motion = sc.target_motion
    return target_trajectories(
        np.asarray(sc.target, dtype=float), np.asarray(motion.velocity, dtype=float),
        motion.model, sc.time.step, sc.time.steps, motion_rngs, motion.turn_rate,
        motion.acceleration_noise,
    )  # fmt: skip


def _run_chunk(
    sc: Scenario,
    seeds: np.ndarray,
    lo: int,
    batch: _Batch,
    buf: _ChunkBuffers,
    kernel_args: tuple[SceneArrays, Any, Any, Any, MissionConstants],
    links: LinkModel | None,
) -> None:
    """Simulate the runs ``lo .. lo + len(seeds) - 1`` of the batch (``links``: the link
    model, or None)."""
    n = len(seeds)
    hi = lo + n
    truth = _draw_inputs(sc, seeds, buf)
    link_io = None
    if links is not None and batch.links is not None:
        for i, s in enumerate(seeds):
            buf.link_keys[i] = stream_key(int(s), LINKS)
        link_io = (buf.link_keys[:n], batch.links[lo:hi])
    x0 = buf.x0[:n]
    x0[:, :2] = truth[:, 0, :2] + np.asarray(sc.estimation.prior_offset)
    batch.eta[lo:hi, 0] = 1.0
    batch.target[lo:hi] = truth[..., :2]
    fim = buf.fim[:n]
    outs = RunOutputs(
        batch.positions[lo:hi], batch.velocities[lo:hi], batch.vref[lo:hi], batch.eta[lo:hi],
        batch.clearance[lo:hi], batch.separation[lo:hi], batch.cost[lo:hi], buf.estimate[:n],
        buf.estimate_variance[:n], batch.distance_to_go[lo:hi], batch.centroid[lo:hi], fim,
        batch.crlb[lo:hi], batch.centroid_error[lo:hi],
    )  # fmt: skip
    inps = RunInputs(
        buf.start[:n], buf.keys[:n], batch.target[lo:hi], np.ascontiguousarray(truth[..., 2:]),
        x0, buf.delta[:n], buf.ids[:n], buf.velocity[:n],
    )  # fmt: skip
    status = buf.status[:n]
    if n == 1:  # one run: the serial kernel (no parallel driver to compile for it), its
        # per-UAV work on all threads for a large swarm
        wide = _ON if sc.uavs.count >= WIDE_UAVS and numba.get_num_threads() > 1 else None
        lio = None if link_io is None else (link_io[0][0], link_io[1][0])
        status[0] = run_mission(RunOutputs(*(a[0] for a in outs)),
                                RunInputs(*(a[0] for a in inps)), *kernel_args,
                                *layer_markers(sc), wide, _crowd(sc), links, lio,
                                buf.frozen)  # fmt: skip
    else:
        run_batch(tuple(outs), tuple(inps), status, *kernel_args, *layer_markers(sc),
                  _crowd(sc), links, link_io, buf.frozen)  # fmt: skip
    bad = np.flatnonzero(status >= 0)
    if bad.size:
        raise _diverged(sc, lo + int(bad[0]), int(seeds[bad[0]]), int(status[bad[0]]))
    if batch.estimate is not None and batch.estimate_variance is not None:  # estimation on
        batch.estimate[lo:hi] = buf.estimate[:n]
        batch.estimate_variance[lo:hi] = buf.estimate_variance[:n]
        summed = fim.sum(axis=0)
        batch.fim_sum[:, 0, 0] += summed[:, 0]
        batch.fim_sum[:, 1, 1] += summed[:, 1]
        batch.fim_sum[:, 0, 1] += summed[:, 2]
        batch.fim_sum[:, 1, 0] += summed[:, 2]


# ---------------------------------------------------------------------------------------
# Missions with faults: one phase after the other (crlbswarm.faults)
# ---------------------------------------------------------------------------------------
class _PhaseArguments(NamedTuple):
    """A phase's kernel arguments (its graph and FIM weights in ``kernel[0]``) and its kept
    rows: ``steps`` (the mission's kept steps in the phase), ``rows`` (their rows in the
    batch) and ``local`` (their rows in the phase's own arrays), ``last`` (the row of its
    last step, always kept)."""

    kernel: tuple[SceneArrays, Any, Any, Any, MissionConstants] | None
    rows: np.ndarray
    local: np.ndarray
    last: int
    n_rows: int
    links: LinkModel | None = None


def _phase_arguments(sc: Scenario, ph: Phase, kept: np.ndarray) -> _PhaseArguments:
    """The kernel arguments of a phase (None when its UAVs hover) and its kept rows."""
    in_phase = np.flatnonzero((kept >= ph.start) & (kept <= ph.stop))
    steps = kept[in_phase]
    keep = np.full(ph.stop - ph.start + 1, -1, dtype=np.int64)
    keep[steps - ph.start] = np.arange(steps.size)
    last = int(keep[-1]) if keep[-1] >= 0 else steps.size
    keep[-1] = last
    if ph.scenario is None:
        return _PhaseArguments(None, in_phase, np.arange(steps.size), last, steps.size + 1)
    scene, index, ctl, rule, const = kernel_arguments(ph.scenario, 0, ph.start)
    scene = phase_scene(scene, ph.indptr, ph.indices, np.where(ph.frozen != 0, 0.0, scene.snr),
                        keep)  # fmt: skip
    return _PhaseArguments((scene, index, ctl, rule, const), in_phase, np.arange(steps.size),
                           last, max(last + 1, steps.size), _phase_links(ph))  # fmt: skip


def _phase_links(ph: Phase) -> LinkModel | None:
    """The link model of a phase (None without a ``[links]`` table): the candidate links of
    its graph (:func:`crlbswarm.faults.swarm_links`, without the links of the UAVs silent
    and the links lost)."""
    sc = ph.scenario
    if sc is None or sc.links is None:
        return None
    adjacency = Adjacency.of_phase(ph.indptr, ph.indices)
    table = sc.links.model_copy(update={"use_graph": True})
    return link_model(table, adjacency, sc.uavs.leader, sc.time.step)


def phase_scene(scene: SceneArrays, indptr: np.ndarray, indices: np.ndarray, snr: np.ndarray,
                keep: np.ndarray) -> SceneArrays:  # fmt: skip
    """``scene`` with another graph, FIM weights and kept rows (a phase of a mission with
    faults, or the UAVs a flight's recorder counts).

    Parameters
    ----------
    scene : SceneArrays
        The scenario's arrays (:func:`kernel_arguments`).
    indptr : ndarray of int64
        The graph's CSR row pointers.
    indices : ndarray of int64
        Its neighbour indices.
    snr : ndarray, shape (M,)
        Each UAV's weight in the FIM (``snr`` of
        :class:`crlbswarm.mission_kernel.SceneArrays`; 0 leaves it out).
    keep : ndarray of int64
        Each step's kept row (-1: not kept).

    Returns
    -------
    SceneArrays
        The arrays.
    """
    return SceneArrays(
        indptr=indptr, indices=indices, rects=scene.rects, circles=scene.circles,
        f_mat=scene.f_mat, q_mat=scene.q_mat, p0=scene.p0, nodes=scene.nodes,
        node_dist=scene.node_dist, next_node=scene.next_node, keep=keep,
        snr=np.ascontiguousarray(snr, dtype=float),
    )  # fmt: skip


def _run_phases(sc: Scenario, plan: FaultPlan, phases: list[_PhaseArguments], seeds: np.ndarray,
                lo: int, batch: _Batch, buf: _ChunkBuffers) -> None:  # fmt: skip
    """Simulate the runs ``lo .. lo + len(seeds) - 1`` of a mission with faults, one phase
    after the other, each resuming from the state the last one stopped at."""
    n = len(seeds)
    hi = lo + n
    truth = _draw_inputs(sc, seeds, buf)
    batch.eta[lo:hi, 0] = 1.0
    batch.target[lo:hi] = truth[..., :2]
    q, v = buf.start[:n].copy(), np.zeros((n, sc.uavs.count, 2))
    delta = buf.delta[:n].copy()
    for p, (ph, args) in enumerate(zip(plan.phases, phases, strict=True)):
        if ph.scenario is None or args.kernel is None:
            _hover(sc, ph, args, lo, hi, batch, q)
            continue
        if ph.replan:
            for i in range(n):
                delta[i, ph.members] = replanned_slots(ph.scenario, q[i, ph.members],
                                                       batch.target[lo + i, ph.start])  # fmt: skip
        out = _run_phase(p, ph, args, seeds, lo, batch, buf, truth, q, v, delta)
        _record_phase(ph, args, out, lo, hi, batch, q, v)


def replanned_slots(sc: Scenario, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The slots of a re-planned formation (:mod:`crlbswarm.faults`) for one run.

    The UAVs take the slots of ``sc``'s formation by the rule of ``formation.assignment``
    (:func:`slot_offsets`) from the positions where the re-planning finds them; a regular
    polygon, whose CRLB does not depend on its rotation, is first turned to fit them (the
    rotation of least squares, :func:`crlbswarm.geometry.fitted_turn`); with the optimal
    assignment its leader takes the vertex nearest to it, before and after the turn. The
    simulator and the leader of ``crlbswarm fly`` re-plan with it.

    Parameters
    ----------
    sc : Scenario
        The scenario of the UAVs that go on (:func:`crlbswarm.faults.phase_scenario`).
    q : ndarray, shape (M', 2)
        Their positions, m.
    target : ndarray, shape (2,)
        The target's position then, m.

    Returns
    -------
    ndarray, shape (M', 2)
        Each UAV's offset from the formation's centre, m.
    """
    design = np.asarray(sc.target, dtype=float)
    centre = design + sc.formation_design.centre_offset
    p = q - (np.asarray(target, dtype=float) - design)
    if not sc.formation_design.regular:
        return slot_offsets(sc, p, centre)
    if sc.formation.assignment != "optimal":
        offsets = slot_offsets(sc, p, centre)
        return offsets @ fitted_turn(offsets, p - centre).T
    # (the optimal assignment: the leader takes the vertex nearest to it, before and after
    # the turn (the vertices are alike), the followers the others)
    leader = sc.uavs.leader
    slots = _nearest_to_leader(sc.slots - centre, p[leader] - centre, leader)
    offsets = slots[assign_slots(p, centre + slots, leader)]
    slots = _nearest_to_leader(slots @ fitted_turn(offsets, p - centre).T, p[leader] - centre,
                               leader)  # fmt: skip
    return slots[assign_slots(p, centre + slots, leader)]


def _nearest_to_leader(slots: np.ndarray, at: np.ndarray, leader: int) -> np.ndarray:
    """The vertices ``slots`` (M, 2) of a regular polygon relabelled in turn so that the
    leader's, ``slots[leader]``, is the one nearest to ``at`` (the leader)."""
    nearest = int(np.argmin(np.hypot(*(slots - at).T)))
    return np.roll(slots, leader - nearest, axis=0)


def _run_phase(p: int, ph: Phase, args: _PhaseArguments, seeds: np.ndarray, lo: int,
               batch: _Batch, buf: _ChunkBuffers, truth: np.ndarray, q: np.ndarray,
               v: np.ndarray, delta: np.ndarray) -> RunOutputs:  # fmt: skip
    """Run one phase of a chunk in the kernel; returns its outputs."""
    assert args.kernel is not None
    assert ph.scenario is not None
    n, k0, k1 = len(seeds), ph.start, ph.stop
    ks, ms = k1 - k0, ph.members.size
    traj = (n, args.n_rows, ms, 2)
    out = RunOutputs(
        np.empty(traj), np.empty(traj), np.empty((n, ks + 1, 2)), np.empty((n, ks + 1)),
        np.empty((n, ks + 1)), np.empty((n, ks + 1)), np.empty((n, ks)),
        np.zeros((n, ks + 1, 2)), np.zeros((n, ks + 1)), np.empty((n, ks + 1)),
        np.empty((n, ks + 1, 2)), np.empty((n, ks + 1, 3)), np.empty((n, ks + 1)),
        np.empty((n, ks + 1)),
    )  # fmt: skip
    out.eta[:, 0] = batch.eta[lo : lo + n, k0]
    keys = np.stack([run_keys(int(s), p) for s in seeds])
    inp = RunInputs(
        np.ascontiguousarray(q[:, ph.members]), keys,
        np.ascontiguousarray(batch.target[lo : lo + n, k0 : k1 + 1]),
        np.ascontiguousarray(truth[:, k0 : k1 + 1, 2:]), buf.x0[:n],
        np.ascontiguousarray(delta[:, ph.members]),
        np.ascontiguousarray(np.broadcast_to(ph.members, (n, ms))),
        np.ascontiguousarray(v[:, ph.members]),
    )  # fmt: skip
    status = buf.status[:n]
    frozen = ph.frozen  # (an array in every phase, zeros too: the mission without faults)
    link_io = None
    if args.links is not None:
        keys = np.array([stream_key(int(s), LINKS + p * PHASE_STREAMS) for s in seeds])
        link_io = (keys.astype(np.int64), np.empty((n, len(LINK_SERIES), ks + 1)))
    run_batch(tuple(out), tuple(inp), status, *args.kernel, *layer_markers(ph.scenario),
              _crowd(ph.scenario), args.links, link_io, frozen)  # fmt: skip
    if link_io is not None and batch.links is not None:
        batch.links[lo : lo + n, :, k0 : k1 + 1] = link_io[1]
    bad = np.flatnonzero(status >= 0)
    if bad.size:
        raise _diverged(ph.scenario, lo + int(bad[0]), int(seeds[bad[0]]),
                        k0 + int(status[bad[0]]))  # fmt: skip
    return out


def _record_phase(ph: Phase, args: _PhaseArguments, out: RunOutputs, lo: int, hi: int,
                  batch: _Batch, q: np.ndarray, v: np.ndarray) -> None:  # fmt: skip
    """Copy a phase's outputs into the batch (its step ``start`` overwritten), the UAVs
    no longer flying (and those lost, not yet declared lost) held where they stopped, at
    velocity 0, and carry its last state into ``q``, ``v``."""
    k0, k1 = ph.start, ph.stop
    steps = slice(k0, k1 + 1)
    batch.vref[lo:hi, steps] = out.v_ref
    batch.centroid[lo:hi, steps] = out.centroid
    for name in ("eta", "clearance", "separation", "distance_to_go", "crlb", "centroid_error"):
        getattr(batch, name)[lo:hi, steps] = getattr(out, name)
    batch.cost[lo:hi, k0:k1] = out.cost
    q[:, ph.members] = out.q[:, args.last]
    v[:, ph.members] = out.v[:, args.last]
    flying = ph.members[ph.frozen == 0]  # (the others hover: velocity 0)
    for row, j in zip(args.rows, args.local, strict=True):
        batch.positions[lo:hi, row] = q
        batch.positions[lo:hi, row][:, ph.members] = out.q[:, j]
        batch.velocities[lo:hi, row] = 0.0
        batch.velocities[lo:hi, row][:, flying] = out.v[:, j][:, ph.frozen == 0]


def _hover(sc: Scenario, ph: Phase, args: _PhaseArguments, lo: int, hi: int, batch: _Batch,
           q: np.ndarray) -> None:  # fmt: skip
    """A phase in which the UAVs hover (too few for a formation): every series holds its
    last value, but the CRLB of the UAVs left, at the (moving) target, and their centroid
    (none left: the CRLB is infinite, the centroid holds its last value)."""
    k0, k1 = ph.start, ph.stop
    steps = slice(k0, k1 + 1)
    target = batch.target[lo:hi, steps]
    held = ["eta", "clearance", "separation", "distance_to_go"]
    sensing = ph.members[ph.frozen == 0]  # (a UAV lost while they hover senses no more)
    if sensing.size:
        left = q[:, sensing]
        batch.crlb[lo:hi, steps] = crlb(left[:, None], target, sc.altitude,
                                        sc.radar_model.take(sensing))  # fmt: skip
        centroid = left.mean(axis=1)
        batch.centroid[lo:hi, steps] = centroid[:, None]
        offset = centroid[:, None] - target
        batch.centroid_error[lo:hi, steps] = np.hypot(offset[..., 0], offset[..., 1])
    else:
        batch.crlb[lo:hi, steps] = np.inf
        held += ["centroid", "centroid_error"]
    batch.vref[lo:hi, steps] = 0.0
    batch.cost[lo:hi, k0:k1] = 0.0
    if batch.links is not None:  # (no formation: no messages counted, no graph)
        none = {"sent": 0.0, "delivered": 0.0, "age": np.nan, "age_max": np.nan, "connected": 0.0}
        for i, name in enumerate(LINK_SERIES):
            batch.links[lo:hi, i, k0 + 1 : k1 + 1] = none[name]
    for name in held:
        series = getattr(batch, name)
        series[lo:hi, steps] = series[lo:hi, k0 : k0 + 1]
    for row in args.rows:
        batch.positions[lo:hi, row] = q
        batch.velocities[lo:hi, row] = 0.0


def _bound_steps(plan: FaultPlan, k_steps: int) -> np.ndarray:
    """The bound of the formation flown at each step (a phase's from its start)."""
    bound = np.empty(k_steps + 1)
    for ph in plan.phases:
        bound[ph.start : ph.stop + 1] = ph.bound
    return bound


def simulate(
    scenario: Scenario,
    seed: int | None = None,
    *,
    seeds: Iterable[int] | None = None,
    keep_trajectories: bool = True,
    trajectory_stride: int = 1,
    progress: Callable[[int], None] | None = None,
) -> MissionResult:
    """Run the mission of ``scenario`` for one seed or a batch of seeds.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario (see :func:`crlbswarm.load_scenario`).
    seed : int, optional
        Seed of a single run (default 0).
    seeds : iterable of int, optional
        Seeds of a batch of independent runs (instead of ``seed``). Run ``b`` is
        bit-identical to ``simulate(scenario, seed=seeds[b])``. A ``range`` is checked
        (its seeds and the memory of the batch) before it is expanded; other iterables
        give at most :data:`MAX_ITERATED_SEEDS` seeds.
    keep_trajectories : bool, default True
        Keep positions and velocities of every step. With ``False`` they are dropped after
        each step (``positions`` and ``velocities`` of the result are ``None``) and memory
        stays at a few arrays of shape (B, K+1) and the kernel's work arrays of shape
        (M, 2): use it for large campaigns and large swarms.
    trajectory_stride : int, default 1
        Keep the positions and velocities every this many steps (and at the last step):
        ``result.trajectory_steps`` lists the kept steps. The time series (CRLB, eta, ...)
        keep every step.
    progress : callable, optional
        Called with the number of runs finished after each chunk of runs (for progress bars).

    Returns
    -------
    MissionResult
        Trajectories, time series and per-run metrics.

    Raises
    ------
    FieldError
        (field ``seeds``) For an invalid seed, or a batch whose arrays would need more than
        half of the memory the process may still allocate (the size needed and the size
        available are in the message).
    SimulationDivergedError
        If a run produces NaN or positions beyond
        :data:`crlbswarm.mission_kernel.DIVERGENCE_LIMIT` (the coordinate range), naming
        the run, its seed and the step.
    """
    if not isinstance(scenario, Scenario):
        raise FieldError(
            "scenario", f"expected a crlbswarm.Scenario, got {type(scenario).__name__}"
        )
    sc = scenario
    if sc.extra_targets:
        raise FieldError("scenario", "has extra_targets (several targets): use simulate_groups")
    k_steps, m_uavs = sc.time.steps, sc.uavs.count
    stride = _v.count(trajectory_stride, "trajectory_stride", 1, max(k_steps, 1))
    links = link_arguments(sc)
    link_bytes = 0 if links is None else link_state_bytes(links)
    seed_arr = _seed_list(seed, seeds, m_uavs, k_steps, keep_trajectories, stride, link_bytes)
    n_runs = seed_arr.shape[0]
    kept = kept_rows(k_steps, stride if keep_trajectories else 0)
    kernel_args = kernel_arguments(sc, stride if keep_trajectories else 0)
    scene = kernel_args[0]
    batch = _Batch(sc, n_runs, kept.size)
    # Chunks: at most CHUNK_RUNS runs or CHUNK_BYTES of work arrays, and at least ~20 chunks
    # for long batches so that progress is reported often.
    chunk_runs = _chunk_runs(n_runs, k_steps, m_uavs, link_bytes)
    buf = _ChunkBuffers(sc, chunk_runs, scene.p0.shape[0])
    plan = sc.fault_plan
    phases = None if plan is None else [_phase_arguments(sc, ph, kept) for ph in plan.phases]
    for lo in range(0, n_runs, chunk_runs):
        if plan is None or phases is None:
            _run_chunk(sc, seed_arr[lo : lo + chunk_runs], lo, batch, buf, kernel_args, links)
        else:
            _run_phases(sc, plan, phases, seed_arr[lo : lo + chunk_runs], lo, batch, buf)
        if progress is not None:
            progress(min(lo + chunk_runs, n_runs))
    pcrb = None
    if sc.estimation.enabled:
        f_mat, q_mat = scene.f_mat, scene.q_mat
        pcrb = posterior_crlb(
            batch.fim_sum / n_runs, f_mat, q_mat, scene.p0, f_mat.shape[0],
            sc.estimation.measure_every,
        )  # fmt: skip
    return MissionResult(
        scenario=sc,
        seeds=seed_arr,
        time=np.arange(k_steps + 1) * sc.time.step,
        positions=batch.positions if keep_trajectories else None,
        velocities=batch.velocities if keep_trajectories else None,
        reference_velocity=batch.vref,
        centroid=batch.centroid,
        target=batch.target,
        estimate=batch.estimate,
        estimate_variance=batch.estimate_variance,
        pcrb=pcrb,
        eta=batch.eta,
        crlb=batch.crlb,
        cost=batch.cost,
        clearance=batch.clearance,
        separation=batch.separation,
        distance_to_go=batch.distance_to_go,
        bound=sc.formation_design.bound if plan is None else plan.phases[-1].bound,
        trajectory_stride=stride,
        centroid_error=batch.centroid_error,
        **_link_fields(batch.links),
        bound_steps=None if plan is None else _bound_steps(plan, k_steps),
    )


def _link_fields(series: np.ndarray | None) -> dict[str, np.ndarray]:
    """The link series of a batch as the result's fields ``link_<name>``
    (:data:`crlbswarm.links.LINK_SERIES`): views of the batch's array, not copies; none
    without links."""
    if series is None:
        return {}
    return {f"link_{n}": series[:, i] for i, n in enumerate(LINK_SERIES)}


def _group_arguments(
    sc: Scenario,
) -> tuple[SceneArrays, Any, Any, Any, MissionConstants, GroupArrays]:
    """The compiled arguments of a mission with several targets: the scene, constants and
    safety settings of group 0's scenario (the same fields for every group), the gains with
    the smallest epsilon and gamma of the groups (each resolved on its own graph: stable for
    all), the eta rule with the largest minimum (each group's floor kept), and the groups."""
    plan = sc.group_plan
    assert plan is not None  # (called with extra targets only)
    scenarios = plan.scenarios
    scene, index, _, _, const = kernel_arguments(scenarios[0])
    gains = [g.gains for g in scenarios]
    eps = min(float(g.epsilon) for g in gains)
    gamma = min(float(g.gamma) for g in gains)
    ctl = gains[0].model_copy(update={"epsilon": eps, "gamma": gamma})
    rule_sc = max(scenarios, key=lambda g: g.eta_rule.minimum)
    rule = rule_sc.eta_rule.kernel_tuple(ctl)
    sizes = [g.uavs.count for g in scenarios]
    indptr = [g.adjacency.indptr for g in scenarios]
    indices = [g.adjacency.indices for g in scenarios]
    groups = GroupArrays(
        bounds=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        leaders=np.array([g.uavs.leader for g in scenarios], dtype=np.int64),
        goals=np.array(
            [np.asarray(g.target) + g.formation_design.centre_offset for g in scenarios]
        ),
        radius=np.array([g.formation_radius for g in scenarios]),
        indptr=np.concatenate(indptr).astype(np.int64),
        indices=np.concatenate(indices).astype(np.int64),
        ptr_off=np.concatenate([[0], np.cumsum([p.size for p in indptr])]).astype(np.int64),
        idx_off=np.concatenate([[0], np.cumsum([i.size for i in indices])]).astype(np.int64),
    )
    return scene, index, ctl.kernel_tuple(), rule, const, groups


def simulate_groups(
    scenario: Scenario,
    seed: int | None = None,
    seeds: Iterable[int] | None = None,
    *,
    keep_trajectories: bool = True,
) -> GroupMissionResult:
    """Run a mission with several targets: the swarm split into groups (one per target, each
    with its own leader and formation, :attr:`crlbswarm.Scenario.group_plan`) flown together.

    Not in the paper (issue 11, item 4). Each group flies the paper's laws on its own UAVs
    and graph toward its own target (:func:`crlbswarm.mission_kernel.run_groups`); the
    obstacle repulsion, the safety filter and the motion act on all UAVs at once, so the
    safety filter keeps UAVs of different groups apart too. The starts are drawn for the
    whole swarm (``uavs.start_region``, the start separation), the disturbance from each
    run's seed as :func:`simulate` does; the slot assignment is made within each group.
    The planner and the filter in the loop are not used (the targets are static and known).

    Parameters
    ----------
    scenario : Scenario
        A validated scenario with ``extra_targets``.
    seed : int, optional
        Seed of a single run (default 0).
    seeds : iterable of int, optional
        Seeds of a batch (instead of ``seed``); run b is bit-identical to the single run
        with ``seeds[b]``.
    keep_trajectories : bool, default True
        Keep every UAV's positions and velocities in the result (they are always computed:
        each group's CRLB comes from them).

    Returns
    -------
    GroupMissionResult
        One :class:`~crlbswarm.MissionResult` per group, and the allocation.

    Raises
    ------
    FieldError
        If the scenario has no extra targets, or for an invalid seed or a batch that
        cannot fit in memory.
    SimulationDivergedError
        If a run diverges (naming the run, its seed and the step).
    """
    if not isinstance(scenario, Scenario):
        raise FieldError(
            "scenario", f"expected a crlbswarm.Scenario, got {type(scenario).__name__}"
        )
    sc = scenario
    plan = sc.group_plan
    if plan is None:
        raise FieldError("scenario", "has one target (no extra_targets): use simulate")
    k_steps, m_uavs = sc.time.steps, sc.uavs.count
    seed_arr = _seed_list(seed, seeds, m_uavs, k_steps, keep_trajectories)
    n_runs, n_groups = seed_arr.shape[0], len(plan.members)
    # The whole batch at once: positions and velocities of every UAV and step, the groups'
    # copies when the trajectories are kept, and the CRLB's temporaries (~6).
    per_value = 8.0 * n_runs * (k_steps + 1) * m_uavs * 2
    _v.check_memory(
        per_value * (2 + (2 if keep_trajectories else 0) + 3), "seeds" if n_runs > 1 else
        "scenario", f"{n_runs} runs of {k_steps} steps with {m_uavs} UAVs (several targets)",
        "use fewer runs per call, or fewer UAVs or steps",
    )  # fmt: skip
    scene, index, ctl, rule, const, groups = _group_arguments(sc)
    order = np.concatenate(plan.members)  # group order: row i is UAV order[i] of the swarm
    k1 = k_steps + 1
    q = np.empty((n_runs, k1, m_uavs, 2))
    v = np.zeros((n_runs, k1, m_uavs, 2))
    keys = np.empty((n_runs, 4), dtype=np.int64)
    delta = np.empty((n_runs, m_uavs, 2))
    for i, s in enumerate(seed_arr):
        start, _ = _draw_run(sc, int(s), keys[i])
        q[i, 0] = start[order]
        for g, gsc in enumerate(plan.scenarios):
            lo, hi = groups.bounds[g], groups.bounds[g + 1]
            delta[i, lo:hi] = slot_offsets(gsc, q[i, 0, lo:hi], groups.goals[g])
    outs = GroupOutputs(
        q, v, np.empty((n_runs, k1, n_groups, 2)), np.ones((n_runs, k1, n_groups)),
        np.empty((n_runs, k1, n_groups)), np.empty((n_runs, k1)),
        np.empty((n_runs, k_steps, n_groups)), np.empty((n_runs, k1, n_groups)),
    )  # fmt: skip
    unused = np.zeros((n_runs, k1, 2))  # (the targets are in ``groups``)
    ids = np.broadcast_to(order.astype(np.int64), (n_runs, m_uavs)).copy()  # draws by swarm UAV
    inps = RunInputs(q[:, 0], keys, unused, unused, np.zeros((n_runs, 2)), delta, ids,
                     np.zeros((n_runs, m_uavs, 2)))  # fmt: skip
    status = np.empty(n_runs, dtype=np.int64)
    run_group_batch(tuple(outs), tuple(inps), status, scene, index, ctl, rule, const, groups,
                    layer_markers(plan.scenarios[0])[0])  # fmt: skip
    bad = np.flatnonzero(status >= 0)
    if bad.size:
        raise _diverged(sc, int(bad[0]), int(seed_arr[bad[0]]), int(status[bad[0]]))
    time = np.arange(k1) * sc.time.step
    results = []
    for g, gsc in enumerate(plan.scenarios):
        lo, hi = groups.bounds[g], groups.bounds[g + 1]
        pos = q[:, :, lo:hi]
        target = np.broadcast_to(np.asarray(gsc.target, dtype=float), (n_runs, k1, 2))
        results.append(MissionResult(
            scenario=gsc, seeds=seed_arr, time=time,
            positions=pos.copy() if keep_trajectories else None,
            velocities=v[:, :, lo:hi].copy() if keep_trajectories else None,
            reference_velocity=outs.v_ref[:, :, g].copy(), centroid=pos.mean(axis=-2),
            target=target.copy(), estimate=None, estimate_variance=None, pcrb=None,
            eta=outs.eta[:, :, g].copy(),
            crlb=crlb(pos, target, gsc.altitude, gsc.radar_model),
            cost=outs.cost[:, :, g].copy(), clearance=outs.clearance[:, :, g].copy(),
            separation=outs.separation, distance_to_go=outs.distance_to_go[:, :, g].copy(),
            bound=gsc.formation_design.bound,
        ))  # fmt: skip
    return GroupMissionResult(scenario=sc, plan=plan, groups=tuple(results))
