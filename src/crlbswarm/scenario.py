"""Mission scenarios: a pydantic model read from TOML, and the built-in scenarios.

A scenario fixes everything a mission simulation needs: the UAVs and how they start, the
altitude and the target, the radar, the time step, the control gains, the motion
disturbance, the communication graph, the obstacles and the rule for the scaling factor
eta, and (beyond the paper) sensing in the loop and the target's motion. Files are TOML
(read with :mod:`tomllib`); ``crlbswarm scenario show paper`` prints the built-in paper
scenario as a file to copy and edit; ``sensing`` and ``moving_target`` are the other
built-ins. Every field, its unit and its default is listed in ``docs/scenarios.md``.

Validation happens when the scenario is built, before anything runs: unknown or missing
fields, wrong types, fewer than 3 UAVs, a disconnected graph, a start or target inside an
obstacle, non-positive time step, or gains beyond the stability bounds of
:mod:`crlbswarm.graphs` raise :class:`ScenarioError` (a :class:`ValueError`) whose one-line
message names the field.
"""

from __future__ import annotations

import copy
import math
import sys
from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Annotated, Any, Literal

import numpy as np
import tomlkit
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from .control import Obstacles, obstacle_clearance
from .design import optimal_formation
from .graphs import Adjacency, communication_graph, formation_step_limit
from .radar import Radar

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "BUILTIN_SCENARIOS",
    "CircleObstacle",
    "ControlConfig",
    "DisturbanceConfig",
    "EstimationConfig",
    "EtaConfig",
    "GraphConfig",
    "RadarConfig",
    "RectangleObstacle",
    "Scenario",
    "ScenarioError",
    "TargetMotionConfig",
    "TimeConfig",
    "UavsConfig",
    "load_scenario",
]


#: Largest number of time steps of a mission.
MAX_STEPS = 10_000_000

#: Largest distance of the prior mean from the truth, in prior standard deviations.
MAX_PRIOR_SIGMAS = 5.0


class ScenarioError(ValueError):
    """An invalid scenario; the message is one line naming the field and the reason."""


PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
Pair = Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class UavsConfig(_Model):
    """The UAVs and their start."""

    count: int = Field(ge=3, description="number of UAVs M (>= 3)")
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


class RadarConfig(_Model):
    """Radar parameters in linear SI units (see :class:`crlbswarm.Radar`)."""

    tx_power: PositiveFloat = Field(0.1, description="transmit power per UAV, W")
    noise_power: PositiveFloat = Field(1e-12, description="receiver noise power, W")
    processing_gain: PositiveFloat = Field(1000.0, description="processing gain, linear")
    tx_gain: PositiveFloat = Field(1.0, description="transmit antenna gain, linear")
    rx_gain: PositiveFloat = Field(1.0, description="receive antenna gain, linear")
    rcs: PositiveFloat = Field(1.0, description="radar cross section, m^2")
    carrier_frequency: PositiveFloat = Field(5.8e9, description="carrier frequency, Hz")
    kappa: PositiveFloat = Field(1.0, description="range-estimation constant")

    def to_radar(self) -> Radar:
        """The :class:`crlbswarm.Radar` with these parameters.

        Returns
        -------
        Radar
            The radar, linear SI units.
        """
        return Radar(**self.model_dump())


class TimeConfig(_Model):
    """Time discretisation."""

    step: PositiveFloat = Field(description="sampling interval dT, s")
    duration: PositiveFloat = Field(description="mission length, s (a whole number of steps)")

    @field_validator("duration")
    @classmethod
    def _whole_steps(cls, duration: float, info: ValidationInfo) -> float:
        step = info.data.get("step")
        if step is not None:
            n = duration / step
            if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
                raise ValueError(f"must be a positive whole number of steps of {step:g} s")
            if n > MAX_STEPS:
                raise ValueError(f"is {n:.3g} steps of {step:g} s; at most {MAX_STEPS:g} allowed")
        return duration

    @property
    def steps(self) -> int:
        """Number of steps K."""
        return round(self.duration / self.step)


class ControlConfig(_Model):
    """Gains of the control laws (Sec. IV; choices documented in docs/control.md)."""

    epsilon: PositiveFloat = Field(0.01, description="formation gain per step (paper: 0.01)")
    gamma: PositiveFloat = Field(0.25, description="consensus step (< 1/max degree; ring: < 0.5)")
    guidance_gain: PositiveFloat = Field(0.5, description="leader guidance gain k_g, 1/s")
    cruise_speed: PositiveFloat = Field(2.0, description="leader cruise speed v_c, m/s")
    safety_radius: PositiveFloat = Field(5.0, description="l_safe, m (paper: 5)")
    repulsion_gain: PositiveFloat = Field(2.0, description="E_r, m^4 per step (u^r is in metres)")
    repulsion_max_step: PositiveFloat = Field(1.0, description="cap on |u^r| per step, m")
    formation_steering: bool = Field(
        True, description="leader also steers the formation (disc of radius eta r*) off obstacles"
    )


class DisturbanceConfig(_Model):
    """Motion disturbance n_{m,k} ~ N(0, sigma^2 I), eq. (3)."""

    sigma: Annotated[float, Field(ge=0, allow_inf_nan=False)] = Field(
        0.01, description="standard deviation per axis per step, m (paper scenario: 0.01)"
    )


class GraphConfig(_Model):
    """Communication graph (see :func:`crlbswarm.communication_graph`)."""

    kind: Literal["ring", "complete", "path", "star", "random_geometric", "edges"] = Field(
        "ring",
        description="ring (paper scenario), complete, path, star, random_geometric or edges",
    )
    radius: PositiveFloat | None = Field(None, description="random_geometric: link radius")
    seed: Annotated[int, Field(ge=0)] | None = Field(None, description="random_geometric seed")
    edges: list[Annotated[list[int], Field(min_length=2, max_length=2)]] | None = Field(
        None, description="edges: explicit list of [m, p] pairs"
    )
    center: Annotated[int, Field(ge=0)] | None = Field(
        None, description="star: index of the hub (default 0)"
    )

    @model_validator(mode="after")
    def _options_fit_kind(self) -> GraphConfig:
        wanted = {"random_geometric": {"radius", "seed"}, "edges": {"edges"}, "star": {"center"}}
        allowed = wanted.get(self.kind, set())
        for option in ("radius", "seed", "edges", "center"):
            if getattr(self, option) is not None and option not in allowed:
                raise ValueError(f"option '{option}' does not apply to kind '{self.kind}'")
        return self


class RectangleObstacle(_Model):
    """Axis-aligned rectangle."""

    type: Literal["rectangle"]
    x: Pair = Field(description="[x_min, x_max], m")
    y: Pair = Field(description="[y_min, y_max], m")

    @model_validator(mode="after")
    def _check(self) -> RectangleObstacle:
        if self.x[0] >= self.x[1] or self.y[0] >= self.y[1]:
            raise ValueError("need x_min < x_max and y_min < y_max")
        return self


class CircleObstacle(_Model):
    """Disc."""

    type: Literal["circle"]
    center: Pair = Field(description="[x, y], m")
    radius: PositiveFloat = Field(description="m")


Obstacle = Annotated[RectangleObstacle | CircleObstacle, Field(discriminator="type")]


class EtaConfig(_Model):
    """Rule for the scaling factor eta (not in the paper; see :func:`crlbswarm.eta_target`)."""

    enabled: bool = Field(True, description="false keeps eta = 1")
    minimum: Annotated[float, Field(gt=0, le=1)] = Field(0.3, description="smallest eta")
    rate: PositiveFloat = Field(0.1, description="largest change of eta per second, 1/s")
    lookahead: PositiveFloat = Field(40.0, description="distance looked ahead, m")
    margin: PositiveFloat | None = Field(
        None, description="clearance to keep, m (default: control.safety_radius)"
    )
    samples: Annotated[int, Field(ge=2)] = Field(32, description="points sampled on the path")


class EstimationConfig(_Model):
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
            raise _FieldError(
                "estimation.prior_offset",
                f"is {offset:g} m, more than {MAX_PRIOR_SIGMAS:g} prior_std = "
                f"{self.prior_std:g} m: the filter's prior would contradict its own covariance",
            )
        return self


class TargetMotionConfig(_Model):
    """How the target moves (not in the paper, whose target is static)."""

    model: Literal["static", "constant_velocity", "turning"] = Field(
        "static", description="static, constant_velocity or turning (coordinated turn)"
    )
    velocity: Pair = Field([0.0, 0.0], description="initial velocity, m/s")
    turn_rate: FiniteFloat = Field(0.0, description="turning: rate of turn, rad/s")
    acceleration_noise: Annotated[float, Field(ge=0, le=100)] = Field(
        0.0, description="std of the white acceleration noise per axis, m/s^2 (at most 100)"
    )

    @model_validator(mode="after")
    def _options_fit_model(self) -> TargetMotionConfig:
        if self.model == "static":
            for name in ("velocity", "turn_rate", "acceleration_noise"):
                if np.any(getattr(self, name)):
                    raise _FieldError(f"target_motion.{name}", "does not apply to a static target")
        if self.model == "constant_velocity" and self.turn_rate:
            raise _FieldError("target_motion.turn_rate", "applies to model 'turning' only")
        if self.model == "turning" and not self.turn_rate:
            raise _FieldError("target_motion.turn_rate", "model 'turning' needs a non-zero rate")
        return self

    @property
    def moving(self) -> bool:
        """Whether the target moves."""
        return self.model != "static"


class Scenario(_Model):
    """A complete mission scenario (see the module docstring and docs/scenarios.md).

    Parameters
    ----------
    name : str
        Short name.
    description : str
        One line of text.
    altitude : float
        Common flight altitude H, m.
    target : [float, float]
        Target position s, m.
    uavs : UavsConfig
        Count, leader, start.
    time : TimeConfig
        Step and duration.
    radar : RadarConfig
        Radar (paper profile by default).
    control : ControlConfig
        Gains.
    disturbance : DisturbanceConfig
        Motion noise.
    graph : GraphConfig
        Communication graph.
    obstacles : list of RectangleObstacle or CircleObstacle
        Obstacles.
    eta : EtaConfig
        Scaling-factor rule.
    estimation : EstimationConfig
        Sensing in the loop (off by default: the formation knows the target).
    target_motion : TargetMotionConfig
        Motion of the target (static by default).
    """

    name: str = Field("custom", description="short name")
    description: str = Field("", description="one line of text")
    altitude: PositiveFloat = Field(description="common flight altitude H, m")
    target: Pair = Field(description="target position s = [x, y], m")
    uavs: UavsConfig
    time: TimeConfig
    radar: RadarConfig = RadarConfig()
    control: ControlConfig = ControlConfig()
    disturbance: DisturbanceConfig = DisturbanceConfig()
    graph: GraphConfig = GraphConfig()
    obstacles: list[Obstacle] = Field(default_factory=list)
    eta: EtaConfig = EtaConfig()
    estimation: EstimationConfig = EstimationConfig()
    target_motion: TargetMotionConfig = TargetMotionConfig()

    @model_validator(mode="after")
    def _check_scene(self) -> Scenario:
        obstacles = self.obstacle_set
        _check_outside(obstacles, np.asarray(self.target)[None], "target")
        if self.uavs.start is not None:
            _check_outside(obstacles, np.asarray(self.uavs.start), "uavs.start")
        else:
            (x0, x1), (y0, y1) = self.uavs.start_region
            for i, ob in enumerate(self.obstacles):
                if _region_overlaps(ob, x0, x1, y0, y1):
                    raise _FieldError(
                        "uavs.start_region", f"overlaps obstacles[{i}]; starts could be inside it"
                    )
        try:
            adjacency = self.adjacency
        except ValueError as exc:
            raise _FieldError(*_split_field(str(exc), "graph")) from exc
        self._check_gains(adjacency)
        self._check_estimation(obstacles)
        clearance = obstacle_clearance(self.formation, obstacles) if obstacles.count else None
        if clearance is not None and np.any(clearance <= self.control.safety_radius):
            m = int(np.argmin(clearance))
            raise _FieldError(
                "target",
                f"the slot of UAV {m} in F* over the target is {clearance[m]:.3g} m from an "
                f"obstacle, within control.safety_radius = {self.control.safety_radius:g} m: "
                "the formation could never settle there",
            )
        return self

    def _check_estimation(self, obstacles: Obstacles) -> None:
        """Sensing-in-the-loop and target-motion settings that cannot work."""
        est, motion, step = self.estimation, self.target_motion, self.time.step
        if est.enabled and est.measure_every > self.time.steps:
            raise _FieldError(
                "estimation.measure_every",
                f"{est.measure_every} exceeds the {self.time.steps} steps of the mission",
            )
        if not motion.moving:
            return
        speed = math.hypot(*motion.velocity)
        if speed >= self.control.cruise_speed:
            raise _FieldError(
                "target_motion.velocity",
                f"the target's speed {speed:g} m/s must be below control.cruise_speed = "
                f"{self.control.cruise_speed:g} m/s, or the formation cannot follow it",
            )
        if motion.model == "turning" and abs(motion.turn_rate) * step >= 0.5 * math.pi:
            raise _FieldError(
                "target_motion.turn_rate",
                f"turns {abs(motion.turn_rate) * step:g} rad per step; must be below pi/2",
            )
        if obstacles.count:
            from .tracking import target_trajectories

            path = target_trajectories(
                np.asarray(self.target, dtype=float), np.asarray(motion.velocity, dtype=float),
                motion.model, step, self.time.steps, [np.random.default_rng(0)],
                motion.turn_rate, 0.0,
            )[0, :, :2]  # fmt: skip
            inside = np.flatnonzero(obstacle_clearance(path, obstacles) <= 0)
            if inside.size:
                raise _FieldError(
                    "target_motion",
                    f"the target's nominal path enters an obstacle at t = {inside[0] * step:g} s",
                )

    def _check_gains(self, adjacency: Adjacency) -> None:
        """Stability bounds of the linear laws and the step-size limits of the nonlinear ones."""
        ctl, step = self.control, self.time.step
        # A relative allowance: at the limit itself the error does not decay, and the
        # computed eigenvalue may fall a rounding error short of it.
        eps_max = formation_step_limit(adjacency) * (1.0 - 1e-12)
        if ctl.epsilon >= eps_max:
            raise _FieldError(
                "control.epsilon",
                f"{ctl.epsilon:g} is unstable on this graph (must be < {eps_max:.4g}, "
                "2/lambda_max(L))",
            )
        max_degree = int(adjacency.degrees.max())
        if ctl.gamma * max_degree >= 1.0:
            raise _FieldError(
                "control.gamma",
                f"{ctl.gamma:g} is too large for this graph: it must be < 1/max degree = "
                f"{1.0 / max_degree:.4g} (for example {0.5 / max_degree:.4g})",
            )
        if ctl.guidance_gain * step >= 1.0:
            raise _FieldError(
                "control.guidance_gain",
                f"guidance_gain x time.step = {ctl.guidance_gain * step:g} must be < 1, or the "
                "leader overshoots its goal",
            )
        if ctl.cruise_speed * step >= ctl.repulsion_max_step:
            raise _FieldError(
                "control.repulsion_max_step",
                f"{ctl.repulsion_max_step:g} m must exceed cruise_speed x time.step = "
                f"{ctl.cruise_speed * step:g} m, or the repulsion cannot stop a cruising UAV "
                "at an obstacle",
            )
        if ctl.repulsion_max_step >= ctl.safety_radius:
            raise _FieldError(
                "control.repulsion_max_step",
                f"{ctl.repulsion_max_step:g} m must be below control.safety_radius = "
                f"{ctl.safety_radius:g} m",
            )

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
        g = self.graph
        graph = communication_graph(
            g.kind,
            self.uavs.count,
            radius=g.radius,
            seed=g.seed,
            edges=g.edges,
            center=0 if g.center is None else g.center,
        )
        return Adjacency.from_graph(graph)

    @cached_property
    def formation(self) -> np.ndarray:
        """The CRLB-optimal formation F* over the target, shape (M, 2), m (read-only)."""
        f = optimal_formation(
            self.uavs.count,
            np.asarray(self.target),
            self.altitude,
            self.radar.to_radar(),
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
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ScenarioError(f"{source}: invalid TOML: {exc}") from exc
        return cls.from_dict(data, source)

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
        """
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise ScenarioError(f"{source}: {_describe(exc)}") from None

    def to_toml(self) -> str:
        """The scenario as a TOML document, each field commented with its meaning and unit.

        Returns
        -------
        str
            TOML text; :meth:`from_toml` reads it back to an equal scenario.
        """
        doc = tomlkit.document()
        doc.add(tomlkit.comment(f"crlbswarm scenario '{self.name}'. Fields: docs/scenarios.md"))
        for key, value in self.model_dump(exclude_none=True).items():
            sub = getattr(self, key)
            if isinstance(sub, BaseModel):
                table = tomlkit.table()
                for sub_key, sub_value in value.items():
                    table.add(sub_key, _commented(sub_value, type(sub).model_fields[sub_key]))
                doc.add(tomlkit.nl())
                doc.add(key, table)
            elif key == "obstacles":
                if value:
                    array = tomlkit.aot()
                    for item in value:
                        array.append(tomlkit.item(item))
                    doc.add(tomlkit.nl())
                    doc.add(key, array)
            else:
                doc.add(key, _commented(value, type(self).model_fields[key]))
        return tomlkit.dumps(doc)


def _commented(value: Any, info: Any) -> Any:
    """A TOML item for ``value`` with the field's description as a trailing comment."""
    item = tomlkit.item(value)
    if info.description:
        item.comment(info.description)
    return item


class _FieldError(ValueError):
    """Raised by validators that know the dotted field name."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")


def _split_field(message: str, prefix: str) -> tuple[str, str]:
    head, sep, reason = message.partition(": ")
    if sep and head.startswith(prefix):
        return head, reason
    return prefix, message


def _describe(exc: ValidationError) -> str:
    """One line from a pydantic error: ``field.path: reason`` (several joined by '; ')."""
    parts = []
    for err in exc.errors(include_url=False):
        loc = [str(p) for p in err["loc"] if not str(p).startswith("function-")]
        # Drop the discriminator tag pydantic inserts after a list index (obstacles.1.circle).
        loc = [p for i, p in enumerate(loc) if not (i and loc[i - 1].isdigit() and p in _TAGS)]
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "missing":
            msg = "missing required field"
        elif err["type"] == "extra_forbidden":
            msg = "unknown field"
        elif "input" in err and not isinstance(err["input"], dict | list):
            msg = f"{msg} (got {err['input']!r})"
        where = ".".join(loc)
        # A section's own validator may already name the full dotted field in its message.
        if where and not msg.startswith(f"{where}."):
            msg = f"{where}: {msg}"
        parts.append(msg)
    return "; ".join(parts)


_TAGS = ("rectangle", "circle")


def _check_outside(obstacles: Obstacles, points: np.ndarray, field: str) -> None:
    if obstacles.count == 0:
        return
    clearance = obstacle_clearance(points, obstacles)
    inside = np.flatnonzero(clearance <= 0)
    if inside.size:
        where = f"{field}[{inside[0]}]" if points.shape[0] > 1 else field
        raise _FieldError(where, "lies inside an obstacle")


def _region_overlaps(ob: RectangleObstacle | CircleObstacle, x0, x1, y0, y1) -> bool:
    if isinstance(ob, RectangleObstacle):
        return ob.x[0] <= x1 and x0 <= ob.x[1] and ob.y[0] <= y1 and y0 <= ob.y[1]
    cx = min(max(ob.center[0], x0), x1)
    cy = min(max(ob.center[1], y0), y1)
    return math.hypot(cx - ob.center[0], cy - ob.center[1]) <= ob.radius


# ---------------------------------------------------------------------------------------
# Built-in scenarios
# ---------------------------------------------------------------------------------------
_PAPER = {
    "name": "paper",
    "description": "Figs. 3-4 of the paper: 6 UAVs through a 20 m gap to hover over (80, 90)",
    "altitude": 20.0,
    "target": [80.0, 90.0],
    "uavs": {"count": 6, "leader": 0, "start_region": [[-10.0, 10.0], [-10.0, 10.0]]},
    "time": {"step": 0.1, "duration": 150.0},
    "control": {"epsilon": 0.01, "safety_radius": 5.0},
    "disturbance": {"sigma": 0.01},
    "graph": {"kind": "ring"},
    "obstacles": [
        {"type": "rectangle", "x": [30.0, 45.0], "y": [0.0, 34.0]},
        {"type": "rectangle", "x": [30.0, 45.0], "y": [54.0, 80.0]},
    ],
}

_SENSING = {
    **copy.deepcopy(_PAPER),
    "name": "sensing",
    "description": "the paper mission, centred on the UAVs' own estimate from a prior 20 m off",
    "estimation": {"enabled": True, "prior_offset": [20.0, 0.0], "prior_std": 20.0},
}

_MOVING = {
    "name": "moving_target",
    "description": "6 UAVs catch and track a target moving at 3 m/s, estimated from their ranges",
    "altitude": 20.0,
    "target": [60.0, 60.0],
    "uavs": {"count": 6, "leader": 0, "start_region": [[-10.0, 10.0], [-10.0, 10.0]]},
    "time": {"step": 0.1, "duration": 150.0},
    "control": {"epsilon": 0.01, "cruise_speed": 6.0, "safety_radius": 5.0},
    "disturbance": {"sigma": 0.01},
    "graph": {"kind": "ring"},
    "target_motion": {
        "model": "constant_velocity",
        "velocity": [3.0, 0.0],
        "acceleration_noise": 0.05,
    },
    "estimation": {
        "enabled": True,
        "prior_offset": [20.0, 0.0],
        "prior_std": 20.0,
        "velocity_prior_std": 5.0,
    },
}

_BUILTINS: dict[str, dict[str, Any]] = {
    "paper": _PAPER,
    "sensing": _SENSING,
    "moving_target": _MOVING,
}

#: Built-in scenarios by name (read-only view; :func:`load_scenario` uses private copies).
BUILTIN_SCENARIOS: Mapping[str, dict[str, Any]] = MappingProxyType(copy.deepcopy(_BUILTINS))


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
        If there is no such scenario or file, or it is invalid (one line naming the field).
    """
    key = str(name_or_path)
    if key in _BUILTINS:
        return Scenario.from_dict(copy.deepcopy(_BUILTINS[key]), source=f"scenario '{key}'")
    path = Path(name_or_path)
    if not path.is_file():
        known = ", ".join(sorted(BUILTIN_SCENARIOS))
        raise ScenarioError(
            f"scenario: {key!r} is neither a built-in scenario ({known}) nor a file"
        )
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read: {exc}") from exc
    return Scenario.from_toml(text, source=str(path))
