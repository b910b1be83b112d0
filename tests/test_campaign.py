"""Campaigns on Dask: a real local cluster, a separate scheduler and worker on 127.0.0.1,
and an interrupted campaign resumed to the same dataset as an uninterrupted one."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from distributed import Client, LocalCluster, WorkerPlugin

from crlbswarm import FieldError, load_scenario, simulate
from crlbswarm.campaign import CampaignSpec, plan_tasks, run_campaign
from crlbswarm.scenario import Scenario

SPEC = """
base = "paper"
batch_size = 7
[seeds]
start = 3
count = 16
[grid]
"control.cruise_speed" = [2.0, 3.0]
"""


def local_cluster(n_workers: int) -> LocalCluster:
    """A local cluster on 127.0.0.1 configured as run_campaign's own (worker processes, one
    thread each, any free dashboard port, quiet logs)."""
    return LocalCluster(
        n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=":0", silence_logs=logging.CRITICAL,
    )  # fmt: skip


@pytest.fixture(scope="session")
def shared_scheduler():
    """Address of one local cluster (2 workers) shared by the campaign tests that do not need
    a cluster of their own: starting a cluster per test is most of their cost."""
    with local_cluster(2) as cluster:
        yield cluster.scheduler_address


def load_runs(folder: Path) -> pd.DataFrame:
    df = pd.read_parquet(folder / "runs")
    df["variant"] = df["variant"].astype(int)
    return df.sort_values(["variant", "seed"]).reset_index(drop=True)


def direct(spec: CampaignSpec) -> pd.DataFrame:
    """The same runs without Dask: one batched simulate per variant."""
    scenarios, _ = plan_tasks(spec)
    frames = []
    seeds = range(spec.seeds.start, spec.seeds.start + spec.seeds.count)
    for v, data in enumerate(scenarios):
        metrics = simulate(Scenario.from_dict(data), seeds=seeds).metrics
        frames.append(pd.DataFrame({"variant": v, **metrics}))
    return pd.concat(frames).sort_values(["variant", "seed"]).reset_index(drop=True)


def assert_same(runs: pd.DataFrame, expected: pd.DataFrame) -> None:
    assert len(runs) == len(expected)
    assert not runs.duplicated(["variant", "seed"]).any()
    for name in expected.columns:
        np.testing.assert_array_equal(runs[name].to_numpy(), expected[name].to_numpy(), name)


def test_plan_splits_seeds_into_batches_per_variant():
    spec = CampaignSpec.from_toml(SPEC)
    scenarios, tasks = plan_tasks(spec)
    assert len(scenarios) == 2
    assert tasks == [(0, 3, 9), (0, 10, 16), (0, 17, 18), (1, 3, 9), (1, 10, 16), (1, 17, 18)]
    assert scenarios[1]["control"]["cruise_speed"] == 3.0


def test_local_cluster_with_two_workers_matches_a_direct_batch(tmp_path):
    spec = CampaignSpec.from_toml(SPEC)
    counts = run_campaign(spec, tmp_path, n_workers=2, spec_text=SPEC)
    assert counts == {"variants": 2, "tasks": 6, "skipped": 0, "ran": 6}
    runs = load_runs(tmp_path)
    assert_same(runs[direct(spec).columns], direct(spec))
    assert set(runs["control.cruise_speed"]) == {2.0, 3.0}
    assert (tmp_path / "spec.toml").read_text() == SPEC
    # A second run finds everything done.
    assert run_campaign(spec, tmp_path, n_workers=2)["skipped"] == 6


def finished_parts(out: Path) -> list[Path]:
    """Finished task files (pathlib's ``*`` also matches hidden temporaries: skip them)."""
    return [p for p in out.glob("runs/*/*.parquet") if not p.name.startswith(".")]


def _wait_for(path: Path, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{path} did not appear within {timeout} s")
        time.sleep(0.2)


def test_separate_scheduler_and_worker_processes_on_loopback(tmp_path):
    """`dask scheduler` and `dask worker` as separate processes on 127.0.0.1."""
    info = tmp_path / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    scheduler = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
         "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
    )  # fmt: skip
    worker = None
    try:
        _wait_for(info, 60)
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(info),
             "--nthreads", "1", "--nworkers", "1", "--no-dashboard", "--host", "127.0.0.1"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
        )  # fmt: skip
        import json

        address = json.loads(info.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        spec = CampaignSpec.from_toml(SPEC)
        run_campaign(spec, tmp_path / "out", scheduler=address)
        runs = load_runs(tmp_path / "out")
        expected = direct(spec)
        assert_same(runs[expected.columns], expected)
    finally:
        for proc in (worker, scheduler):
            if proc is not None:
                proc.terminate()
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()


def test_killed_campaign_resumes_to_the_same_dataset(tmp_path):
    """Kill the CLI (and its local cluster) once some tasks have finished; re-running the
    same command completes the dataset: same rows as an uninterrupted run, no duplicates."""
    spec_text = SPEC.replace("batch_size = 7", "batch_size = 2").replace(
        "count = 16", "count = 40"
    )
    spec_path = tmp_path / "spec.toml"
    spec_path.write_text(spec_text)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "crlbswarm.cli", "sweep", str(spec_path), "--out", str(out),
           "--workers", "1"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while len(finished_parts(out)) < 3:
            assert proc.poll() is None, "the campaign ended before it could be interrupted"
            assert time.monotonic() < deadline, "no task finished within 120 s"
            time.sleep(0.1)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finished = len(finished_parts(out))
    assert 3 <= finished < 40
    # A file being written at the kill stays a hidden temporary (.part-...), which Parquet
    # readers skip; the resumed run removes it.
    assert len(load_runs(out)) == 2 * finished
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    assert f"skipped {finished}" in done.stdout
    assert not list(out.glob("runs/*/.*"))
    expected = direct(CampaignSpec.from_toml(spec_text))
    runs = load_runs(out)
    assert_same(runs[expected.columns], expected)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('base = "paper"\n[seeds]\ncount = 0\n', "seeds.count"),
        ('base = "paper"\nbatch = 3\n[seeds]\ncount = 2\n', "batch"),
        ('base = "nowhere.toml"\n[seeds]\ncount = 2\n', "base"),
        ('base = "paper"\n[seeds]\ncount = 2\n[grid]\n"uavs.count" = [2]\n', "uavs.count"),
    ],
)
def test_bad_specs_name_the_field_and_run_nothing(tmp_path, text, field):
    def attempt():
        run_campaign(CampaignSpec.from_toml(text), tmp_path / "out")

    with pytest.raises(FieldError, match=field):
        attempt()
    assert not (tmp_path / "out").exists()


def test_sweep_cli_one_line_error_and_exit_2(tmp_path, capsys):
    from crlbswarm.cli import main

    path = tmp_path / "bad.toml"
    path.write_text('base = "paper"\n[seeds]\ncount = 2\n[grid]\n"uavs.count" = [2]\n')
    status = main(["sweep", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1
    assert "uavs.count" in err
    assert not (tmp_path / "out").exists()


def test_paper_base_is_the_builtin():
    spec = CampaignSpec.from_toml('base = "paper"\n[seeds]\ncount = 1\n')
    assert Scenario.from_dict(spec.base_dict()) == load_scenario("paper")


def test_random_sample_of_variants_is_seeded_and_in_range():
    text = (
        'base = "paper"\n[seeds]\ncount = 1\n[random]\nsamples = 5\nseed = 7\n'
        'fields = { "altitude" = { uniform = [10.0, 60.0] }, '
        '"control.cruise_speed" = { choice = [2.0, 3.0] } }\n'
    )
    a = CampaignSpec.from_toml(text).variants()
    b = CampaignSpec.from_toml(text).variants()
    assert a == b
    assert len(a) == 5
    assert all(10.0 <= v["altitude"] <= 60.0 for v in a)
    assert {v["control.cruise_speed"] for v in a} <= {2.0, 3.0}
    assert CampaignSpec.from_toml(text.replace("seed = 7", "seed = 8")).variants() != a
    scenarios, tasks = plan_tasks(CampaignSpec.from_toml(text))
    assert [s["altitude"] for s in scenarios] == [v["altitude"] for v in a]
    assert len(tasks) == 5


def test_trajectories_only_when_asked(tmp_path, shared_scheduler):
    """With ``trajectories = true`` each task also saves its positions, equal to simulate's."""
    text = 'base = "paper"\nbatch_size = 2\ntrajectories = true\n[seeds]\ncount = 3\n'
    run_campaign(CampaignSpec.from_toml(text), tmp_path, scheduler=shared_scheduler)
    files = sorted(tmp_path.glob("trajectories/*/*.npz"))
    # The Parquet dataset holds only Parquet files, so pandas reads it as is.
    assert len(load_runs(tmp_path)) == 3
    assert len(files) == 2
    with np.load(files[-1]) as data:
        positions = data["positions"]
    single = simulate(load_scenario("paper"), seed=2)
    np.testing.assert_array_equal(positions[0], single.positions[0])
    run_campaign(
        CampaignSpec.from_toml(text.replace("true", "false")),
        tmp_path / "b",
        scheduler=shared_scheduler,
    )
    assert not (tmp_path / "b" / "trajectories").exists()


def test_a_folder_of_another_campaign_is_refused(tmp_path, shared_scheduler):
    """Resuming into a folder that holds a different campaign would mix two datasets."""
    first = CampaignSpec.from_toml('base = "paper"\n[seeds]\ncount = 1\n')
    run_campaign(first, tmp_path, scheduler=shared_scheduler)
    other = CampaignSpec.from_toml('base = "paper"\n[seeds]\ncount = 2\n')
    with pytest.raises(FieldError, match=r"^out: .*different campaign"):
        run_campaign(other, tmp_path, scheduler=shared_scheduler)
    assert len(load_runs(tmp_path)) == 1


def test_grid_values_of_mixed_types_are_refused_before_running(tmp_path):
    text = 'base = "paper"\n[seeds]\ncount = 1\n[grid]\n"name" = ["a", 1]\n'
    with pytest.raises(FieldError):
        run_campaign(CampaignSpec.from_toml(text), tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_int_and_float_grid_values_share_one_column_type(tmp_path, shared_scheduler):
    text = 'base = "paper"\n[seeds]\ncount = 1\n[grid]\n"control.cruise_speed" = [2, 2.5]\n'
    run_campaign(CampaignSpec.from_toml(text), tmp_path, scheduler=shared_scheduler)
    runs = load_runs(tmp_path)
    assert runs["control.cruise_speed"].tolist() == [2.0, 2.5]


def test_a_failing_task_names_its_variant_and_keeps_finished_ones(tmp_path, shared_scheduler):
    """A variant whose runs diverge stops the campaign with one message naming it."""
    from crlbswarm.campaign import CampaignError

    text = 'base = "paper"\n[seeds]\ncount = 1\n[grid]\n"disturbance.sigma" = [0.01, 1e9]\n'
    with pytest.raises(CampaignError, match=r"^variant 1 \(disturbance.sigma=1000000000.0\)"):
        run_campaign(CampaignSpec.from_toml(text), tmp_path, scheduler=shared_scheduler)


class KillWorkerOnce(WorkerPlugin):
    """Fault injection from the test side: the first campaign task to start executing on
    any worker kills that worker's process (``os._exit``, as on a crash) after creating
    ``marker`` with the process id in it; later tasks find the marker and run normally.

    Defined at module level, so the workers (spawned with this process's ``sys.path``)
    unpickle it by importing this module.
    """

    name = "crlbswarm-test-kill-worker-once"

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def transition(self, key, start, finish, **kwargs):
        if finish != "executing" or not str(key).startswith("crlbswarm-"):
            return
        try:
            fd = os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        os._exit(1)  # the worker dies mid-task, as on a crash


def worker_pids(client: Client) -> set[int]:
    return set(client.run(os.getpid).values())


def test_a_worker_that_dies_has_its_task_rescheduled(tmp_path):
    """The first task kills its own worker process (a worker plugin injects the fault); the
    nanny restarts it, the scheduler reschedules the task, and the dataset is complete and
    correct. Its own cluster: the shared one must not lose a worker."""
    marker = tmp_path / "killed-once"
    spec = CampaignSpec.from_toml(SPEC)
    with local_cluster(2) as cluster, Client(cluster) as client:
        client.wait_for_workers(2, timeout=120)
        before = worker_pids(client)
        client.register_plugin(KillWorkerOnce(str(marker)))
        run_campaign(spec, tmp_path / "out", scheduler=cluster.scheduler_address)
        assert marker.exists()  # a worker did die
        killed = int(marker.read_text())
        client.wait_for_workers(2, timeout=120)  # the nanny restarts it
        after = worker_pids(client)
    assert killed in before
    assert killed not in after
    assert len(after) == 2
    expected = direct(spec)
    assert_same(load_runs(tmp_path / "out")[expected.columns], expected)
