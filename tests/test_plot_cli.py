"""``crlbswarm plot`` (issue 13): the figures of any run of a saved result, and of its batch,
for every kind of ``simulate`` folder; reload of each kind; the batch view's numbers."""

from __future__ import annotations

import copy
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from crlbswarm import FieldError, load_results, load_scenario
from crlbswarm.cli import main
from crlbswarm.plots import plot_batch_metrics, plot_mission_trajectories
from crlbswarm.replay import load_mission_folder
from crlbswarm.scenario import Scenario

DPI = ["--dpi", "30"]  # small images: the test is about which files, not how they look


def short_scenario(folder: Path, name: str, duration: float, **top: object) -> Path:
    """A built-in scenario cut to ``duration`` seconds, written as a TOML file."""
    data = copy.deepcopy(load_scenario(name).model_dump())
    data["time"].update(duration=duration, hold=2.0, stall=5.0)
    data.update(top)
    path = folder / f"{name}_{len(list(folder.glob('*.toml')))}.toml"
    path.write_text(Scenario.from_dict(data).to_toml(), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """One ``simulate`` folder of each kind, written by the command itself."""
    root = tmp_path_factory.mktemp("runs")
    paper = short_scenario(root, "paper", 20.0)
    sensing = short_scenario(root, "sensing", 12.0)
    groups = short_scenario(root, "paper_safe", 6.0, target=[60.0, 70.0], obstacles=[],
                            extra_targets=[[100.0, -20.0]])  # fmt: skip
    kinds = {
        "single": [str(paper)],
        "batch": [str(paper), "--runs", "3", "--seed", "4", "--trajectory-stride", "7"],
        "estimation": [str(sensing), "--runs", "2"],
        "no_trajectories": [str(paper), "--runs", "2", "--no-trajectories"],
        "groups": [str(groups), "--runs", "2"],
    }
    out = {}
    for kind, argv in kinds.items():
        out[kind] = root / kind
        assert main(["simulate", *argv, "--out", str(out[kind])]) in (0, 1)
    return out


def plot(capsys, *argv: str) -> tuple[int, list[str], list[str]]:
    capsys.readouterr()
    status = main(["plot", *argv])
    captured = capsys.readouterr()
    return status, captured.out.splitlines(), captured.err.splitlines()


def written(out: Path) -> set[str]:
    return {p.name for p in out.iterdir()}


def assert_images(folder: Path, names: set[str]) -> None:
    assert written(folder) == names
    for name in names:
        if name.endswith(".png"):
            with Image.open(folder / name) as image:
                image.load()  # a complete, decodable PNG
                assert min(image.size) > 50
        else:
            assert (folder / name).read_text(encoding="utf-8").lstrip().startswith("<?xml")


@pytest.mark.parametrize(
    ("kind", "run", "expected"),
    [
        ("batch", 2, {"run2_trajectories.png", "run2_timeseries.png", "metrics.png"}),
        ("estimation", 1, {"run1_trajectories.png", "run1_timeseries.png", "estimation.png",
                           "metrics.png"}),
        ("no_trajectories", 1, {"run1_timeseries.svg", "metrics.svg"}),
    ],
)  # fmt: skip
def test_plot_writes_the_figures_of_each_kind_of_folder(runs, tmp_path, capsys, kind, run,
                                                        expected):  # fmt: skip
    out = tmp_path / "figs"
    fmt = next(iter(expected)).rsplit(".", 1)[1]
    status, lines, err = plot(capsys, str(runs[kind]), "--run", str(run), "--out", str(out),
                              "--format", fmt, *DPI)  # fmt: skip
    assert status == 0, err
    assert_images(out, expected)
    assert sorted(line.removeprefix("wrote ") for line in lines if line.startswith("wrote")) \
        == sorted(str(out / name) for name in expected)  # fmt: skip
    if kind == "no_trajectories":
        assert any(line.startswith("note: no trajectories") for line in lines)


def test_plot_defaults_to_a_plots_folder_and_replaces_files_only_with_force(runs, capsys):
    argv = [str(runs["single"]), *DPI]
    status, _, err = plot(capsys, *argv)
    assert status == 0, err
    folder = runs["single"] / "plots"
    assert_images(folder, {"run0_trajectories.png", "run0_timeseries.png"})
    figure = folder / "run0_timeseries.png"
    assert load_results(runs["single"]).n_runs == 1  # the folder is still a result
    stamp = figure.stat().st_mtime_ns
    status, _, err = plot(capsys, *argv)
    assert status == 2
    assert len(err) == 1
    assert "already exists" in err[0]
    assert "--force" in err[0]
    assert figure.stat().st_mtime_ns == stamp
    assert plot(capsys, *argv, "--force")[0] == 0
    assert figure.stat().st_mtime_ns != stamp


def test_plot_refuses_a_run_out_of_range_and_writes_nothing(runs, tmp_path, capsys):
    out = tmp_path / "figs"
    status, lines, err = plot(capsys, str(runs["batch"]), "--run", "3", "--out", str(out))
    assert status == 2
    assert err == ["crlbswarm: error: --run: must be an index in 0..2, got 3"]
    assert lines == []
    assert not out.exists()
    status, _, err = plot(capsys, str(runs["batch"]), "--run", "-1", "--out", str(out))
    assert (status, len(err), out.exists()) == (2, 1, False)


def test_plot_draws_each_group_of_several_targets(runs, tmp_path, capsys):
    """The top folder of a mission with several targets: each group's figures, its UAVs
    named by their indices in the swarm (1-based, as every legend)."""
    out = tmp_path / "x"
    status, _, err = plot(capsys, str(runs["groups"]), "--out", str(out), *DPI)
    assert status == 0, err
    names = ("run0_trajectories", "run0_timeseries", "metrics")
    assert_images(out, {f"group{g}_{name}.png" for g in (0, 1) for name in names})
    grouped = load_mission_folder(runs["groups"])
    group, members = grouped.groups[1], grouped.plan.members[1]
    assert members[0] > 0  # (the second group's UAVs are not the first of the swarm)
    fig = plot_mission_trajectories(group, uavs=members)
    labels = [t.get_text() for t in fig.legends[0].get_texts() if t.get_text().startswith("UAV")]
    leader = int(grouped.plan.leaders[1])
    assert labels == [f"UAV {u + 1}" + (" (leader)" if u == leader else "") for u in members]
    # Each group's folder is a result of its own.
    status, _, err = plot(capsys, str(runs["groups"] / "group1"), "--out", str(tmp_path / "g"),
                          *DPI)  # fmt: skip
    assert status == 0, err
    assert "run0_trajectories.png" in written(tmp_path / "g")


def test_animate_writes_one_file_per_group_of_several_targets(runs, tmp_path, capsys):
    """With several targets, FILE_group<g>.gif for each group; all checked first: an existing
    file of the second group refuses the command before the first is written."""
    argv = ["animate", str(runs["groups"]), "-o", str(tmp_path / "m.gif"), "--dpi", "20",
            "--max-frames", "3"]  # fmt: skip
    (tmp_path / "m_group1.gif").write_bytes(b"keep")
    capsys.readouterr()
    assert main(argv) == 2
    assert "m_group1.gif' already exists" in capsys.readouterr().err
    assert written(tmp_path) == {"m_group1.gif"}
    assert main([*argv, "--force"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == [f"wrote {tmp_path / f'm_group{g}.gif'} (3 frames, 0.1 s at 20 fps)"
                   for g in (0, 1)]  # fmt: skip
    for g in (0, 1):
        with Image.open(tmp_path / f"m_group{g}.gif") as gif:
            assert gif.n_frames == 3


@pytest.mark.parametrize("command", ["plot", "animate", "replay"])
def test_a_missing_or_wrong_folder_is_one_line_and_nothing_is_made(tmp_path, capsys, command):
    out = ["-o", str(tmp_path / "a.html" if command == "replay" else tmp_path / "a.gif")]
    if command == "plot":
        out = ["--out", str(tmp_path / "x")]
    missing = tmp_path / "nowhere"
    capsys.readouterr()
    assert main([command, str(missing), *out]) == 2
    assert (
        capsys.readouterr().err == f"crlbswarm: error: RUNS_DIR: {str(missing)!r} does not exist\n"
    )
    assert main([command, str(tmp_path), *out]) == 2
    err = capsys.readouterr().err
    assert err.startswith("crlbswarm: error: RUNS_DIR: ")
    assert "holds no saved result" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("dpi", ["0", "19", "601"])
def test_plot_checks_the_dpi_before_making_its_folder(runs, tmp_path, capsys, dpi):
    out = tmp_path / "x1"
    status, lines, err = plot(capsys, str(runs["single"]), "--dpi", dpi, "--out", str(out))
    assert status == 2
    assert len(err) == 1
    assert err[0].startswith("crlbswarm: error: --dpi: must be ")
    assert lines == []
    assert not out.exists()


def test_every_kind_of_folder_reloads_with_its_own_arrays(runs):
    for kind in ("single", "batch", "estimation", "no_trajectories"):
        result = load_results(runs[kind])
        with np.load(runs[kind] / "trajectories.npz") as data:
            np.testing.assert_array_equal(result.crlb, data["crlb"])
            assert ("positions" in data) == (result.positions is not None)
            assert ("estimate" in data) == (result.estimate is not None)
    assert load_results(runs["batch"]).trajectory_stride == 7
    assert load_results(runs["batch"]).seeds.tolist() == [4, 5, 6]
    with pytest.raises(FieldError, match="several targets"):
        load_results(runs["groups"])


def test_batch_view_counts_the_runs_of_metrics_csv(runs):
    """The bars and histograms hold what metrics.csv says (read with the csv module)."""
    result = load_results(runs["estimation"])
    with open(runs["estimation"] / "metrics.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    fig = plot_batch_metrics(result)
    axes = fig.axes
    assert len(axes) == 6
    bars = {t.get_text(): p.get_height()
            for t, p in zip(axes[0].get_xticklabels(), axes[0].patches, strict=True)}  # fmt: skip
    for outcome in ("collision", "converged", "timeout", "stuck"):
        assert bars[outcome] == sum(row["outcome"] == outcome for row in rows)
    columns = ["final_crlb_ratio", "convergence_time_s", "min_clearance_m", "min_separation_m",
               "final_estimation_error_m"]  # fmt: skip
    for ax, column in zip(axes[1:], columns, strict=True):
        finite = [row[column] for row in rows if row[column] != ""]
        assert sum(p.get_height() for p in ax.patches) == len(finite), column
    for ax in axes:
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            assert label == "outcome" or label.endswith(")"), label


def test_refusals_load_no_matplotlib(runs, tmp_path):
    """A wrong folder or run is refused before Matplotlib (or Pillow, or ffmpeg) loads."""
    code = (
        "import contextlib, io, json, sys\nfrom crlbswarm.cli import main\n"
        "with contextlib.redirect_stderr(io.StringIO()):\n"
        f"    main(['plot', {str(tmp_path)!r}])\n"
        f"    main(['plot', {str(runs['single'])!r}, '--run', '1'])\n"
        f"    main(['animate', {str(tmp_path)!r}, '-o', 'x.mp4'])\n"
        "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120)  # fmt: skip
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    assert loaded & {"matplotlib", "PIL", "imageio_ffmpeg"} == set()
