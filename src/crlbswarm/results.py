"""Results of a batch of missions: trajectories, time series, per-run metrics, files.

:class:`MissionResult` is what :func:`crlbswarm.simulate` returns. It computes the per-run
metrics once (convergence, clearance, separation, cost and, with sensing in the loop, the
estimation error), gives the columns behind each figure, summarises the batch, and writes
itself to a folder (:meth:`MissionResult.save`) that :func:`load_results` reads back to an
result with the same arrays and metrics.

Adding an output format: write a method beside :meth:`MissionResult.save` (or a function
taking a result) and list its file in ``docs/cli.md``.
"""

from __future__ import annotations

import dataclasses
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import FieldError
from .faults import FAULT_OUTCOMES
from .links import LINK_SERIES
from .output import atomic_path, staged_folder, write_csv, write_json, write_text
from .scenario import GroupPlan, Scenario, load_scenario

__all__ = [
    "CENTROID_TOL",
    "CRLB_TOL",
    "OUTCOMES",
    "PROGRESS_TOL",
    "RESULT_FILES",
    "STEADY_STATE_S",
    "GroupMissionResult",
    "MissionResult",
    "kept_rows",
    "load_results",
    "outcome_report",
    "result_nbytes",
]

#: Convergence: CRLB within this factor of the bound and centroid within CENTROID_TOL.
CRLB_TOL = 0.01
#: Convergence: the centroid within this distance of the target, m.
CENTROID_TOL = 0.5

#: Progress: the distance to go must fall by more than this over the stall window, m.
PROGRESS_TOL = CENTROID_TOL

#: The outcomes of a run, in order of precedence.
OUTCOMES = ("collision", "converged", "timeout", "stuck", *FAULT_OUTCOMES)

#: Length of the "steady state" window at the end of a mission (estimation metrics), s.
STEADY_STATE_S = 30.0

#: The files of a saved result, in the order they are written.
RESULT_FILES = ("trajectories.npz", "metrics.csv", "scenario.toml", "summary.json")


@dataclass(frozen=True, eq=False)
class MissionResult:
    """Trajectories and metrics of a batch of missions (B runs, K steps, M UAVs).

    Attributes
    ----------
    scenario : Scenario
        The scenario that was run.
    seeds : ndarray of int, shape (B,)
        Seed of each run.
    time : ndarray, shape (K+1,)
        Time of each sample, s.
    positions : ndarray, shape (B, R, M, 2), or None
        UAV positions, m, at the R steps :attr:`trajectory_steps` (every step by default;
        ``None`` if ``keep_trajectories=False``).
    velocities : ndarray, shape (B, R, M, 2), or None
        Consensus velocities :math:`\\mathbf v_{m,k}` (the leader's is :math:`\\mathbf v^*_k`),
        m/s, at the steps :attr:`trajectory_steps` (``None`` if ``keep_trajectories=False``).
    centroid : ndarray, shape (B, K+1, 2)
        Formation centroid, m.
    target : ndarray, shape (B, K+1, 2)
        True target position, m (constant for a static target).
    estimate : ndarray, shape (B, K+1, 2), or None
        The UAVs' own estimate of the target after each step's measurement (sensing in the
        loop), m; ``None`` when estimation is off.
    estimate_variance : ndarray, shape (B, K+1), or None
        Trace of the position block of the filter's covariance, m^2.
    pcrb : ndarray, shape (K+1,), or None
        Posterior CRLB of the position (:func:`crlbswarm.tracking.posterior_crlb`, averaged
        over the runs of the batch), m^2.
    reference_velocity : ndarray, shape (B, K+1, 2)
        Leader's reference :math:`\\mathbf v^*_k`, m/s.
    eta : ndarray, shape (B, K+1)
        Scaling factor.
    crlb : ndarray, shape (B, K+1)
        CRLB at the actual positions and the true target, m^2.
    cost : ndarray, shape (B, K)
        :math:`\\mathcal L_\\text{tot}` of eq. (15) at steps 0..K-1.
    clearance : ndarray, shape (B, K+1)
        Smallest signed distance from a UAV to an obstacle, m (inf without obstacles).
    separation : ndarray, shape (B, K+1)
        Smallest distance between two UAVs, m.
    distance_to_go : ndarray, shape (B, K+1)
        Distance from the formation's centroid to the target along the planned route (the
        straight line without the planner), m: the progress of the mission.
    bound : float
        The CRLB the formation converges to, m^2: the attainable optimum
        (:func:`crlbswarm.crlb_bound`; :math:`4/\\sum_m w_m^*` of eq. (11) for equal UAVs),
        or, when :math:`F^*` is blocked, the CRLB of the constrained design
        (:attr:`crlbswarm.Scenario.formation_design`).
    trajectory_stride : int, default 1
        ``positions`` and ``velocities`` hold every this many steps, and the last
        (:attr:`trajectory_steps`; ``simulate(..., trajectory_stride=...)``).
    centroid_error : ndarray, shape (B, K+1)
        Distance from the formation centroid to its place over the (true) target, m: the
        target itself for a regular polygon, else the target plus the formation's centre
        offset (``centre_offset`` of :class:`crlbswarm.scenario.FormationDesign`). The
        simulator's kernel computes it at every step; when it is not given (``None``, e.g.
        a result saved by an older build) it is computed from ``centroid`` and ``target``,
        with the same bits.
    link_sent : ndarray, shape (B, K+1), or None
        With links (the scenario's ``[links]`` table, :mod:`crlbswarm.links`): the
        messages sent at each step (one per link in range, at the sending steps); ``None``
        without links (perfect links: every state of the step, instantly).
    link_delivered : ndarray, shape (B, K+1), or None
        Of those, the messages not lost (received then or later).
    link_age : ndarray, shape (B, K+1), or None
        Mean age of the neighbours' states the laws use at the step, s (NaN when a UAV
        uses none).
    link_age_max : ndarray, shape (B, K+1), or None
        Largest such age, s.
    link_connected : ndarray, shape (B, K+1), or None
        1 where the communication graph is connected (the links in use whose last message
        is at most ``links.timeout`` old), else 0.
    bound_steps : ndarray, shape (K+1,), or None
        With faults (the scenario's ``[faults]`` table, :mod:`crlbswarm.faults`): the
        bound of the formation flown at each step (it changes when the swarm re-plans;
        ``bound`` is the last); the CRLB is measured against it. ``None`` without faults.
    metrics : dict of str to ndarray, shape (B,)
        Per-run metrics, computed once (the columns of ``metrics.csv``): ``seed``,
        ``outcome`` (:data:`OUTCOMES`; with faults, ``split`` or ``too_few`` when the
        swarm fell apart, unless it collided), ... ``convergence_time_s`` is the first time from
        which the CRLB stays within ``1 + CRLB_TOL`` of ``bound`` and the centroid within
        ``CENTROID_TOL`` of its place until the end, for at least ``time.hold`` seconds
        (NaN if never): a run that settled and yet collided has a convergence time too,
        so count converged runs by ``outcome == "converged"``, not by this column.
    """

    scenario: Scenario
    seeds: np.ndarray
    time: np.ndarray
    positions: np.ndarray | None
    velocities: np.ndarray | None
    centroid: np.ndarray
    reference_velocity: np.ndarray
    target: np.ndarray
    estimate: np.ndarray | None
    estimate_variance: np.ndarray | None
    pcrb: np.ndarray | None
    eta: np.ndarray
    crlb: np.ndarray
    cost: np.ndarray
    clearance: np.ndarray
    separation: np.ndarray
    distance_to_go: np.ndarray
    bound: float
    trajectory_stride: int = 1
    centroid_error: np.ndarray = None  # type: ignore[assignment]  # None: computed
    link_sent: np.ndarray | None = None
    link_delivered: np.ndarray | None = None
    link_age: np.ndarray | None = None
    link_age_max: np.ndarray | None = None
    link_connected: np.ndarray | None = None
    bound_steps: np.ndarray | None = None
    metrics: dict[str, np.ndarray] = field(init=False)

    def __post_init__(self) -> None:
        if self.centroid_error is None:
            offset = self.centroid - self.target - self.scenario.formation_design.centre_offset
            object.__setattr__(self, "centroid_error", np.hypot(offset[..., 0], offset[..., 1]))
        object.__setattr__(self, "metrics", self._metrics())

    @property
    def trajectory_steps(self) -> np.ndarray:
        """The steps at which ``positions`` and ``velocities`` are kept: every
        ``trajectory_stride``-th step from 0, and the last step."""
        return kept_rows(int(self.time.shape[0]) - 1, self.trajectory_stride)

    @property
    def n_runs(self) -> int:
        """Number of runs B."""
        return int(self.seeds.shape[0])

    @property
    def estimation_error(self) -> np.ndarray | None:
        """Distance from the UAVs' estimate to the true target, m, shape (B, K+1)."""
        if self.estimate is None:
            return None
        offset = self.estimate - self.target
        return np.hypot(offset[..., 0], offset[..., 1])

    @property
    def steady_state(self) -> np.ndarray:
        """Mask of the steps in the last :data:`STEADY_STATE_S` seconds (at most the last
        half of the mission), shape (K+1,)."""
        window = min(STEADY_STATE_S, 0.5 * float(self.time[-1]))
        return self.time >= self.time[-1] - window - 1e-9

    def _metrics(self) -> dict[str, np.ndarray]:
        ratio = self.crlb / (self.bound if self.bound_steps is None else self.bound_steps)
        centroid = self.centroid_error
        ok = (ratio <= 1.0 + CRLB_TOL) & (centroid <= CENTROID_TOL)
        # Within tolerance from step k on: every later step is ok (reverse cumulative AND);
        # converged if that lasts at least time.hold seconds.
        settled = np.flip(np.logical_and.accumulate(np.flip(ok, axis=1), axis=1), axis=1)
        first = np.argmax(settled, axis=1)
        held = settled[:, -1] & (
            self.time[-1] - self.time[first] >= self.scenario.time.hold - 1e-9
        )
        conv = np.where(held, self.time[first], np.nan)
        return {
            "seed": self.seeds,
            "outcome": self._outcomes(held),
            "final_crlb_ratio": ratio[:, -1],
            "final_centroid_error_m": centroid[:, -1],
            "final_eta": self.eta[:, -1],
            "min_eta": self.eta.min(axis=1),
            "convergence_time_s": conv,
            "min_clearance_m": self.clearance.min(axis=1),
            "min_separation_m": self.separation.min(axis=1),
            "max_cost": self.cost.max(axis=1),
            "final_cost": self.cost[:, -1],
            **self._estimation_metrics(),
            **self._link_metrics(),
        }

    def _outcomes(self, converged: np.ndarray) -> np.ndarray:
        """Each run's outcome: ``collision`` (a UAV inside an obstacle, or two UAVs closer
        than ``safety.min_separation``, at any step), else ``converged``, else ``timeout``
        (the distance to go fell by more than PROGRESS_TOL over the last ``time.stall``
        seconds) or ``stuck`` (it did not)."""
        sc = self.scenario
        collided = (self.separation.min(axis=1) < sc.safety.min_separation * (1.0 - 1e-9)) | (
            self.clearance.min(axis=1) <= 0.0
        )
        window = min(sc.time.stall, float(self.time[-1]))
        k0 = int(np.argmax(self.time >= self.time[-1] - window - 1e-9))
        tail = np.ascontiguousarray(self.distance_to_go[:, k0:])
        progressing = tail.max(axis=1) - tail[:, -1] > PROGRESS_TOL
        out = np.where(progressing, "timeout", "stuck")
        out = np.where(converged, "converged", out)
        plan = sc.fault_plan
        if plan is not None and plan.outcome:
            out = np.full_like(out, plan.outcome)
        return np.where(collided, "collision", out)

    @property
    def outcome_counts(self) -> dict[str, int]:
        """How many runs ended in each outcome (see ``metrics["outcome"]``)."""
        names, counts = np.unique(self.metrics["outcome"], return_counts=True)
        return {str(n): int(c) for n, c in zip(names, counts, strict=True)}

    def _estimation_metrics(self) -> dict[str, np.ndarray]:
        error, variance = self.estimation_error, self.estimate_variance
        if error is None or variance is None:
            return {}
        # A contiguous suffix, so each run's reduction does not depend on the batch.
        k0 = int(np.argmax(self.steady_state))
        tail_error = np.ascontiguousarray(error[:, k0:])
        tail_std = np.sqrt(np.ascontiguousarray(variance[:, k0:]))
        return {
            "final_estimation_error_m": error[:, -1],
            "steady_rms_estimation_error_m": np.sqrt(np.mean(tail_error**2, axis=1)),
            "steady_max_error_over_sqrt_crlb": np.max(
                tail_error / np.sqrt(self.crlb[:, k0:]), axis=1
            ),
            "steady_max_error_over_filter_std": np.max(tail_error / tail_std, axis=1),
        }

    def _link_metrics(self) -> dict[str, np.ndarray]:
        """With links: the delivered fraction of the messages, the mean (over the steps
        with links in use) and largest age of information, and the time the communication
        graph was disconnected. Without links none (their perfect values would be 1, 0, 0
        and 0)."""
        sent, delivered = self.link_sent, self.link_delivered
        age, oldest, connected = self.link_age, self.link_age_max, self.link_connected
        if sent is None or delivered is None or age is None or oldest is None:
            return {}
        assert connected is not None
        total = sent.sum(axis=1)
        steps = np.count_nonzero(age == age, axis=1)  # (NaN: no link in use at the step)
        with np.errstate(invalid="ignore", divide="ignore"):
            fraction = np.where(total > 0, delivered.sum(axis=1) / total, np.nan)
            mean_age = np.where(steps > 0, np.nansum(age, axis=1) / steps, np.nan)
        # (fmax skips NaN; a run without any link in use keeps NaN)
        largest = np.fmax.reduce(oldest, axis=1)
        return {
            "delivered_fraction": fraction,
            "mean_age_s": mean_age,
            "max_age_s": largest,
            "disconnected_s": np.sum(connected == 0.0, axis=1) * self.scenario.time.step,
        }

    @property
    def steady_rmse_over_sqrt_pcrb(self) -> float | None:
        """Batch figure of tracking efficiency: the RMS over runs of the estimation error,
        divided by the square root of the PCRB, averaged over the steady-state steps (1 for
        an efficient tracker). ``None`` without estimation."""
        error, pcrb = self.estimation_error, self.pcrb
        if error is None or pcrb is None:
            return None
        tail = self.steady_state
        rmse = np.sqrt(np.mean(error[:, tail] ** 2, axis=0))
        return float(np.mean(rmse / np.sqrt(pcrb[tail])))

    def run_index(self, run: object) -> int:
        """Check a run index of this batch.

        Parameters
        ----------
        run : int
            Index of a run, ``0 <= run < n_runs``.

        Returns
        -------
        int
            The index.
        """
        if not isinstance(run, int | np.integer) or not 0 <= run < self.n_runs:
            raise FieldError("run", f"must be an index in 0..{self.n_runs - 1}, got {run!r}")
        return int(run)

    def trajectory_columns(self, run: int = 0) -> dict[str, np.ndarray]:
        """Columns of Fig. 3's data: time, eta and every UAV's x and y (UAVs numbered from 1).

        Parameters
        ----------
        run : int, default 0
            Index of the run in the batch.

        Returns
        -------
        dict of str to ndarray, shape (K+1,)
            ``time_s``, ``eta``, ``target_x``, ``target_y``, ``estimate_x``, ``estimate_y``
            (with estimation), ``x_uav1``, ``y_uav1``, ..., in metres.
        """
        b = self.run_index(run)
        if self.positions is None:
            raise FieldError(
                "result", "has no trajectories (simulated with keep_trajectories=False)"
            )
        cols = {
            "time_s": self.time,
            "eta": self.eta[b],
            "target_x": self.target[b, :, 0],
            "target_y": self.target[b, :, 1],
        }
        if self.estimate is not None:
            cols["estimate_x"] = self.estimate[b, :, 0]
            cols["estimate_y"] = self.estimate[b, :, 1]
        kept = self.trajectory_steps  # (NaN at the steps not kept)
        for m in range(self.positions.shape[2]):
            for axis, name in ((0, "x"), (1, "y")):
                col = np.full(self.time.shape, np.nan)
                col[kept] = self.positions[b, :, m, axis]
                cols[f"{name}_uav{m + 1}"] = col
        return cols

    def timeseries_columns(self, run: int = 0) -> dict[str, np.ndarray]:
        """Columns of Fig. 4's data: time, CRLB, bound, cost (NaN at the last sample), eta,
        smallest clearance and separation, centroid error.

        Parameters
        ----------
        run : int, default 0
            Index of the run in the batch.

        Returns
        -------
        dict of str to ndarray, shape (K+1,)
            ``time_s``, ``crlb_m2``, ``bound_m2``, ``cost``, ``eta``, ``min_clearance_m``,
            ``min_separation_m``, ``centroid_error_m``.
        """
        b = self.run_index(run)
        return {
            "time_s": self.time,
            "crlb_m2": self.crlb[b],
            "bound_m2": np.full(self.time.shape, self.bound)
            if self.bound_steps is None
            else self.bound_steps,
            "cost": np.append(self.cost[b], np.nan),
            "eta": self.eta[b],
            "min_clearance_m": self.clearance[b],
            "min_separation_m": self.separation[b],
            "centroid_error_m": self.centroid_error[b],
        }

    def estimation_columns(self) -> dict[str, np.ndarray]:
        """Columns of the sensing-in-the-loop figure: statistics over the runs per step.

        Returns
        -------
        dict of str to ndarray, shape (K+1,)
            ``time_s``, ``rms_estimation_error_m`` (over runs), ``pcrb_m2``,
            ``mean_crlb_m2`` (instantaneous CRLB, mean over runs), ``rms_centroid_error_m``.
        """
        error = self.estimation_error
        if error is None:
            raise FieldError("result", "has no estimates (simulate a scenario with estimation on)")
        return {
            "time_s": self.time,
            "rms_estimation_error_m": np.sqrt(np.mean(error**2, axis=0)),
            "pcrb_m2": self.pcrb,
            "mean_crlb_m2": self.crlb.mean(axis=0),
            "rms_centroid_error_m": np.sqrt(np.mean(self.centroid_error**2, axis=0)),
        }

    def save(self, folder: str | os.PathLike[str], *, overwrite: bool = False) -> list[Path]:
        """Write the result to a folder: arrays, per-run metrics, scenario and summary.

        Files: ``trajectories.npz`` (compressed; every array attribute that is not
        ``None``, and ``formation``, the scenario's :math:`F^*`), ``metrics.csv`` (one row
        per run), ``scenario.toml`` (the scenario, readable by
        :func:`crlbswarm.load_scenario`) and ``summary.json`` (:meth:`summary`, the first
        and last seed and the crlbswarm version). They are written in a hidden folder and
        moved into place at the end (:func:`crlbswarm.output.staged_folder`): an
        interrupted save leaves a missing ``folder`` absent or complete, and an existing
        one without a new ``summary.json`` (its presence marks a complete set).
        :func:`load_results` reads the folder back.

        Parameters
        ----------
        folder : str or path-like
            Output folder: missing or empty (created if missing).
        overwrite : bool, default False
            Accept a folder that already holds files, replacing those of the same names.

        Returns
        -------
        list of pathlib.Path
            The files written, in order (``summary.json`` last: its presence marks a
            complete set).

        Raises
        ------
        FieldError
            If ``folder`` holds files and ``overwrite`` is not set, or cannot be written
            (field ``folder``).
        """
        from . import __version__

        arrays: dict[str, Any] = {n: np.asarray(getattr(self, n)) for n in _ARRAY_FIELDS}
        arrays = {k: v for k, v in arrays.items() if v.dtype != object}  # None: not kept
        arrays["formation"] = self.scenario.slots
        summary = self.summary()
        summary["seeds"] = {"first": int(self.seeds[0]), "last": int(self.seeds[-1])}
        summary["crlbswarm_version"] = __version__
        with staged_folder(folder, "folder", overwrite=overwrite, marker=RESULT_FILES[3]) as out:
            paths = [out / name for name in RESULT_FILES]
            with atomic_path(paths[0]) as tmp:
                np.savez_compressed(tmp, **arrays)
            write_csv(paths[1], self.metrics)
            write_text(paths[2], self.scenario.to_toml())
            write_json(paths[3], summary)
        return [Path(folder) / name for name in RESULT_FILES]

    def summary(self) -> dict[str, Any]:
        """Aggregate figures over the runs, JSON-ready.

        Returns
        -------
        dict
            Scenario name, number of runs, steps, the bound, the number of runs whose
            outcome is ``converged`` (``converged_runs``), the count of each outcome, and
            for each numeric metric its min, mean and max over the runs (NaN-aware for the
            convergence time).
        """
        out: dict[str, Any] = {
            "scenario": self.scenario.name,
            "runs": self.n_runs,
            "steps": int(self.time.shape[0] - 1),
            "duration_s": float(self.time[-1]),
            "bound_m2": float(self.bound),
            "converged_runs": int(np.sum(self.metrics["outcome"] == "converged")),
            "outcomes": self.outcome_counts,
        }
        design = self.scenario.formation_design
        if design.method != "closed form":  # (F* blocked: what the constrained design cost)
            out["design"] = design.to_dict()
        if self.estimate is not None:
            out["steady_rmse_over_sqrt_pcrb"] = self.steady_rmse_over_sqrt_pcrb
        for name, values in self.metrics.items():
            if name == "seed" or values.dtype.kind not in "fiu":
                continue
            finite = values[np.isfinite(values)]
            out[name] = {
                "min": float(finite.min()) if finite.size else None,
                "mean": float(finite.mean()) if finite.size else None,
                "max": float(finite.max()) if finite.size else None,
            }
        return out


def kept_rows(k_steps: int, stride: int) -> np.ndarray:
    """The steps whose positions and velocities are kept: every ``stride``-th step from 0,
    and the last step K (0 steps when ``stride`` is 0).

    Parameters
    ----------
    k_steps : int
        Steps K of the run.
    stride : int
        Keep every this many steps; 0 keeps none.

    Returns
    -------
    ndarray of int64
        The kept steps, increasing.
    """
    if stride <= 0:
        return np.empty(0, dtype=np.int64)
    steps = np.arange(0, k_steps + 1, stride, dtype=np.int64)
    return steps if steps[-1] == k_steps else np.append(steps, k_steps)


def result_nbytes(
    n_runs: int, k_steps: int, m_uavs: int, keep_trajectories: bool, stride: int = 1
) -> int:
    """Bytes of the arrays of a result: its time series (about 14 values per run and step:
    eta, CRLB, cost, centroid, target, estimate, ...) and, if kept, the positions and
    velocities of every UAV (the memory :func:`crlbswarm.simulate` needs, and about the
    size of ``trajectories.npz`` before compression).

    Parameters
    ----------
    n_runs : int
        Runs.
    k_steps : int
        Steps per run.
    m_uavs : int
        UAVs.
    keep_trajectories : bool
        Whether positions and velocities are kept.
    stride : int, default 1
        They are kept every this many steps (and at the last).

    Returns
    -------
    int
        Bytes.
    """
    series = n_runs * (k_steps + 1) * 14 * 8
    rows = kept_rows(k_steps, stride).size if keep_trajectories else 0
    trajectories = 2 * n_runs * rows * m_uavs * 2 * 8
    return series + trajectories


def outcome_report(result: MissionResult) -> list[str]:
    """A few lines for the end of a batch: outcomes, median convergence time, worst final
    CRLB / bound, smallest clearance and separation, and a warning when a run did not
    converge.

    Parameters
    ----------
    result : MissionResult
        The batch.

    Returns
    -------
    list of str
        The lines (the last one starts with ``warning:`` if some runs did not end with the
        outcome ``converged``).
    """
    m, n = result.metrics, result.n_runs
    counts = result.outcome_counts
    conv = m["convergence_time_s"]
    median = f"{np.nanmedian(conv):.1f} s" if np.isfinite(conv).any() else "-"
    clearance = np.min(m["min_clearance_m"])
    lines = [
        "outcomes            "
        + ", ".join(f"{k} {counts[k]}/{n}" for k in OUTCOMES if k in counts),
        f"median convergence  {median}",
        f"worst CRLB/bound    {np.max(m['final_crlb_ratio']):.4g} (final)",
        "min clearance       "
        + (f"{clearance:.4g} m" if np.isfinite(clearance) else "- (no obstacles)"),
        f"min separation      {np.min(m['min_separation_m']):.4g} m "
        f"(safety.min_separation {result.scenario.safety.min_separation:g} m)",
    ]
    if "delivered_fraction" in m:
        lines.append(
            f"links               delivered {np.nanmean(m['delivered_fraction']):.3g} (mean), "
            f"age {np.nanmean(m['mean_age_s']):.3g} s (mean) {np.max(m['max_age_s']):.3g} s "
            f"(max), disconnected {np.max(m['disconnected_s']):.3g} s (worst)"
        )
    failed = n - counts.get("converged", 0)
    if failed:
        why = ", ".join(f"{k} {counts[k]}" for k in OUTCOMES if k != "converged" and k in counts)
        lines.append(
            f"warning: {failed} of {n} runs did not end converged ({why}); see metrics.csv"
        )
    return lines


@dataclass(frozen=True, eq=False)
class GroupMissionResult:
    """A batch of missions with several targets (:func:`crlbswarm.simulate_groups`).

    Each group is a :class:`MissionResult` of its own scenario (its UAVs, target, leader and
    formation; :attr:`crlbswarm.Scenario.group_plan`), with its own metrics and outcomes,
    except ``separation``: the smallest distance between any two UAVs of the whole swarm,
    so that a near miss between two groups counts as a collision in both.

    Attributes
    ----------
    scenario : Scenario
        The whole scenario.
    plan : GroupPlan
        The allocation of the UAVs to the targets, the groups and their scenarios.
    groups : tuple of MissionResult
        One result per group, in the order of the targets.
    """

    scenario: Scenario
    plan: GroupPlan
    groups: tuple[MissionResult, ...]

    @property
    def n_runs(self) -> int:
        """Number of runs B."""
        return self.groups[0].n_runs

    @property
    def positions(self) -> np.ndarray | None:
        """Every UAV's positions in the swarm's order, m, shape (B, K+1, M, 2), or None if
        the trajectories were not kept."""
        first = self.groups[0].positions
        if first is None:
            return None
        out = np.empty((first.shape[0], first.shape[1], self.scenario.uavs.count, 2))
        for members, group in zip(self.plan.members, self.groups, strict=True):
            out[:, :, members] = group.positions
        return out

    @property
    def metrics(self) -> dict[str, np.ndarray]:
        """Per-run metrics of every group, one row per run and group: the group's index and
        target, then the columns of each group's ``MissionResult.metrics``."""
        rows: dict[str, list[np.ndarray]] = {}
        for g, group in enumerate(self.groups):
            target = group.scenario.target
            head = {"group": np.full(self.n_runs, g), "target_x": np.full(self.n_runs, target[0]),
                    "target_y": np.full(self.n_runs, target[1])}  # fmt: skip
            for name, values in {**head, **group.metrics}.items():
                rows.setdefault(name, []).append(np.asarray(values))
        return {name: np.concatenate(parts) for name, parts in rows.items()}

    @property
    def outcome_counts(self) -> dict[str, int]:
        """How many (run, group) pairs ended in each outcome."""
        names, counts = np.unique(self.metrics["outcome"], return_counts=True)
        return {str(n): int(c) for n, c in zip(names, counts, strict=True)}

    def summary(self) -> dict[str, Any]:
        """The allocation and each group's :meth:`MissionResult.summary`, JSON-ready.

        Returns
        -------
        dict
            Scenario name, runs, the allocation (objective, whether exhaustive, each
            target's attainable CRLB), the outcome counts over runs and groups, and per
            group its target, UAVs, leader and summary.
        """
        allocation = self.plan.allocation
        return {
            "scenario": self.scenario.name,
            "runs": self.n_runs,
            "allocation": {
                "objective": allocation.objective,
                "exhaustive": allocation.exhaustive,
                "evaluated": allocation.evaluated,
                "crlb_m2": allocation.crlb.tolist(),
                "value_m2": allocation.value,
            },
            "outcomes": self.outcome_counts,
            "groups": [
                {
                    "target": list(group.scenario.target),
                    "uavs": members.tolist(),
                    "leader": int(leader),
                    **group.summary(),
                }
                for members, leader, group in zip(
                    self.plan.members, self.plan.leaders, self.groups, strict=True
                )
            ],
        }

    def save(self, folder: str | os.PathLike[str], *, overwrite: bool = False) -> list[Path]:
        """Write the result to a folder: each group's result in ``group<g>/`` (a folder
        :func:`load_results` reads), then ``metrics.csv`` (every group's rows),
        ``scenario.toml`` (the whole scenario) and ``summary.json`` (:meth:`summary`, last:
        its presence marks a complete set), staged as :meth:`MissionResult.save` does.

        Parameters
        ----------
        folder : str or path-like
            Output folder: missing or empty (created if missing).
        overwrite : bool, default False
            Accept a folder that already holds files, replacing those of the same names.

        Returns
        -------
        list of pathlib.Path
            The files and group folders written, ``summary.json`` last.
        """
        from . import __version__

        summary = self.summary()
        summary["crlbswarm_version"] = __version__
        names = [f"group{g}" for g in range(len(self.groups))]
        with staged_folder(folder, "folder", overwrite=overwrite, marker=RESULT_FILES[3]) as out:
            for name, group in zip(names, self.groups, strict=True):
                group.save(out / name)
            write_csv(out / RESULT_FILES[1], self.metrics)
            write_text(out / RESULT_FILES[2], self.scenario.to_toml())
            write_json(out / RESULT_FILES[3], summary)
        return [Path(folder) / name for name in (*names, *RESULT_FILES[1:])]


#: The array attributes of a result (everything but the scenario and the derived metrics).
_ARRAY_FIELDS = tuple(
    f.name for f in dataclasses.fields(MissionResult) if f.init and f.name != "scenario"
)


def load_results(folder: str | os.PathLike[str]) -> MissionResult:
    """Read a result written by :meth:`MissionResult.save` (``crlbswarm simulate``), or
    the saved trajectories of a campaign variant (``crlbswarm sweep`` with
    ``trajectories = true``).

    A campaign saves each task's result as a folder of the same form,
    ``trajectories/variant=<id>/part-<first>-<last>/``: give that folder (one task's runs)
    or the variant's folder ``trajectories/variant=<id>`` (the runs of all its finished
    tasks, in the order of their seeds; with estimation on, the PCRB of the whole is the
    mean of the parts' PCRBs weighted by their runs, which is exact only for parts of one
    task, as each part's PCRB comes from its runs' mean information).

    Parameters
    ----------
    folder : str or path-like
        The folder holding ``trajectories.npz`` and ``scenario.toml``, or a campaign
        variant's ``trajectories/variant=<id>`` folder.

    Returns
    -------
    MissionResult
        The result: the saved arrays, and the metrics recomputed from them (bit for bit
        those saved).

    Raises
    ------
    FieldError
        If the folder does not hold a complete result (naming the missing file), or holds
        a mission with several targets (each group's folder is a result), or a campaign
        (naming the folders to load instead).
    ScenarioError
        If its scenario file is not a valid scenario.
    """
    path = Path(folder)
    if not (path / RESULT_FILES[0]).is_file():
        _refuse_other_folders(path)
        parts = sorted(p for p in path.glob("part-*") if (p / RESULT_FILES[3]).is_file())
        if parts:
            return _concatenate([load_results(p) for p in parts], path)
    for name in RESULT_FILES:
        if not (path / name).is_file():
            raise FieldError("folder", f"{str(path)!r} holds no saved result ({name} missing)")
    scenario = load_scenario(path / "scenario.toml")
    npz = path / "trajectories.npz"
    try:
        with np.load(npz, allow_pickle=False) as data:
            arrays = {name: data.get(name) for name in _ARRAY_FIELDS}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise FieldError("folder", f"cannot read {str(npz)!r}: {exc}") from None
    stride = arrays["trajectory_stride"]
    arrays["trajectory_stride"] = 1 if stride is None else int(stride)
    _check_arrays(arrays, scenario, npz)
    arrays["bound"] = float(arrays["bound"])
    return MissionResult(scenario=scenario, **arrays)


def _refuse_other_folders(path: Path) -> None:
    """Name what to load instead when ``path`` holds a mission with several targets, a
    campaign, or a campaign's positions in the form of older versions."""
    where = str(path)
    if (path / "group0").is_dir():
        raise FieldError(
            "folder", f"{where!r} holds a mission with several targets: load each group's "
            f"folder ({str(path / 'group0')!r}, ...)",
        )  # fmt: skip
    if (path / "spec.json").is_file() and (path / "runs").is_dir():
        variants = sorted((path / "trajectories").glob("variant=*"))
        raise FieldError(
            "folder", f"{where!r} holds a campaign: load a variant's trajectories "
            f"({str(variants[0])!r}, ...)" if variants else f"{where!r} holds a campaign run "
            "without trajectories = true: its runs are metrics only (runs/*.parquet)",
        )  # fmt: skip
    if any(path.glob("part-*.npz")):
        raise FieldError(
            "folder", f"{where!r} holds a campaign's positions only (part-*.npz, written by "
            "an older crlbswarm), not results; run the campaign again to save them",
        )  # fmt: skip


def _concatenate(parts: list[MissionResult], path: Path) -> MissionResult:
    """The runs of several results of one scenario (a campaign variant's tasks), in order."""
    first = parts[0]
    for part in parts[1:]:
        if (
            part.scenario != first.scenario
            or part.trajectory_stride != first.trajectory_stride
            or (part.positions is None) != (first.positions is None)
        ):
            raise FieldError(
                "folder", f"{str(path)!r}: its parts hold different scenarios or arrays; load "
                "one part folder",
            )  # fmt: skip
    arrays: dict[str, Any] = {}
    for name in _ARRAY_FIELDS:
        values = [getattr(part, name) for part in parts]
        if name in ("time", "bound", "trajectory_stride", "bound_steps") or values[0] is None:
            arrays[name] = values[0]
        elif name == "pcrb":
            runs = np.array([part.n_runs for part in parts], dtype=float)
            arrays[name] = np.average(np.stack(values), axis=0, weights=runs)
        else:
            arrays[name] = np.concatenate(values)
    return MissionResult(scenario=first.scenario, **arrays)


def _check_arrays(arrays: dict[str, Any], scenario: Scenario, npz: Path) -> None:
    """The arrays a result of ``scenario`` must have, with their shapes (B runs); a bound
    finite and positive, a trajectory stride at least 1."""
    k1, m = scenario.time.steps + 1, scenario.uavs.count
    if arrays["trajectory_stride"] < 1:
        raise FieldError("folder", f"{str(npz)!r}: trajectory_stride is "
                         f"{arrays['trajectory_stride']}, expected at least 1")  # fmt: skip
    seeds = arrays["seeds"]
    b = -1 if seeds is None or seeds.ndim != 1 else seeds.shape[0]
    shapes = {
        "seeds": (b,), "time": (k1,), "centroid": (b, k1, 2), "reference_velocity": (b, k1, 2),
        "target": (b, k1, 2), "eta": (b, k1), "crlb": (b, k1), "cost": (b, k1 - 1),
        "clearance": (b, k1), "separation": (b, k1), "distance_to_go": (b, k1), "bound": (),
    }  # fmt: skip
    if arrays["positions"] is not None or arrays["velocities"] is not None:
        rows = kept_rows(k1 - 1, arrays["trajectory_stride"]).size
        shapes.update(positions=(b, rows, m, 2), velocities=(b, rows, m, 2))
    if scenario.estimation.enabled:
        shapes.update(estimate=(b, k1, 2), estimate_variance=(b, k1), pcrb=(k1,))
    if arrays["centroid_error"] is not None:  # (absent from results of older builds)
        shapes.update(centroid_error=(b, k1))
    if scenario.links is not None:
        shapes.update({f"link_{n}": (b, k1) for n in LINK_SERIES})
    if scenario.faults is not None:
        shapes.update(bound_steps=(k1,))
    for name, shape in shapes.items():
        value = arrays[name]
        if value is None or value.shape != shape:
            got = "missing" if value is None else f"shape {value.shape}"
            raise FieldError(
                "folder",
                f"{str(npz)!r}: array {name!r} is {got}, expected shape {shape} for its "
                f"scenario.toml ({m} UAVs, {k1 - 1} steps)",
            )
    bound = float(arrays["bound"])
    if not (np.isfinite(bound) and bound > 0.0):
        raise FieldError("folder", f"{str(npz)!r}: bound is {bound}, expected a finite CRLB > 0")
