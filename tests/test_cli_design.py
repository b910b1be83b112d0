"""``crlbswarm design`` with constraints, altitude bands, a scenario, several targets and
``-o/--out``: each option, the JSON round trip, and one-line errors that write nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest

from crlbswarm import (
    Obstacles,
    Radar,
    allocate_targets,
    constrained_design,
    crlb_bound,
    load_scenario,
)
from crlbswarm.cli import main
from crlbswarm.scenario import Scenario, design_arguments


def run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def run_json(capsys, *argv):
    status, out, err = run(capsys, "design", "--json", *argv)
    assert status == 0, err
    assert err == ""
    return json.loads(out)


def test_closed_form_output_is_unchanged_without_constraints(capsys):
    data = run_json(capsys, "--target", "80,90")
    assert "design" not in data  # the closed-form report, as before
    assert data["crlb_m2"] == pytest.approx(float(crlb_bound(6, 20.0)), rel=1e-12)
    _status, out, _ = run(capsys, "design", "--target", "80", "90")
    assert out.startswith("CRLB-optimal formation F*")


def test_constraint_options_give_the_library_design(capsys):
    data = run_json(capsys, "--uavs", "5", "--obstacle", "circle:14,0,6", "--obstacle",
                    "rect:-40,-30,-5,5", "--no-fly", "poly:0,30,30,30,30,60", "--no-fly",
                    "circle:-20,-20,5", "--clearance", "1", "--min-separation", "12",
                    "--max-radius", "40", "--criterion", "d", "--starts", "4", "--seed",
                    "3", "--rotation", "10")  # fmt: skip
    d = constrained_design(
        5, (0.0, 0.0), 20.0, criterion="D",
        obstacles=Obstacles(rectangles=[[-40, -30, -5, 5]], circles=[[14, 0, 6]]),
        no_fly=[[(0, 30), (30, 30), (30, 60)], (-20.0, -20.0, 5.0)], clearance=1.0,
        min_separation=12.0, max_radius=40.0, starts=4, seed=3, rotation=np.radians(10.0),
    )  # fmt: skip
    assert data["design"] == "constrained"
    assert data["criterion"] == "D"
    assert data["unit"] == "m^4"
    assert data["value"] == d.value
    assert data["unconstrained"] == d.unconstrained
    assert data["ratio"] == pytest.approx(d.ratio, rel=1e-15)
    assert data["active"] == list(d.active)
    assert data["starts"] == 4
    assert data["feasible_starts"] == d.feasible_starts
    np.testing.assert_array_equal(data["positions_m"], d.positions)
    c = data["constraints"]
    assert c["clearance_m"] == 1.0
    assert c["min_separation_m"] == 12.0
    assert c["max_radius_m"] == 40.0
    assert c["obstacles"] == {"rectangles": [[-40.0, -30.0, -5.0, 5.0]],
                              "circles": [[14.0, 0.0, 6.0]]}  # fmt: skip
    assert c["no_fly"] == [[[0.0, 30.0], [30.0, 30.0], [30.0, 60.0]], [-20.0, -20.0, 5.0]]
    assert data["altitude_m"] == 20.0
    assert data["altitudes_m"] == [20.0] * 5
    assert data["altitude_bands_m"] is None


def test_table_reports_the_certificate(capsys):
    status, out, err = run(capsys, "design", "--max-radius", "10", "--starts", "4")
    assert status == 0
    assert err == ""
    for text in ("criterion value", "unconstrained", "ratio                1.157",
                 "max_radius UAV 1", "4 (4 feasible)"):  # fmt: skip
        assert text in out, text


@pytest.mark.parametrize("bands", [["15:30"], ["10:30", "20:25", "5:50", "30:30"]])
def test_altitude_bands_once_or_per_uav(capsys, bands):
    argv = ["--uavs", "4", "--starts", "3"]
    for band in bands:
        argv += ["--altitude-band", band]
    data = run_json(capsys, *argv)
    low = [float(b.split(":")[0]) for b in bands] * (4 if len(bands) == 1 else 1)
    assert data["altitudes_m"] == low
    assert data["altitude_m"] is None
    assert len(data["altitude_bands_m"]) == 4
    assert data["ratio"] == pytest.approx(1.0, abs=1e-9)
    _status, out, _ = run(capsys, "design", *argv)
    assert "band (m)" in out
    assert "each UAV at its band's low end" in out


def test_per_uav_radar_with_constraints(capsys):
    data = run_json(capsys, "--uavs", "3", "--tx-power", "1", "0.1", "0.2", "--max-radius",
                    "10", "--starts", "2")  # fmt: skip
    assert data["radar"]["tx_power"] == [1.0, 0.1, 0.2]
    d = constrained_design(3, (0, 0), 20.0, Radar(tx_power=[1.0, 0.1, 0.2]), max_radius=10.0,
                           starts=2)  # fmt: skip
    assert data["value"] == d.value


@pytest.mark.parametrize("source", ["builtin", "file"])
def test_scenario_gives_the_scene_and_options_override(capsys, tmp_path, source):
    sc = load_scenario("paper_safe")
    name = "paper_safe"
    if source == "file":
        path = tmp_path / "mine.toml"
        path.write_text(sc.to_toml())
        name = str(path)
    data = run_json(capsys, "--scenario", name, "--starts", "2")
    assert data["n_uavs"] == sc.uavs.count
    assert data["target_m"] == list(sc.target)
    assert data["altitude_m"] == sc.altitude
    c = data["constraints"]
    args = design_arguments(sc)  # what the scenario flies when its F* is blocked
    assert c["clearance_m"] == args["clearance"]
    assert c["min_separation_m"] == args["min_separation"]
    assert len(c["obstacles"]["rectangles"]) == 2
    over = run_json(capsys, "--scenario", name, "--starts", "2", "--uavs", "4", "--clearance",
                    "2", "--altitude", "30", "--power", "1", "--target", "0,0")  # fmt: skip
    assert over["n_uavs"] == 4
    assert over["constraints"]["clearance_m"] == 2.0
    assert over["altitude_m"] == 30.0
    assert over["radar"]["tx_power"] == 1.0
    assert over["target_m"] == [0.0, 0.0]
    assert over["radar"]["noise_power"] == sc.radar_model.noise_power


def test_scenario_design_is_the_one_the_scenario_flies(capsys, tmp_path):
    """A scenario whose F* is blocked: ``design --scenario`` prints the formation the mission
    flies (its design arguments: clearance, separation, criterion, max_radius, starts,
    seed), and a scenario with several targets is allocated over all of them."""
    data = load_scenario("paper_safe").model_dump()
    data.update(target=[52.0, 88.0])
    # (the D-optimum is not unique; with seed 2 the design found leaves the route its room)
    data["formation"].update(criterion="D", seed=2, max_radius=16.0, starts=4)
    sc = Scenario.from_dict(data)
    path = tmp_path / "blocked.toml"
    path.write_text(sc.to_toml())
    report = run_json(capsys, "--scenario", str(path))
    assert report["criterion"] == "D"
    assert report["constraints"]["max_radius_m"] == 16.0
    np.testing.assert_array_equal(report["positions_m"], sc.slots)
    data = load_scenario("paper_safe").model_dump()
    data.update(obstacles=[], extra_targets=[[200.0, 0.0]])
    data["uavs"].update(count=7, start_region=[[-15.0, 15.0], [-15.0, 15.0]])
    path.write_text(Scenario.from_dict(data).to_toml())
    report = run_json(capsys, "--scenario", str(path))
    assert report["design"] == "allocation"
    assert len(report["groups"]) == 2


@pytest.mark.parametrize("objective", ["sum", "max"])
def test_repeated_targets_allocate(capsys, objective):
    data = run_json(capsys, "--uavs", "7", "--target", "0,0", "--target", "200", "0",
                    "--objective", objective)  # fmt: skip
    a = allocate_targets([[0.0, 0.0], [200.0, 0.0]], 7, 20.0, objective=objective)
    assert data["design"] == "allocation"
    assert data["exhaustive"] is True
    assert data["value_m2"] == a.value
    assert [g["uavs"] for g in data["groups"]] == [(g + 1).tolist() for g in a.groups]
    assert data["assignment"] == (a.assignment + 1).astype(int).tolist()
    _status, out, _ = run(capsys, "design", "--uavs", "7", "--target", "0,0", "--target",
                         "200,0")  # fmt: skip
    assert "target 2 at (200, 0) m: UAVs" in out
    assert "exhaustive" in out


def test_many_uavs_to_targets_use_the_heuristic(capsys):
    data = run_json(capsys, "--uavs", "14", "--target", "0,0", "--target", "100,0",
                    "--target", "0,100")  # fmt: skip
    assert data["exhaustive"] is False
    _status, out, _ = run(capsys, "design", "--uavs", "14", "--target", "0,0", "--target",
                         "100,0", "--target", "0,100")  # fmt: skip
    assert "heuristic" in out


def test_out_writes_the_json_and_refuses_to_overwrite(capsys, tmp_path):
    path = tmp_path / "design.json"
    status, out, err = run(capsys, "design", "--max-radius", "10", "--starts", "2", "-o",
                           str(path))  # fmt: skip
    assert status == 0
    assert err == ""
    assert out.rstrip().endswith(f"wrote {path}")
    first = json.loads(path.read_text())
    assert first["design"] == "constrained"
    status, out, err = run(capsys, "design", "--json", "--out", str(path))
    assert status == 2
    assert out == ""
    assert err.count("\n") == 1
    assert "-o/--out" in err
    assert "--force" in err
    assert json.loads(path.read_text()) == first  # untouched
    status, out, err = run(capsys, "design", "--json", "--out", str(path), "--force")
    assert status == 0
    assert json.loads(path.read_text()) == json.loads(out)  # the JSON round trip
    assert [p.name for p in tmp_path.iterdir()] == ["design.json"]  # no temporary left


@pytest.mark.parametrize(
    ("argv", "option"),
    [(["--target", "1"], "--target"), (["--target", "1,2,3"], "--target"),
     (["--obstacle", "rect:1,2"], "--obstacle"), (["--obstacle", "hex:1,2,3"], "--obstacle"),
     (["--obstacle", "rect:2,1,0,1"], "--obstacle"),
     (["--obstacle", "circle:0,0,nan"], "--obstacle"),
     (["--no-fly", "poly:1,2,3,4"], "--no-fly"), (["--no-fly", "circle:0,0,-1"], "--no-fly"),
     (["--no-fly", "poly:0,0,1,1,1,0,0,1"], "--no-fly"), (["--clearance", "-1"], "--clearance"),
     (["--min-separation", "nan"], "--min-separation"), (["--max-radius", "0"], "--max-radius"),
     (["--altitude-band", "30:20"], "--altitude-band"),
     (["--altitude-band", "x"], "--altitude-band"),
     (["--altitude-band", "0:20"], "--altitude-band"),
     (["--altitude-band", "10:20", "--altitude-band", "10:30"], "--altitude-band"),
     (["--criterion", "Q"], "--criterion"), (["--starts", "0"], "--starts"),
     (["--starts", "1000000"], "--starts"), (["--seed", "-1"], "--seed"),
     (["--scenario", "nope"], "--scenario"), (["--objective", "max"], "--objective"),
     (["--target", "0,0", "--target", "1,1", "--objective", "min"], "--objective"),
     (["--target", "0,0", "--target", "1,1", "--max-radius", "9"], "--max-radius"),
     (["--target", "0,0", "--target", "1,1", "--rotation", "5"], "--rotation"),
     (["--target", "0,0", "--target", "9,9", "--uavs", "5"], "--uavs"),
     (["--uavs", "501", "--max-radius", "10"], "--uavs"),
     (["--max-radius", "1", "--min-separation", "5", "--starts", "2"], "--min-separation"),
     (["--force"], "--out")],
)  # fmt: skip
def test_errors_are_one_line_exit_2_and_write_nothing(capsys, tmp_path, argv, option):
    path = tmp_path / "never.json"
    out_args = [] if option == "--out" else ["-o", str(path)]
    status, out, err = run(capsys, "design", *argv, *out_args)
    assert status == 2
    assert out == ""
    assert err.count("\n") == 1, err
    assert err.startswith("crlbswarm: error:")
    assert option in err
    assert "Traceback" not in err
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where", ["folder", "missing_folder"])
def test_out_to_a_folder_or_a_missing_folder_is_refused(capsys, tmp_path, where):
    path = tmp_path if where == "folder" else tmp_path / "no" / "x.json"
    status, _, err = run(capsys, "design", "-o", str(path))
    assert status == 2
    assert "-o/--out" in err
    assert err.count("\n") == 1
