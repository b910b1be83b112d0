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

import math
import typing
from collections.abc import Iterator, Mapping
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, ValidationInfo, create_model, field_validator, model_validator

from . import _validation as _v
from ._config import ConfigModel, PositiveFloat, model_to_toml, read_toml, read_toml_file, validate
from ._validation import MIN_UAVS
from .control import ControlGains, EtaRule
from .design import optimal_formation
from .errors import FieldError, ScenarioError
from .graphs import GRAPH_KINDS, Adjacency, communication_graph
from .obstacles import Obstacles
from .planning import FormationConfig, GuidanceConfig, Roadmap, build_roadmap
from .radar import Radar, radar_parameters
from .safety import SafetyConfig, disturbance_margins
from .scenario_checks import check_scenario

__all__ = [
    "BUILTIN_SCENARIOS",
    "CircleObstacle",
    "DisturbanceConfig",
    "EstimationConfig",
    "FormationConfig",
    "GraphConfig",
    "GuidanceConfig",
    "RadarConfig",
    "RectangleObstacle",
    "SafetyConfig",
    "Scenario",
    "TargetMotionConfig",
    "TimeConfig",
    "UavsConfig",
    "builtin_scenario_text",
    "load_scenario",
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
                PositiveFloat,
                Field(p.default, description=f"{p.label}, {p.unit or 'linear'}"),
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

    @model_validator(mode="after")
    def _check_whole(self) -> Scenario:
        check_scenario(self)
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
        """Radius of F* around the target, m."""
        offsets = self.slots - np.asarray(self.target)
        return float(np.max(np.hypot(offsets[:, 0], offsets[:, 1])))

    @property
    def formation_side(self) -> float:
        """Side of the regular polygon F* (distance between neighbouring slots), m."""
        return 2.0 * self.formation_radius * math.sin(math.pi / self.uavs.count)

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
        plan around, and a static target (the roadmap is built for one goal)."""
        return (
            self.guidance.planner and self.obstacle_set.count > 0 and not self.target_motion.moving
        )

    @property
    def route_goal(self) -> np.ndarray:
        """The goal of the route: the target, or the filter's prior mean with sensing in the
        loop (the UAVs do not know the target)."""
        goal = np.asarray(self.target, dtype=float)
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
        """The control gains with ``"auto"`` resolved on this scenario's graph."""
        return self.control.resolve(self.adjacency, self.uavs.leader)

    @cached_property
    def slots(self) -> np.ndarray:
        """The slots of the CRLB-optimal formation F* over the target, in the order of the
        UAVs' indices (slot m is UAV m's unless ``formation.assignment`` reassigns them),
        shape (M, 2), m (read-only)."""
        f = optimal_formation(
            self.uavs.count,
            np.asarray(self.target),
            self.altitude,
            self.radar_model,
            rotation=math.radians(self.uavs.rotation_deg),
        )
        f.flags.writeable = False
        return f

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
