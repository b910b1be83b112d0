r"""Failures during a mission: UAVs and links lost, and the swarm that re-forms (not in the
paper).

The scenario's ``[faults]`` table (:class:`FaultsConfig`) lists UAVs lost at given times
(``uav_lost``, and ``leader_lost`` for whichever UAV leads at that time) and links lost
(``link_lost``). :func:`plan_faults` turns it into the mission's **phases**: spans of steps
over which the swarm's membership, graph, leader and formation are fixed. The simulator
runs one phase after the other, each resuming from the state where the last one stopped
(:func:`crlbswarm.simulate`). The choices (documented in ``docs/faults.md``):

Loss
    A lost UAV stops sending and stops moving (it hovers where it was lost, or has landed
    there: its recorded position stays put) and no longer senses: its range leaves the FIM
    at once. Its neighbours stop hearing it at once, and their laws of eqs. (14) and (19)
    sum over the neighbours they hear, so its terms drop out; a lost leader sends no more
    reference (the followers' consensus then runs among themselves). A lost link is no
    longer heard by either end, from the step it is lost.
Detection
    Nobody is told. The swarm declares a UAV lost after ``timeout`` seconds without a
    message from it (the field of :class:`FaultsConfig`). A live UAV is never declared
    lost: with perfect links it is never silent, and with lossy links (a ``[links]``
    table) the timeout is taken to be longer than any gap loss and delay make (a run's
    ``max_age_s`` tells the longest). Until then the formation keeps its slots, its leader
    and its graph, minus what is silent.
Re-planning (at the step a loss is declared)
    The UAVs left, and the graph among them (the swarm's communication graph,
    :func:`swarm_links`, without the lost UAVs and lost links), form the new swarm. If
    that graph has several parts, the part with the most UAVs goes on (ties: the part of
    the current leader, then the part of the lowest index) and the others hover where
    they are: the outcome is ``split``. If fewer than three UAVs go on, none can fly a
    formation: all hover, the outcome is ``too_few``.
    Otherwise the new swarm flies the optimal formation for its own UAVs (the scenario's
    design over the same target, for these UAVs and their radars: :func:`phase_scenario`),
    its slots taken by the rule of ``formation.assignment`` from the positions where the
    re-planning finds the UAVs (a regular polygon first turned to fit them, its leader,
    with the optimal assignment, on the vertex nearest to it); the CRLB is then measured
    against the new bound.
Leader election
    If the leader is among the UAVs that go on, it stays leader; otherwise the UAV with the
    lowest index among them leads. Every UAV can apply the rule alone, with no vote.
Links
    With a ``[links]`` table a silent UAV and a lost link leave the link layer's graph as
    they leave the laws'; the link layer restarts at each phase, as at the start.
Draws
    Phase ``p`` draws the disturbance (and the links) from the streams ``stream + p *``
    :data:`crlbswarm.counter_rng.PHASE_STREAMS` of the run's seed, so a run's bits do not
    depend on its batch; phase 0 is the mission without faults, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated

import numpy as np
from pydantic import Field

from ._config import ConfigModel, PositiveFloat
from ._validation import MIN_UAVS
from .errors import FieldError, ScenarioError

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = [
    "FAULT_OUTCOMES",
    "MAX_FAULTS",
    "FaultPlan",
    "FaultsConfig",
    "LinkLoss",
    "Phase",
    "SwarmDecision",
    "UavLoss",
    "check_faults",
    "decide",
    "fault_step",
    "phase_scenario",
    "plan_faults",
    "swarm_links",
]

#: Most events in a ``[faults]`` table (UAVs and links lost).
MAX_FAULTS = 64

#: The outcomes a fault can give a run (:data:`crlbswarm.results.OUTCOMES`): the swarm's
#: graph fell into parts, or fewer than three UAVs were left to fly a formation.
FAULT_OUTCOMES = ("split", "too_few")

Time = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
Index = Annotated[int, Field(ge=0)]


class UavLoss(ConfigModel):
    """A UAV lost during the mission."""

    uav: Index = Field(description="index of the UAV (0 .. M-1)")
    time: Time = Field(description="time it is lost, s")


class LinkLoss(ConfigModel):
    """A link of the communication graph lost during the mission (both directions)."""

    uavs: Annotated[list[Index], Field(min_length=2, max_length=2)] = Field(
        description="the two UAVs [m, p] of a link of the graph"
    )
    time: Time = Field(description="time it is lost, s")


class FaultsConfig(ConfigModel):
    """Failures during the mission: the scenario's ``[faults]`` table (none: no failures).
    The model is described in the module docstring and ``docs/faults.md``."""

    timeout: PositiveFloat = Field(
        1.0, description="silence after which the swarm declares a UAV lost and re-plans, s"
    )
    uav_lost: Annotated[list[UavLoss], Field(max_length=MAX_FAULTS)] = Field(
        default_factory=list, description="UAVs lost: [[faults.uav_lost]] uav = m, time = t"
    )
    leader_lost: Time | None = Field(
        None, description="time the UAV leading at that time is lost, s (none: never)"
    )
    link_lost: Annotated[list[LinkLoss], Field(max_length=MAX_FAULTS)] = Field(
        default_factory=list,
        description="links lost: [[faults.link_lost]] uavs = [m, p], time = t",
    )


def swarm_links(sc: Scenario) -> set[tuple[int, int]]:
    """The links of the swarm's communication graph, ``(a, b)`` with ``a < b``: those of the
    configured graph, or, with ``links.use_graph = false``, every pair (any two UAVs in
    range may talk). Losses, splits and re-plannings are decided on them.

    Parameters
    ----------
    sc : Scenario
        The scenario.

    Returns
    -------
    set of tuple of int
        The links.
    """
    if sc.links is not None and not sc.links.use_graph:
        n = sc.uavs.count
        return {(a, b) for a in range(n) for b in range(a + 1, n)}
    return {(int(a), int(b)) for a, b in sc.adjacency.edges}


def check_faults(sc: Scenario) -> None:
    """The checks of a ``[faults]`` table against its scenario (called by its validation).

    Parameters
    ----------
    sc : Scenario
        The scenario, with ``faults``.

    Raises
    ------
    FieldError
        Naming the field: a UAV or link that does not exist, a UAV lost twice, a layer
        the faults do not support yet, or, with a ``[links]`` table, a timeout shorter than
        a send period plus the largest delay (a UAV that flies would look silent).
    """
    faults = sc.faults
    assert faults is not None
    unsupported = (
        ("extra_targets", bool(sc.extra_targets), "several targets"),
        ("estimation.enabled", sc.estimation.enabled, "sensing in the loop"),
    )
    for name, on, what in unsupported:
        if on:
            raise FieldError("faults", f"is not supported yet with {what} ({name})")
    links, dt = sc.links, sc.time.step
    if links is not None:
        gap = links.silence_steps(dt) * dt
        if faults.timeout < gap - 1e-9:
            raise FieldError(
                "faults.timeout", f"{faults.timeout:g} s is shorter than the links' send "
                f"period plus their largest delay, {gap:g} s: a UAV that flies would look lost",
            )  # fmt: skip
    n = sc.uavs.count
    seen: set[int] = set()
    for i, loss in enumerate(faults.uav_lost):
        if loss.uav >= n:
            raise FieldError(f"faults.uav_lost.{i}.uav", f"must be below uavs.count = {n}")
        if loss.uav in seen:
            raise FieldError(f"faults.uav_lost.{i}.uav", f"UAV {loss.uav} is lost twice")
        seen.add(loss.uav)
    edges = swarm_links(sc)
    for i, cut in enumerate(faults.link_lost):
        a, b = sorted(cut.uavs)
        if (a, b) not in edges:
            raise FieldError(
                f"faults.link_lost.{i}.uavs", f"[{a}, {b}] is not a link of the graph"
            )


@dataclass(frozen=True)
class Phase:
    """A span of steps with a fixed swarm (:func:`plan_faults`).

    Parameters
    ----------
    start, stop : int
        Its first and last steps (the next phase starts at ``stop``).
    members : ndarray of int64
        The UAVs it simulates (swarm indices, increasing): the swarm of the last
        re-planning, lost ones not yet declared included.
    frozen : ndarray of int8
        Per member, 1 if it is lost and not yet declared lost (it does not move).
    indptr, indices : ndarray of int64
        The graph its laws use, over the members (CSR): the scenario's graph without the
        links to frozen members and without the lost links.
    scenario : Scenario or None
        The swarm's scenario (its formation, leader, gains); None when the UAVs hover
        (too few).
    replan : bool
        Whether the members take new slots at ``start``.
    bound : float
        The CRLB bound of the formation flown (when the UAVs hover, that of the last
        formation), m^2.
    """

    start: int
    stop: int
    members: np.ndarray
    frozen: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    scenario: Scenario | None
    replan: bool
    bound: float


@dataclass(frozen=True)
class FaultPlan:
    """The phases of a mission with faults (:func:`plan_faults`).

    Parameters
    ----------
    phases : tuple of Phase
        In order; they cover steps 0 .. K.
    outcome : str
        ``""``, or one of :data:`FAULT_OUTCOMES`.
    events : tuple of str
        What happens, one line per event (``"t = 100 s: UAV 2 lost"``).
    """

    phases: tuple[Phase, ...]
    outcome: str
    events: tuple[str, ...] = field(default=())


def phase_scenario(sc: Scenario, members: np.ndarray, leader: int, edges: np.ndarray,
                   label: str) -> Scenario:  # fmt: skip
    """The scenario of the UAVs ``members`` flying on after a re-planning.

    It is ``sc`` restricted to those UAVs (:meth:`crlbswarm.Scenario.restricted`: their
    count, radars and start), ``leader`` (a swarm index) as leader, the graph ``edges``
    (swarm indices), no faults; the formation is then the scenario's design for these
    UAVs.

    Parameters
    ----------
    sc : Scenario
        The mission's scenario.
    members : ndarray of int
        The UAVs (swarm indices, increasing).
    leader : int
        The leader (a member).
    edges : ndarray of int, shape (E, 2)
        The graph among them (swarm indices).
    label : str
        Said in an error: when the re-planning happens.

    Returns
    -------
    Scenario
        The validated scenario.

    Raises
    ------
    FieldError
        ``faults``, when these UAVs cannot fly a valid mission.
    """
    local = {int(m): i for i, m in enumerate(members)}
    graph = {"kind": "edges", "edges": [[local[int(a)], local[int(b)]] for a, b in edges]}
    try:
        return sc.restricted(members.tolist(), leader, name=f"{sc.name}/{len(members)} UAVs",
                             faults=None, graph=graph)  # fmt: skip
    except ScenarioError as exc:
        reason = f"{exc.field}: {exc.reason}" if exc.field else exc.reason
        raise FieldError(
            "faults", f"{label}, UAVs {members.tolist()} cannot fly on: {reason}"
        ) from None


def _phase_graph(members: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The CSR rows of ``edges`` (swarm indices) over ``members``, neighbours sorted (a
    member may have none, and there may be no member: a phase's graph, :class:`Phase`).

    Parameters
    ----------
    members : ndarray of int64
        The UAVs (swarm indices, increasing): row ``i`` is ``members[i]``'s.
    edges : ndarray of int64, shape (E, 2)
        The links (swarm indices).

    Returns
    -------
    indptr, indices : ndarray of int64
        CSR row pointers and neighbour rows.
    """
    local = np.full(int(members.max(initial=-1)) + 1, -1, dtype=np.int64)
    local[members] = np.arange(members.size)
    e = local[edges] if edges.size else np.empty((0, 2), np.int64)
    rows = np.concatenate([e[:, 0], e[:, 1]])
    cols = np.concatenate([e[:, 1], e[:, 0]])
    order = np.lexsort((cols, rows))
    indptr = np.zeros(members.size + 1, dtype=np.int64)
    np.add.at(indptr, rows + 1, 1)
    return np.cumsum(indptr), cols[order].astype(np.int64)


def _parts(members: list[int], edges: set[tuple[int, int]]) -> list[list[int]]:
    """The connected parts of the graph ``edges`` over ``members`` (each sorted)."""
    neighbours: dict[int, list[int]] = {m: [] for m in members}
    for a, b in edges:
        if a in neighbours and b in neighbours:
            neighbours[a].append(b)
            neighbours[b].append(a)
    parts, seen = [], set()
    for m in members:
        if m in seen:
            continue
        stack, part = [m], []
        seen.add(m)
        while stack:
            x = stack.pop()
            part.append(x)
            for y in neighbours[x]:
                if y not in seen:
                    seen.add(y)
                    stack.append(y)
        parts.append(sorted(part))
    return parts


@dataclass
class _Swarm:
    """The planner's state: the swarm flying, what is silent, what is lost."""

    members: list[int]
    leader: int
    edges: set[tuple[int, int]]
    scenario: Scenario | None
    bound: float
    silent: set[int] = field(default_factory=set)
    cut: set[tuple[int, int]] = field(default_factory=set)
    outcome: str = ""


def _events(sc: Scenario) -> tuple[dict[int, list[int | str]], dict[int, list[tuple[int, int]]],
                                    int]:  # fmt: skip
    """The losses by step (a UAV index, or "leader"), the links lost by step, and the
    detection delay in steps."""
    faults = sc.faults
    assert faults is not None
    dt, k_steps = sc.time.step, sc.time.steps
    losses: dict[int, list[int | str]] = {}
    for loss in faults.uav_lost:
        losses.setdefault(fault_step(loss.time, dt, k_steps), []).append(loss.uav)
    if faults.leader_lost is not None:
        losses.setdefault(fault_step(faults.leader_lost, dt, k_steps), []).append("leader")
    cuts: dict[int, list[tuple[int, int]]] = {}
    for cut in faults.link_lost:
        a, b = sorted(cut.uavs)
        cuts.setdefault(fault_step(cut.time, dt, k_steps), []).append((a, b))
    losses = {k: v for k, v in losses.items() if k < k_steps}
    cuts = {k: v for k, v in cuts.items() if k < k_steps}
    return losses, cuts, max(1, math.ceil(min(faults.timeout / dt, k_steps + 1.0) - 1e-9))


def fault_step(time: float, dt: float, k_steps: int) -> int:
    """The step at which a fault of the ``[faults]`` table happens.

    Parameters
    ----------
    time : float
        Its time, s (>= 0, finite).
    dt : float
        The time step, s.
    k_steps : int
        The mission's steps, K.

    Returns
    -------
    int
        ``round(time / dt)``, or ``K + 1`` for any time beyond the mission's end (after
        it: the fault never happens; a time of 1e308 s is no overflow).
    """
    return round(min(time / dt, k_steps + 1.0))


def plan_faults(sc: Scenario) -> FaultPlan:
    """The phases of the mission of a scenario with a ``[faults]`` table.

    Parameters
    ----------
    sc : Scenario
        The scenario (``sc.faults`` not None).

    Returns
    -------
    FaultPlan
        The phases, the outcome and the events.

    Raises
    ------
    FieldError
        ``faults``, when the UAVs left after a re-planning cannot fly a valid mission.
    """
    losses, cuts, delay = _events(sc)
    dt, k_steps = sc.time.step, sc.time.steps
    swarm = _Swarm(list(range(sc.uavs.count)), sc.uavs.leader,
                   swarm_links(sc), sc,
                   float(sc.formation_design.bound))  # fmt: skip
    detect: dict[int, list[int]] = {}
    steps = sorted({0, k_steps, *losses, *cuts})
    phases: list[Phase] = []
    events: list[str] = []
    k, replan = 0, False
    while k < k_steps:
        for what in losses.get(k, []):
            uav = swarm.leader if what == "leader" else int(what)
            if uav in swarm.members and uav not in swarm.silent:
                swarm.silent.add(uav)
                detect.setdefault(k + delay, []).append(uav)
                events.append(f"t = {k * dt:g} s: UAV {uav} lost")
        for a, b in cuts.get(k, []):
            swarm.cut.add((a, b))
            detect.setdefault(k + delay, [])
            events.append(f"t = {k * dt:g} s: link {a}-{b} lost")
        if k in detect and swarm.scenario is not None:
            replan = _replan(sc, swarm, detect.pop(k), k, events)
        later = [s for s in (*steps, *detect) if s > k]
        stop = min(min(later), k_steps)
        phases.append(_phase(swarm, k, stop, replan))
        k, replan = stop, False
    return FaultPlan(tuple(phases), swarm.outcome, tuple(events))


@dataclass(frozen=True)
class SwarmDecision:
    """Who flies on after a re-planning (:func:`decide`).

    Parameters
    ----------
    parts : list of list of int
        The parts of the graph among the UAVs left, the part that goes on first.
    members : list of int
        The part that goes on (swarm indices, increasing).
    leader : int
        Its leader.
    edges : ndarray of int64, shape (E, 2)
        The graph among its members (swarm indices).
    outcome : str
        ``""``, ``"split"`` (the graph fell into parts) or ``"too_few"`` (fewer than
        three UAVs go on: they hover).
    """

    parts: list[list[int]]
    members: list[int]
    leader: int
    edges: np.ndarray
    outcome: str


def decide(members: list[int], leader: int, edges: set[tuple[int, int]],
           lost: set[int]) -> SwarmDecision:  # fmt: skip
    """The re-planning's decision (the rules of the module docstring): drop the UAVs
    ``lost``, keep the part of the graph that goes on, elect its leader. The simulator
    (:func:`plan_faults`) and every UAV of ``crlbswarm fly`` decide with it.

    Parameters
    ----------
    members : list of int
        The swarm before (swarm indices).
    leader : int
        Its leader.
    edges : set of tuple of int
        The links among them (``(a, b)``, ``a < b``), lost links left out.
    lost : set of int
        The UAVs declared lost.

    Returns
    -------
    SwarmDecision
        The parts, the members and leader that go on, their graph, the outcome.
    """
    left = [m for m in members if m not in lost]
    parts = _parts(left, edges)
    parts.sort(key=lambda p: (-len(p), leader not in p, p[0]))
    keep = parts[0] if parts else []
    outcome = "too_few" if len(keep) < MIN_UAVS else "split" if len(parts) > 1 else ""
    inner = np.array(sorted(e for e in edges if e[0] in keep and e[1] in keep),
                     dtype=np.int64).reshape(-1, 2)  # fmt: skip
    new_leader = leader if leader in keep else (keep[0] if keep else leader)
    return SwarmDecision(parts, keep, new_leader, inner, outcome)


def _replan(sc: Scenario, swarm: _Swarm, declared: list[int], k: int, events: list[str]) -> bool:
    """Re-plan at step ``k``: drop the UAVs ``declared`` lost and the lost links, keep the
    part that goes on, elect its leader, design its formation. Returns whether the
    members take new slots."""
    dt = sc.time.step
    label = f"after the re-planning at t = {k * dt:g} s"
    gone = set(declared)
    swarm.edges -= swarm.cut
    swarm.cut = set()
    swarm.silent -= gone
    choice = decide(swarm.members, swarm.leader, swarm.edges, gone)
    parts, keep = choice.parts, choice.members
    if len(parts) > 1:
        events.append(f"t = {k * dt:g} s: the graph split into {[p for p in parts]}; "
                      f"UAVs {keep} go on, the others hover")  # fmt: skip
    swarm.members = keep
    if choice.outcome:
        swarm.outcome = choice.outcome
    if choice.outcome == "too_few":
        swarm.scenario = None
        events.append(f"t = {k * dt:g} s: {len(keep)} UAVs left, too few for a formation: "
                      "they hover")  # fmt: skip
        return False
    swarm.leader = choice.leader
    swarm.scenario = phase_scenario(sc, np.array(keep), swarm.leader, choice.edges, label)
    swarm.bound = float(swarm.scenario.formation_design.bound)
    events.append(
        f"t = {k * dt:g} s: re-planned for UAVs {keep}, leader {swarm.leader}, bound "
        f"{swarm.bound:.4g} m^2"
    )
    return bool(gone) or len(parts) > 1


def _phase(swarm: _Swarm, start: int, stop: int, replan: bool) -> Phase:
    """The phase of the swarm's present state from ``start`` to ``stop``."""
    members = np.array(swarm.members, dtype=np.int64)
    frozen = np.array([m in swarm.silent for m in swarm.members], dtype=np.int8)
    live = [
        e for e in swarm.edges
        if e not in swarm.cut and e[0] in swarm.members and e[1] in swarm.members
        and e[0] not in swarm.silent and e[1] not in swarm.silent
    ]  # fmt: skip
    indptr, indices = _phase_graph(members, np.array(sorted(live), dtype=np.int64).reshape(-1, 2))
    return Phase(start, stop, members, frozen, indptr, indices, swarm.scenario, replan,
                 swarm.bound)  # fmt: skip
