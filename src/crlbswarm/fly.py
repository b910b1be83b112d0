r"""``crlbswarm fly``: one process per UAV over Zenoh, a recorder, and their launcher.

:func:`fly` starts one process per UAV (:func:`crlbswarm.uav_node.run_uav`) and a recorder
(:func:`run_recorder`), each ``python -m crlbswarm.cli fly SCENARIO --uav I`` (or
``--recorder``): the same commands a user types to start them by hand on different
machines. Each listens on its own endpoint (free ports on 127.0.0.1 unless given) and
connects to the endpoints of the members started before it; none scouts by multicast
(:mod:`crlbswarm.flynet`). Every member waits until all are alive, then the UAVs fly.

The recorder subscribes to every UAV's log (its true state, the leader's eta, distance
to go and estimate), computes the step's metrics from the recorded states with the kernel's
own functions (the centroid, FIM, CRLB and centroid error of
:func:`crlbswarm.mission_kernel.step_state`, the smallest separation of
:func:`crlbswarm.mission_kernel.separation_of`, the cost of
:func:`crlbswarm.control.control_cost`), and writes the same folder as ``crlbswarm
simulate`` (:meth:`crlbswarm.MissionResult.save`), plus ``fly.json`` (the flight's record:
mode, steps recorded, UAVs lost, timeouts, wall time).

A flight that ends early (Ctrl-C, or a UAV lost) keeps what was recorded: the steps
``0 .. k`` that every UAV logged, saved as a result of a mission of ``k`` steps (the
scenario's ``time.duration`` cut to ``k`` steps, and ``time.hold`` and ``time.stall`` to
fit), which :func:`crlbswarm.load_results`, ``crlbswarm plot`` and ``crlbswarm replay``
read like any other; ``fly.json`` says that it was cut and where.
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from .control import control_cost
from .errors import FieldError
from .flynet import (
    DEFAULT_KEY,
    DEFAULT_TIMEOUT,
    DONE,
    LOG,
    LOG_FIELDS,
    RECORDER,
    FlightOptions,
    Inbox,
    Member,
    Packet,
    SwarmBlock,
    done_key,
    import_zenoh,
    log_key,
    member_name,
)
from .mission_kernel import separation_of, step_state
from .output import check_output_folder, write_json
from .results import MissionResult, outcome_report
from .scenario import Scenario
from .simulation import phase_scene
from .tracking import posterior_crlb
from .uav_node import FlyRun, compile_laws, fly_run, phase_run, wait_for_members

__all__ = [
    "FLY_FILE",
    "SHUTDOWN_GRACE",
    "FlightReport",
    "Recorder",
    "check_kill",
    "cut_scenario",
    "fly",
    "record_step",
    "run_recorder",
]

#: The flight's record in the output folder, beside the result's files.
FLY_FILE = "fly.json"

#: After Ctrl-C, how long the launcher waits for its children to stop (the recorder to
#: write) before it kills them, s.
SHUTDOWN_GRACE = 20.0

#: Once the recorder has ended, how long the other members have (beyond the timeout) to
#: end before the launcher stops them, s.
LINGER = 5.0

#: The exit status of a member that refused its arguments (the CLI's usage error).
EXIT_USAGE = 2

#: The recorder's wait for a UAV's log, in timeouts (a UAV may itself wait one timeout
#: for a neighbour before it logs).
RECORDER_PATIENCE = 3.0


@njit(cache=True)
def record_step(k, q, v, tx, ty, part, scene, const, centroid, fim, crlb, centroid_error, crowd):
    """The metrics of recorded step ``k`` as the kernel computes them: the centroid, FIM,
    CRLB and centroid error (:func:`crlbswarm.mission_kernel.step_state`, into row ``k`` of
    the arrays) and the smallest separation (returned,
    :func:`crlbswarm.mission_kernel.separation_of`)."""
    step_state(k, q, q, v, v, tx, ty, scene.snr, part, const, centroid, fim, crlb,
               centroid_error, None)  # fmt: skip
    return separation_of(q, None, crowd)


def cut_scenario(scenario: Scenario, steps: int, why: str) -> Scenario:
    """``scenario`` with its mission cut to ``steps`` steps (a flight that ended early):
    ``time.duration`` of ``steps`` steps, ``time.hold`` and ``time.stall`` at most half of
    it, and the description saying so.

    Parameters
    ----------
    scenario : Scenario
        The scenario flown.
    steps : int
        Steps recorded, at least 1.
    why : str
        Why the flight ended (in the description).

    Returns
    -------
    Scenario
        The scenario of the result.
    """
    data = scenario.model_dump()
    t = data["time"]
    duration = steps * t["step"]
    t["duration"] = duration
    t["hold"] = min(t["hold"], duration / 2)
    t["stall"] = min(t["stall"], duration / 2)
    data["description"] = (
        f"{scenario.description} [crlbswarm fly: {why}; {steps} of {scenario.time.steps} steps]"
    )
    return Scenario.from_dict(data)


class Recorder:
    """The recorder of a flight: every UAV's log, step by step, and the metrics.

    Parameters
    ----------
    run : FlyRun
        The run.
    options : FlightOptions
        Mode and timeout.
    member : Member
        Its Zenoh session.
    """

    def __init__(self, run: FlyRun, options: FlightOptions, member: Member) -> None:
        k1, n = run.k_steps + 1, run.m_uavs
        self.run, self.options, self.member = run, options, member
        self.positions, self.velocities = np.zeros((k1, n, 2)), np.zeros((k1, n, 2))
        self.vref, self.centroid = np.zeros((k1, 2)), np.zeros((k1, 2))
        self.fim = np.zeros((k1, 3))
        self.eta = np.ones(k1)
        self.crlb, self.clearance, self.separation = np.zeros(k1), np.zeros(k1), np.zeros(k1)
        self.distance_to_go, self.centroid_error = np.zeros(k1), np.zeros(k1)
        self.cost = np.zeros(max(k1 - 1, 1))
        self.estimate = np.full((k1, 2), np.nan)
        self.estimate_variance = np.full(k1, np.nan)
        self.part = np.zeros((1, 8))
        self.recorded = -1  # the last step recorded, in a row from 0
        self.lost: dict[int, int] = {}  # UAV -> the step whose log never came
        self.late = np.zeros(n, dtype=np.int64)
        self.started = self.ended = math.nan
        # the formation flown (re-planned when UAVs are lost), its run and bound per step
        self.block = SwarmBlock(0, -1, False, run.leader, np.arange(n, dtype=np.int64),
                                run.delta, np.empty(0))  # fmt: skip
        self.brun: FlyRun | None = run
        self.bounds = np.full(k1, float(run.scenario.formation_design.bound))
        self.declared: dict[int, int] = {}  # UAV lost -> the step the swarm re-planned

    def record(self, k: int, packets: dict[int, Packet]) -> None:
        """Record step ``k`` from the UAVs' logs: the states (a UAV without a log held where
        it was), the leader's eta, distance to go and estimate, the formation flown, and
        the step's metrics as the kernel computes them (:func:`record_step`, over the
        formation's UAVs that logged; the cost of the step before).

        Parameters
        ----------
        k : int
            The step (the steps before it are recorded).
        packets : dict
            UAV -> its log of step ``k`` (:data:`crlbswarm.flynet.LOG_FIELDS`, then the
            swarm it knows, :data:`crlbswarm.flynet.SWARM_FIELDS`).
        """
        run = self.run
        before = max(k - 1, 0)
        self.positions[k] = self.positions[before] if k else run.start
        self.velocities[k] = 0.0
        clear = []
        newest = self.block
        for m, packet in packets.items():
            values = packet.values
            self.positions[k, m] = values[0:2]
            self.velocities[k, m] = values[2:4]
            clear.append(values[4])
            self.late[m] = int(values[10])
            block = SwarmBlock.read(values, len(LOG_FIELDS))
            if block is not None and block.newer_than(newest):
                newest = block
        if k:  # (the move from step k - 1, under the formation then)
            self._cost(k)
        if newest is not self.block:
            self._adopt(newest, k)
        heads = [p.values for p in packets.values() if not math.isnan(p.values[5])]
        if heads:  # (the leader's log; none while a lost leader is replaced: held)
            head = heads[0]
            self.vref[k] = head[2:4]
            self.eta[k], self.distance_to_go[k] = head[5], head[6]
            self.estimate[k], self.estimate_variance[k] = head[7:9], head[9]
        elif k:
            self.vref[k], self.eta[k] = self.vref[k - 1], self.eta[k - 1]
            self.distance_to_go[k] = self.distance_to_go[k - 1]
            self.estimate[k], self.estimate_variance[k] = self.estimate[k - 1], math.nan
        self.clearance[k] = min(clear) if clear else math.inf
        self._metrics(k, packets)
        self.recorded = k

    def _metrics(self, k: int, packets: dict[int, Packet]) -> None:
        """The CRLB, centroid and separation of step ``k``: over every UAV (the kernel's
        arrays) while none is lost, else over the formation's UAVs that logged."""
        run = self.run
        every = self.block.phase == 0 and len(packets) == run.m_uavs
        rows = np.array([p for p in self.block.members.tolist() if p in packets], np.int64)
        if every:
            rows = np.arange(run.m_uavs)
        scene, const = run.scene, run.const if self.brun is None else self.brun.const
        if not every:
            scene = phase_scene(scene, scene.indptr, scene.indices, scene.snr[rows], scene.keep)
        q, v = self.positions[k][rows], self.velocities[k][rows]
        self.separation[k] = record_step(
            k, q, v, run.target[k, 0], run.target[k, 1], self.part, scene, const,
            self.centroid, self.fim, self.crlb, self.centroid_error, run.crowd,
        )  # fmt: skip

    def _cost(self, k: int) -> None:
        """The cost of eq. (15) of the move from step ``k - 1`` to ``k``, with the formation
        flown at step ``k - 1`` (:func:`crlbswarm.control.control_cost`)."""
        run, brun = self.run, self.brun
        if brun is None:  # (hovering: no formation, no cost)
            self.cost[k - 1] = 0.0
            return
        members = self.block.members
        self.cost[k - 1] = control_cost(
            self.positions[k - 1][members], self.positions[k][members], brun.delta,
            self.vref[k - 1], run.const.dt, brun.scene.indptr, brun.scene.indices,
        )  # fmt: skip

    def _adopt(self, block: SwarmBlock, k: int) -> None:
        """Take a re-planned formation from step ``k`` on: its run (its bound, constants
        and graph) and the UAVs it left out that are lost."""
        for p in self.block.members.tolist():
            if p not in block.members.tolist() and p in self.lost:
                self.declared[p] = block.step
        self.block = block
        self.brun = None if block.hover else phase_run(self.run, block)
        if self.brun is not None:
            self.bounds[k:] = float(self.brun.scenario.formation_design.bound)

    def fly(self) -> None:
        """Record every step (a UAV whose log does not come is lost: the recording goes on
        without it, until every UAV is lost), then send the end of the flight."""
        run, inbox = self.run, self.member.inbox
        names = {m: member_name(m) for m in range(run.m_uavs)}
        patience = RECORDER_PATIENCE * self.options.timeout
        self.started = time.monotonic()
        for k in range(run.k_steps + 1):
            wanted = [m for m in range(run.m_uavs) if m not in self.lost]
            missing = inbox.wait_step(LOG, k, wanted, patience, names)
            packets = {p.sender: p for p in inbox.take(LOG, k) if p.step == k}
            for m in sorted(missing):
                self.lost[m] = k
                packets.pop(m, None)
                print(f"crlbswarm fly: recorder: no log of UAV {m} for step {k}: "
                      f"{'gone' if names[m] in inbox.gone else 'silent'}; it is lost and "
                      "held where it was", file=sys.stderr, flush=True)  # fmt: skip
            if len(self.lost) == run.m_uavs:
                break
            if self.recorded == k - 1:
                self.record(k, packets)
        self.ended = time.monotonic()
        key = self.member.key
        self.member.publish(done_key(key), Packet(DONE, RECORDER, run.k_steps, run.k_steps,
                                                  np.empty(0)))  # fmt: skip

    def scenario(self, steps: int, why: str) -> Scenario:
        """The scenario of the result: the one flown, cut to ``steps`` if the flight ended
        early (:func:`cut_scenario`), with the UAVs the swarm lost as a ``[faults]`` table
        (each lost one step before the step the swarm re-planned at, with a timeout of one
        step: :func:`crlbswarm.faults.plan_faults` then re-plans at the same steps, for
        the same UAVs), when the scenario's layers allow one.

        Parameters
        ----------
        steps : int
            Steps recorded.
        why : str
            Why the flight ended, if it ended early.

        Returns
        -------
        Scenario
            The scenario.
        """
        run = self.run
        sc = run.scenario
        if self.declared and sc.links is None and run.track is None:
            dt = sc.time.step
            lost = [{"uav": p, "time": max(k - 1, 0) * dt}  # (a loss at step 0: at 0)
                    for p, k in sorted(self.declared.items())]  # fmt: skip
            sc = Scenario.from_dict({**sc.model_dump(), "faults": {"timeout": dt,
                                                                   "uav_lost": lost}})  # fmt: skip
        return sc if steps == run.k_steps else cut_scenario(sc, steps, why)

    def result(self, why: str) -> MissionResult | None:
        """The recorded steps as a result.

        Parameters
        ----------
        why : str
            Why the flight ended, if it ended early (:func:`cut_scenario`).

        Returns
        -------
        MissionResult or None
            One run: the whole mission, or a mission cut to the steps recorded; None if
            no step after the start was recorded. With UAVs lost, ``bound_steps`` holds
            the bound of the formation flown at each step.
        """
        run = self.run
        steps = self.recorded
        if steps < 1:
            return None
        sc = self.scenario(steps, why)
        k1 = steps + 1
        pcrb = None
        if run.track is not None:
            fim = np.zeros((k1, 2, 2))
            fim[:, 0, 0], fim[:, 1, 1] = self.fim[:k1, 0], self.fim[:k1, 1]
            fim[:, 0, 1] = fim[:, 1, 0] = self.fim[:k1, 2]
            f_mat, q_mat = run.scene.f_mat, run.scene.q_mat
            pcrb = posterior_crlb(fim, f_mat, q_mat, run.scene.p0, f_mat.shape[0],
                                  sc.estimation.measure_every)  # fmt: skip
        track = run.track is not None
        replanned = self.block.phase > 0 or sc.faults is not None
        return MissionResult(
            scenario=sc, seeds=np.array([run.seed], dtype=np.int64),
            time=np.arange(k1) * sc.time.step, positions=self.positions[None, :k1].copy(),
            velocities=self.velocities[None, :k1].copy(), centroid=self.centroid[None, :k1],
            reference_velocity=self.vref[None, :k1], target=run.target[None, :k1],
            estimate=self.estimate[None, :k1] if track else None,
            estimate_variance=self.estimate_variance[None, :k1] if track else None,
            pcrb=pcrb, eta=self.eta[None, :k1], crlb=self.crlb[None, :k1],
            cost=self.cost[None, : k1 - 1], clearance=self.clearance[None, :k1],
            separation=self.separation[None, :k1], distance_to_go=self.distance_to_go[None, :k1],
            bound=float(self.bounds[steps]), centroid_error=self.centroid_error[None, :k1],
            bound_steps=self.bounds[:k1].copy() if replanned else None,
        )  # fmt: skip


@dataclass
class FlightReport:
    """What a flight did (the content of ``fly.json``).

    Parameters
    ----------
    scenario : str
        The scenario's name.
    seed : int
        The seed.
    mode : str
        ``stepped`` or ``realtime``.
    steps : int
        The mission's steps K.
    recorded : int
        The last step every UAV logged (-1: none).
    interrupted : bool
        Whether the flight was stopped (Ctrl-C).
    lost : dict
        UAV -> the first step whose log did not come.
    late : list of int
        Each UAV's count of steps it went on without a state it waited for.
    timeout_s : float
        The stepped mode's timeout, s.
    loss : float
        Injected loss probability.
    delay_steps : int
        Injected delay, steps.
    wall_time_s : float
        From the start of the flight (all members alive) to the end of the recording, s.
    files : list of str
        The files written.
    """

    scenario: str
    seed: int
    mode: str
    steps: int
    recorded: int
    interrupted: bool
    lost: dict[int, int]
    late: list[int]
    timeout_s: float
    loss: float
    delay_steps: int
    wall_time_s: float
    files: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        """Whether every step was recorded."""
        return self.recorded == self.steps

    def to_dict(self) -> dict[str, Any]:
        """The report as JSON-ready data.

        Returns
        -------
        dict
            Its fields, ``complete``, and a one-line ``note`` when the mission was cut.
        """
        data: dict[str, Any] = {
            "scenario": self.scenario, "seed": self.seed, "mode": self.mode,
            "steps": self.steps, "recorded_steps": self.recorded, "complete": self.complete,
            "interrupted": self.interrupted,
            "lost": {f"uav {m}": step for m, step in sorted(self.lost.items())},
            "late_steps": self.late, "timeout_s": self.timeout_s, "loss": self.loss,
            "delay_steps": self.delay_steps, "wall_time_s": self.wall_time_s,
            "files": self.files,
        }  # fmt: skip
        if not self.complete:
            data["note"] = (
                f"the flight ended at step {self.recorded} of {self.steps}: the result holds "
                "the steps every UAV logged, as a mission of that length (scenario.toml's "
                "time.duration)"
                if self.recorded >= 1
                else "the flight ended before any step was recorded: no result written"
            )
        return data


def _save(recorder: Recorder, out: Path, force: bool, interrupted: bool) -> FlightReport:
    """Write the recorded result (if a step after the start was recorded) and ``fly.json``
    (if the flight started: nothing is written for a flight that never did)."""
    run, opts = recorder.run, recorder.options
    lost = f"UAV {min(recorder.lost)} lost" if recorder.lost else "stopped"
    result = recorder.result("interrupted" if interrupted else lost)
    started = math.isfinite(recorder.started)
    ended = recorder.ended if math.isfinite(recorder.ended) else time.monotonic()
    report = FlightReport(
        scenario=run.scenario.name, seed=run.seed, mode=opts.mode, steps=run.k_steps,
        recorded=recorder.recorded, interrupted=interrupted, lost=dict(recorder.lost),
        late=[int(x) for x in recorder.late], timeout_s=float(opts.timeout),
        loss=float(opts.loss), delay_steps=int(opts.delay),
        wall_time_s=float(ended - recorder.started) if started else 0.0,
    )  # fmt: skip
    if not started:
        return report
    if result is not None:
        report.files = [str(p) for p in result.save(out, overwrite=force)]
        for line in outcome_report(result):
            print(line, flush=True)
    else:
        out.mkdir(parents=True, exist_ok=True)
    write_json(out / FLY_FILE, report.to_dict())
    report.files.append(str(out / FLY_FILE))
    for path in report.files:
        print(f"wrote {path}", flush=True)
    return report


def run_recorder(run: FlyRun, out: str | os.PathLike[str], options: FlightOptions,
                 force: bool = False) -> FlightReport:  # fmt: skip
    """Run the recorder of a flight in this process: record, then write the folder.

    Parameters
    ----------
    run : FlyRun
        The run (:func:`crlbswarm.uav_node.fly_run`).
    out : str or path-like
        Output folder (missing or empty, unless ``force``).
    options : FlightOptions
        Key, endpoints, mode, timeout.
    force : bool, default False
        Write into a folder that holds files.

    Returns
    -------
    FlightReport
        What was recorded. On Ctrl-C (or SIGTERM) the steps recorded so far are written
        and ``interrupted`` is set.

    Raises
    ------
    FieldError
        (field ``out``) If the folder cannot be written; (``listen``) if the session cannot
        open.
    FlightError
        If the members do not all appear within :data:`crlbswarm.flynet.START_TIMEOUT`.
    """
    out = Path(out)
    check_output_folder(out, "out", new=True, overwrite=force)
    _compile_recorder(run)  # (before it joins)
    inbox = Inbox(options.parent)
    member = Member(options.key, member_name(None), options.listen, options.connect, inbox)
    recorder = Recorder(run, options, member)
    interrupted = False
    try:
        member.subscribe([log_key(options.key, m) for m in range(run.m_uavs)])
        member.announce()
        wait_for_members(member, run)
        print(f"flying: {run.m_uavs} UAVs and the recorder connected ({options.mode})",
              flush=True)  # fmt: skip
        recorder.fly()
    except KeyboardInterrupt:
        interrupted = True
    finally:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # (writing: not again)
        try:
            member.close()
            report = _save(recorder, out, force, interrupted)
        finally:
            signal.signal(signal.SIGINT, previous)
    return report


# ---------------------------------------------------------------------------------------
# The launcher
# ---------------------------------------------------------------------------------------
def _free_endpoints(n: int, host: str = "127.0.0.1") -> list[str]:
    """``n`` TCP endpoints on free ports of ``host`` (the ports are released just before
    the members bind them)."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind((host, 0))
            socks.append(s)
        return [f"tcp/{host}:{s.getsockname()[1]}" for s in socks]
    finally:
        for s in socks:
            s.close()


def _member_command(scenario_file: Path, seed: int, options: FlightOptions, listen: str,
                    connect: Sequence[str], role: list[str]) -> list[str]:  # fmt: skip
    """The command line of one member (the by-hand command, with its launcher's id)."""
    cmd = [sys.executable, "-m", "crlbswarm.cli", "fly", str(scenario_file), "--seed",
           str(seed), "--mode", options.mode, "--timeout", repr(float(options.timeout)),
           "--loss", repr(float(options.loss)), "--delay", str(options.delay), "--key",
           options.key, "--listen", listen, "--parent", str(os.getpid())]  # fmt: skip
    for endpoint in connect:
        cmd += ["--connect", endpoint]
    if options.kill is not None:
        cmd += ["--kill", f"{options.kill[0]}@{options.kill[1]!r}"]
    return cmd + role


def check_kill(kill: tuple[int, float] | None, run: FlyRun) -> None:
    """Check a ``--kill UAV@TIME`` against the run.

    Parameters
    ----------
    kill : tuple of (int, float) or None
        The UAV and the time.
    run : FlyRun
        The run.

    Raises
    ------
    FieldError
        (field ``kill``) For a UAV that does not exist or a time outside the mission.
    """
    if kill is None:
        return
    uav, at = kill
    if not 0 <= uav < run.m_uavs:
        raise FieldError("kill", f"UAV {uav} does not exist (0 .. {run.m_uavs - 1})")
    duration = run.k_steps * run.const.dt
    if not 0.0 <= at <= duration:
        raise FieldError("kill", f"time {at:g} s is outside the mission (0 .. {duration:g} s)")


def _stop(procs: dict[str, subprocess.Popen[bytes]], grace: float) -> None:
    """Ask every running member to stop (SIGINT: the recorder writes what it has), wait
    at most ``grace`` seconds, then kill those left."""
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + grace
    for proc in procs.values():
        try:
            proc.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _wait(procs: dict[str, subprocess.Popen[bytes]], linger: float) -> None:
    """Wait for the members to end; once the recorder has, the others get ``linger``
    seconds (a member stopped, or cut off from the others, would never end); a member that
    refused its arguments (exit status 2) ends the flight at once."""
    recorder = procs[member_name(None)]
    deadline = math.inf
    while any(p.poll() is None for p in procs.values()):
        if any(p.returncode == EXIT_USAGE for p in procs.values()):
            return
        if recorder.returncode is not None and deadline == math.inf:
            deadline = time.monotonic() + linger
        if time.monotonic() > deadline:
            return
        time.sleep(0.05)


def fly(
    scenario: Scenario,
    out: str | os.PathLike[str],
    *,
    seed: int = 0,
    mode: str = "stepped",
    timeout: float = DEFAULT_TIMEOUT,
    loss: float = 0.0,
    delay: int = 0,
    force: bool = False,
    key: str | None = None,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] = (),
    kill: tuple[int, float] | None = None,
) -> dict[str, int]:
    """Fly ``scenario`` with one process per UAV and a recorder, on this machine.

    Parameters
    ----------
    scenario : Scenario
        The scenario (one target).
    out : str or path-like
        Output folder of the recorder (missing or empty, unless ``force``).
    seed : int, default 0
        The run's seed (the same starts and draws as ``simulate(scenario, seed)``).
    mode : str, default "stepped"
        ``stepped`` or ``realtime`` (:data:`crlbswarm.flynet.MODES`).
    timeout : float, default DEFAULT_TIMEOUT
        The stepped mode's timeout, s (:class:`crlbswarm.flynet.FlightOptions`).
    loss : float, default 0
        Probability that a swarm message is lost (injected at the sender).
    delay : int, default 0
        Steps a swarm message is held back at the sender.
    force : bool, default False
        Write into a folder that holds files.
    key : str, optional
        The flight's key prefix (default: ``crlbswarm/fly/<random>``, one per flight).
    listen : sequence of str, optional
        One endpoint per member, the recorder's first then UAV 0, 1, ... (default: free
        ports on 127.0.0.1).
    connect : sequence of str, default ()
        Endpoints every member connects to as well.
    kill : tuple of (int, float), optional
        ``(uav, time)``: UAV ``uav``'s process kills itself (SIGKILL) when the mission
        reaches ``time`` s: a UAV lost; the others re-form (docs/fly.md).

    Returns
    -------
    dict
        Each member's exit status (``recorder``, ``uav/0``, ...): 0 when it finished, 130
        when it was stopped, 1 when it failed; a negative value is the signal that ended it.

    Raises
    ------
    FieldError
        For an invalid option or output folder, before any process starts; (field
        ``zenoh``) without Zenoh.
    KeyboardInterrupt
        On Ctrl-C, after every member has stopped (the recorder wrote what it had).
    """
    import_zenoh()
    run = fly_run(scenario, seed, delay)
    n = run.m_uavs
    options = FlightOptions(key=key or f"{DEFAULT_KEY}/{uuid.uuid4().hex[:12]}", mode=mode,
                            timeout=timeout, loss=loss, delay=delay,
                            connect=tuple(connect), kill=kill)  # fmt: skip
    check_kill(kill, run)
    check_output_folder(out, "out", new=True, overwrite=force)
    if listen is not None and len(listen) != n + 1:
        raise FieldError("listen", f"give one endpoint per member ({n + 1}: the recorder's, "
                         f"then UAV 0 .. {n - 1}), got {len(listen)}")  # fmt: skip
    endpoints = list(listen) if listen is not None else _free_endpoints(n + 1)
    FlightOptions(listen=tuple(endpoints))  # (checks their form)
    compile_laws(run)
    _compile_recorder(run)
    roles = [["--recorder", "--out", str(out)] + (["--force"] if force else [])]
    roles += [["--uav", str(m)] for m in range(n)]
    procs: dict[str, subprocess.Popen[bytes]] = {}
    folder = Path(tempfile.mkdtemp(prefix="crlbswarm-fly-"))
    try:
        scenario_file = folder / "scenario.toml"
        scenario_file.write_text(scenario.to_toml(), encoding="utf-8")
        for i, role in enumerate(roles):
            cmd = _member_command(scenario_file, run.seed, options, endpoints[i],
                                  [*endpoints[:i], *options.connect], role)  # fmt: skip
            name = member_name(None if i == 0 else i - 1)
            procs[name] = subprocess.Popen(cmd, start_new_session=True,
                                           preexec_fn=_default_sigint)  # fmt: skip
        _wait(procs, options.timeout + LINGER)
    except KeyboardInterrupt:
        _stop(procs, SHUTDOWN_GRACE)
        raise
    finally:
        _stop(procs, 1.0)
        shutil.rmtree(folder, ignore_errors=True)
    return {name: int(p.returncode) for name, p in procs.items()}


def _default_sigint() -> None:
    """In a member, before it starts: SIGINT's default action, even if the launcher was
    started with SIGINT ignored (which children inherit), since the launcher stops its
    members with SIGINT."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _compile_recorder(run: FlyRun) -> None:
    """Compile (or load) the recorder's laws before the flight: record the start twice."""
    logs = {}
    for m in range(run.m_uavs):
        values = np.zeros(11)
        values[0:2] = run.start[m]
        logs[m] = Packet(LOG, m, 0, 0, values)
    recorder = Recorder(run, FlightOptions(), None)  # type: ignore[arg-type]
    recorder.record(0, logs)
    if run.k_steps > 0:
        recorder.record(1, logs)
