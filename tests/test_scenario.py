"""Mission scenarios (crlbswarm.scenario): the paper scenario, validation, TOML round trip.

The paper scenario is checked field by field against the paper scenario of docs/scenarios.md
and the profile of tests/conftest.py; its formation F* against the reference optimal
elevation (a root of dw/dphi found numerically in conftest). Every invalid input listed in
the issue must raise :class:`ScenarioError` (a ValueError) with one line that starts with
the source's name and names the field, whether it arrives as a dictionary or as TOML text.
"""

from __future__ import annotations

import copy
import math
import re

import numpy as np
import pytest
import tomlkit
from hypothesis import given, settings, strategies as st
from pydantic import ValidationError

from conftest import PAPER_LAWS
from crlbswarm import (
    BUILTIN_SCENARIOS,
    Scenario,
    ScenarioError,
    consensus_step_limit,
    formation_step_limit,
    load_scenario,
)

SOURCE = "mission.toml"


def paper_dict() -> dict:
    """A fresh, mutable copy of the built-in paper scenario."""
    return copy.deepcopy(BUILTIN_SCENARIOS["paper"])


def laplacian_by_hand(n: int, edges) -> np.ndarray:
    lap = np.zeros((n, n))
    for m, p in edges:
        lap[m, p] = lap[p, m] = -1.0
    lap[np.diag_indices(n)] = -lap.sum(axis=1)
    return lap


# -- the paper scenario ---------------------------------------------------------------------


def test_paper_scenario_matches_the_notes(ref):
    """the paper scenario of docs/scenarios.md, item by item."""
    sc = load_scenario("paper")
    assert sc.name == "paper"
    assert sc.uavs.count == 6
    assert sc.uavs.leader == 0
    assert sc.uavs.start is None
    assert sc.uavs.start_region == [[-10.0, 10.0], [-10.0, 10.0]]
    assert sc.altitude == 20.0
    assert sc.target == [80.0, 90.0]
    assert sc.time.step == 0.1
    assert sc.time.duration == 150.0
    assert sc.time.steps == 1500
    assert sc.control.epsilon == 0.01
    assert sc.control.safety_radius == 5.0
    assert sc.disturbance.sigma == 0.01
    assert sc.graph.kind == "ring"
    rects = sorted((o.x, o.y) for o in sc.obstacles)
    assert rects == [([30.0, 45.0], [0.0, 34.0]), ([30.0, 45.0], [54.0, 80.0])]
    assert all(o.type == "rectangle" for o in sc.obstacles)
    for key, value in ref.PAPER_PROFILE.items():
        assert getattr(sc.radar, key) == value, key


def test_paper_derived_objects(ref):
    """Ring adjacency, obstacle arrays, and F* = regular hexagon of radius H/tan(phi*)
    around the target with the leader at azimuth 0 (phi* from conftest's brentq)."""
    sc = load_scenario("paper")
    adj = sc.adjacency
    assert {tuple(e) for e in adj.edges.tolist()} == {(i, (i + 1) % 6) for i in range(5)} | {
        (0, 5)
    }
    np.testing.assert_array_equal(
        sc.obstacle_set.rectangles, [[30.0, 45.0, 0.0, 34.0], [30.0, 45.0, 54.0, 80.0]]
    )
    assert sc.obstacle_set.circles.shape == (0, 3)
    a = float(ref.snr_constant(ref.radar_params()))
    phi = ref.optimal_elevation_numeric(20.0, a)
    r_star = 20.0 / math.tan(phi)
    angles = 2.0 * math.pi * np.arange(6) / 6
    expected = np.array([80.0, 90.0]) + r_star * np.stack([np.cos(angles), np.sin(angles)], -1)
    np.testing.assert_allclose(sc.slots, expected, rtol=0, atol=1e-9)


def test_paper_scenario_rotation_and_leader():
    """rotation_deg turns F* about the target; UAV m keeps slot m."""
    d = paper_dict()
    d["uavs"]["rotation_deg"] = 30.0
    sc = Scenario.from_dict(d)
    base = load_scenario("paper").slots - [80.0, 90.0]
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    rotated = base @ np.array([[c, s], [-s, c]])
    np.testing.assert_allclose(sc.slots - [80.0, 90.0], rotated, atol=1e-12)


def test_scenario_is_frozen():
    sc = load_scenario("paper")
    with pytest.raises(ValidationError):
        sc.altitude = 30.0


def test_integers_are_accepted_for_float_fields():
    """A TOML file may write 20 for 20.0."""
    d = paper_dict()
    d["altitude"] = 20
    d["target"] = [80, 90]
    d["time"] = {"step": 0.1, "duration": 150}
    sc = Scenario.from_dict(d)
    assert sc == load_scenario("paper")


# -- validation errors ------------------------------------------------------------------------


def _set(path: str, value):
    """A mutation setting the dotted ``path`` (creating tables) to ``value``."""

    def mutate(d):
        *head, leaf = path.split(".")
        for key in head:
            d = d.setdefault(key, {})
        d[leaf] = value

    return mutate


def _drop(path: str):
    def mutate(d):
        *head, leaf = path.split(".")
        for key in head:
            d = d[key]
        del d[leaf]

    return mutate


def _explicit_start(points):
    def mutate(d):
        d["uavs"].pop("start_region")
        d["uavs"]["start"] = points

    return mutate


INSIDE_START = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [35.0, 10.0], [4.0, 0.0], [5.0, 0.0]]

#: (case id, mutation of the paper scenario, the field the message must name).
INVALID = [
    # Step-size limits of the nonlinear laws (the scenario's dT enters each).
    ("step-too-long-for-repulsion", _set("time.step", 0.5), "control.repulsion_max_step"),
    (
        "cap-beyond-safety-radius",
        _set("control.repulsion_max_step", 5.0),
        "control.repulsion_max_step",
    ),
    ("guidance-overshoots", _set("control.guidance_gain", 10.0), "control.guidance_gain"),
    ("gamma-over-one-over-degree", _set("control.gamma", 0.5), "control.gamma"),
    # F* must be able to settle: every slot farther than l_safe from every obstacle.
    (
        "slot-near-obstacle",
        _set("obstacles", [{"type": "circle", "center": [84.0, 104.0], "radius": 3.0}]),
        "target",
    ),
    # Graph options must belong to the chosen kind.
    ("ring-with-radius", _set("graph.radius", 0.5), "graph"),
    ("ring-with-edges", _set("graph.edges", [[0, 1]]), "graph"),
    ("complete-with-center", _set("graph", {"kind": "complete", "center": 1}), "graph"),
    ("unknown-top", _set("altitud", 20.0), "altitud"),
    ("unknown-nested", _set("control.epsilonn", 0.01), "control.epsilonn"),
    ("unknown-table", _set("wind.speed", 3.0), "wind"),
    ("missing-altitude", _drop("altitude"), "altitude"),
    ("missing-target", _drop("target"), "target"),
    ("missing-count", _drop("uavs.count"), "uavs.count"),
    ("missing-step", _drop("time.step"), "time.step"),
    ("missing-duration", _drop("time.duration"), "time.duration"),
    ("count-str", _set("uavs.count", "six"), "uavs.count"),
    ("count-float", _set("uavs.count", 6.5), "uavs.count"),
    ("altitude-str", _set("altitude", "high"), "altitude"),
    ("epsilon-bool", _set("control.epsilon", True), "control.epsilon"),
    ("gamma-str", _set("control.gamma", "0.2"), "control.gamma"),
    ("target-short", _set("target", [80.0]), "target"),
    ("m-below-3", _set("uavs.count", 2), "uavs.count"),
    (
        "disconnected",
        _set("graph", {"kind": "edges", "edges": [[0, 1], [1, 2], [3, 4], [4, 5]]}),
        "graph",
    ),
    (
        "rgg-disconnected",
        _set("graph", {"kind": "random_geometric", "radius": 0.01, "seed": 1}),
        "graph",
    ),
    ("rgg-no-radius", _set("graph", {"kind": "random_geometric", "seed": 1}), "graph"),
    ("edges-out-of-range", _set("graph", {"kind": "edges", "edges": [[0, 1], [1, 6]]}), "graph"),
    ("graph-kind", _set("graph.kind", "hexagon"), "graph.kind"),
    ("target-inside", _set("target", [35.0, 10.0]), "target"),
    (
        "target-inside-circle",
        lambda d: d["obstacles"].append({"type": "circle", "center": [80.0, 91.0], "radius": 2.0}),
        "target",
    ),
    ("start-inside", _explicit_start(INSIDE_START), "uavs.start"),
    (
        "region-overlaps",
        _set("uavs.start_region", [[20.0, 31.0], [0.0, 10.0]]),
        "uavs.start_region",
    ),
    (
        "region-overlaps-circle",
        lambda d: d["obstacles"].append({"type": "circle", "center": [12.0, 0.0], "radius": 2.5}),
        "uavs.start_region",
    ),
    ("step-zero", _set("time.step", 0.0), "time.step"),
    ("step-negative", _set("time.step", -0.1), "time.step"),
    ("duration-fraction", _set("time.duration", 150.05), "time.duration"),
    ("duration-below-step", _set("time.duration", 0.04), "time.duration"),
    ("epsilon-unstable", _set("control.epsilon", 0.6), "control.epsilon"),
    ("gamma-unstable", _set("control.gamma", 0.9), "control.gamma"),
    ("leader-too-big", _set("uavs.leader", 6), "uavs.leader"),
    ("leader-negative", _set("uavs.leader", -1), "uavs.leader"),
    ("start-and-region", _set("uavs.start", [[0.0, 0.0]] * 6), "uavs"),
    ("start-count", _explicit_start([[0.0, 0.0], [1.0, 1.0]]), "uavs.start"),
    ("sigma-negative", _set("disturbance.sigma", -0.01), "disturbance.sigma"),
    ("eta-minimum", _set("eta.minimum", 1.5), "eta.minimum"),
    (
        "rect-inverted",
        lambda d: d["obstacles"].append({"type": "rectangle", "x": [5.0, 1.0], "y": [50.0, 60.0]}),
        "obstacles.2",
    ),
    ("obstacle-type", lambda d: d["obstacles"].append({"type": "triangle"}), "obstacles.2"),
    (
        "radius-negative",
        lambda d: d["obstacles"].append({"type": "circle", "center": [0.0, 50.0], "radius": -1.0}),
        "obstacles.2.radius",
    ),
]


def assert_one_line_naming(message: str, source: str, field: str) -> None:
    """One line, starting with ``source: `` and then the dotted field path and a colon."""
    assert "\n" not in message
    assert message.startswith(f"{source}: {field}"), message


@pytest.mark.parametrize(("case", "mutate", "field"), INVALID, ids=[c[0] for c in INVALID])
def test_invalid_dict_raises_one_line_naming_field(case, mutate, field):
    data = paper_dict()
    mutate(data)
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data, source=SOURCE)
    assert isinstance(info.value, ValueError)
    assert_one_line_naming(str(info.value), SOURCE, field)


@pytest.mark.parametrize(("case", "mutate", "field"), INVALID, ids=[c[0] for c in INVALID])
def test_invalid_toml_raises_one_line_naming_field(case, mutate, field):
    """The same errors through TOML text (types as TOML writes them)."""
    data = paper_dict()
    mutate(data)
    with pytest.raises(ScenarioError) as info:
        Scenario.from_toml(tomlkit.dumps(data), source=SOURCE)
    assert_one_line_naming(str(info.value), SOURCE, field)


def test_cross_field_checks_name_the_dotted_field():
    """Checks that need two fields (duration vs step, leader vs count, start vs count) still
    name the offending field with its dotted path, like every other message."""
    cases = [
        (("time", "duration", 150.05), r"^mission\.toml: time\.duration: .*whole number"),
        (("uavs", "leader", 6), r"^mission\.toml: uavs\.leader: .*below count = 6"),
    ]
    for (section, key, value), pattern in cases:
        data = paper_dict()
        data[section][key] = value
        with pytest.raises(ScenarioError, match=pattern):
            Scenario.from_dict(data, source=SOURCE)
    data = paper_dict()
    data["uavs"].pop("start_region")
    data["uavs"]["start"] = [[0.0, 0.0]] * 5
    with pytest.raises(ScenarioError, match=r"^mission\.toml: uavs\.start: has 5 positions"):
        Scenario.from_dict(data, source=SOURCE)


def test_invalid_toml_syntax():
    with pytest.raises(ScenarioError) as info:
        Scenario.from_toml("altitude = = 20\n[uavs\ncount = 6\n", source="bad.toml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("bad.toml: invalid TOML")


def test_load_missing_file(tmp_path):
    path = tmp_path / "nowhere" / "mission.toml"
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    assert message.startswith("scenario: ")


def test_load_file_reports_errors_with_its_path(tmp_path):
    path = tmp_path / "mission.toml"
    data = paper_dict()
    data["control"]["epsilon"] = True
    path.write_text(tomlkit.dumps(data), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert_one_line_naming(str(info.value), str(path), "control.epsilon")
    path.write_bytes(b"altitude = 20.0\n\xff\xfe")
    with pytest.raises(ScenarioError, match=rf"^{re.escape(str(path))}: "):
        load_scenario(str(path))


@pytest.mark.parametrize(("kind", "n"), [("ring", 6), ("complete", 6), ("path", 7), ("star", 5)])
def test_stability_limits_are_enforced_at_the_computed_bound(kind, n):
    """epsilon just below 2/lambda_max(L) (numpy on a hand-built Laplacian) passes, just
    above fails; gamma must stay below the 1/max degree of docs/control.md (which implies the exact
    consensus limit 2/lambda_max(L_ff)). Failures name the field."""
    edges = {
        "ring": [(i, (i + 1) % n) for i in range(n)],
        "complete": [(i, j) for i in range(n) for j in range(i + 1, n)],
        "path": [(i, i + 1) for i in range(n - 1)],
        "star": [(0, i) for i in range(1, n)],
    }[kind]
    lap = laplacian_by_hand(n, edges)
    eps_max = 2.0 / np.linalg.eigvalsh(lap)[-1]
    leader = 1
    gamma_exact = 2.0 / np.linalg.eigvalsh(np.delete(np.delete(lap, leader, 0), leader, 1))[-1]
    gamma_max = 1.0 / np.diag(lap).max()
    assert gamma_max <= gamma_exact

    def build(eps, gamma):
        d = paper_dict()
        d["uavs"].update(count=n, leader=leader)
        d["graph"] = {"kind": kind}
        d["control"].update(epsilon=eps, gamma=gamma)
        return Scenario.from_dict(d, source=SOURCE)

    sc = build(eps_max * (1 - 1e-9), gamma_max * (1 - 1e-9))
    assert formation_step_limit(sc.adjacency) == pytest.approx(eps_max, rel=1e-12)
    assert consensus_step_limit(sc.adjacency, leader) == pytest.approx(gamma_exact, rel=1e-12)
    with pytest.raises(ScenarioError, match=r"^mission\.toml: control\.epsilon: "):
        build(eps_max * (1 + 1e-9), 0.01)
    with pytest.raises(ScenarioError, match=r"^mission\.toml: control\.gamma: "):
        build(0.01, gamma_max)


def test_epsilon_exactly_at_the_ring_limit_is_rejected():
    """epsilon * lambda_max = 2 is not stable (|1 - eps lambda_max| = 1), so it must fail."""
    data = paper_dict()
    data["control"]["epsilon"] = 0.5
    with pytest.raises(ScenarioError, match=r"^mission\.toml: control\.epsilon: "):
        Scenario.from_dict(data, source=SOURCE)


def test_epsilon_exactly_at_the_complete_limit_is_rejected():
    """Complete graph of 4: lambda_max = 4 exactly in floating point, epsilon = 0.5 fails."""
    data = paper_dict()
    data["uavs"]["count"] = 4
    data["graph"] = {"kind": "complete"}
    data["control"]["epsilon"] = 0.5
    with pytest.raises(ScenarioError, match=r"^mission\.toml: control\.epsilon: "):
        Scenario.from_dict(data, source=SOURCE)


def test_valid_variants_are_accepted():
    """A start region touching nothing, explicit starts, circles, every graph kind."""
    for graph in [
        {"kind": "complete"},
        {"kind": "path"},
        {"kind": "star", "center": 3},
        {"kind": "random_geometric", "radius": 0.9, "seed": 0},
        {"kind": "edges", "edges": [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5]]},
    ]:
        d = paper_dict()
        d["graph"] = graph
        d["control"]["gamma"] = 0.05
        d["control"]["epsilon"] = 0.01
        assert Scenario.from_dict(d).adjacency.n_nodes == 6
    d = paper_dict()
    _explicit_start([[float(i), 0.0] for i in range(6)])(d)
    d["obstacles"].append({"type": "circle", "center": [60.0, 40.0], "radius": 3.0})
    sc = Scenario.from_dict(d)
    assert sc.obstacle_set.circles.tolist() == [[60.0, 40.0, 3.0]]


# -- TOML round trip --------------------------------------------------------------------------


def awkward_scenario() -> Scenario:
    """Floats that need all 17 digits, circles, explicit starts, an edges graph, a margin."""
    d = paper_dict()
    d["altitude"] = 20.0 / 3.0
    d["obstacles"].append({"type": "circle", "center": [1.0 / 3.0, 70.0], "radius": 2.0 / 7.0})
    d["uavs"] = {
        "count": 6,
        "leader": 2,
        "rotation_deg": 1.0 / 9.0,
        "start": [[0.1 * i, 1.0 / (i + 3)] for i in range(6)],
    }
    d["graph"] = {"kind": "edges", "edges": [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0]]}
    d["eta"] = {"margin": 4.5, "minimum": 0.25}
    d["control"]["formation_steering"] = False
    return Scenario.from_dict(d)


@pytest.mark.parametrize("make", [lambda: load_scenario("paper"), awkward_scenario])
def test_toml_round_trip(make):
    sc = make()
    text = sc.to_toml()
    back = Scenario.from_toml(text, source="printed")
    assert back == sc
    assert back.model_dump() == sc.model_dump()
    assert back.to_toml() == text
    np.testing.assert_array_equal(back.slots, sc.slots)


def test_toml_is_commented():
    """Every top-level value and every value in a table carries its description."""
    text = load_scenario("paper").to_toml()
    assert text.startswith("#")
    lines = [ln for ln in text.splitlines() if "=" in ln and not ln.startswith("#")]
    in_obstacles = False
    for line in text.splitlines():
        if line.startswith("[["):
            in_obstacles = True
        elif line.startswith("["):
            in_obstacles = False
        elif "=" in line and not in_obstacles:
            assert " # " in line, line
    assert lines


def test_load_scenario_from_file_equals_builtin(tmp_path):
    path = tmp_path / "paper.toml"
    path.write_text(load_scenario("paper").to_toml(), encoding="utf-8")
    assert load_scenario(path) == load_scenario("paper")
    assert load_scenario(str(path)) == load_scenario("paper")


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=40)
@given(
    altitude=st.floats(0.1, 1e5),
    target=st.tuples(finite, finite),
    rotation=finite,
    sigma=st.floats(0.0, 10.0),
    epsilon=st.floats(1e-8, 0.49),
    steps=st.integers(1, 10_000),
    # Dyadic steps keep the duration exact; below 0.5 s so that cruise_speed x step stays
    # under the default repulsion cap (a separate validation rule).
    step=st.integers(1, 511).map(lambda i: i / 1024),
)
def test_toml_round_trip_any_floats(altitude, target, rotation, sigma, epsilon, steps, step):
    """Without obstacles any finite values survive to_toml/from_toml bit for bit."""
    d = {
        "altitude": altitude,
        "target": list(target),
        "uavs": {"count": 5, "start_region": [[-1.0, 1.0], [-1.0, 1.0]], "rotation_deg": rotation},
        # time.hold must be shorter than the mission: half of it, bit-exact too
        "time": {"step": step, "duration": step * steps, "hold": step * steps / 2},
        "disturbance": {"sigma": sigma},
        "control": {"epsilon": epsilon},
        **PAPER_LAWS,
    }
    sc = Scenario.from_dict(d)
    back = Scenario.from_toml(sc.to_toml())
    assert back == sc
    assert back.time.steps == steps
