"""Scenarios whose F* is blocked fly the constrained design (issue 11, item 2), and every
formation that is not a regular polygon converges about its own centre."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from crlbswarm import ScenarioError, crlb, crlb_bound, load_scenario, simulate
from crlbswarm.obstacles import obstacle_clearance
from crlbswarm.scenario import DESIGN_CLEARANCE, Scenario

SEEDS = range(6)


def _safe(**changes):
    data = copy.deepcopy(load_scenario("paper_safe").model_dump())
    for dotted, value in changes.items():
        node = data
        *path, last = dotted.split(".")
        for key in path:
            node = node[key]
        node[last] = value
    return Scenario.from_dict(data)


@pytest.fixture(scope="module")
def blocked():
    # F*'s slot of UAV 4 (azimuth -120 deg) falls inside the upper wall of paper_safe.
    return _safe(target=[52.0, 88.0], name="blocked")


def test_blocked_fstar_gets_the_constrained_design(blocked):
    design = blocked.formation_design
    assert design.method == "constrained"
    assert "inside an obstacle" in design.blocked
    slots = blocked.slots
    clearance = obstacle_clearance(slots, blocked.obstacle_set)
    assert np.all(clearance >= (1 + DESIGN_CLEARANCE) * blocked.control.safety_radius - 1e-9)
    gaps = np.hypot(*(slots[:, None] - slots[None]).transpose(2, 0, 1))
    gaps[np.diag_indices(slots.shape[0])] = np.inf
    assert gaps.min() >= 2 * blocked.start_separation - 1e-9
    # The bound the mission converges to is the CRLB of the design, at least the optimum.
    target = np.asarray(blocked.target)
    assert design.bound == pytest.approx(float(crlb(slots, target, blocked.altitude)), rel=1e-12)
    best = float(crlb_bound(6, blocked.altitude))
    assert design.unconstrained_bound == best
    assert design.bound >= best * (1 - 1e-9)
    assert design.ratio >= 1 - 1e-9
    assert np.allclose(design.centre_offset, slots.mean(axis=0) - target)
    assert blocked.formation_side == pytest.approx(gaps.min())


def test_blocked_mission_converges_to_the_design(blocked):
    result = simulate(blocked, seeds=SEEDS)
    metrics = result.metrics
    assert list(metrics["outcome"]) == ["converged"] * len(SEEDS)
    assert result.bound == blocked.formation_design.bound
    assert np.all(metrics["final_crlb_ratio"] < 1.001)
    assert np.all(metrics["final_centroid_error_m"] < 0.5)
    assert np.all(metrics["min_clearance_m"] > 0)
    summary = result.summary()
    assert summary["design"]["method"] == "constrained"
    assert summary["design"]["ratio"] >= 1 - 1e-9


def test_closed_form_design_refuses_a_blocked_fstar():
    with pytest.raises(ScenarioError) as info:
        _safe(target=[52.0, 88.0], **{"formation.design": "closed_form"})
    message = str(info.value)
    assert "\n" not in message
    assert "target:" in message
    assert "inside an obstacle" in message
    assert 'formation.design = "auto"' in message


def test_max_radius_shrinks_the_formation():
    sc = _safe(**{"formation.max_radius": 10.0, "obstacles": [], "guidance.planner": False})
    design = sc.formation_design
    assert design.method == "constrained"
    assert "formation.max_radius" in design.blocked
    offsets = sc.slots - np.asarray(sc.target)
    assert np.max(np.hypot(*offsets.T)) <= 10.0 + 1e-9
    assert design.bound > design.unconstrained_bound
    result = simulate(sc, seeds=range(3))
    assert list(result.metrics["outcome"]) == ["converged"] * 3


def test_criterion_seed_and_starts_reach_the_design():
    a = _safe(**{"formation.max_radius": 10.0, "formation.criterion": "E",
                 "formation.starts": 3, "obstacles": []})  # fmt: skip
    assert a.formation_design.criterion == "E"
    b = _safe(**{"formation.max_radius": 10.0, "formation.criterion": "E",
                 "formation.starts": 3, "obstacles": []})  # fmt: skip
    assert np.array_equal(a.slots, b.slots)  # the same seed: the same design


def test_no_formation_fits_is_refused_in_one_line():
    # A small disc around the target, all of it within l_safe of a circle.
    with pytest.raises(ScenarioError) as info:
        _safe(
            obstacles=[{"type": "circle", "center": [82.5, 90.0], "radius": 1.0}],
            **{"formation.max_radius": 3.0, "guidance.planner": False, "safety.enabled": False},
        )
    message = str(info.value)
    assert "\n" not in message
    assert "no formation fits" in message


@pytest.mark.parametrize("safety", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_unequal_uavs_converge_about_their_centre(seed, safety):
    """Unequal UAVs fly a formation whose centre is not the target: the centroid converges
    to the target plus the centre offset, and the CRLB to the design's bound (the attainable
    optimum, or, when two slots of F* are too close, the constrained design that keeps them
    apart: twice the start separation with the safety filter on, else
    safety.min_separation)."""
    rng = np.random.default_rng(seed)
    power = [float(p) for p in np.round(rng.uniform(0.02, 0.5, 6), 3)]
    sc = _safe(obstacles=[], **{"radar.tx_power": power, "safety.enabled": safety})
    design = sc.formation_design
    assert not design.regular
    best = float(crlb_bound(6, sc.altitude, sc.radar_model))
    if design.method == "constrained":
        assert "apart" in design.blocked
        assert design.bound >= best * (1 - 1e-9)
    else:
        assert design.bound == best
    result = simulate(sc, seeds=range(3))
    if safety:  # (without the filter the paths may cross: a collision on the way)
        assert list(result.metrics["outcome"]) == ["converged"] * 3
    gaps = np.hypot(*(sc.slots[:, None] - sc.slots[None]).transpose(2, 0, 1))
    assert np.min(gaps[np.triu_indices(6, 1)]) >= sc.safety.min_separation * (1 - 1e-9)
    assert np.all(result.metrics["final_crlb_ratio"] < 1.001)
    assert result.bound == design.bound
    offset = result.centroid[:, -1] - np.asarray(sc.target)
    assert np.allclose(offset, design.centre_offset, atol=0.5)
    assert np.linalg.norm(design.centre_offset) > 0.5  # (the check above is not vacuous)


def test_regular_polygon_has_no_centre_offset():
    for name in ("paper", "paper_safe", "sensing", "moving_target"):
        design = load_scenario(name).formation_design
        assert design.regular
        assert design.method == "closed form"
        assert np.array_equal(design.centre_offset, np.zeros(2))


def test_a_large_blocked_swarm_is_refused_before_searching():
    """F* of 80 UAVs with the safety filter on has slots closer than twice the start
    separation: beyond MAX_SCENARIO_DESIGN_UAVS the scenario is refused in one line, at
    once, instead of a long search at every load."""
    with pytest.raises(ScenarioError) as info:
        _safe(obstacles=[], **{"uavs.count": 80, "uavs.start_region": [[-60, 60], [-60, 60]],
                               "guidance.planner": False})  # fmt: skip
    message = str(info.value)
    assert "\n" not in message
    assert "at most 64 UAVs" in message


def test_the_design_is_made_once_per_process(blocked):
    """Loading the same blocked scenario again reuses its design (same slots)."""
    from crlbswarm.scenario import _DESIGNS

    assert _DESIGNS
    again = Scenario.from_dict(blocked.model_dump())
    assert np.array_equal(again.slots, blocked.slots)


@pytest.mark.parametrize("radius", [0.0, 1e-300, -1.0, 1e9, float("nan")])
def test_max_radius_out_of_range_is_refused_at_the_field(radius):
    with pytest.raises(ScenarioError) as info:
        _safe(**{"formation.max_radius": radius})
    assert info.value.field == "formation.max_radius"


def test_too_many_starts_for_a_large_blocked_swarm_are_refused():
    with pytest.raises(ScenarioError) as info:
        _safe(obstacles=[], **{"uavs.count": 41, "uavs.start_region": [[-40, 40], [-40, 40]],
                               "guidance.planner": False, "formation.starts": 500})  # fmt: skip
    assert info.value.field == "formation.starts"
    assert "at most 144 starts" in str(info.value)
