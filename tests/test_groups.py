"""Missions with several targets: the swarm split into groups, each with its own leader and
formation, flown together with the safety filter across groups (issue 11, item 4)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from crlbswarm import (
    FieldError,
    ScenarioError,
    allocate_targets,
    load_results,
    load_scenario,
    simulate,
    simulate_groups,
)
from crlbswarm.cli import main
from crlbswarm.scenario import Scenario


def _data(count=7, extra=((100.0, -20.0),), target=(60.0, 70.0), **changes):
    data = copy.deepcopy(load_scenario("paper_safe").model_dump())
    data.update(name="groups", target=list(target), extra_targets=[list(t) for t in extra],
                obstacles=[])  # fmt: skip
    data["uavs"].update(count=count, start_region=[[-15.0, 15.0], [-15.0, 15.0]])
    for dotted, value in changes.items():
        node = data
        *path, last = dotted.split(".")
        for key in path:
            node = node[key]
        node[last] = value
    return data


def _scenario(**kwargs):
    return Scenario.from_dict(_data(**kwargs))


def test_plan_matches_the_allocation_and_the_leader_rule():
    sc = _scenario(count=10, extra=((100.0, -20.0), (-60.0, 80.0)), **{"uavs.leader": 5})
    plan = sc.group_plan
    targets = [sc.target, *sc.extra_targets]
    ref = allocate_targets(targets, 10, sc.altitude, objective="sum")
    assert plan.allocation.exhaustive
    assert [m.tolist() for m in plan.members] == [g.tolist() for g in ref.groups]
    assert sorted(np.concatenate(plan.members).tolist()) == list(range(10))
    for members, leader, gsc, target in zip(plan.members, plan.leaders, plan.scenarios, targets,
                                            strict=True):  # fmt: skip
        assert len(members) >= 3
        assert leader == (5 if 5 in members else members[0])
        assert gsc.uavs.count == len(members)
        assert members[gsc.uavs.leader] == leader
        assert list(gsc.target) == list(target)
        assert not gsc.planner_on


@pytest.fixture(scope="module")
def three_groups():
    sc = _scenario(count=10, extra=((100.0, -20.0), (-60.0, 80.0)))
    return sc, simulate_groups(sc, seeds=range(4))


def test_every_group_reaches_its_own_bound(three_groups):
    sc, result = three_groups
    assert len(result.groups) == 3
    for group in result.groups:
        m = group.metrics
        assert list(m["outcome"]) == ["converged"] * 4
        assert np.all(m["final_crlb_ratio"] < 1.01)
        assert np.all(m["final_centroid_error_m"] < 0.5)
        assert group.bound == pytest.approx(group.scenario.formation_design.bound)
    metrics = result.metrics
    assert metrics["group"].tolist() == [0] * 4 + [1] * 4 + [2] * 4
    assert result.outcome_counts == {"converged": 12}
    positions = result.positions
    assert positions is not None
    assert positions.shape == (4, sc.time.steps + 1, 10, 2)
    for members, group in zip(result.plan.members, result.groups, strict=True):
        assert np.array_equal(positions[:, :, members], group.positions)


def test_a_run_of_a_batch_is_the_single_run(three_groups):
    sc, result = three_groups
    single = simulate_groups(sc, seed=2)
    for group, alone in zip(result.groups, single.groups, strict=True):
        assert np.array_equal(group.positions[2], alone.positions[0])
        assert np.array_equal(group.crlb[2], alone.crlb[0])


def test_safety_filter_keeps_groups_apart():
    """Two targets 12 m apart: the two formations (radius 14 m) overlap; the safety filter
    keeps every pair of UAVs, across the groups, at least min_separation apart."""
    sc = _scenario(count=6, target=(60.0, 70.0), extra=((72.0, 70.0),))
    result = simulate_groups(sc, seeds=range(3))
    sep = result.groups[0].separation
    assert np.all(sep.min(axis=1) >= sc.safety.min_separation)
    assert "collision" not in result.outcome_counts
    # The separation of each group is the swarm's: pairs across groups included.
    positions = result.positions
    gaps = np.linalg.norm(positions[:, :, :, None] - positions[:, :, None, :], axis=-1)
    gaps[..., np.arange(6), np.arange(6)] = np.inf
    assert np.allclose(gaps.min(axis=(-1, -2)), sep)


def test_save_writes_a_folder_per_group(three_groups, tmp_path):
    _, result = three_groups
    paths = result.save(tmp_path / "out")
    assert [p.name for p in paths] == ["group0", "group1", "group2", "metrics.csv",
                                       "scenario.toml", "summary.json"]  # fmt: skip
    back = load_results(tmp_path / "out" / "group1")
    assert np.array_equal(back.positions, result.groups[1].positions)
    with pytest.raises(FieldError, match="several targets"):
        load_results(tmp_path / "out")


def test_cli_simulate_flies_the_groups(tmp_path, capsys):
    path = tmp_path / "mt.toml"
    path.write_text(_scenario().to_toml())
    assert main(["simulate", str(path), "--runs", "2", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "group 0: UAV indices" in out
    assert "group 1: UAV indices" in out
    assert (tmp_path / "o" / "group1" / "trajectories.npz").is_file()


@pytest.mark.parametrize(
    ("changes", "field", "words"),
    [
        ({"count": 5}, "uavs.count", "cannot give"),
        ({"estimation.enabled": True}, "estimation.enabled", "known targets"),
        (
            {"target_motion.model": "constant_velocity", "target_motion.velocity": [0.5, 0.0]},
            "target_motion.model",
            "static",
        ),
        ({"graph.kind": "edges", "graph.edges": [[0, 1]]}, "graph.kind", "edges"),
    ],
)
def test_invalid_group_scenarios_are_one_line_errors(changes, field, words):
    with pytest.raises(ScenarioError) as info:
        _scenario(**changes)
    message = str(info.value)
    assert "\n" not in message
    assert info.value.field == field
    assert words in message


def test_a_group_that_cannot_fly_names_its_target():
    # The second target's F* is all inside a wall and no formation fits within max_radius.
    data = _data(extra=((100.0, -20.0),), **{"formation.max_radius": 3.0})
    data["obstacles"] = [{"type": "circle", "center": [102.5, -20.0], "radius": 1.0}]
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data)
    assert info.value.field == "extra_targets.0"
    assert "\n" not in str(info.value)


def test_simulate_and_simulate_groups_refuse_the_other_kind():
    with pytest.raises(FieldError, match="simulate_groups"):
        simulate(_scenario())
    with pytest.raises(FieldError, match="use simulate"):
        simulate_groups(load_scenario("paper"))


def test_campaigns_refuse_several_targets(tmp_path):
    from crlbswarm.campaign import CampaignSpec, run_campaign

    path = tmp_path / "mt.toml"
    path.write_text(_scenario().to_toml())
    spec = CampaignSpec.from_toml(f'base = "{path}"\n[seeds]\ncount = 2\n')
    with pytest.raises(ScenarioError, match="extra_targets: campaigns fly one target"):
        run_campaign(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_overlapping_group_formations_are_refused():
    """Two targets at the same place: the groups' slots coincide, which no flight can
    resolve; refused in one line naming the extra target."""
    with pytest.raises(ScenarioError) as info:
        _scenario(extra=((60.0, 70.0),))
    assert info.value.field == "extra_targets.0"
    assert "overlap" in str(info.value)


def test_a_groups_scenario_has_no_single_formation():
    sc = _scenario()
    with pytest.raises(FieldError, match="one formation per group"):
        sc.formation_design
