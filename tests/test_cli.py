"""The command-line interface: output, JSON keys, one-line errors with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from crlbswarm import Radar, crlb_bound, optimal_elevation, optimal_formation
from crlbswarm.cli import main


def run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_design_table(capsys):
    status, out, err = run(
        capsys, "design", "--uavs", "6", "--altitude", "20", "--target", "80", "90"
    )
    assert status == 0
    assert err == ""
    assert "54.7354 deg" in out
    assert "5.347628e-03 m^2" in out
    assert out.count("\n") >= 6 + 8


def test_design_json_keys_and_values(capsys):
    status, out, _ = run(
        capsys,
        "design",
        "--uavs",
        "5",
        "--altitude",
        "50",
        "--target",
        "1",
        "-2",
        "--rotation",
        "30",
        "--json",
    )
    assert status == 0
    data = json.loads(out)
    assert set(data) == {
        "n_uavs",
        "altitude_m",
        "target_m",
        "rotation_deg",
        "elevation_deg",
        "radius_m",
        "positions_m",
        "crlb_m2",
        "bound_m2",
        "isotropic",
        "rmse_bound_m",
        "radar",
    }
    assert data["isotropic"] is True
    np.testing.assert_allclose(
        data["positions_m"],
        optimal_formation(5, (1, -2), 50.0, rotation=np.radians(30)),
        rtol=0,
        atol=1e-12,
    )
    assert data["elevation_deg"] == pytest.approx(float(np.degrees(optimal_elevation(50.0))))
    assert data["bound_m2"] == pytest.approx(float(crlb_bound(5, 50.0)), rel=1e-14)
    assert data["crlb_m2"] == pytest.approx(data["bound_m2"], rel=1e-12)
    assert data["rmse_bound_m"] == pytest.approx(np.sqrt(data["crlb_m2"]))


def test_design_with_per_uav_radar_values(capsys):
    """One value per UAV of a radar option gives unequal UAVs: their own elevations and
    radii, and the attainable optimum (here one UAV dominates)."""
    status, out, _ = run(capsys, "design", "--uavs", "3", "--tx-power", "10", "0.1", "0.1",
                         "--json")  # fmt: skip
    assert status == 0
    data = json.loads(out)
    radar = Radar(tx_power=[10.0, 0.1, 0.1])
    assert data["isotropic"] is False
    assert len(data["elevation_deg"]) == len(data["radius_m"]) == 3
    assert data["bound_m2"] == pytest.approx(float(crlb_bound(3, 20.0, radar)), rel=1e-14)
    assert data["crlb_m2"] == pytest.approx(data["bound_m2"], rel=1e-9)
    status, out, _ = run(capsys, "design", "--uavs", "3", "--tx-power", "10", "0.1", "0.1")
    assert "one UAV dominates" in out
    status, _, err = run(capsys, "design", "--uavs", "4", "--tx-power", "0.1", "0.2")
    assert status == 2
    assert err.count("\n") == 1


def test_design_radar_options_change_the_result(capsys):
    _, out1, _ = run(capsys, "design", "--json")
    _, out2, _ = run(capsys, "design", "--json", "--power", "1.0")
    b1, b2 = json.loads(out1)["bound_m2"], json.loads(out2)["bound_m2"]
    assert b2 < b1
    assert json.loads(out2)["radar"]["tx_power"] == 1.0


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["design", "--uavs", "2"], "--uavs"),
        (["design", "--altitude", "0"], "--altitude"),
        (["design", "--altitude", "-5"], "--altitude"),
        (["design", "--altitude", "nan"], "--altitude"),
        (["design", "--target", "inf", "0"], "--target"),
        (["design", "--power", "0"], "--power"),
        (["design", "--power", "-1"], "--power"),
        (["design", "--rcs", "nan"], "--rcs"),
        (["design", "--uavs", "three"], "--uavs"),
        (["design", "--target", "1"], "--target"),
        (["figures", "--uavs", "2", "--out", "unused"], "--uavs"),
    ],
)
def test_user_errors_are_one_line_exit_2(capsys, argv, option):
    with pytest.raises(SystemExit) as info:  # argparse errors exit, ours return
        raise SystemExit(main(argv))
    assert info.value.code == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.count("\n") == 1, err
    assert err.startswith("crlbswarm")
    assert option in err
    assert "Traceback" not in err


def test_missing_command_is_an_error(capsys):
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.fixture
def small_figures(monkeypatch):
    """Fewer Monte Carlo trials and runs for the figures command (same code paths)."""
    import crlbswarm.paper as paper_module

    monkeypatch.setattr(paper_module, "FIGURE_TRIALS", 50)
    monkeypatch.setattr(paper_module, "FIGURE_RUNS", 3)


def test_figures_writes_everything(tmp_path, capsys, small_figures):
    out = tmp_path / "figs"
    status, _, err = run(capsys, "figures", "--out", str(out))
    assert status == 0, err
    names = sorted(p.name for p in out.iterdir())
    stems = [
        "estimator_mse_vs_crlb",
        "fig2_crlb_vs_altitude",
        "fig3_formation_evolution",
        "fig4_crlb_and_cost",
        "moving_target_tracking",
        "moving_target_trajectories",
        "optimal_elevation",
        "sensing_in_the_loop",
    ]
    expected = sorted([f"{s}.{ext}" for s in stems for ext in ("csv", "png")] + ["manifest.json"])
    assert names == expected
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(manifest["files"]) == [n for n in names if n != "manifest.json"]
    assert manifest["fig2_crlb_vs_altitude"]["benchmark_parameters"]["seed"] == 0
    for png in out.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = np.genfromtxt(out / "fig2_crlb_vs_altitude.csv", delimiter=",", names=True)
    assert np.all(data["crlb_optimal_m2"] == pytest.approx(data["bound_m2"], rel=1e-12))
    for name in ("fixed_polygon", "arc", "line", "random_disc"):
        assert np.all(data[f"crlb_{name}_m2"] > data["crlb_optimal_m2"]), name
    elev = np.genfromtxt(out / "optimal_elevation.csv", delimiter=",", names=True)
    assert elev["altitude_m"][0] == 1.0
    assert elev["altitude_m"][-1] == pytest.approx(2e4)
    assert 54.73 < elev["elevation_deg"][0] < 54.7357
    assert 45.0 < elev["elevation_deg"][-1] < 46.0


def test_figures_in_pdf(tmp_path, capsys, small_figures):
    status, _, _ = run(capsys, "figures", "--out", str(tmp_path), "--format", "pdf")
    assert status == 0
    assert (tmp_path / "fig2_crlb_vs_altitude.pdf").read_bytes()[:4] == b"%PDF"


def test_figures_unwritable_out_is_one_line_error(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    status, _, err = run(capsys, "figures", "--out", str(blocker / "sub"))
    assert status == 2
    assert err.count("\n") == 1
    assert "--out" in err
    assert blocker.read_text() == "not a folder"


def test_console_script_entry_point():
    """The installed module runs as a program and exits 2 on a bad value."""
    proc = subprocess.run(
        [sys.executable, "-m", "crlbswarm.cli", "design", "--uavs", "1"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert "--uavs" in proc.stderr


def test_figures_3_and_4_data(tmp_path, capsys, small_figures):
    """Fig. 4's CSV ends at the bound with eta back at 1; Fig. 3's has every UAV's track."""
    status, _, err = run(capsys, "figures", "--out", str(tmp_path), "--seed", "2")
    assert status == 0, err
    ts = np.genfromtxt(tmp_path / "fig4_crlb_and_cost.csv", delimiter=",", names=True)
    assert ts["time_s"][-1] == pytest.approx(150.0)
    assert ts["crlb_m2"][-1] / ts["bound_m2"][-1] < 1.01
    assert ts["eta"][-1] == 1.0
    assert ts["eta"].min() < 1.0
    assert np.isnan(ts["cost"][-1])
    traj = np.genfromtxt(tmp_path / "fig3_formation_evolution.csv", delimiter=",", names=True)
    assert {f"x_uav{m}" for m in range(1, 7)} <= set(traj.dtype.names)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["fig4_crlb_and_cost"]["seed"] == 2
    assert manifest["sensing_in_the_loop"]["seeds"] == [2, 4]
    mc = np.genfromtxt(tmp_path / "estimator_mse_vs_crlb.csv", delimiter=",", names=True)
    assert np.all(mc["mse_low_optimal_m2"] <= mc["mse_optimal_m2"])
    assert np.all(mc["mse_optimal_m2"] <= mc["mse_high_optimal_m2"])
    low = mc["altitude_m"] < 50.0
    ratio = mc["mse_optimal_m2"][low] / mc["crlb_optimal_m2"][low]
    assert np.all((ratio > 0.5) & (ratio < 2.0))  # 50 trials: loose, the tests of
    # test_montecarlo.py check efficiency with 20 000 trials
    track = np.genfromtxt(tmp_path / "moving_target_tracking.csv", delimiter=",", names=True)
    assert track["rms_estimation_error_m"][-1] < 2.0 * np.sqrt(track["pcrb_m2"][-1])


def test_scenario_show_round_trips(tmp_path, capsys):
    """`scenario show paper` prints TOML that simulates exactly like the built-in."""
    from crlbswarm import Scenario, load_scenario, simulate

    status, out, _ = run(capsys, "scenario", "show", "paper")
    assert status == 0
    path = tmp_path / "paper.toml"
    path.write_text(out)
    status, out2, _ = run(capsys, "scenario", "show", str(path))

    def fields(text: str) -> list[str]:  # (the shipped file adds full-line comments)
        return [line for line in text.splitlines() if not line.startswith("#")]

    assert fields(out2) == fields(out)
    a = simulate(load_scenario("paper"), seed=4)
    b = simulate(Scenario.from_toml(out), seed=4)
    assert np.array_equal(a.positions, b.positions)


def test_scenario_list(capsys):
    status, out, _ = run(capsys, "scenario", "list")
    assert status == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert names == sorted(["paper", "paper_safe", "sensing", "moving_target"])


def test_simulate_writes_outputs(tmp_path, capsys):
    out = tmp_path / "sim"
    status, _, err = run(
        capsys, "simulate", "paper", "--seed", "3", "--runs", "4", "--out", str(out)
    )
    assert status == 0, err
    assert sorted(p.name for p in out.iterdir()) == [
        "metrics.csv",
        "scenario.toml",
        "summary.json",
        "trajectories.npz",
    ]
    metrics = np.genfromtxt(out / "metrics.csv", delimiter=",", names=True)
    assert metrics["seed"].tolist() == [3, 4, 5, 6]
    with np.load(out / "trajectories.npz") as data:
        assert data["positions"].shape == (4, 1501, 6, 2)
        from crlbswarm import load_scenario, simulate

        single = simulate(load_scenario("paper"), seed=5)
        assert np.array_equal(data["positions"][2], single.positions[0])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == 4
    assert summary["seeds"] == {"first": 3, "last": 6}


def test_simulate_without_trajectories(tmp_path, capsys):
    status, _, _ = run(
        capsys, "simulate", "paper", "--runs", "2", "--no-trajectories", "--out", str(tmp_path)
    )
    assert status == 0
    with np.load(tmp_path / "trajectories.npz") as data:
        assert "positions" not in data
        assert data["crlb"].shape == (2, 1501)


@pytest.mark.parametrize(
    ("toml_edit", "field"),
    [
        (("count = 6", "count = 2"), "uavs.count"),
        (("count = 6", 'count = "six"'), "uavs.count"),
        (("altitude = 20.0", "altitude = 20.0\nspeed = 3"), "speed"),
        (("step = 0.1", "step = 0.0"), "time.step"),
        (('kind = "ring"', 'kind = "edges"\nedges = [[0, 1], [2, 3], [3, 4], [4, 5]]'), "graph"),
        (("target = [80.0, 90.0]", "target = [35.0, 10.0]"), "target"),
    ],
)
def test_simulate_bad_scenario_file_exit_2_nothing_written(tmp_path, capsys, toml_edit, field):
    _, text, _ = run(capsys, "scenario", "show", "paper")
    old, new = toml_edit
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new, 1))
    out = tmp_path / "out"
    status, stdout, err = run(capsys, "simulate", str(path), "--out", str(out))
    assert status == 2
    assert stdout == ""
    assert err.count("\n") == 1
    assert field in err
    assert str(path) in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["simulate", "paper", "--runs", "0"], "--runs"),
        (["simulate", "paper", "--seed", "-1"], "--seed"),
        (["simulate", "nowhere.toml"], "nowhere.toml"),
    ],
)
def test_simulate_bad_options_exit_2(tmp_path, capsys, argv, option):
    out = tmp_path / "out"
    status, _, err = run(capsys, *argv, "--out", str(out))
    assert status == 2
    assert option in err
    assert err.count("\n") == 1
    assert not out.exists()
