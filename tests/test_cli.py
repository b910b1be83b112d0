"""The command-line interface: output, JSON keys, one-line errors with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from crlbswarm import crlb_bound, optimal_elevation, optimal_formation
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
        "rmse_bound_m",
        "radar",
    }
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


def test_figures_writes_everything(tmp_path, capsys):
    out = tmp_path / "figs"
    status, _, err = run(capsys, "figures", "--out", str(out))
    assert status == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "fig2_crlb_vs_altitude.csv",
        "fig2_crlb_vs_altitude.png",
        "manifest.json",
        "optimal_elevation.csv",
        "optimal_elevation.png",
    ]
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


def test_figures_in_pdf(tmp_path, capsys):
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
