"""The numerical checks of a scenario: what validates field by field but cannot fly.

:func:`check_scenario` runs when a :class:`~crlbswarm.scenario.Scenario` is built, after every
field has passed its own check: the target and the starts must lie outside the obstacles,
the graph must be connected, the gains must be inside the stability bounds of the linear
laws and the step-size limits of the nonlinear ones, the target's slot formation must fit
between the obstacles, and sensing in the loop and the target's motion must be consistent.
Each failure raises :class:`~crlbswarm.errors.FieldError` naming the dotted field.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .errors import FieldError
from .graphs import Adjacency, formation_step_limit
from .obstacles import Obstacles, obstacle_clearance

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = ["check_scenario"]


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
    if scenario.uavs.start is not None:
        _check_outside(obstacles, np.asarray(scenario.uavs.start), "uavs.start")
    elif scenario.uavs.start_region is not None:  # (exactly one of the two is set)
        (x0, x1), (y0, y1) = scenario.uavs.start_region
        for i, ob in enumerate(scenario.obstacles):
            if ob.overlaps_box(x0, x1, y0, y1):
                raise FieldError(
                    "uavs.start_region", f"overlaps obstacles[{i}]; starts could be inside it"
                )
    try:
        adjacency = scenario.adjacency
    except FieldError as exc:
        field = exc.field if exc.field.startswith("graph") else "graph"
        raise FieldError(field, exc.reason) from exc
    _check_gains(scenario, adjacency)
    _check_estimation(scenario, obstacles)
    clearance = obstacle_clearance(scenario.formation, obstacles) if obstacles.count else None
    if clearance is not None and np.any(clearance <= scenario.control.safety_radius):
        m = int(np.argmin(clearance))
        raise FieldError(
            "target",
            f"the slot of UAV {m} in F* over the target is {clearance[m]:.3g} m from an "
            f"obstacle, within control.safety_radius = {scenario.control.safety_radius:g} m: "
            "the formation could never settle there",
        )


def _check_estimation(scenario: Scenario, obstacles: Obstacles) -> None:
    """Sensing-in-the-loop and target-motion settings that cannot work."""
    est, motion, step = scenario.estimation, scenario.target_motion, scenario.time.step
    if est.enabled and est.measure_every > scenario.time.steps:
        raise FieldError(
            "estimation.measure_every",
            f"{est.measure_every} exceeds the {scenario.time.steps} steps of the mission",
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
    ctl, step = scenario.control, scenario.time.step
    # A relative allowance: at the limit itself the error does not decay, and the
    # computed eigenvalue may fall a rounding error short of it.
    eps_max = formation_step_limit(adjacency) * (1.0 - 1e-12)
    if ctl.epsilon >= eps_max:
        raise FieldError(
            "control.epsilon",
            f"{ctl.epsilon:g} is unstable on this graph (must be < {eps_max:.4g}, "
            "2/lambda_max(L))",
        )
    max_degree = int(adjacency.degrees.max())
    if ctl.gamma * max_degree >= 1.0:
        raise FieldError(
            "control.gamma",
            f"{ctl.gamma:g} is too large for this graph: it must be < 1/max degree = "
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
