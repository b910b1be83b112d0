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
from crlbswarm.plots import plot_batch_metrics
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


def test_plot_names_what_to_load_for_other_folders(runs, tmp_path, capsys):
    status, _, err = plot(capsys, str(runs["groups"]), "--out", str(tmp_path / "x"))
    assert status == 2
    assert len(err) == 1
    assert "several targets: load each group's folder" in err[0]
    assert "group0" in err[0]
    status, _, err = plot(capsys, str(tmp_path), "--out", str(tmp_path / "x"))
    assert status == 2
    assert err[0].startswith("crlbswarm: error: RUNS_DIR: ")
    assert not (tmp_path / "x").exists()
    # Each group's folder is a result of its own.
    status, _, err = plot(capsys, str(runs["groups"] / "group1"), "--out", str(tmp_path / "g"),
                          *DPI)  # fmt: skip
    assert status == 0, err
    assert "run0_trajectories.png" in written(tmp_path / "g")


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
