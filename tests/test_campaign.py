"""Campaigns on Dask: a real local cluster, a separate scheduler and worker on 127.0.0.1,
and an interrupted campaign resumed to the same dataset as an uninterrupted one.

Hardening (issue 10): every bad input (sizes, bounds, addresses, files) is one line, exit
status 2, with nothing written; the local cluster listens on 127.0.0.1 only; a TLS
scheduler with throwaway certificates; one sweep per folder; ``kill -9`` at random moments
(``CRLBSWARM_LONG_TESTS=1`` for 24 kills instead of 3)."""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from distributed import Client, LocalCluster, WorkerPlugin

from crlbswarm import FieldError, load_results, load_scenario, simulate
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
    thread each, any free dashboard port on 127.0.0.1, quiet logs)."""
    return LocalCluster(
        n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL,
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
        stop(worker, scheduler)


#: kill -9 rounds of the test below; CRLBSWARM_LONG_TESTS=1 runs the long version.
KILLS = 24 if os.environ.get("CRLBSWARM_LONG_TESTS") == "1" else 3


def wait_gone(pids: set[int], timeout: float) -> set[int]:
    """The processes of ``pids`` still running (zombies aside) after up to ``timeout`` s."""
    import psutil

    deadline = time.monotonic() + timeout
    while True:
        alive = set()
        for pid in pids:
            with contextlib.suppress(psutil.Error):
                if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                    alive.add(pid)
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.2)


def temporaries(out: Path) -> list[str]:
    """The hidden temporaries of files being written in a campaign folder (not its lock)."""
    from crlbswarm.campaign import LOCK_NAME

    found = []
    for folder in (out, *out.glob("runs/variant=*")):
        with contextlib.suppress(OSError):
            found += [e.name for e in os.scandir(folder) if e.name.startswith(".")]
    return [name for name in found if name != LOCK_NAME]


def test_kill_9_at_random_moments_leaves_absent_complete_or_resumable(tmp_path):
    """``kill -9`` of the sweep (only its own process: its local cluster's workers must go
    by themselves) at random moments, the first once some tasks have finished, every third
    one as soon as a file is being written (a hidden temporary seen), re-running
    the same command in the same folder after each kill. After every kill the folder is
    absent, or every visible row is right (a file being written stays a hidden temporary,
    which readers skip); a complete folder equals an uninterrupted run's dataset; and the
    last, resumed run completes it to the same dataset with no temporary left behind."""
    from crlbswarm.campaign import LOCK_NAME

    spec_text = SPEC.replace("batch_size = 7", "batch_size = 2").replace(
        "count = 16", "count = 12"
    )
    spec_path = tmp_path / "spec.toml"
    spec_path.write_text(spec_text)
    out = tmp_path / "out"
    cmd = sweep_command(spec_path, out, "--workers", "1")
    expected = direct(CampaignSpec.from_toml(spec_text))
    rng = np.random.default_rng(2026)
    outcomes = dict.fromkeys(["absent", "partial", "complete", "with temporaries"], 0)
    for round_ in range(KILLS):
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True)  # fmt: skip
        try:
            if round_ == 0:  # surely mid-campaign: some tasks done, others not
                deadline = time.monotonic() + 120
                while len(finished_parts(out)) < 3 and proc.poll() is None:
                    assert time.monotonic() < deadline, "no task finished within 120 s"
                    time.sleep(0.05)
            elif round_ % 3 == 1:  # while a file is being written, if caught in time
                deadline = time.monotonic() + 30
                while not temporaries(out) and proc.poll() is None:
                    assert time.monotonic() < deadline, "no file written within 30 s"
            else:
                time.sleep(rng.uniform(0.3, 8.0))
            tree = process_tree(proc.pid) - {proc.pid}
            if proc.poll() is None:  # (it may have finished first: a reaped pid is gone)
                os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
            lingering = wait_gone(tree, 60)
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)  # whatever is left, so as not to leak
        assert not lingering, f"round {round_}: processes left after kill -9: {lingering}"
        parts = len(finished_parts(out))
        state = "absent" if not out.exists() else "complete" if parts == 12 else "partial"
        outcomes[state] += 1
        # A kill while a file was being written leaves its hidden temporary (counted).
        outcomes["with temporaries"] += bool(temporaries(out))
        if parts:
            runs = load_runs(out)
            assert len(runs) == 2 * parts
            merged = runs[["variant", "seed"]].merge(expected, on=["variant", "seed"])
            assert_same(runs[expected.columns], merged[expected.columns])
        if state == "complete":
            assert_same(load_runs(out)[expected.columns], expected)
            shutil.rmtree(out)  # start afresh: the next kill lands in a new campaign
    print(f"kill -9 outcomes over {KILLS} kills: {outcomes}")
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    assert_same(load_runs(out)[expected.columns], expected)
    assert not temporaries(out)
    assert [p.name for p in out.rglob(".*")] == [LOCK_NAME]
    assert outcomes["partial"] >= 1


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
    """With ``trajectories = true`` each task also saves its result (simulate's folder),
    read back by load_results: one part, or the variant's folder with all its parts."""
    text = 'base = "paper"\nbatch_size = 2\ntrajectories = true\n[seeds]\ncount = 3\n'
    run_campaign(CampaignSpec.from_toml(text), tmp_path, scheduler=shared_scheduler)
    files = sorted(tmp_path.glob("trajectories/*/*/trajectories.npz"))
    # The Parquet dataset holds only Parquet files, so pandas reads it as is.
    assert len(load_runs(tmp_path)) == 3
    assert len(files) == 2
    with np.load(files[-1]) as data:
        positions = data["positions"]
    single = simulate(load_scenario("paper"), seed=2)
    np.testing.assert_array_equal(positions[0], single.positions[0])
    part = load_results(files[-1].parent)
    assert part.seeds.tolist() == [2]
    np.testing.assert_array_equal(part.crlb, single.crlb)
    variant = load_results(files[-1].parent.parent)
    assert variant.seeds.tolist() == [0, 1, 2]
    np.testing.assert_array_equal(variant.positions[2], single.positions[0])
    metrics = load_runs(tmp_path)
    np.testing.assert_array_equal(variant.metrics["final_crlb_ratio"],
                                  metrics["final_crlb_ratio"].to_numpy())  # fmt: skip
    with pytest.raises(FieldError, match="holds a campaign: load a variant"):
        load_results(tmp_path)
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


# -- hardening (issue 10): every bad input a one-line error, nothing exposed or overwritten --


def sweep_cli(capsys, *argv: str) -> tuple[int, str]:
    """``crlbswarm sweep ...`` in this process: its exit status and its stderr."""
    from crlbswarm.cli import main

    status = main(["sweep", *argv])
    return status, capsys.readouterr().err


def assert_refused(status: int, err: str, *words: str) -> None:
    """Exit status 2 and one line ``crlbswarm: error: ...`` naming ``words``, no traceback."""
    assert status == 2, err
    assert err.startswith("crlbswarm: error: ")
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    for word in words:
        assert word in err, err


GRID_1E8 = "\n".join(
    f'"{name}" = [{", ".join(str(float(i)) for i in range(100))}]'
    for name in ("altitude", "control.cruise_speed", "disturbance.sigma", "time.duration")
)
UNIFORM = 'base = "paper"\n[seeds]\ncount = 1\n[random]\nsamples = 3\nfields = {{ "altitude" = {{ uniform = {} }} }}\n'  # noqa: E501


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('base = "paper"\n[seeds]\ncount = 1000000000000\n',
         ["seeds.count", "4,000,000,000 tasks", "limit of 100,000", "batch_size"]),
        ('base = "paper"\nbatch_size = 1000000000000\n[seeds]\ncount = 1000000000000\n',
         ["batch_size", "TiB", "lower batch_size"]),
        ('base = "paper"\n[seeds]\nstart = 9223372036854775000\ncount = 1000\n',
         ["seeds.count", "2**63 - 1"]),
        (f'base = "paper"\n[seeds]\ncount = 1\n[grid]\n{GRID_1E8}\n',
         ["grid", "100 x 100 x 100 x 100 = 100,000,000 variants", "limit of 10,000"]),
        ('base = "paper"\n[seeds]\ncount = 1\n[random]\nsamples = 100000\n'
         'fields = { "altitude" = { uniform = [10.0, 60.0] } }\n',
         ["random.samples", "100,000 variants", "limit of 10,000"]),
        (UNIFORM.format("[nan, 1.0]"), ["random.fields.altitude.uniform", "finite"]),
        (UNIFORM.format("[0.0, inf]"), ["random.fields.altitude.uniform", "finite"]),
        (UNIFORM.format("[60.0, 10.0]"), ["random.fields.altitude.uniform", "at most"]),
    ],
    ids=["seeds-1e12", "task-memory", "seed-overflow", "grid-1e8", "samples-1e5", "nan", "inf",
         "low>high"],
)  # fmt: skip
def test_sizes_and_bounds_are_refused_before_anything_is_built(tmp_path, capsys, text, words):
    """Counted, not built: the limits are checked on the product of the lengths, the sample
    size and the number of tasks before a list of them exists (or a cluster starts)."""
    path = tmp_path / "spec.toml"
    path.write_text(text)
    status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "out"))
    assert_refused(status, err, *words)
    assert not (tmp_path / "out").exists()


def test_a_base_that_is_not_a_regular_file_is_refused(tmp_path, capsys):
    """A device, a FIFO (by absolute path or beside the spec) or a folder: never read."""
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    (tmp_path / "folder.toml").mkdir()
    for base in ("/dev/zero", str(fifo), str(tmp_path / "folder.toml"), "fifo.toml"):
        path = tmp_path / "spec.toml"
        path.write_text(f'base = "{base}"\n[seeds]\ncount = 1\n')
        status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "out"))
        assert_refused(status, err, "base", "not a regular file")
        assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "text",
    [
        f'base = "{"x" * 1_000_000}"\n[seeds]\ncount = 1\n',
        f'base = "paper"\nbatch_size = "{"x" * 1_000_000}"\n[seeds]\ncount = 1\n',
        f'base = "paper"\n[seeds]\ncount = 1\n[grid]\naltitude = ["{"y" * 1_000_000}"]\n',
    ],
    ids=["base", "batch_size", "grid-value"],
)
def test_long_values_are_cut_in_messages(tmp_path, capsys, text):
    path = tmp_path / "spec.toml"
    path.write_text(text)
    status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "out"))
    assert_refused(status, err)
    assert len(err) < 2000
    assert not (tmp_path / "out").exists()


def closed_port() -> int:
    """A port of 127.0.0.1 on which nothing listens (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(
    ("address", "words"),
    [
        ("", ["empty address"]),
        ("inproc://127.0.0.1/1/2", ["inproc://", "inside the process"]),
        ("http://127.0.0.1:8786", ["unsupported scheme"]),
        ("tcp://127.0.0.1", ["host:port"]),
        ("tcp://127.0.0.1:99999", ["host:port"]),
        ("tcp://127.0.0.1:8786/path", ["host:port"]),
        ("tcp://" + "h" * 100_000 + ":1", ["longer than 253"]),
        ("tcp://" + "h" * 100 + ".invalid:1", ["cannot connect"]),
        ("CLOSED", ["cannot connect", "refused"]),
    ],
    ids=["empty", "inproc", "http", "no-port", "bad-port", "path", "long", "label", "closed"],
)
def test_bad_or_unreachable_scheduler_is_refused_and_nothing_written(
    tmp_path, capsys, address, words
):
    address = address.replace("CLOSED", f"tcp://127.0.0.1:{closed_port()}")
    path = tmp_path / "spec.toml"
    path.write_text('base = "paper"\n[seeds]\ncount = 1\n')
    out = tmp_path / "out"
    status, err = sweep_cli(capsys, str(path), "--out", str(out), "--scheduler", address,
                            "--connect-timeout", "5")  # fmt: skip
    assert_refused(status, err, "--scheduler", *words)
    assert len(err) < 1000
    assert not out.exists()


def test_tls_files_without_a_tls_scheduler_are_refused(tmp_path, capsys):
    path = tmp_path / "spec.toml"
    path.write_text('base = "paper"\n[seeds]\ncount = 1\n')
    status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "o"),
                            "--tls-ca-file", str(path))  # fmt: skip
    assert_refused(status, err, "--tls-ca-file", "tls://")
    status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "o"), "--scheduler",
                            "tls://127.0.0.1:1", "--tls-ca-file", "/dev/zero")  # fmt: skip
    assert_refused(status, err, "--tls-ca-file", "not a readable regular file")
    assert not (tmp_path / "o").exists()


def test_a_task_failing_on_its_input_is_exit_2_naming_variant_and_seeds(
    tmp_path, capsys, shared_scheduler
):
    path = tmp_path / "spec.toml"
    path.write_text(
        'base = "paper"\n[seeds]\nstart = 5\ncount = 1\n[grid]\n"disturbance.sigma" = [1e9]\n'
    )
    status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "out"),
                            "--scheduler", shared_scheduler)  # fmt: skip
    assert_refused(status, err, "variant 0 (disturbance.sigma=1000000000.0), seeds 5..5: ")
    assert len(err) < 700


class KillWorkerAlways(WorkerPlugin):
    """Every campaign task kills its worker (``os._exit``): an infrastructure failure."""

    name = "crlbswarm-test-kill-worker-always"

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and str(key).startswith("crlbswarm-"):
            os._exit(1)


def test_a_lost_worker_is_exit_1_in_one_line(tmp_path, capsys):
    """A task whose worker dies more often than allowed (here: at all) is the cluster's
    failure, not the user's: exit status 1, one line, no traceback."""
    import dask

    path = tmp_path / "spec.toml"
    path.write_text('base = "paper"\n[seeds]\ncount = 1\n')
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = local_cluster(1)
    with cluster, Client(cluster) as client:
        client.register_plugin(KillWorkerAlways())
        status, err = sweep_cli(capsys, str(path), "--out", str(tmp_path / "out"),
                                "--scheduler", cluster.scheduler_address)  # fmt: skip
    assert status == 1, err
    assert err.startswith("crlbswarm: error: variant 0, seeds 0..0: KilledWorker")
    assert err.count("\n") == 1
    assert "Traceback" not in err


def listening_sockets(pids: set[int]) -> list[str]:
    """The local addresses of the listening TCP sockets of ``pids`` (``ss -ltnp``, or
    psutil when ``ss`` is missing)."""
    import psutil

    if shutil.which("ss"):
        lines = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True,
                               check=True).stdout.splitlines()  # fmt: skip
        return [line.split()[3] for line in lines if any(f"pid={pid}," in line for pid in pids)]
    found = []
    for pid in pids:
        with contextlib.suppress(psutil.Error):
            for c in psutil.Process(pid).net_connections(kind="tcp"):
                if c.status == psutil.CONN_LISTEN:
                    found.append(f"{c.laddr.ip}:{c.laddr.port}")
    return found


def process_tree(pid: int) -> set[int]:
    import psutil

    with contextlib.suppress(psutil.Error):
        return {pid, *(c.pid for c in psutil.Process(pid).children(recursive=True))}
    return set()


def sweep_command(spec_path: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "crlbswarm.cli", "sweep", str(spec_path), "--out", str(out),
            *extra]  # fmt: skip


def test_a_running_local_sweep_listens_on_loopback_only_and_locks_its_folder(tmp_path):
    """While a local sweep runs: every listening socket of its process tree (scheduler,
    nannies, workers, dashboard) is on 127.0.0.1, and a second sweep on the same folder is
    refused at once naming the first one's pid; the first one then completes. (The first
    one is paused meanwhile, so that it cannot finish before the second one starts.)"""
    spec_path = tmp_path / "spec.toml"
    # Many small tasks, and a quick poll: the first sweep is paused long before its last
    # task (a fast machine once finished 12 tasks between two polls of 0.1 s).
    spec_path.write_text('base = "paper"\nbatch_size = 1\n[seeds]\ncount = 60\n')
    out = tmp_path / "out"
    first = subprocess.Popen(sweep_command(spec_path, out, "--workers", "1"),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not finished_parts(out):
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < deadline, "no task finished within 120 s"
            time.sleep(0.005)
        os.kill(first.pid, signal.SIGSTOP)  # paused (lock held) while the second one tries
        try:
            tree = process_tree(first.pid)
            sockets = listening_sockets(tree)
            second = subprocess.run(sweep_command(spec_path, out, "--workers", "1"),
                                    capture_output=True, text=True, timeout=120)  # fmt: skip
        finally:
            os.kill(first.pid, signal.SIGCONT)
        _, err = first.communicate(timeout=300)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(first.pid, signal.SIGKILL)
    assert len(tree) >= 2  # the sweep and its worker process
    assert len(sockets) >= 2, sockets  # the scheduler, the dashboard, the worker, ...
    assert all(s.startswith("127.0.0.1:") for s in sockets), sockets
    assert second.returncode == 2, second.stderr
    assert second.stderr == (
        f"crlbswarm: error: --out: {str(out)!r} is in use by another crlbswarm sweep "
        f"(pid {first.pid})\n"
    )
    assert first.returncode == 0, err
    assert len(load_runs(out)) == 60


def make_certificates(folder: Path, name: str) -> dict[str, Path]:
    """Throwaway PEM files (openssl): a certificate authority ``name``, and a certificate
    and key signed by it for 127.0.0.1 (scheduler, worker and client alike)."""
    folder.mkdir()
    ca, ca_key, cert, key = (folder / n for n in ("ca.pem", "ca.key", "cert.pem", "cert.key"))
    ext = folder / "ext.cnf"
    ext.write_text(
        "basicConstraints=CA:FALSE\nsubjectAltName=IP:127.0.0.1,DNS:localhost\n"
        "keyUsage=digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth,clientAuth\n"
        "subjectKeyIdentifier=hash\nauthorityKeyIdentifier=keyid\n"
    )
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    for cmd in (
        ["req", "-x509", *ec, "-keyout", ca_key, "-out", ca, "-days", "2", "-subj",
         f"/CN={name}", "-addext", "basicConstraints=critical,CA:TRUE",
         "-addext", "keyUsage=critical,keyCertSign,cRLSign"],
        ["req", *ec, "-keyout", key, "-out", folder / "cert.csr", "-subj", "/CN=127.0.0.1"],
        ["x509", "-req", "-in", folder / "cert.csr", "-CA", ca, "-CAkey", ca_key,
         "-CAcreateserial", "-out", cert, "-days", "2", "-extfile", ext],
    ):  # fmt: skip
        subprocess.run(["openssl", *map(str, cmd)], check=True, capture_output=True, timeout=60)
    return {"ca": ca, "cert": cert, "key": key}


def stop(*procs: subprocess.Popen | None) -> None:
    for proc in procs:
        if proc is not None:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl command")
def test_tls_scheduler_with_certificates(tmp_path, capsys):
    """A TLS-only scheduler and worker on 127.0.0.1 with throwaway certificates: the sweep
    runs through them with --tls-* files; plain tcp:// or another authority's certificate
    is refused in one line and writes nothing."""
    certs = make_certificates(tmp_path / "tls", "crlbswarm-test-ca")
    other = make_certificates(tmp_path / "other", "another-ca")
    tls = ["--tls-ca-file", str(certs["ca"]), "--tls-cert", str(certs["cert"]),
           "--tls-key", str(certs["key"])]  # fmt: skip
    info = tmp_path / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
    scheduler = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--protocol", "tls", "--host",
         "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(info), *tls],
        **quiet,
    )  # fmt: skip
    worker = None
    try:
        _wait_for(info, 60)
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(info),
             "--nthreads", "1", "--nworkers", "1", "--no-dashboard", "--host", "127.0.0.1",
             "--protocol", "tls", *tls],
            **quiet,
        )  # fmt: skip
        import json

        address = json.loads(info.read_text())["address"]
        assert address.startswith("tls://127.0.0.1:")
        spec_path = tmp_path / "spec.toml"
        spec_path.write_text(SPEC)
        out = tmp_path / "out"
        status, err = sweep_cli(capsys, str(spec_path), "--out", str(out), "--scheduler",
                                address, *tls)  # fmt: skip
        assert status == 0, err
        expected = direct(CampaignSpec.from_toml(SPEC))
        assert_same(load_runs(out)[expected.columns], expected)
        wrong_ca = ["--tls-ca-file", str(other["ca"]), "--tls-cert", str(other["cert"]),
                    "--tls-key", str(other["key"])]  # fmt: skip
        for argv in (["--scheduler", address.replace("tls://", "tcp://")],
                     ["--scheduler", address, *wrong_ca]):  # fmt: skip
            status, err = sweep_cli(capsys, str(spec_path), "--out", str(tmp_path / "no"),
                                    "--connect-timeout", "3", *argv)  # fmt: skip
            assert_refused(status, err, "--scheduler: cannot connect")
            assert not (tmp_path / "no").exists()
    finally:
        stop(worker, scheduler)
