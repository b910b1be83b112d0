"""The numerical checks of a scenario: what validates field by field but cannot fly.

:func:`check_scenario` runs when a :class:`~crlbswarm.scenario.Scenario` is built, after every
field has passed its own check: the target and the starts must lie outside the obstacles,
the graph must be connected, the gains must be inside the stability bounds of the linear
laws and the step-size limits of the nonlinear ones, the target's slot formation must fit
between the obstacles, sensing in the loop and the target's motion must be consistent, the
safety filter's settings must fit the formation and the starts, and with the planner on a
route must exist for the formation's smallest footprint. Each failure raises
:class:`~crlbswarm.errors.FieldError` naming the dotted field.

:func:`convergence_estimate` and :func:`preflight` are the checks that warn instead of
refusing: whether the mission is long enough for the formation to settle.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from . import _validation as _v
from .errors import FieldError
from .graphs import Adjacency, formation_step_limit, settling_steps
from .obstacles import Obstacles, obstacle_clearance
from .planning import check_roadmap_size, plan_route, segment_clear
from .tracking import motion_matrices

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = ["check_scenario", "convergence_estimate", "preflight"]


def check_scenario(scenario: Scenario) -> None:
    """Check a scenario whose fields are each valid (called by its model validator).

    Parameters
    ----------
    scenario : Scenario
        The scenario.

    Raises
    ------
    FieldError
        For the first problem found, naming the dotted field.
    """
    obstacles = scenario.obstacle_set
    _check_outside(obstacles, np.asarray(scenario.target)[None], "target")
    if scenario.extra_targets:
        _check_outside(obstacles, np.asarray(scenario.extra_targets), "extra_targets")
    if scenario.uavs.start is not None:
        _check_outside(obstacles, np.asarray(scenario.uavs.start), "uavs.start")
    elif scenario.uavs.start_region is not None:  # (exactly one of the two is set)
        (x0, x1), (y0, y1) = scenario.uavs.start_region
        for i, ob in enumerate(scenario.obstacles):
            if ob.overlaps_box(x0, x1, y0, y1):
                raise FieldError(
                    "uavs.start_region", f"overlaps obstacles[{i}]; starts could be inside it"
                )
    if scenario.extra_targets:  # one group per target, each checked as its own mission
        _check_groups(scenario)
        return
    try:
        adjacency = scenario.adjacency
    except FieldError as exc:
        field = exc.field if exc.field.startswith("graph") else "graph"
        raise FieldError(field, exc.reason) from exc
    _check_gains(scenario, adjacency)
    _check_motion(scenario)
    _check_estimation(scenario, obstacles)
    scenario.formation_design  # noqa: B018  (F*, or the best formation that fits: may refuse)
    _check_safety(scenario)
    _check_route(scenario)


def _check_groups(scenario: Scenario) -> None:
    """A swarm with several targets: the layers that need one formation are off, the starts
    fit, and each group's own scenario (:attr:`Scenario.group_plan`) is valid."""
    if scenario.estimation.enabled:
        raise FieldError("estimation.enabled", "several targets fly with known targets: set "
                         "estimation.enabled = false")  # fmt: skip
    if scenario.target_motion.moving:
        raise FieldError("target_motion.model", 'several targets are static: set '
                         'target_motion.model = "static"')  # fmt: skip
    if scenario.graph.kind == "edges":
        why = 'each group builds its own graph of this kind; "edges" names UAVs of the swarm'
        raise FieldError("graph.kind", f"with several targets {why}: choose another kind")
    if scenario.safety.enabled:
        _check_starts(scenario)
    plan = scenario.group_plan
    assert plan is not None  # (extra targets)
    # The groups' formations must not overlap: slots of two groups as far apart as two
    # slots of one (each group's own design keeps that within the group).
    slots = [g.slots for g in plan.scenarios]
    need = 2.0 * scenario.start_separation if scenario.safety.enabled else (
        scenario.safety.min_separation)  # fmt: skip
    for j in range(1, len(slots)):
        for i in range(j):
            gaps = np.hypot(*(slots[i][:, None] - slots[j][None]).transpose(2, 0, 1))
            if gaps.min() < need:
                field = "target" if i == 0 and j == 0 else f"extra_targets.{j - 1}"
                raise FieldError(
                    field,
                    f"the formations over targets {i} and {j} overlap: two of their slots are "
                    f"{gaps.min():.4g} m apart, closer than {need:.4g} m; move the targets "
                    "apart",
                )


def _check_safety(scenario: Scenario) -> None:
    """The safety filter's settings against the formation, the gains and the starts."""
    safety = scenario.safety
    if not safety.enabled:
        return
    cruise = scenario.control.cruise_speed
    if safety.max_speed < cruise:
        raise FieldError(
            "safety.max_speed",
            f"{safety.max_speed:g} m/s is below control.cruise_speed = {cruise:g} m/s: the "
            "leader could not fly its own reference",
        )
    need, side = scenario.start_separation, scenario.formation_side
    if 2.0 * need > side:
        why = (
            "the formation itself would break it"
            if need >= side
            else "a UAV could not pass between two neighbours in their slots (the formation "
            "could lock up)"
        )
        raise FieldError(
            "safety.min_separation",
            f"{safety.min_separation:g} m plus a margin of {need - safety.min_separation:.3g} m "
            f"against the disturbance needs a side of F* of at least 2 x {need:.4g} = "
            f"{2.0 * need:.4g} m, but it is {side:.4g} m: {why}; lower it, fly higher (a "
            "larger F*) or use fewer UAVs",
        )
    dt = scenario.time.step
    reach = need + 2.0 * safety.max_speed * dt
    radius = safety.radius_for(dt, scenario.safety_margins[0])
    if radius < reach:
        raise FieldError(
            "safety.sensing_radius",
            f"{radius:g} m is too short: two UAVs farther apart could close "
            f"the gap in one step; it must be at least {reach:.4g} m (min_separation, its "
            "margin and 2 max_speed time.step)",
        )
    _check_starts(scenario)


def _check_starts(scenario: Scenario) -> None:
    """With the safety filter on: the explicit starts keep the start separation, or the start
    region has room to draw them so."""
    safety, need = scenario.safety, scenario.start_separation
    if scenario.uavs.start is not None:
        start = np.asarray(scenario.uavs.start, dtype=float)
        gaps = np.hypot(*(start[:, None] - start[None, :]).transpose(2, 0, 1))
        np.fill_diagonal(gaps, math.inf)
        i, j = np.unravel_index(int(np.argmin(gaps)), gaps.shape)
        if gaps[i, j] < need:
            raise FieldError(
                "uavs.start",
                f"UAVs {min(i, j)} and {max(i, j)} start {gaps[i, j]:.4g} m apart, closer than "
                f"safety.min_separation = {safety.min_separation:g} m plus its margin against "
                f"the disturbance ({need:.4g} m in all)",
            )
    elif scenario.uavs.start_region is not None:
        (x0, x1), (y0, y1) = scenario.uavs.start_region
        room = (x1 - x0 + need) * (y1 - y0 + need)
        if room < 4.0 * scenario.uavs.count * need * need:
            raise FieldError(
                "uavs.start_region",
                f"too small to draw {scenario.uavs.count} starts {need:.3g} m apart "
                "(safety.min_separation and its margin): make it larger",
            )


def _check_route(scenario: Scenario) -> None:
    """With the planner on: the UAVs can gather, a route for the formation's smallest
    footprint exists, and every slot can be reached from the target as the formation opens
    up there (the followers have no planner of their own)."""
    if not scenario.planner_on:
        return
    obstacles = scenario.obstacle_set
    try:
        check_roadmap_size(obstacles, "guidance.planner")
    except FieldError as exc:
        raise FieldError(exc.field, f"{exc.reason}; merge obstacles or switch the planner "
                         "off (guidance.planner = false)") from None  # fmt: skip
    start = _start_centre(scenario)
    if scenario.uavs.start is not None:
        for m, (x, y) in enumerate(scenario.uavs.start):
            if not segment_clear(x, y, start[0], start[1], obstacles.rectangles,
                                 obstacles.circles, 0.0):  # fmt: skip
                raise FieldError(
                    "uavs.start",
                    f"UAV {m} starts behind an obstacle as seen from the middle of the starts "
                    f"({start[0]:.4g}, {start[1]:.4g}), where the formation gathers: move the "
                    "starts to one side of the obstacles",
                )
    kinds = [type(ob).__name__ for ob in scenario.obstacles]
    order = [i for i, k in enumerate(kinds) if k == "RectangleObstacle"]
    order += [i for i, k in enumerate(kinds) if k != "RectangleObstacle"]
    shrink = "lower eta.minimum" if scenario.eta.enabled else "switch [eta] on"
    goal = "the target"
    if scenario.estimation.enabled:
        goal = "the prior mean of the target (target + estimation.prior_offset)"
    plan_route(
        start, scenario.route_goal, obstacles, scenario.route_inflation,
        names=[f"obstacles[{i}]" for i in order], field="guidance", goal_name=goal,
        hint=f"{shrink} or guidance.clearance, widen the passage, or lower the altitude (a "
        "smaller F*)",
    )  # fmt: skip
    target = np.asarray(scenario.target, dtype=float)
    l_safe = scenario.control.safety_radius
    for m, (x, y) in enumerate(scenario.slots):
        if not segment_clear(target[0], target[1], x, y, obstacles.rectangles,
                             obstacles.circles, l_safe):  # fmt: skip
            raise FieldError(
                "target",
                f"the slot of UAV {m} in F* is behind an obstacle as seen from the target "
                f"(the segment between them passes within control.safety_radius = {l_safe:g} "
                "m of it): the formation opens up over the target and could not reach it; "
                "move the target, rotate F* (uavs.rotation_deg) or change the altitude",
            )


def _check_motion(scenario: Scenario) -> None:
    """The target's motion model is within the model's range for this time step, and its
    straight-line path stays inside the coordinate range over the mission."""
    motion = scenario.target_motion
    if not motion.moving:
        return
    try:
        motion_matrices(motion.model, scenario.time.step, motion.turn_rate,
                        motion.acceleration_noise)  # fmt: skip
    except FieldError as exc:
        raise FieldError(f"target_motion.{exc.field}", exc.reason) from None
    travel = math.hypot(*motion.velocity) * scenario.time.duration
    reach = float(np.max(np.abs(scenario.target))) + travel
    if reach > _v.MAX_COORDINATE:
        raise FieldError(
            "target_motion.velocity",
            f"the target would travel {travel:.3g} m over the mission and leave the model's "
            f"range (coordinates within +-{_v.MAX_COORDINATE:g} m)",
        )


def _check_estimation(scenario: Scenario, obstacles: Obstacles) -> None:
    """Sensing-in-the-loop and target-motion settings that cannot work."""
    est, motion, step = scenario.estimation, scenario.target_motion, scenario.time.step
    if est.enabled and est.measure_every > scenario.time.steps:
        raise FieldError(
            "estimation.measure_every",
            f"{est.measure_every} exceeds the {scenario.time.steps} steps of the mission",
        )
    if est.enabled and scenario.radar_model.per_uav:
        raise FieldError(
            "estimation.enabled",
            "the filter in the loop models equal UAVs; with one radar value per UAV set "
            "estimation.enabled = false (the formation then knows the target)",
        )
    if not motion.moving:
        return
    speed = math.hypot(*motion.velocity)
    if speed >= scenario.control.cruise_speed:
        raise FieldError(
            "target_motion.velocity",
            f"the target's speed {speed:g} m/s must be below control.cruise_speed = "
            f"{scenario.control.cruise_speed:g} m/s, or the formation cannot follow it",
        )
    if motion.model == "turning" and abs(motion.turn_rate) * step >= 0.5 * math.pi:
        raise FieldError(
            "target_motion.turn_rate",
            f"turns {abs(motion.turn_rate) * step:g} rad per step; must be below pi/2",
        )
    if obstacles.count:
        from .tracking import target_trajectories

        path = target_trajectories(
            np.asarray(scenario.target, dtype=float), np.asarray(motion.velocity, dtype=float),
            motion.model, step, scenario.time.steps, [np.random.default_rng(0)],
            motion.turn_rate, 0.0,
        )[0, :, :2]  # fmt: skip
        inside = np.flatnonzero(obstacle_clearance(path, obstacles) <= 0)
        if inside.size:
            raise FieldError(
                "target_motion",
                f"the target's nominal path enters an obstacle at t = {inside[0] * step:g} s",
            )


def _check_gains(scenario: Scenario, adjacency: Adjacency) -> None:
    """Stability bounds of the linear laws and the step-size limits of the nonlinear ones."""
    ctl, step = scenario.gains, scenario.time.step  # "auto" gains resolved on the graph
    # A relative allowance: at the limit itself the error does not decay, and the
    # computed eigenvalue may fall a rounding error short of it.
    eps, gamma = float(ctl.epsilon), float(ctl.gamma)
    eps_max = formation_step_limit(adjacency) * (1.0 - 1e-12)
    if eps >= eps_max:
        raise FieldError(
            "control.epsilon",
            f"{eps:g} is unstable on this graph (must be < {eps_max:.4g}, 2/lambda_max(L))",
        )
    max_degree = int(adjacency.degrees.max())
    if gamma * max_degree >= 1.0:
        raise FieldError(
            "control.gamma",
            f"{gamma:g} is too large for this graph: it must be < 1/max degree = "
            f"{1.0 / max_degree:.4g} (for example {0.5 / max_degree:.4g})",
        )
    if ctl.guidance_gain * step >= 1.0:
        raise FieldError(
            "control.guidance_gain",
            f"guidance_gain x time.step = {ctl.guidance_gain * step:g} must be < 1, or the "
            "leader overshoots its goal",
        )
    if ctl.cruise_speed * step >= ctl.repulsion_max_step:
        raise FieldError(
            "control.repulsion_max_step",
            f"{ctl.repulsion_max_step:g} m must exceed cruise_speed x time.step = "
            f"{ctl.cruise_speed * step:g} m, or the repulsion cannot stop a cruising UAV "
            "at an obstacle",
        )
    if ctl.repulsion_max_step >= ctl.safety_radius:
        raise FieldError(
            "control.repulsion_max_step",
            f"{ctl.repulsion_max_step:g} m must be below control.safety_radius = "
            f"{ctl.safety_radius:g} m",
        )


def _check_outside(obstacles: Obstacles, points: np.ndarray, field: str) -> None:
    if obstacles.count == 0:
        return
    clearance = obstacle_clearance(points, obstacles)
    inside = np.flatnonzero(clearance <= 0)
    if inside.size:
        where = f"{field}[{inside[0]}]" if points.shape[0] > 1 else field
        raise FieldError(where, "lies inside an obstacle")


def convergence_estimate(scenario: Scenario) -> dict[str, float]:
    """A rough time for the formation to settle over the target, before flying.

    Travel: the route's length (the straight line without the planner) from the middle of
    the start region at the cruise speed, or, if longer, the time for the farthest UAV to
    gather (its distance from the middle of the starts plus the formation's radius, at the
    speed limit of the safety filter, or the cruise speed without it); settling: the steps
    the slower linear law needs to shrink its error a hundredfold
    (:func:`crlbswarm.graphs.settling_steps`); hold: ``time.hold``. Not a bound: obstacles,
    the eta rule and the safety filter slow the formation down (``docs/safety.md`` gives
    the ratios measured).

    Parameters
    ----------
    scenario : Scenario
        The scenario.

    Returns
    -------
    dict
        ``travel_s``, ``settling_s``, ``hold_s`` and their sum ``total_s`` (``nan`` settling
        above ``EXACT_EIGEN_MAX_NODES`` UAVs).
    """
    start = _start_centre(scenario)
    goal = np.asarray(scenario.target, dtype=float)
    if scenario.planner_on:
        route = plan_route(start, scenario.route_goal, scenario.obstacle_set,
                           scenario.route_inflation)  # fmt: skip
        length = float(np.sum(np.hypot(*np.diff(route, axis=0).T)))
    else:
        length = float(np.hypot(*(goal - start)))
    gains = scenario.gains
    steps = settling_steps(scenario.adjacency, scenario.uavs.leader, float(gains.epsilon),
                           float(gains.gamma))  # fmt: skip
    if scenario.uavs.start is not None:
        corners = np.asarray(scenario.uavs.start, dtype=float)
    else:
        (x0, x1), (y0, y1) = scenario.uavs.start_region  # type: ignore[misc]
        corners = np.array([[x0, y0], [x0, y1], [x1, y0], [x1, y1]])
    spread = float(np.max(np.hypot(*(corners - start).T))) + scenario.formation_radius
    speed = scenario.safety.max_speed if scenario.safety.enabled else gains.cruise_speed
    out = {
        "travel_s": max(length / gains.cruise_speed, spread / speed),
        "settling_s": steps * scenario.time.step,
        "hold_s": scenario.time.hold,
    }
    out["total_s"] = sum(out.values())
    return out


def preflight(scenario: Scenario) -> list[str]:
    """Warnings before flying: what a valid scenario may still fail at.

    The estimated time to settle (:func:`convergence_estimate`) exceeds the mission's
    duration; or the UAVs keep the paper's slots by index with the safety filter on (their
    paths to the slots cross, and a crowd can lock up while the filter keeps them apart).

    Parameters
    ----------
    scenario : Scenario
        The scenario.

    Returns
    -------
    list of str
        One line per warning (empty if none).
    """
    out = []
    if scenario.safety.enabled and scenario.formation.assignment == "index":
        out.append(
            'formation.assignment = "index" with the safety filter on: the UAVs\' paths to '
            "their slots cross, and a crowd can lock up while the filter keeps them apart; "
            '"optimal" assigns the slots without crossings'
        )
    est = convergence_estimate(scenario)
    if not est["total_s"] > scenario.time.duration:  # (nan: not estimated)
        return out
    fixes = ["lengthen time.duration"]
    if est["travel_s"] >= est["settling_s"]:
        fixes.append("raise control.cruise_speed")
    else:
        control = scenario.control
        fixed = [n for n in ("epsilon", "gamma") if getattr(control, n) != "auto"]
        fixes.append(
            f'set control.{" and control.".join(fixed)} to "auto"'
            if fixed
            else "use a denser graph"
        )
    out.append(
        f"the formation needs about {_seconds(est['total_s'])} to settle (travel "
        f"{_seconds(est['travel_s'])}, settling {_seconds(est['settling_s'])}, hold "
        f"{_seconds(est['hold_s'])}), more than time.duration = {scenario.time.duration:g} s: "
        + " or ".join(fixes)
    )
    return out


def _seconds(value: float) -> str:
    """A duration for a message; beyond a year (or infinite, a gain that is zero in double
    precision) it says so instead of printing a huge number."""
    return f"{value:.0f} s" if value < 3.2e7 else "more than a year"


def _start_centre(scenario: Scenario) -> np.ndarray:
    if scenario.uavs.start is not None:
        return np.mean(np.asarray(scenario.uavs.start, dtype=float), axis=0)
    (x0, x1), (y0, y1) = scenario.uavs.start_region  # type: ignore[misc]
    return np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
