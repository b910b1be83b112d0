"""Results written to a folder and read back (MissionResult.save / crlbswarm.load_results),
and the paper pipeline called from Python (crlbswarm.reproduce)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from crlbswarm import FieldError, MissionResult, load_results, load_scenario, reproduce, simulate
from crlbswarm.cli import main
from crlbswarm.results import RESULT_FILES


def assert_same_result(a: MissionResult, b: MissionResult) -> None:
    assert a.scenario == b.scenario
    for field in dataclasses.fields(MissionResult):
        if field.name in ("scenario", "metrics"):
            continue
        x, y = getattr(a, field.name), getattr(b, field.name)
        if x is None:
            assert y is None, field.name
        else:
            np.testing.assert_array_equal(x, y, err_msg=field.name, strict=True)
    assert a.metrics.keys() == b.metrics.keys()
    for name in a.metrics:
        np.testing.assert_array_equal(a.metrics[name], b.metrics[name], err_msg=name)
    assert a.summary() == b.summary()


@pytest.mark.parametrize(("scenario", "keep"), [("paper", True), ("moving_target", False)])
def test_save_then_load_gives_the_same_result(tmp_path, scenario, keep):
    result = simulate(load_scenario(scenario), seeds=[4, 9], keep_trajectories=keep)
    written = result.save(tmp_path / "run")
    assert [p.name for p in written] == list(RESULT_FILES)
    assert_same_result(load_results(tmp_path / "run"), result)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["seeds"] == {"first": 4, "last": 9}


def test_the_cli_folder_reads_back_to_the_library_result(tmp_path):
    assert main(["simulate", "sensing", "--seed", "2", "--runs", "2", "--out", str(tmp_path)]) == 0
    assert_same_result(load_results(tmp_path), simulate(load_scenario("sensing"), seeds=[2, 3]))


def test_loading_an_incomplete_folder_names_the_missing_file(tmp_path):
    with pytest.raises(FieldError, match=r"trajectories\.npz missing") as info:
        load_results(tmp_path)
    assert info.value.field == "folder"


def test_reproduce_from_python(tmp_path):
    """The pipeline of `crlbswarm figures`, callable without the CLI; a bad argument is
    refused (naming it) before anything is computed or written."""
    with pytest.raises(FieldError) as info:
        reproduce(tmp_path / "bad", fmt="bmp")
    assert info.value.field == "fmt"
    with pytest.raises(FieldError) as info:
        reproduce(tmp_path / "bad", seed=-1)
    assert info.value.field == "seed"
    assert not (tmp_path / "bad").exists()
    seen = []
    files = reproduce(tmp_path / "figs", trials=20, runs=2, fmt="svg", on_write=seen.append)
    assert files == seen
    assert files[-1].name == "manifest.json"
    manifest = json.loads(files[-1].read_text())
    assert sorted(manifest["files"]) == sorted(p.name for p in files[:-1])
    assert all(p.stat().st_size > 0 for p in files)


def test_a_damaged_folder_is_refused_naming_the_problem(tmp_path):
    """A missing array, arrays that do not fit the scenario file, or a corrupt archive: one
    line naming the folder's file and what is wrong."""
    simulate(load_scenario("paper"), seed=1).save(tmp_path)
    npz = tmp_path / "trajectories.npz"
    with np.load(npz) as data:
        arrays = dict(data)
    np.savez(npz, **{k: v for k, v in arrays.items() if k != "eta"})
    with pytest.raises(FieldError, match="array 'eta' is missing") as info:
        load_results(tmp_path)
    assert info.value.field == "folder"
    toml = (tmp_path / "scenario.toml").read_text().replace("count = 6", "count = 5", 1)
    np.savez(npz, **arrays)
    (tmp_path / "scenario.toml").write_text(toml)
    with pytest.raises(FieldError, match=r"array 'positions' is shape \(1, 1501, 6, 2\)"):
        load_results(tmp_path)
    npz.write_bytes(b"not an archive")
    with pytest.raises(FieldError, match="cannot read"):
        load_results(tmp_path)
