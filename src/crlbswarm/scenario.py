"""Mission scenarios: the schema of a scenario file, the built-in scenarios, loading.

A scenario fixes everything a mission simulation needs: the UAVs and how they start, the
altitude and the target, the radar, the time step, the control gains, the motion
disturbance, the communication graph, the obstacles and the rule for the scaling factor
eta, and (beyond the paper) sensing in the loop and the target's motion. Files are TOML;
``crlbswarm scenario show paper`` prints the built-in paper scenario as a file to copy and
edit. The built-in scenarios are TOML files shipped inside the package
(``crlbswarm/scenarios/*.toml``). Every field, its unit and its default is listed in
``docs/scenarios.md``.

Each table of the file is a model declared where its parameters belong: ``[radar]`` is
derived from the fields of :class:`crlbswarm.Radar`, ``[control]`` is
:class:`crlbswarm.ControlGains` and ``[eta]`` :class:`crlbswarm.EtaRule`, ``[graph]``
follows :data:`crlbswarm.GRAPH_KINDS`. Validation happens when the scenario is built, before
anything runs: field by field (unknown or missing fields, wrong types, fewer than 3 UAVs),
then the scene as a whole (:func:`crlbswarm.scenario_checks.check_scenario`: a disconnected
graph, a start or target inside an obstacle, gains beyond the stability bounds, ...). Any
failure raises :class:`crlbswarm.ScenarioError` (a :class:`ValueError`) whose one-line
message names the dotted field.
"""

from __future__ import annotations

import json
import math
import typing
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, ValidationInfo, create_model, field_validator, model_validator

from . import _validation as _v
from ._config import ConfigModel, PositiveFloat, model_to_toml, read_toml, read_toml_file, validate
from ._validation import MIN_UAVS
from .constrained import ConstrainedDesign, constrained_design, default_starts
from .control import ControlGains, EtaRule
from .design import crlb_bound, optimal_formation
from .errors import FieldError, ScenarioError
from .faults import FaultPlan, FaultsConfig, check_faults, plan_faults
from .fisher import crlb
from .graphs import GRAPH_KINDS, Adjacency, communication_graph, ring_adjacency
from .links import (
    MAX_ALL_PAIRS_UAVS,
    LinksConfig,
    all_pairs_adjacency,
    check_link_timing,
    check_links,
)
from .multitarget import TargetAllocation, allocate_targets
from .obstacles import Obstacles, obstacle_clearance
from .planning import (
    MAX_SCENARIO_STARTS,
    FormationConfig,
    GuidanceConfig,
    Roadmap,
    build_roadmap,
)
from .radar import Radar, radar_parameters
from .safety import SafetyConfig, disturbance_margins
from .scenario_checks import check_scenario
from .spatial import min_separation

__all__ = [
    "BUILTIN_SCENARIOS",
    "DESIGN_CACHE",
    "DESIGN_CLEARANCE",
    "MAX_SCENARIO_DESIGN_UAVS",
    "CircleObstacle",
    "DisturbanceConfig",
    "EstimationConfig",
    "FormationConfig",
    "FormationDesign",
    "GraphConfig",
    "GroupPlan",
    "GuidanceConfig",
    "LinksConfig",
    "RadarConfig",
    "RectangleObstacle",
    "SafetyConfig",
    "Scenario",
    "TargetMotionConfig",
    "TimeConfig",
    "UavsConfig",
    "builtin_scenario_text",
    "design_arguments",
    "design_formation",
    "load_scenario",
    "plan_groups",
    "scenario_starts",
]


#: Largest number of time steps of a mission.
MAX_STEPS = 10_000_000

#: Largest distance of the prior mean from the truth, in prior standard deviations.
MAX_PRIOR_SIGMAS = 5.0

#: Smallest margin of the safety filter (pair and obstacle), as a fraction of
#: ``safety.min_separation`` (:attr:`Scenario.safety_margins`).
MIN_MARGIN = 1e-3

#: Largest sampling interval dT, s (the discrete laws are meant for steps of a fraction of a
#: second; beyond a minute nothing of the paper's model holds).
MAX_STEP = 60.0

#: Most obstacles of a scenario (each is checked by every UAV at every step; with the
#: planner on, :data:`crlbswarm.planning.MAX_ROADMAP_OBSTACLES` is the limit).
MAX_OBSTACLES = 10_000

#: Most extra targets of a scenario (each needs a group of at least three UAVs).
MAX_EXTRA_TARGETS = 32

#: Largest target speed, m/s (targets of low-altitude networks; keeps the target's path
#: inside the model's range over a mission).
MAX_TARGET_SPEED = 1000.0

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
#: A horizontal coordinate, m, inside the model's range.
Coordinate = Annotated[
    float, Field(ge=-_v.MAX_COORDINATE, le=_v.MAX_COORDINATE, allow_inf_nan=False)
]
Pair = Annotated[list[Coordinate], Field(min_length=2, max_length=2)]


class UavsConfig(ConfigModel):
    """The UAVs and their start."""

    count: int = Field(
        ge=MIN_UAVS,
        le=_v.MAX_UAVS,
        description=f"number of UAVs M ({MIN_UAVS} to {_v.MAX_UAVS:,})",
    )
    leader: int = Field(0, ge=0, description="index of the leader (the paper's UAV 1 is 0)")
    start_region: Annotated[list[Pair], Field(min_length=2, max_length=2)] | None = Field(
        None, description="[[x_min, x_max], [y_min, y_max]], m: starts drawn uniformly (seeded)"
    )
    start: list[Pair] | None = Field(None, description="explicit start positions [[x, y], ...], m")
    rotation_deg: FiniteFloat = Field(
        0.0, description="azimuth of the leader's slot in F*, seen from the target, deg"
    )

    @field_validator("leader")
    @classmethod
    def _leader_in_range(cls, leader: int, info: ValidationInfo) -> int:
        count = info.data.get("count")
        if count is not None and leader >= count:
            raise ValueError(f"must be a UAV index below count = {count}")
        return leader

    @field_validator("start_region")
    @classmethod
    def _region_ordered(cls, region: list[list[float]] | None) -> list[list[float]] | None:
        if region is not None:
            (x0, x1), (y0, y1) = region
            if x0 > x1 or y0 > y1:  # (finiteness: checked by the Pair type)
                raise ValueError("need x_min <= x_max and y_min <= y_max")
        return region

    @field_validator("start")
    @classmethod
    def _start_matches_count(
        cls, start: list[list[float]] | None, info: ValidationInfo
    ) -> list[list[float]] | None:
        if start is not None:
            count = info.data.get("count")
            if count is not None and len(start) != count:
                raise ValueError(f"has {len(start)} positions but count is {count}")
        return start

    @model_validator(mode="after")
    def _one_start(self) -> UavsConfig:
        if (self.start is None) == (self.start_region is None):
            raise ValueError("give exactly one of 'start' and 'start_region'")
        return self


class _RadarTable(ConfigModel):
    """Radar parameters in linear SI units (see :class:`crlbswarm.Radar`)."""

    def to_radar(self) -> Radar:
        """The :class:`crlbswarm.Radar` with these parameters.

        Returns
        -------
        Radar
            The radar, linear SI units.
        """
        return Radar(**self.model_dump())

    @model_validator(mode="after")
    def _constant_in_range(self) -> _RadarTable:
        self.to_radar()  # every field may be fine while A = p G_p beta0 / (kappa sigma0^2) is not
        return self


# The [radar] table: one scalar field per declared field of Radar (default, unit and doc).
if TYPE_CHECKING:
    RadarConfig = _RadarTable
else:
    RadarConfig = create_model(
        "RadarConfig",
        __base__=_RadarTable,
        __module__=__name__,
        __doc__=_RadarTable.__doc__,
        **{
            p.name: (
                PositiveFloat | Annotated[list[PositiveFloat], Field(min_length=1)],
                Field(
                    p.default,
                    description=f"{p.label}, {p.unit or 'linear'} (or one value per UAV)",
                ),
            )
            for p in radar_parameters()
        },
    )  # fmt: skip


class TimeConfig(ConfigModel):
    """Time discretisation."""

    step: Annotated[float, Field(gt=0, le=MAX_STEP, allow_inf_nan=False)] = Field(
        description=f"sampling interval dT, s (at most {MAX_STEP:g})"
    )
    duration: PositiveFloat = Field(description="mission length, s (a whole number of steps)")
    hold: PositiveFloat = Field(
        10.0, description="converged: within tolerance at least this long until the end, s"
    )
    stall: PositiveFloat = Field(
        20.0, description="stuck: no progress toward the target for this long at the end, s"
    )

    @field_validator("duration")
    @classmethod
    def _whole_steps(cls, duration: float, info: ValidationInfo) -> float:
        step = info.data.get("step")
        if step is not None:
            n = duration / step
            if n > MAX_STEPS:
                raise ValueError(f"is {n:.3g} steps of {step:g} s; at most {MAX_STEPS:g} allowed")
            if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
                raise ValueError(f"must be a positive whole number of steps of {step:g} s")
        return duration

    @model_validator(mode="after")
    def _hold_fits(self) -> TimeConfig:
        if self.hold >= self.duration:
            raise FieldError(
                "time.hold",
                f"{self.hold:g} s is not shorter than time.duration = {self.duration:g} s: no "
                "run could end converged; lower time.hold or lengthen the mission",
            )
        return self

    @property
    def steps(self) -> int:
        """Number of steps K."""
        return round(self.duration / self.step)


class DisturbanceConfig(ConfigModel):
    """Motion disturbance n_{m,k} ~ N(0, sigma^2 I), eq. (3)."""

    sigma: Annotated[float, Field(ge=0, allow_inf_nan=False)] = Field(
        0.01, description="standard deviation per axis per step, m (paper scenario: 0.01)"
    )


class GraphConfig(ConfigModel):
    """Communication graph (see :func:`crlbswarm.communication_graph`)."""

    kind: Literal[tuple(GRAPH_KINDS)] = Field(  # type: ignore[valid-type]
        "ring", description=f"{', '.join(GRAPH_KINDS)} (ring: the paper scenario)"
    )
    radius: PositiveFloat | None = Field(None, description="random_geometric: link radius")
    seed: Annotated[int, Field(ge=0)] | None = Field(None, description="random_geometric seed")
    edges: list[Annotated[list[int], Field(min_length=2, max_length=2)]] | None = Field(
        None, description="edges: explicit list of [m, p] pairs"
    )
    center: Annotated[int, Field(ge=0)] | None = Field(
        None, description="star: index of the hub (default: UAV 0)"
    )

    @model_validator(mode="after")
    def _options_fit_kind(self) -> GraphConfig:
        options = {o for opts in GRAPH_KINDS.values() for o in opts}
        for option in sorted(options):
            if getattr(self, option) is not None and option not in GRAPH_KINDS[self.kind]:
                raise FieldError(f"graph.{option}", f"does not apply to kind '{self.kind}'")
        return self


class RectangleObstacle(ConfigModel):
    """Axis-aligned rectangle."""

    type: Literal["rectangle"]
    x: Pair = Field(description="[x_min, x_max], m")
    y: Pair = Field(description="[y_min, y_max], m")

    @model_validator(mode="after")
    def _check(self) -> RectangleObstacle:
        if self.x[0] >= self.x[1] or self.y[0] >= self.y[1]:
            raise ValueError("need x_min < x_max and y_min < y_max")
        return self

    def overlaps_box(self, x0: float, x1: float, y0: float, y1: float) -> bool:
        """Whether the rectangle meets the box ``[x0, x1] x [y0, y1]``.

        Parameters
        ----------
        x0 : float
            Smallest x of the box, m.
        x1 : float
            Largest x of the box, m.
        y0 : float
            Smallest y of the box, m.
        y1 : float
            Largest y of the box, m.

        Returns
        -------
        bool
            True if they share a point.
        """
        return self.x[0] <= x1 and x0 <= self.x[1] and self.y[0] <= y1 and y0 <= self.y[1]


class CircleObstacle(ConfigModel):
    """Disc."""

    type: Literal["circle"]
    center: Pair = Field(description="[x, y], m")
    radius: Annotated[float, Field(gt=0, le=_v.MAX_COORDINATE, allow_inf_nan=False)] = Field(
        description="m"
    )

    def overlaps_box(self, x0: float, x1: float, y0: float, y1: float) -> bool:
        """Whether the disc meets the box ``[x0, x1] x [y0, y1]``.

        Parameters
        ----------
        x0 : float
            Smallest x of the box, m.
        x1 : float
            Largest x of the box, m.
        y0 : float
            Smallest y of the box, m.
        y1 : float
            Largest y of the box, m.

        Returns
        -------
        bool
            True if they share a point.
        """
        cx = min(max(self.center[0], x0), x1)
        cy = min(max(self.center[1], y0), y1)
        return math.hypot(cx - self.center[0], cy - self.center[1]) <= self.radius


#: An obstacle table: one of the shapes, told apart by its ``type``.
Obstacle = Annotated[RectangleObstacle | CircleObstacle, Field(discriminator="type")]

#: The ``type`` tags of the obstacle shapes (pydantic puts them in its error locations).
OBSTACLE_TYPES: tuple[str, ...] = tuple(
    tag
    for shape in typing.get_args(typing.get_args(Obstacle)[0])
    for tag in typing.get_args(shape.model_fields["type"].annotation)
)


class EstimationConfig(ConfigModel):
    """Sensing in the loop (not in the paper): the formation is centred on the UAVs' own
    estimate of the target, fused by an iterated EKF from their ranges."""

    enabled: bool = Field(False, description="false: the formation knows the true target")
    prior_offset: Pair = Field(
        [20.0, 0.0], description="initial estimate minus the true target position, m"
    )
    prior_std: Annotated[float, Field(ge=1e-3, le=1e6)] = Field(
        20.0, description="prior standard deviation per axis, m (1e-3 to 1e6)"
    )
    velocity_prior_std: Annotated[float, Field(ge=1e-3, le=1e4)] = Field(
        5.0, description="prior standard deviation of each velocity component, m/s (moving)"
    )
    measure_every: Annotated[int, Field(ge=1)] = Field(
        1, description="ranges are measured and fused every this many steps"
    )

    @model_validator(mode="after")
    def _prior_consistent(self) -> EstimationConfig:
        offset = math.hypot(*self.prior_offset)
        if self.enabled and offset > MAX_PRIOR_SIGMAS * self.prior_std:
            raise FieldError(
                "estimation.prior_offset",
                f"is {offset:g} m, more than {MAX_PRIOR_SIGMAS:g} prior_std = "
                f"{self.prior_std:g} m: the filter's prior would contradict its own covariance",
            )
        return self


class TargetMotionConfig(ConfigModel):
    """How the target moves (not in the paper, whose target is static)."""

    model: Literal["static", "constant_velocity", "turning"] = Field(
        "static", description="static, constant_velocity or turning (coordinated turn)"
    )
    velocity: Annotated[
        list[Annotated[float, Field(ge=-MAX_TARGET_SPEED, le=MAX_TARGET_SPEED)]],
        Field(min_length=2, max_length=2),
    ] = Field([0.0, 0.0], description=f"initial velocity, m/s (each at most {MAX_TARGET_SPEED:g})")
    turn_rate: Annotated[
        float, Field(ge=-_v.MAX_TURN_RATE, le=_v.MAX_TURN_RATE, allow_inf_nan=False)
    ] = Field(0.0, description=f"turning: rate of turn, rad/s (at most {_v.MAX_TURN_RATE:g})")
    acceleration_noise: Annotated[float, Field(ge=0, le=100)] = Field(
        0.0, description="std of the white acceleration noise per axis, m/s^2 (at most 100)"
    )

    @model_validator(mode="after")
    def _options_fit_model(self) -> TargetMotionConfig:
        if self.model == "static":
            for name in ("velocity", "turn_rate", "acceleration_noise"):
                if np.any(getattr(self, name)):
                    raise FieldError(f"target_motion.{name}", "does not apply to a static target")
        if self.model == "constant_velocity" and self.turn_rate:
            raise FieldError("target_motion.turn_rate", "applies to model 'turning' only")
        if self.model == "turning" and not self.turn_rate:
            raise FieldError("target_motion.turn_rate", "model 'turning' needs a non-zero rate")
        return self

    @property
    def moving(self) -> bool:
        """Whether the target moves."""
        return self.model != "static"


class Scenario(ConfigModel):
    """A complete mission scenario (see the module docstring and docs/scenarios.md).

    Each table of the scenario file is a field below, declared once with its meaning; this
    docstring's Parameters section is generated from the declarations.
    """

    name: str = Field("custom", description="short name")
    description: str = Field("", description="one line of text")
    altitude: Annotated[
        float, Field(ge=_v.MIN_ALTITUDE, le=_v.MAX_ALTITUDE, allow_inf_nan=False)
    ] = Field(
        description=f"common flight altitude H, m ({_v.MIN_ALTITUDE:g} to {_v.MAX_ALTITUDE:g})"
    )
    target: Pair = Field(description="target position s = [x, y], m")
    extra_targets: Annotated[list[Pair], Field(max_length=MAX_EXTRA_TARGETS)] = Field(
        default_factory=list,
        description="more targets [[x, y], ...], m: the swarm splits into one group per "
        "target, each with its own leader and formation (none by default)",
    )
    uavs: UavsConfig = Field(description="count, leader and start of the UAVs")
    time: TimeConfig = Field(description="step and duration")
    radar: RadarConfig = Field(RadarConfig(), description="radar (paper profile by default)")
    control: ControlGains = Field(ControlGains(), description="gains of the control laws")
    disturbance: DisturbanceConfig = Field(DisturbanceConfig(), description="motion noise")
    graph: GraphConfig = Field(GraphConfig(), description="communication graph")
    obstacles: Annotated[list[Obstacle], Field(max_length=MAX_OBSTACLES)] = Field(
        default_factory=list, description=f"obstacles (at most {MAX_OBSTACLES:,})"
    )
    eta: EtaRule = Field(EtaRule(), description="rule for the scaling factor eta")
    estimation: EstimationConfig = Field(
        EstimationConfig(),
        description="sensing in the loop (off by default: the formation knows the target)",
    )
    target_motion: TargetMotionConfig = Field(
        TargetMotionConfig(), description="motion of the target (static by default)"
    )
    safety: SafetyConfig = Field(SafetyConfig(), description="inter-UAV safety filter")
    guidance: GuidanceConfig = Field(GuidanceConfig(), description="route planner")
    formation: FormationConfig = Field(FormationConfig(), description="slot assignment")
    links: LinksConfig | None = Field(
        None, description="communication links: range, loss, delay, rate (none: perfect links)"
    )
    faults: FaultsConfig | None = Field(
        None, description="UAVs and links lost during the mission, and the timeout that "
        "detects them (none: no failures)",
    )  # fmt: skip

    @model_validator(mode="after")
    def _check_whole(self) -> Scenario:
        if self.links is not None and self.extra_targets:
            raise FieldError("links", "is not supported with extra_targets (several targets)")
        if self.links is not None:  # (first: the gains are resolved for the links' delay)
            check_link_timing(self.links, self.time.step, self.time.steps)
        check_scenario(self)
        if self.links is not None:
            check_links(self.links, self.uavs.count, self.gains)
        if self.faults is not None:
            check_faults(self)
        return self

    # -- derived objects -----------------------------------------------------------------
    @cached_property
    def obstacle_set(self) -> Obstacles:
        """The obstacles as arrays for the control kernels."""
        rects = [[*o.x, *o.y] for o in self.obstacles if isinstance(o, RectangleObstacle)]
        circles = [[*o.center, o.radius] for o in self.obstacles if isinstance(o, CircleObstacle)]
        return Obstacles(rects, circles)

    @cached_property
    def adjacency(self) -> Adjacency:
        """The communication graph as CSR adjacency."""
        spec = self.graph
        if spec.kind == "ring":  # (the paper's graph: built without networkx)
            return ring_adjacency(self.uavs.count)
        graph = communication_graph(
            spec.kind,
            self.uavs.count,
            radius=spec.radius,
            seed=spec.seed,
            edges=spec.edges,
            center=spec.center,
        )
        return Adjacency.from_graph(graph)

    @cached_property
    def safety_margins(self) -> tuple[float, float]:
        """Margins of the safety filter against the motion disturbance, m: (between two UAVs,
        from an obstacle) (:func:`crlbswarm.safety.disturbance_margins`), each at least
        ``MIN_MARGIN`` times ``safety.min_separation``: without one (no disturbance, or
        ``noise_sigmas = 0``) a UAV pushed toward an obstacle for long halves its clearance
        every step until it rounds to zero."""
        s = self.safety
        pair, obstacle = disturbance_margins(self.disturbance.sigma, s.decay, s.noise_sigmas)
        floor = MIN_MARGIN * s.min_separation
        return max(pair, floor), max(obstacle, floor)

    @property
    def start_separation(self) -> float:
        """Smallest distance between two starts drawn in the start region with the safety
        filter on: ``safety.min_separation`` plus the pair margin, m."""
        return self.safety.min_separation + self.safety_margins[0]

    @property
    def formation_radius(self) -> float:
        """Radius of the formation around its centre (the target for F*), m."""
        offsets = self.slots - np.asarray(self.target) - self.formation_design.centre_offset
        return float(np.max(np.hypot(offsets[:, 0], offsets[:, 1])))

    @cached_property
    def formation_side(self) -> float:
        """Smallest distance between two slots, m: the side of the regular polygon F*
        (:math:`2 r^* \\sin(\\pi/M)`), or for any other formation (unequal UAVs, a
        constrained design) the smallest distance between two of its slots."""
        if self.formation_design.regular:
            return 2.0 * self.formation_radius * math.sin(math.pi / self.uavs.count)
        return float(min_separation(np.ascontiguousarray(self.slots)))

    @cached_property
    def eta_rule(self) -> EtaRule:
        """The eta rule as flown: with the safety filter on, its ``minimum`` is raised (if
        needed) so that the smallest formation's side is twice ``start_separation``: a UAV
        can pass between two neighbours at any scale, and the shrunk polygon keeps room to
        move (with its sides at the separation the pair barriers would hold it rigid)."""
        if not self.safety.enabled:
            return self.eta
        floor = 2.0 * self.start_separation * (1.0 + 1e-6) / self.formation_side
        return (
            self.eta
            if floor <= self.eta.minimum
            else self.eta.model_copy(update={"minimum": min(1.0, floor)})
        )

    @property
    def route_clearance(self) -> float:
        """``guidance.clearance``, or ``control.safety_radius`` when unset, m."""
        clearance = self.guidance.clearance
        return self.control.safety_radius if clearance is None else clearance

    @property
    def route_inflation(self) -> float:
        """How far the route of the formation's centre keeps from every obstacle: the radius
        of its smallest disc plus :attr:`route_clearance`, m."""
        smallest = self.eta_rule.minimum if self.eta.enabled else 1.0  # eta off: never shrinks
        return smallest * self.formation_radius + self.route_clearance

    @property
    def steering_radius(self) -> float:
        """:math:`l_\text{safe}` of the leader's steering, m: ``control.safety_radius``, or
        with the planner on at most :attr:`route_clearance`, so that the steering does not
        push the formation off a route that keeps that clearance (at a corner the two would
        balance and hold the formation still)."""
        if self.planner_on:
            return min(self.control.safety_radius, self.route_clearance)
        return self.control.safety_radius

    @property
    def route_carrot(self) -> float:
        """How far ahead of the formation's centre along the route the leader aims: twice the
        distance at which its guidance saturates, ``2 cruise_speed / guidance_gain``, m (so
        it flies the route at cruise speed)."""
        return 2.0 * self.control.cruise_speed / self.control.guidance_gain

    @property
    def planner_on(self) -> bool:
        """Whether the leader follows a planned route: ``guidance.planner`` on, obstacles to
        plan around, a static target and no extra targets (the roadmap is built for one
        goal)."""
        return (
            self.guidance.planner
            and self.obstacle_set.count > 0
            and not self.target_motion.moving
            and not self.extra_targets
        )

    @property
    def route_goal(self) -> np.ndarray:
        """The goal of the route: the formation's centre over the target (the target for
        F*), or over the filter's prior mean with sensing in the loop (the UAVs do not know
        the target)."""
        goal = np.asarray(self.target, dtype=float) + self.formation_design.centre_offset
        if self.estimation.enabled:
            goal = goal + np.asarray(self.estimation.prior_offset)
        return goal

    @cached_property
    def radar_model(self) -> Radar:
        """The :class:`crlbswarm.Radar` of the ``[radar]`` table (built once)."""
        return self.radar.to_radar()

    @cached_property
    def roadmap(self) -> Roadmap | None:
        """The roadmap of the route (:func:`crlbswarm.planning.build_roadmap`), built once;
        ``None`` when the planner is off (:attr:`planner_on`)."""
        if not self.planner_on:
            return None
        return build_roadmap(self.obstacle_set, self.route_goal, self.route_inflation)

    @cached_property
    def gains(self) -> ControlGains:
        """The control gains with ``"auto"`` resolved on this scenario's graph (on every pair
        of UAVs when ``links.use_graph`` is false: the laws may then link any two), for the
        largest age of the links' messages (:meth:`crlbswarm.links.LinksConfig.largest_age`;
        0 without links: the gains of the state of the step)."""
        links, count, leader = self.links, self.uavs.count, self.uavs.leader
        if links is None:
            return self.control.resolve(self.adjacency, leader)
        age = links.largest_age(self.time.step)
        if links.use_graph or count > MAX_ALL_PAIRS_UAVS:
            return self.control.resolve(self.adjacency, leader, age)
        return self.control.resolve(all_pairs_adjacency(count), leader, age)

    @cached_property
    def formation_design(self) -> FormationDesign:
        """The formation flown over the target (:class:`FormationDesign`): :math:`F^*` in
        closed form, or, with ``formation.design = "auto"`` and :math:`F^*` blocked, the
        constrained design (made once, when the scenario is validated)."""
        return design_formation(self)

    @cached_property
    def fault_plan(self) -> FaultPlan | None:
        """With a ``[faults]`` table: the mission's phases
        (:func:`~crlbswarm.faults.plan_faults`, made once); None without."""
        return None if self.faults is None else plan_faults(self)

    @cached_property
    def group_plan(self) -> GroupPlan | None:
        """With ``extra_targets``: which UAVs serve which target and each group's own
        scenario (:func:`plan_groups`); None with one target."""
        return plan_groups(self) if self.extra_targets else None

    @property
    def slots(self) -> np.ndarray:
        """The slots of the formation over the target (F*, or the constrained design when F*
        is blocked: :attr:`formation_design`), in the order of the UAVs' indices (slot m is
        UAV m's unless ``formation.assignment`` reassigns them), shape (M, 2), m
        (read-only)."""
        return self.formation_design.slots

    def restricted(self, members: list[int], leader: int, **changes: Any) -> Scenario:
        """This scenario restricted to some of its UAVs: a group of a mission with several
        targets (:func:`plan_groups`), or the swarm left after a failure
        (:func:`crlbswarm.faults.plan_faults`).

        Parameters
        ----------
        members : list of int
            The UAVs (swarm indices, increasing): their count, start and radars are kept.
        leader : int
            The leader (a member).
        **changes
            Top-level fields to replace (``name``, ``target``, ``graph``, ...).

        Returns
        -------
        Scenario
            The scenario, validated.

        Raises
        ------
        ScenarioError
            When the UAVs cannot fly a valid mission.
        """
        data = {**self.model_dump(), **changes}
        data["uavs"] = {**data["uavs"], "count": len(members), "leader": members.index(leader)}
        if self.uavs.start is not None:
            data["uavs"]["start"] = [self.uavs.start[m] for m in members]
        data["radar"] = self.radar_model.take(members).to_dict()
        return Scenario.from_dict(data, source="")

    # -- TOML ------------------------------------------------------------------------------
    @classmethod
    def from_toml(cls, text: str, source: str = "scenario") -> Scenario:
        """Parse and validate a scenario from TOML text.

        Parameters
        ----------
        text : str
            TOML document.
        source : str, default "scenario"
            Name used in error messages (for example the file name).

        Returns
        -------
        Scenario
            The validated scenario.

        Raises
        ------
        ScenarioError
            With one line naming the field and the reason.
        """
        return cls.from_dict(read_toml(text, source, ScenarioError), source)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "scenario") -> Scenario:
        """Validate a scenario from a (TOML-shaped) dictionary.

        Parameters
        ----------
        data : dict
            Nested dictionary as read from TOML.
        source : str, default "scenario"
            Name used in error messages.

        Returns
        -------
        Scenario
            The validated scenario.

        Raises
        ------
        ScenarioError
            With one line naming the field and the reason.
        """
        return validate(cls, data, source, ScenarioError, tags=OBSTACLE_TYPES)

    def to_toml(self) -> str:
        """The scenario as a TOML document, each field commented with its meaning and unit.

        Returns
        -------
        str
            TOML text; :meth:`from_toml` reads it back to an equal scenario.
        """
        return model_to_toml(self, f"crlbswarm scenario '{self.name}'. Fields: docs/scenarios.md")


# ---------------------------------------------------------------------------------------
# Built-in scenarios: TOML files inside the package
# ---------------------------------------------------------------------------------------
#: With the constrained design, every slot keeps this much more than
#: ``control.safety_radius`` from the obstacles (relative): the repulsion, zero beyond
#: :math:`l_\text{safe}`, then leaves the formation alone over the target.
DESIGN_CLEARANCE = 0.05


@dataclass(frozen=True, eq=False)
class FormationDesign:
    """The formation a scenario flies over its target (:attr:`Scenario.formation_design`).

    Attributes
    ----------
    slots : ndarray, shape (M, 2)
        Slot positions over the target, m (read-only).
    bound : float
        The CRLB of ``slots`` the mission converges to, m^2: the attainable optimum
        (:func:`crlbswarm.crlb_bound`) for :math:`F^*`, the CRLB (eq. (10)) of the
        constrained design otherwise.
    unconstrained_bound : float
        :func:`crlbswarm.crlb_bound`, m^2 (``bound / unconstrained_bound`` is what the
        obstacles cost).
    method : str
        ``"closed form"`` (:math:`F^*`) or ``"constrained"``.
    regular : bool
        Whether ``slots`` is the regular polygon of the paper (equal UAVs, closed form).
    centre_offset : ndarray, shape (2,)
        The formation's centre (the mean of its slots) minus the target, m: exactly 0 for a
        regular polygon. The centroid converges to target + centre_offset, and the eta
        rule scales the formation about its centre.
    blocked : str
        Why :math:`F^*` did not fit (empty for the closed form).
    criterion : str
        Criterion of the design (``formation.criterion``; the closed form is optimal for
        all three).
    ratio : float
        The criterion of ``slots`` over its unconstrained optimum (1 for :math:`F^*`).
    active : tuple of str
        The constrained design's active constraints (empty for the closed form).
    """

    slots: np.ndarray
    bound: float
    unconstrained_bound: float
    method: str
    regular: bool
    centre_offset: np.ndarray
    blocked: str
    criterion: str
    ratio: float
    active: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """The design's figures, JSON-ready (the slots excluded)."""
        return {
            "method": self.method,
            "criterion": self.criterion,
            "bound_m2": self.bound,
            "unconstrained_bound_m2": self.unconstrained_bound,
            "ratio": self.ratio,
            "blocked": self.blocked,
            "active": list(self.active),
        }


def _blocked(sc: Scenario, fstar: np.ndarray, regular: bool) -> tuple[str, str]:
    """Why :math:`F^*` cannot be flown as it is ("" if it can), with the field to change: a
    slot within ``control.safety_radius`` of an obstacle (or inside one), beyond
    ``formation.max_radius``, two slots closer than twice :attr:`Scenario.start_separation`
    with the safety filter on (and ``design = "auto"``: else the safety checks refuse it),
    or, for a formation that is not a regular polygon (unequal UAVs, whose azimuths may
    bring two together), two slots closer than ``safety.min_separation`` (a collision)."""
    obstacles = sc.obstacle_set
    if obstacles.count:
        clearance = obstacle_clearance(fstar, obstacles)
        if np.any(clearance <= sc.control.safety_radius):
            m = int(np.argmin(clearance))
            return "target", (
                f"the slot of UAV {m} in F* over the target is inside an obstacle"
                if clearance[m] <= 0
                else f"the slot of UAV {m} in F* over the target is {clearance[m]:.3g} m from "
                f"an obstacle, within control.safety_radius = {sc.control.safety_radius:g} m"
            )
    limit = sc.formation.max_radius
    radius = float(np.max(np.hypot(*(fstar - np.asarray(sc.target)).T)))
    if limit is not None and radius > limit:
        return "formation.max_radius", (
            f"F* has radius {radius:.4g} m, beyond formation.max_radius = {limit:g} m"
        )
    need, why = 0.0, ""
    if sc.safety.enabled and sc.formation.design == "auto":
        need = 2.0 * sc.start_separation
        why = "twice the start separation (safety.min_separation and its margin)"
    elif not regular:
        need = sc.safety.min_separation
        why = "safety.min_separation: they would collide"
    if need > 0.0:
        gap = float(min_separation(np.ascontiguousarray(fstar)))
        if gap < need:
            return "safety.min_separation", (
                f"two slots of F* are {gap:.4g} m apart, closer than {need:.4g} m, {why}"
            )
    return "", ""


def _centre(slots: np.ndarray, target: np.ndarray, irregular: bool) -> np.ndarray:
    """The mean of the slots minus the target, read-only; exactly 0 for a regular polygon
    (whose computed mean differs from the target only by rounding)."""
    offset = np.mean(slots, axis=0) - target if irregular else np.zeros(2)
    offset.flags.writeable = False
    return offset


_DESIGN_FIELDS = {
    "max_radius": "formation.max_radius",
    "starts": "formation.starts",
    "min_separation": "safety.min_separation",
    "n_uavs": "uavs.count",
}

#: Most UAVs of a scenario's constrained design: it runs when the scenario is validated,
#: and its work grows as M^3 per start (41 UAVs: a few seconds).
MAX_SCENARIO_DESIGN_UAVS = 64


def scenario_starts(n_uavs: int) -> int:
    """Starts of a scenario's constrained design when ``formation.starts`` is not set:
    :func:`crlbswarm.constrained.default_starts`, and at most ``16384 / M^2`` (at least
    2), so the design stays within seconds (6 UAVs: 64 starts; 41: 9; 64: 4).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs.

    Returns
    -------
    int
        Number of starts.
    """
    return max(2, min(default_starts(n_uavs), 16384 // max(int(n_uavs), 1) ** 2))


def design_arguments(sc: Scenario) -> dict[str, Any]:
    """The arguments of :func:`crlbswarm.constrained_design` with which a scenario's blocked
    :math:`F^*` is replaced (:func:`design_formation`; ``crlbswarm design --scenario``):
    its obstacles, every slot at least ``(1 + DESIGN_CLEARANCE) control.safety_radius``
    from them, two slots at least twice :attr:`Scenario.start_separation` apart,
    ``formation.max_radius``, ``criterion``, ``starts`` (default :func:`scenario_starts`),
    ``seed`` and the rotation of ``uavs.rotation_deg``.

    Parameters
    ----------
    sc : Scenario
        The scenario.

    Returns
    -------
    dict
        Keyword arguments (besides ``n_uavs``, ``target_xy``, ``altitude`` and ``radar``).
    """
    spec = sc.formation
    return {
        "criterion": spec.criterion,
        "obstacles": sc.obstacle_set if sc.obstacle_set.count else None,
        "clearance": (1.0 + DESIGN_CLEARANCE) * sc.control.safety_radius,
        "min_separation": 2.0 * sc.start_separation,
        "max_radius": spec.max_radius,
        "starts": scenario_starts(sc.uavs.count) if spec.starts is None else spec.starts,
        "seed": spec.seed,
        "rotation": math.radians(sc.uavs.rotation_deg),
    }


def _cached_design(sc: Scenario) -> ConstrainedDesign:
    """:func:`crlbswarm.constrained_design` with :func:`design_arguments`, remembered for
    the last scenarios of this process (a scenario is validated again at every load)."""
    kwargs = design_arguments(sc)
    obstacles = kwargs["obstacles"]
    key = json.dumps(
        [sc.uavs.count, list(sc.target), sc.altitude, sc.radar_model.to_dict(),
         None if obstacles is None else [obstacles.rectangles.tolist(),
                                         obstacles.circles.tolist()],
         {k: v for k, v in kwargs.items() if k != "obstacles"}],
        sort_keys=True,
    )  # fmt: skip
    found = _DESIGNS.get(key)
    if found is None:
        found = constrained_design(sc.uavs.count, np.asarray(sc.target, dtype=float),
                                   sc.altitude, sc.radar_model, **kwargs)  # fmt: skip
        _DESIGNS[key] = found
        while len(_DESIGNS) > DESIGN_CACHE:
            _DESIGNS.pop(next(iter(_DESIGNS)))
    return found


#: Constrained designs remembered per process (the last ones; a scenario is validated
#: again at every load, and its design is made once).
DESIGN_CACHE = 32
_DESIGNS: dict[str, ConstrainedDesign] = {}


def design_formation(sc: Scenario) -> FormationDesign:
    """The formation of a scenario: :math:`F^*` (:func:`crlbswarm.optimal_formation`), or,
    when it is blocked and ``formation.design = "auto"``, the best formation that fits
    (:func:`crlbswarm.constrained_design` with :func:`design_arguments`: the scenario's
    obstacles, each slot at least ``(1 + DESIGN_CLEARANCE) control.safety_radius`` from
    them, two slots at least twice :attr:`Scenario.start_separation` apart,
    ``formation.max_radius``, criterion, starts and seed), for at most
    :data:`MAX_SCENARIO_DESIGN_UAVS` UAVs.

    Parameters
    ----------
    sc : Scenario
        The scenario (its fields each valid), with one target.

    Returns
    -------
    FormationDesign
        The slots, the bound the mission converges to and how they were made.

    Raises
    ------
    FieldError
        If :math:`F^*` is blocked and ``formation.design = "closed_form"``, or no formation
        fits, or the scenario has extra targets (one formation per group,
        :attr:`Scenario.group_plan`); one line naming the field to change.
    """
    if sc.extra_targets:
        raise FieldError("extra_targets", "a scenario with several targets flies one "
                         "formation per group: see Scenario.group_plan")  # fmt: skip
    n, target, radar = sc.uavs.count, np.asarray(sc.target, dtype=float), sc.radar_model
    rotation = math.radians(sc.uavs.rotation_deg)
    fstar = optimal_formation(n, target, sc.altitude, radar, rotation=rotation)
    best = float(crlb_bound(n, sc.altitude, radar))
    field, blocked = _blocked(sc, fstar, not radar.per_uav)
    if not blocked:
        fstar.flags.writeable = False
        return FormationDesign(
            slots=fstar, bound=best, unconstrained_bound=best, method="closed form",
            regular=not radar.per_uav, centre_offset=_centre(fstar, target, radar.per_uav),
            blocked="", criterion=sc.formation.criterion, ratio=1.0, active=(),
        )  # fmt: skip
    if sc.formation.design == "closed_form":
        hint = '(formation.design = "auto" flies the best formation that fits)'
        raise FieldError(field, f"{blocked}: the formation could never settle there {hint}")
    most = 16 * scenario_starts(n) if n > 16 else MAX_SCENARIO_STARTS
    if sc.formation.starts is not None and sc.formation.starts > most:
        raise FieldError(
            "formation.starts", f"{blocked}; at most {most} starts for {n} UAVs in a scenario "
            f"(the design runs when the scenario is loaded), got {sc.formation.starts}",
        )  # fmt: skip
    if n > MAX_SCENARIO_DESIGN_UAVS:
        raise FieldError(
            field, f"{blocked}; a scenario designs another formation for at most "
            f"{MAX_SCENARIO_DESIGN_UAVS} UAVs (uavs.count = {n}): make F* fit (the UAVs, "
            "the altitude, the target) or design one with crlbswarm.constrained_design",
        )  # fmt: skip
    try:
        found = _cached_design(sc)
    except FieldError as exc:
        raise FieldError(
            _DESIGN_FIELDS.get(exc.field, field),
            f"{blocked}, and no formation fits: {exc.reason}",
        ) from None
    slots = np.array(found.positions)
    slots.flags.writeable = False
    return FormationDesign(
        slots=slots, bound=float(crlb(slots, target, sc.altitude, radar)),
        unconstrained_bound=best, method="constrained", regular=False,
        centre_offset=_centre(slots, target, True), blocked=blocked,
        criterion=found.criterion, ratio=found.ratio, active=found.active,
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class GroupPlan:
    """The groups of a scenario with several targets (:attr:`Scenario.group_plan`).

    Attributes
    ----------
    allocation : TargetAllocation
        Which UAVs serve which target (:func:`crlbswarm.allocate_targets`; target 0 is
        ``target``, target k the k-th of ``extra_targets``).
    members : tuple of ndarray of int
        The UAVs of each group, in increasing order (indices of the whole swarm).
    leaders : ndarray of int, shape (G,)
        Each group's leader (an index of the whole swarm): ``uavs.leader`` in its own
        group, the lowest index in the others.
    scenarios : tuple of Scenario
        Each group's own mission: its UAVs (count, starts, radar), its target and leader,
        the rest of the fields as in the whole scenario (the planner off).
    """

    allocation: TargetAllocation
    members: tuple[np.ndarray, ...]
    leaders: np.ndarray
    scenarios: tuple[Scenario, ...]


def _target_field(g: int) -> str:
    return "target" if g == 0 else f"extra_targets.{g - 1}"


def plan_groups(sc: Scenario) -> GroupPlan:
    """Split a swarm between its targets and build each group's scenario.

    The allocation is :func:`crlbswarm.allocate_targets` over ``target`` and
    ``extra_targets`` with ``formation.objective`` (exhaustive for small swarms, a stated
    local search above). Group g flies its own formation (its design, F* or the constrained
    one, over its target) with its own leader; its scenario is the whole scenario restricted
    to its UAVs, validated like any scenario, so a group that cannot fly is refused with one
    line naming its target.

    Parameters
    ----------
    sc : Scenario
        A scenario with ``extra_targets`` (its fields each valid).

    Returns
    -------
    GroupPlan
        The allocation, the groups, their leaders and their scenarios.

    Raises
    ------
    FieldError
        When the UAVs are too few for the targets, or a group's mission is invalid.
    """
    targets = np.array([sc.target, *sc.extra_targets], dtype=float)
    n = sc.uavs.count
    try:
        allocation = allocate_targets(
            targets, n, sc.altitude, sc.radar_model, objective=sc.formation.objective
        )
    except FieldError as exc:
        field = {"n_uavs": "uavs.count", "objective": "formation.objective"}
        raise FieldError(field.get(exc.field, "extra_targets"), exc.reason) from None
    guidance = {**sc.guidance.model_dump(), "planner": False}
    members, leaders, scenarios = [], [], []
    for g, uavs in enumerate(allocation.groups):
        lead = sc.uavs.leader if sc.uavs.leader in uavs else int(uavs[0])
        try:
            scenarios.append(sc.restricted(
                uavs.tolist(), lead, name=f"{sc.name}/group{g}", target=targets[g].tolist(),
                extra_targets=[], guidance=guidance,
            ))  # fmt: skip
        except ScenarioError as exc:  # the group's own field and reason, in one line
            reason = f"{exc.field}: {exc.reason}" if exc.field else exc.reason
            raise FieldError(
                _target_field(g), f"the group of UAVs {uavs.tolist()} cannot fly: {reason}"
            ) from None
        members.append(uavs)
        leaders.append(lead)
    return GroupPlan(allocation, tuple(members), np.array(leaders, dtype=np.int64),
                     tuple(scenarios))  # fmt: skip


def _builtin_files() -> dict[str, Any]:
    folder = resources.files(__package__).joinpath("scenarios")
    return {f.name.removesuffix(".toml"): f for f in folder.iterdir() if f.name.endswith(".toml")}


def builtin_scenario_text(name: str) -> str:
    """The TOML file of a built-in scenario, as shipped.

    Parameters
    ----------
    name : str
        A key of :data:`BUILTIN_SCENARIOS`.

    Returns
    -------
    str
        The file's text (what ``crlbswarm scenario show NAME`` prints).
    """
    files = _builtin_files()
    if name not in files:
        raise _unknown(name)
    return files[name].read_text(encoding="utf-8")


def _unknown(key: str) -> ScenarioError:
    known = ", ".join(sorted(_builtin_files()))
    return ScenarioError(
        "scenario", "", f"{key!r} is neither a built-in scenario ({known}) nor a file"
    )


class _BuiltinScenarios(Mapping[str, dict[str, Any]]):
    """Read-only mapping of the built-in scenarios' names to their data (a fresh copy of the
    parsed TOML file on every access)."""

    def __getitem__(self, name: str) -> dict[str, Any]:
        if name not in self:
            raise KeyError(name)
        return read_toml(builtin_scenario_text(name), f"scenario '{name}'", ScenarioError)

    def __contains__(self, name: object) -> bool:
        return name in _builtin_files()

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(_builtin_files()))

    def __len__(self) -> int:
        return len(_builtin_files())

    def __repr__(self) -> str:
        return f"BUILTIN_SCENARIOS({', '.join(self)})"


#: Built-in scenarios by name (read-only; each access returns a fresh copy of the data).
BUILTIN_SCENARIOS: Mapping[str, dict[str, Any]] = _BuiltinScenarios()


def scenario_data(name_or_path: str | Path) -> tuple[str, dict[str, Any]]:
    """The data of a built-in scenario or of a scenario file, not yet validated.

    Parameters
    ----------
    name_or_path : str or path-like
        A built-in name or the path of a ``.toml`` file.

    Returns
    -------
    source : str
        Where the data came from (``"scenario 'paper'"`` or the file name), for messages.
    data : dict
        The parsed TOML document.

    Raises
    ------
    ScenarioError
        If there is no such scenario or file, or it cannot be read or parsed.
    """
    key = str(name_or_path)
    if key in BUILTIN_SCENARIOS:
        return f"scenario '{key}'", BUILTIN_SCENARIOS[key]
    if not Path(name_or_path).exists():
        raise _unknown(key)
    return key, read_toml_file(name_or_path, ScenarioError)[1]


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a built-in scenario by name, or a TOML scenario file by path.

    Parameters
    ----------
    name_or_path : str or path-like
        ``"paper"``, ``"sensing"``, ``"moving_target"`` (see :data:`BUILTIN_SCENARIOS`) or
        the path of a ``.toml`` file.

    Returns
    -------
    Scenario
        The validated scenario.

    Raises
    ------
    ScenarioError
        If there is no such scenario or file, or it is invalid (one line naming the
        field).
    """
    source, data = scenario_data(name_or_path)
    return Scenario.from_dict(data, source)
