"""``crlbswarm fly``: one process per UAV over Zenoh, on 127.0.0.1 only.

The stepped flight with perfect links is checked against ``simulate`` with the same seed
(the acceptance: 1e-9 m; it is the same bits); Ctrl-C and a UAV killed outright are checked
on the process table (every member's command line carries the flight's key, a marker no
other process has); the injected loss and delay, the messages and the command's errors are
checked without a network.
"""

from __future__ import annotations

import copy
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from crlbswarm import Scenario, crlb_bound, load_results, load_scenario, simulate
from crlbswarm.cli import main
from crlbswarm.flynet import (
    LOG,
    NO_STAMP,
    STATE,
    FlightOptions,
    Injection,
    Packet,
    decode,
    encode,
)

zenoh = pytest.importorskip("zenoh")  # (the `test` extra installs it)


def short(name: str, duration: float, **uavs: int) -> Scenario:
    """A built-in scenario with a shorter mission (and optionally another UAV count)."""
    data = copy.deepcopy(load_scenario(name).model_dump())
    data["time"].update(duration=duration, hold=min(10.0, duration / 2),
                        stall=min(20.0, duration / 2))  # fmt: skip
    data["uavs"].update(uavs)
    return Scenario.from_dict(data)


def members(key: str) -> list[int]:
    """The processes whose command line holds ``key`` (the members of that flight)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            words = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:  # (gone meanwhile)
            continue
        if key.encode() in words:
            pids.append(int(entry.name))
    return pids


@pytest.fixture
def flight(tmp_path):
    """A flight's key, scenario file and output folder; afterwards, no member is left (and
    any that is, after a failure, is killed)."""
    key = f"crlbswarm/fly/test{uuid.uuid4().hex[:10]}"
    yield key, tmp_path
    left = members(key)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert left == []


def launch(key: str, scenario: Path, out: Path, *extra: str) -> subprocess.Popen[str]:
    """``crlbswarm fly`` in a process of its own; returns once the flight is under way."""
    cmd = [sys.executable, "-m", "crlbswarm.cli", "fly", str(scenario), "--out", str(out),
           "--key", key, *extra]  # fmt: skip
    # (SIGINT's default action in the launcher: a pytest-xdist worker ignores SIGINT, and a
    # child inherits that)
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith("flying:"):
            return proc
    proc.wait()
    raise AssertionError(f"the flight did not start: {proc.stderr.read() if proc.stderr else ''}")


def finish(proc: subprocess.Popen[str], limit: float) -> tuple[int, str, str]:
    """The launcher's status and output, waiting at most ``limit`` seconds."""
    out, err = proc.communicate(timeout=limit)
    return proc.returncode, out, err


def test_stepped_flight_with_perfect_links_is_the_simulation(flight):
    """The paper scenario (6 UAVs, 15 s of mission), 6 UAV processes and a recorder: the
    same trajectories as simulate with the same seed (to 1e-9 m; in fact the same bits),
    and a folder that load_results reads."""
    from crlbswarm.fly import fly

    key, tmp = flight
    scenario = short("paper", 15.0)
    statuses = fly(scenario, tmp / "out", seed=7, key=key)
    assert statuses == {"recorder": 0, **{f"uav/{m}": 0 for m in range(6)}}
    flown = load_results(tmp / "out")
    truth = simulate(scenario, seed=7)
    assert flown.positions.shape == truth.positions.shape == (1, 151, 6, 2)
    assert np.max(np.abs(flown.positions - truth.positions)) <= 1e-9
    assert np.max(np.abs(flown.velocities - truth.velocities)) <= 1e-9
    for name in ("crlb", "eta", "cost", "separation", "clearance", "centroid_error"):
        np.testing.assert_allclose(getattr(flown, name), getattr(truth, name), rtol=1e-12)
    record = json.loads((tmp / "out" / "fly.json").read_text())
    assert record["complete"]
    assert record["late_steps"] == [0] * 6


def test_ctrl_c_stops_every_process_and_keeps_what_was_recorded(flight):
    """SIGINT to the launcher (real-time mode, 3 UAVs): it exits within seconds, every
    member is gone, and the folder holds the steps recorded as a shorter mission."""
    key, tmp = flight
    path = tmp / "three.toml"
    path.write_text(short("paper", 60.0, count=3).to_toml())
    proc = launch(key, path, tmp / "out", "--mode", "realtime")
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    # (a hang guard, not a speed test: members compiling on a cold cache on a loaded
    # machine take their time to stop, and the launcher kills what is left after its grace)
    status, _, err = finish(proc, 90.0)
    assert status == 130
    assert "interrupted" in err
    assert members(key) == []
    record = json.loads((tmp / "out" / "fly.json").read_text())
    assert record["interrupted"]
    assert not record["complete"]
    recorded = record["recorded_steps"]
    assert 1 <= recorded < 600
    result = load_results(tmp / "out")
    assert result.positions.shape == (1, recorded + 1, 3, 2)
    assert result.scenario.time.steps == recorded
    assert np.all(np.isfinite(result.crlb))


def killed_flight(flight, uav: int, at: float, count: int = 4, duration: float = 30.0):
    """A stepped flight of the paper scenario with ``count`` UAVs in which UAV ``uav``'s
    process kills itself (SIGKILL) at ``at`` s; the launcher's status and output, the
    scenario flown, the result and fly.json."""
    key, tmp = flight
    scenario = short("paper", duration, count=count)
    path = tmp / "swarm.toml"
    path.write_text(scenario.to_toml())
    proc = launch(key, path, tmp / "out", "--seed", "3", "--kill", f"{uav}@{at}")
    status, out, err = finish(proc, 90.0)  # (a hang guard)
    assert members(key) == []
    record = json.loads((tmp / "out" / "fly.json").read_text())
    return status, out, err, scenario, load_results(tmp / "out"), record


@pytest.mark.parametrize("uav", [0], ids=["leader"])  # (a follower: the next test)
def test_a_uav_killed_outright_is_lost_and_the_others_re_form(flight, uav):
    """SIGKILL to UAV ``uav``'s process at t = 10 s (stepped, 4 UAVs on a ring): the
    others see it gone, the leader (UAV 0, or after it is lost UAV 1, the lowest index left)
    re-plans the formation for the 3 left, and they fly to the end. Until the loss the
    flight is the simulation; the lost UAV stays where it was; the bound after the
    re-planning is the 3-UAV bound; the saved scenario tells the loss as a [faults] table
    whose plan re-plans at the same step, for the same UAVs, with the same leader."""
    status, out, err, scenario, result, record = killed_flight(flight, uav, 10.0)
    assert status == 1
    assert f"uav/{uav} -9" in out
    assert list(record["lost"]) == [f"uav {uav}"]
    assert record["complete"]
    leader = 1 if uav == 0 else 0
    assert f"leader {leader}" in err
    faults = result.scenario.faults
    assert faults is not None
    assert [u.uav for u in faults.uav_lost] == [uav]
    plan = result.scenario.fault_plan
    replan = plan.phases[-1]
    assert replan.members.tolist() == [m for m in range(4) if m != uav]
    assert replan.scenario.uavs.leader == replan.members.tolist().index(leader)
    k = replan.start
    assert 99 <= k <= 101  # (the loss at step 100, seen that step or the one after)
    three = crlb_bound(3, scenario.altitude, scenario.radar_model)
    four = crlb_bound(4, scenario.altitude, scenario.radar_model)
    np.testing.assert_allclose(result.bound_steps[k:], three, rtol=1e-12)
    np.testing.assert_allclose(result.bound_steps[: k - 1], four, rtol=1e-12)
    truth = simulate(scenario, seed=3)
    np.testing.assert_array_equal(result.positions[0, : k - 2], truth.positions[0, : k - 2])
    held = result.positions[0, k:, uav]
    assert np.all(held == held[0])
    others = [m for m in range(4) if m != uav]  # (they fly on)
    moved = result.positions[0, -1, others] - result.positions[0, k, others]
    assert np.all(np.hypot(*moved.T) > 0.0)
    assert np.all(np.isfinite(result.crlb))


def free_endpoints(n: int) -> list[str]:
    """``n`` endpoints on free ports of 127.0.0.1."""
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return [f"tcp/127.0.0.1:{p}" for p in ports]


def test_the_uavs_lost_of_a_faults_table_are_flown(flight):
    """A ``[faults]`` table flown (5 UAVs, 30 s): UAV 3 lost at 10 s, then the leader at
    20 s. Their processes kill themselves then; the others re-form, then, two left in one
    part and one in the other, hover (outcome ``too_few``), without waiting a timeout for
    anybody (no late step); the saved scenario tells both losses."""
    key, tmp = flight
    data = copy.deepcopy(short("paper", 30.0, count=5).model_dump())
    data["faults"] = {"uav_lost": [{"uav": 3, "time": 10.0}], "leader_lost": 20.0}
    path = tmp / "faults.toml"
    path.write_text(Scenario.from_dict(data).to_toml())
    proc = launch(key, path, tmp / "out", "--seed", "1")
    status, out, _ = finish(proc, 90.0)  # (a hang guard)
    assert status == 1
    assert "uav/0 -9" in out
    assert "uav/3 -9" in out
    assert members(key) == []
    record = json.loads((tmp / "out" / "fly.json").read_text())
    assert record["complete"]
    assert record["late_steps"] == [0] * 5
    result = load_results(tmp / "out")
    assert sorted(u.uav for u in result.scenario.faults.uav_lost) == [0, 3]
    assert result.metrics["outcome"][0] in ("too_few", "collision")
    assert result.scenario.fault_plan.outcome == "too_few"
    held = result.positions[0, 210:]
    assert np.all(held == held[0])


def test_members_started_by_hand_find_each_other(flight):
    """The recorder and 3 UAVs started as separate commands (``--recorder``, ``--uav I``),
    each on its own endpoint and connecting only to the recorder's (Zenoh's gossip
    introduces the UAVs to each other): the flight is the simulation."""
    key, tmp = flight
    scenario = short("paper", 5.0, count=3)
    path = tmp / "three.toml"
    path.write_text(scenario.to_toml())
    ends = free_endpoints(4)
    base = [sys.executable, "-m", "crlbswarm.cli", "fly", str(path), "--key", key, "--seed",
            "4"]  # fmt: skip
    roles = [["--recorder", "--out", str(tmp / "out")]]
    roles += [["--uav", str(m), "--connect", ends[0]] for m in range(3)]
    procs = [
        subprocess.Popen([*base, *role, "--listen", end], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
        for role, end in zip(roles, ends, strict=True)
    ]  # fmt: skip
    results = [p.communicate(timeout=60) for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0, 0], results
    flown = load_results(tmp / "out")
    np.testing.assert_array_equal(flown.positions, simulate(scenario, seed=4).positions)


def test_injected_delay_holds_each_message_back():
    """Without loss, the message sent at step k carries the state of step k - d (nothing
    for k < d)."""
    line = Injection(seed=3, sender=2, loss=0.0, delay=4)
    for k in range(30):
        sent = line.outgoing(k, np.array([float(k), -float(k)]))
        if k < 4:
            assert sent is None
        else:
            assert sent is not None
            stamp, values = sent
            assert stamp == k - 4
            assert values.tolist() == [k - 4.0, 4.0 - k]


@pytest.mark.parametrize(("seed", "loss"), [(0, 0.2), (5, 0.5)])
def test_injected_loss_is_independent_with_its_probability(seed, loss):
    """The fraction lost over many messages lies within 4.5 standard deviations of the
    binomial's mean; two senders lose different messages; the same seed, the same ones."""
    n = 20_000

    def delivered(sender: int) -> np.ndarray:
        line = Injection(seed=seed, sender=sender, loss=loss, delay=0)
        return np.array([line.outgoing(k, np.zeros(1)) is not None for k in range(n)])

    first = delivered(0)
    lost = 1.0 - first.mean()
    assert abs(lost - loss) <= 4.5 * math.sqrt(loss * (1 - loss) / n)
    assert not np.array_equal(first, delivered(1))
    np.testing.assert_array_equal(first, delivered(0))
    # independence: a loss does not make the next one likelier (lag-1 correlation ~ 0)
    x = first.astype(float)
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) <= 4.5 / math.sqrt(n)


def test_packets_round_trip_and_foreign_bytes_are_ignored():
    packet = Packet(LOG, 5, 1234, 1230, np.array([1.5, -2.25, math.nan, math.inf]))
    back = decode(encode(packet))
    assert back is not None
    assert (back.kind, back.sender, back.step, back.stamp) == (LOG, 5, 1234, 1230)
    np.testing.assert_array_equal(back.values, packet.values)
    empty = decode(encode(Packet(STATE, 0, 7, NO_STAMP, np.empty(0))))
    assert empty is not None
    assert empty.stamp == NO_STAMP
    assert empty.values.size == 0
    assert decode(b"hello world, not ours") is None
    assert decode(encode(packet)[:-3]) is None


def fly_error(capsys, *argv: str) -> str:
    """The one line ``crlbswarm fly ARGV`` prints on stderr, with exit status 2."""
    capsys.readouterr()
    assert main(["fly", *argv]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    return lines[0]


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--loss", "1.5"], "--loss"),
        (["--timeout", "0"], "--timeout"),
        (["--timeout", "nan"], "--timeout"),
        (["--delay", "-1"], "--delay"),
        (["--seed", "-3"], "--seed"),
        (["--key", "a/*"], "--key"),
        (["--connect", "nowhere"], "--connect"),
        (["--listen", "tcp/127.0.0.1:1"], "--listen"),
        (["--uav", "6"], "--uav"),
        (["--kill", "6@10"], "kill: UAV 6 does not exist"),
        (["--kill", "2@200"], "kill: time 200 s is outside the mission"),
        (["--kill", "2"], "--kill"),
        (["--kill", "2@nan"], "--kill"),
    ],
)  # fmt: skip
def test_errors_are_one_line_before_anything_starts(capsys, tmp_path, argv, words):
    out = tmp_path / "out"
    if "--uav" in argv:
        line = fly_error(capsys, "paper", *argv, "--connect", "tcp/127.0.0.1:9")
    else:
        line = fly_error(capsys, "paper", "--out", str(out), *argv)
    assert line.startswith("crlbswarm: error: ")
    assert words in line
    assert not out.exists()


def test_out_is_required_and_an_occupied_folder_is_refused(capsys, tmp_path):
    assert "--out" in fly_error(capsys, "paper")
    assert "--out" in fly_error(capsys, "paper", "--uav", "0", "--out", str(tmp_path))
    (tmp_path / "keep.txt").write_text("mine")
    line = fly_error(capsys, "paper", "--out", str(tmp_path))
    assert "already holds files" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_several_targets_and_a_missing_scenario_are_refused(capsys, tmp_path):
    data = copy.deepcopy(load_scenario("paper").model_dump())
    data["extra_targets"] = [[40.0, -60.0]]
    path = tmp_path / "two.toml"
    path.write_text(Scenario.from_dict(data).to_toml())
    assert "extra_targets" in fly_error(capsys, str(path), "--out", str(tmp_path / "o"))
    assert "nowhere.toml" in fly_error(capsys, "nowhere.toml", "--out", str(tmp_path / "o"))


@pytest.mark.parametrize(
    ("table", "words"),
    [
        ({"links": {"loss": 0.1}}, "links: crlbswarm fly does not fly a [links] table"),
        ({"faults": {"link_lost": [{"uavs": [0, 1], "time": 5.0}]}},
         "faults.link_lost: crlbswarm fly cannot cut a link yet"),
    ],
)  # fmt: skip
def test_links_and_links_lost_are_refused(capsys, tmp_path, table, words):
    data = copy.deepcopy(load_scenario("paper").model_dump())
    data.update(table)
    path = tmp_path / "s.toml"
    path.write_text(Scenario.from_dict(data).to_toml())
    assert words in fly_error(capsys, str(path), "--out", str(tmp_path / "o"))
    assert not (tmp_path / "o").exists()


def test_without_zenoh_the_error_names_the_extra(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "zenoh", None)  # (import zenoh raises ImportError)
    line = fly_error(capsys, "paper", "--out", str(tmp_path / "o"))
    assert "crlbswarm[fly]" in line
    assert "eclipse-zenoh" in line


def test_flight_options_name_the_field():
    with pytest.raises(ValueError, match="mode"):
        FlightOptions(mode="bogus")
    assert FlightOptions().mode == "stepped"


def test_an_injected_delay_resolves_the_auto_formation_gain():
    """--delay d flies an "auto" epsilon resolved for d steps (the simulator's rule for a
    [links] table's delay); explicit gains, and no delay, fly the scenario as it is."""
    from crlbswarm.graphs import auto_formation_step
    from crlbswarm.uav_node import delayed_gains, fly_run

    safe, paper = load_scenario("paper_safe"), load_scenario("paper")
    flown = fly_run(safe, 0, 3).scenario
    assert flown.gains.epsilon == auto_formation_step(safe.adjacency, 3)
    assert flown.gains.gamma == safe.gains.gamma
    same, before = flown.model_dump(), safe.model_dump()
    same["control"].pop("epsilon")
    before["control"].pop("epsilon")
    assert same == before
    assert fly_run(safe, 0).scenario is safe
    assert delayed_gains(paper, 3) is paper
