"""Issue 10, one test per class of failure of the scenario, file and command-line layers:
sizes refused before allocating, values outside the model's range, odd files, one error
line, no output on error, results never overwritten unasked. (The public functions are in
test_api_hardening.py, the campaigns in test_campaign.py, kill -9 in
test_interrupted_writes.py, the fuzzing in test_fuzz.py.)"""

from __future__ import annotations

import copy
import itertools
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from crlbswarm import FieldError, Scenario, ScenarioError, load_scenario, simulate
from crlbswarm._config import MAX_DEPTH, MAX_FILE_BYTES, read_toml, read_toml_file
from crlbswarm.cli import main
from crlbswarm.errors import MAX_REASON
from crlbswarm.output import write_csv
from crlbswarm.planning import MAX_ROADMAP_OBSTACLES
from crlbswarm.scenario import BUILTIN_SCENARIOS


def changed(name: str, **changes: object) -> dict:
    """A built-in scenario's data with dotted fields changed."""
    data = copy.deepcopy(BUILTIN_SCENARIOS[name])
    for dotted, value in changes.items():
        node = data
        *parents, leaf = dotted.split("__")
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = value
    return data


def refused(data: dict, field: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data, source="s.toml")
    assert info.value.field == field, str(info.value)
    assert "\n" not in str(info.value)
    return info.value


# -- values outside the model's range --------------------------------------------------------
@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"altitude": 1e308}, "altitude"),
        ({"altitude": 1e-300}, "altitude"),
        ({"target": [1e300, 0.0]}, "target.0"),
        ({"uavs__count": 10**7}, "uavs.count"),
        ({"time__duration": 1e308}, "time.duration"),
        ({"time__step": 1e300}, "time.step"),
        ({"radar__kappa": 5e-324}, "radar"),
        ({"radar__noise_power": 1e-300}, "radar"),
        ({"eta__samples": 10**9}, "eta.samples"),
    ],
)
def test_values_outside_the_range_are_refused_naming_the_field(changes, field):
    refused(changed("paper", **changes), field)


def test_target_motion_outside_the_range():
    base = {"target_motion__model": "turning", "target_motion__velocity": [3.0, 0.0]}
    refused(changed("moving_target", **base, target_motion__turn_rate=5e-324),
            "target_motion.turn_rate")  # fmt: skip
    refused(changed("moving_target", **base, target_motion__turn_rate=1e6),
            "target_motion.turn_rate")  # fmt: skip
    far = changed("moving_target", target_motion__velocity=[999.0, 0.0], time__duration=1.5e5)
    assert "leave the model's range" in str(refused(far, "target_motion.velocity"))


def test_a_planner_over_too_many_obstacles_is_refused_and_fine_without_it():
    rng = np.random.default_rng(0)
    circles = [{"type": "circle", "center": [float(x), float(y)], "radius": 1.0}
               for x, y in rng.uniform(200, 2000, (MAX_ROADMAP_OBSTACLES + 1, 2))]  # fmt: skip
    data = changed("paper_safe")
    data["obstacles"] = circles
    start = time.perf_counter()
    error = refused(data, "guidance.planner")
    assert time.perf_counter() - start < 5  # refused before the roadmap is built
    assert "guidance.planner = false" in str(error)
    data["guidance"]["planner"] = False
    assert Scenario.from_dict(data).obstacle_set.count == MAX_ROADMAP_OBSTACLES + 1


# -- sizes refused before allocating ---------------------------------------------------------
def test_batches_that_cannot_fit_are_refused_before_allocating():
    sc = load_scenario("paper")
    with pytest.raises(FieldError, match=r"would need about .* can still allocate") as info:
        simulate(sc, seeds=range(10**9))
    assert info.value.field == "seeds"
    with pytest.raises(FieldError, match="from an iterator"):
        simulate(sc, seeds=itertools.count())
    data = changed("paper", uavs__count=100_000, graph__kind="complete")
    assert "edges" in str(refused(data, "graph"))


def test_the_memory_check_follows_the_process_limit(tmp_path):
    """Under ``ulimit -v`` a batch that fits the machine but not the process is refused
    (before, the check compared with the physical memory and MemoryError followed)."""
    code = (
        "import resource, crlbswarm as c\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))\n"
        "try:\n"
        "    c.simulate(c.load_scenario('paper'), seeds=range(20_000))\n"
        "except ValueError as e:\n"
        "    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120).stdout  # fmt: skip
    assert out.startswith("seeds: 20000 runs of 1500 steps with 6 UAVs would need about")


# -- files -----------------------------------------------------------------------------------
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX FIFOs")
def test_files_that_are_not_regular_too_large_or_too_deep(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path in (fifo, Path("/dev/zero"), tmp_path):
        if path.exists():
            with pytest.raises(ValueError, match=r"not a regular file|cannot read"):
                read_toml_file(path)
    big = tmp_path / "big.toml"
    big.write_text("a = 1\n" + "#" * MAX_FILE_BYTES)
    with pytest.raises(ValueError, match="larger than"):
        read_toml_file(big)
    with pytest.raises(ValueError, match="nested too deeply"):
        read_toml("a = " + "[" * 100_000, "deep")
    with pytest.raises(ValueError, match=f"nested more than {MAX_DEPTH}"):
        read_toml("a = " + "[" * (MAX_DEPTH + 2) + "]" * (MAX_DEPTH + 2), "deep")


def test_errors_are_one_line_and_cut():
    error = FieldError("altitude", "got " + "9" * 1_000_000 + "\nsecond line")
    assert "\n" not in str(error)
    assert len(error.reason) <= MAX_REASON
    assert error.reason.endswith("characters)")


def test_csv_cells_of_nan_and_inf_are_empty(tmp_path):
    write_csv(tmp_path / "m.csv", {"a": np.array([1.5, np.nan, np.inf]), "b": [1, 2, 3]})
    assert (tmp_path / "m.csv").read_text() == "a,b\n1.5,1\n,2\n,3\n"


# -- the command line --------------------------------------------------------------------------
def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def test_no_command_prints_the_usage_in_one_line(capsys):
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "usage: crlbswarm" in err


def test_an_error_after_warnings_is_the_only_line(tmp_path, capsys):
    """A run that fails prints its error alone: the preflight warnings come after a
    success, and numerical warnings are held back."""
    data = changed("paper", disturbance__sigma=1e9, time__duration=20.0)  # diverges at once
    path = tmp_path / "s.toml"
    path.write_text(Scenario.from_dict(data).to_toml())
    status, _, err = run_cli(["simulate", str(path), "--out", str(tmp_path / "o")], capsys)
    assert status == 2
    assert err.count("\n") == 1
    assert err.startswith("crlbswarm: error: run 0 (seed 0) diverged")
    assert not (tmp_path / "o").exists()


def test_figures_refuses_a_folder_with_files_at_once(tmp_path, capsys):
    (tmp_path / "mine.txt").write_text("keep")
    start = time.perf_counter()
    status, _, err = run_cli(["figures", "--out", str(tmp_path)], capsys)
    assert status == 2
    assert time.perf_counter() - start < 5  # before half a minute of work
    assert "--force" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt"]


def test_results_into_the_working_folder(tmp_path, capsys, monkeypatch):
    """``--out .`` in an empty working folder: the files land in it (it is not renamed
    over, which would leave the shell in a deleted folder); a second run is refused."""
    from crlbswarm import load_results

    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    status, _, err = run_cli(["simulate", "paper", "--out", "."], capsys)
    assert status == 0, err
    assert load_results(work).seeds.tolist() == [0]
    assert os.path.samefile(os.getcwd(), work)
    assert not list(tmp_path.glob(".crlbswarm-partial-*"))
    assert not list(work.glob(".crlbswarm-partial-*"))
    status, _, err = run_cli(["simulate", "paper", "--out", "."], capsys)
    assert status == 2
    assert "already holds files" in err


def test_existing_folders_are_filled_not_replaced(tmp_path, capsys):
    """A link to an empty folder, and a shared folder's group and mode, are kept (the set
    is staged inside an existing folder and its files moved up)."""
    real = tmp_path / "real"
    real.mkdir()
    real.chmod(0o2775)
    (tmp_path / "link").symlink_to(real)
    status, _, err = run_cli(["simulate", "paper", "--out", str(tmp_path / "link")], capsys)
    assert status == 0, err
    assert (tmp_path / "link").is_symlink()
    assert (real / "summary.json").is_file()
    assert real.stat().st_mode & 0o7777 == 0o2775
    assert not list(real.glob(".crlbswarm-partial-*"))


def test_long_arrays_in_toml_do_not_collide_with_user_text():
    data = changed("paper", description="@crlbswarm-array-0@ and more")
    count = 70
    data["uavs"] = {"count": count, "start": [[-200.0 - 3 * (i % 10), 3.0 * (i // 10)]
                                             for i in range(count)]}  # fmt: skip
    sc = Scenario.from_dict(data)
    back = Scenario.from_toml(sc.to_toml())
    assert back == sc


def test_campaign_folder_checks_before_any_cluster(tmp_path, capsys):
    spec = tmp_path / "specs" / "spec.toml"
    spec.parent.mkdir()
    spec.write_text('base = "paper"\n[seeds]\ncount = 1\n')
    (spec.parent / "paper").mkdir()  # a folder named like a built-in beside the spec
    from crlbswarm.campaign import CampaignSpec

    assert CampaignSpec.from_file(spec)[0].base == "paper"
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    status, _, err = run_cli(["sweep", str(spec), "--out", str(mine)], capsys)
    assert status == 2
    assert "no campaign" in err
    fifo = tmp_path / "fifo"
    fifo.mkdir()
    if hasattr(os, "mkfifo"):
        os.mkfifo(fifo / "spec.json")
        start = time.perf_counter()
        status, _, err = run_cli(["sweep", str(spec), "--out", str(fifo)], capsys)
        assert status == 2
        assert time.perf_counter() - start < 20  # refused, not blocked on the FIFO
        assert "different campaign" in err
    assert (mine / "notes.txt").read_text() == "keep"
