r"""Mission simulator: the distributed controller of Sec. IV, run for a batch of seeds.

:func:`simulate` runs a :class:`~crlbswarm.scenario.Scenario` from its start to the end of its
duration for one seed or a batch of seeds at once. Per step :math:`k` (all UAVs in parallel,
each using only its neighbours' information, except two formation-wide quantities: the
scaling factor :math:`\eta_k`, global in the paper too, and the formation centroid that
the leader uses to steer the formation off obstacles, a crlbswarm addition):

0. with sensing in the loop (``estimation.enabled``), every ``measure_every`` steps the UAVs
   measure their ranges to the (possibly moving) target and an iterated EKF fuses them; the
   formation's goal is then the estimate instead of the true target (not in the paper);
1. the leader computes its reference velocity :math:`\mathbf v^*_k` toward its slot of
   :math:`F^*` over the target (:func:`crlbswarm.leader_guidance`), with the target's
   (estimated) velocity as feedforward;
2. each UAV computes its formation input and obstacle repulsion, eqs. (18)-(19);
3. every UAV moves by the motion model of eq. (3),
   :math:`\mathbf q_{m,k+1} = \mathbf q_{m,k} + \mathbf u_{m,k} + \mathbf v_{m,k}\Delta T +
   \mathbf n_{m,k}`, with :math:`\mathbf g_{m,k} = \mathbf v_{m,k}` from the consensus (the
   leader's is :math:`\mathbf v^*_k`);
4. the followers update their velocity estimates by the corrected consensus, eq. (14);
5. :math:`\eta` steps toward :func:`crlbswarm.eta_target` at a limited rate;
6. the filter predicts the target state with its motion model
   (:func:`crlbswarm.tracking.motion_matrices`).

The compiled kernel loops over runs (in parallel threads) and steps; each run uses only its
own random streams, so run :math:`b` of a batch is bit-identical to the single run with the
same seed. Random numbers: for seed :math:`s`, ``SeedSequence(s).spawn(4)`` gives the streams
of the start positions, the motion disturbance, the range noise and the target's
acceleration noise, in that order (spawning more children leaves the first ones unchanged,
so the streams of a scenario without estimation are the same as before it existed).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

from . import _validation as _v
from .control import (
    _clearance_point,
    _consensus,
    _cost,
    _eta_goal,
    _formation,
    _reference,
    _repulsion_point,
)
from .design import crlb_bound
from .errors import FieldError
from .fisher import crlb
from .scenario import Scenario
from .tracking import (
    motion_matrices,
    posterior_crlb,
    summed_range_information,
    target_trajectories,
)

__all__ = ["MissionResult", "SimulationDivergedError", "simulate", "start_positions"]

#: Positions beyond this distance from the origin (m) count as a diverged run.
DIVERGENCE_LIMIT = 1.0e6

#: Convergence: CRLB within this factor of the bound and centroid within CENTROID_TOL.
CRLB_TOL = 0.01
CENTROID_TOL = 0.5

#: Length of the "steady state" window at the end of a mission (estimation metrics), s.
STEADY_STATE_S = 30.0

#: Largest number of runs simulated per chunk.
CHUNK_RUNS = 256

#: Memory budget of the per-chunk work buffers (pre-drawn disturbance), bytes.
CHUNK_BYTES = 64 * 2**20

#: Largest seed (seeds are stored as int64).
MAX_SEED = 2**63 - 1

#: Fraction of the machine's memory that the kept trajectories may take.
MEMORY_FRACTION = 0.5


class SimulationDivergedError(RuntimeError):
    """A run produced NaN or runaway positions; the message names the seed and the step."""


# ---------------------------------------------------------------------------------------
# Kernel
# ---------------------------------------------------------------------------------------
#: Up to this many UAVs the smallest separation is found by checking every pair.
SEPARATION_BRUTE_FORCE_MAX = 64


@njit(cache=True)
def _min_separation(q):
    """Smallest distance between two UAVs: all pairs for small swarms, a uniform grid (cell
    list, O(M) for a spread-out swarm) for large ones; exact in both cases."""
    n = q.shape[0]
    if n < 2:
        return math.inf
    if n <= SEPARATION_BRUTE_FORCE_MAX:
        best = math.inf
        for m in range(n):
            for p in range(m + 1, n):
                dx = q[m, 0] - q[p, 0]
                dy = q[m, 1] - q[p, 1]
                best = min(best, dx * dx + dy * dy)
        return math.sqrt(best)
    x0, x1 = q[:, 0].min(), q[:, 0].max()
    y0, y1 = q[:, 1].min(), q[:, 1].max()
    # Cells of about one UAV each; a pair closer than the cell size is always found in the
    # same or a neighbouring cell. If no pair is that close, grow the cells and try again.
    cell = max(math.sqrt(max((x1 - x0) * (y1 - y0), 1e-12) / n), 1e-9)
    while True:
        nx = min(int((x1 - x0) / cell) + 1, 4 * n)
        ny = min(int((y1 - y0) / cell) + 1, 4 * n)
        cell = max(cell, (x1 - x0) / nx * (1 + 1e-12), (y1 - y0) / ny * (1 + 1e-12))
        # Counting sort of the UAVs by cell: start[k] .. start[k + 1] index ``order``.
        key = np.empty(n, dtype=np.int64)
        start = np.zeros(nx * ny + 1, dtype=np.int64)
        for m in range(n):
            cx = min(int((q[m, 0] - x0) / cell), nx - 1)
            cy = min(int((q[m, 1] - y0) / cell), ny - 1)
            key[m] = cx * ny + cy
            start[key[m] + 1] += 1
        for k in range(nx * ny):
            start[k + 1] += start[k]
        fill = start[:-1].copy()
        order = np.empty(n, dtype=np.int64)
        for m in range(n):
            order[fill[key[m]]] = m
            fill[key[m]] += 1
        best = cell * cell
        found = False
        for m in range(n):
            cx, cy = key[m] // ny, key[m] % ny
            for ax in range(max(cx - 1, 0), min(cx + 2, nx)):
                for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
                    k = ax * ny + ay
                    for j in range(start[k], start[k + 1]):
                        p = order[j]
                        if p > m:
                            dx = q[m, 0] - q[p, 0]
                            dy = q[m, 1] - q[p, 1]
                            d2 = dx * dx + dy * dy
                            if d2 < best:
                                best = d2
                                found = True
        if found:
            return math.sqrt(best)
        cell *= 2.0


class Gains(NamedTuple):
    """Scalars of the mission kernel (a typed tuple for Numba; see the scenario fields)."""

    dt: float
    eps: float
    gamma: float
    kg: float
    vc: float
    l_safe: float
    e_r: float
    u_max: float
    eta_on: bool
    eta_min: float
    eta_rate: float
    lookahead: float
    n_samples: int
    margin: float
    radius: float
    steer: bool
    leader: int
    estimate: bool
    n_state: int
    every: int
    snr_constant: float
    altitude: float


@njit(cache=True)
def _solve_small(a, b, n):
    """Solve the n x n system a x = b (n <= 4) by Gaussian elimination with pivoting."""
    m = a[:n, :n].copy()
    x = b[:n].copy()
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if piv != c:
            for j in range(n):
                m[c, j], m[piv, j] = m[piv, j], m[c, j]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, n):
            f = m[r, c] / m[c, c]
            for j in range(c, n):
                m[r, j] -= f * m[c, j]
            x[r] -= f * x[c]
    for c in range(n - 1, -1, -1):
        acc = x[c]
        for j in range(c + 1, n):
            acc -= m[c, j] * x[j]
        x[c] = acc / m[c, c]
    return x


@njit(cache=True)
def _inverse_small(a, n):
    out = np.zeros((4, 4))
    e = np.zeros(4)
    for j in range(n):
        e[:] = 0.0
        e[j] = 1.0
        col = _solve_small(a, e, n)
        for i in range(n):
            out[i, j] = col[i]
    return out


@njit(cache=True)
def _iekf_update(x, p_cov, q, ranges, g, n_iter):
    """Iterated EKF update with all M ranges, in information form (Gauss-Newton on the MAP
    objective, each range weighted by 1/sigma^2 = A/d^4 at the current iterate). Updates x
    and p_cov in place."""
    n = g.n_state
    info0 = _inverse_small(p_cov, n)
    prior = x.copy()
    xi = x.copy()
    info = np.zeros((4, 4))
    h2 = g.altitude * g.altitude
    for _ in range(n_iter):
        info[:, :] = info0
        rhs = np.zeros(4)
        # - P^-1 (x_i - x_prior)
        for r in range(n):
            for c in range(n):
                rhs[r] -= info0[r, c] * (xi[c] - prior[c])
        for m in range(q.shape[0]):
            dx = xi[0] - q[m, 0]
            dy = xi[1] - q[m, 1]
            d2 = dx * dx + dy * dy + h2
            d = math.sqrt(d2)
            w = g.snr_constant / (d2 * d2)  # 1 / sigma^2 at the iterate
            hx = dx / d
            hy = dy / d
            res = ranges[m] - d
            info[0, 0] += w * hx * hx
            info[0, 1] += w * hx * hy
            info[1, 0] += w * hx * hy
            info[1, 1] += w * hy * hy
            rhs[0] += w * hx * res
            rhs[1] += w * hy * res
        step = _solve_small(info, rhs, n)
        for r in range(n):
            xi[r] += step[r]
    cov = _inverse_small(info, n)
    for r in range(n):
        x[r] = xi[r]
        for c in range(n):
            p_cov[r, c] = cov[r, c]


@njit(cache=True)
def _mission(
    q_out, v_out, vref_out, eta_out, clear_out, sep_out, cost_out, est_out, est_var_out,
    noise, range_noise, s_true, v_true, delta, indptr, indices, rects, circles,
    f_mat, q_mat, x0, p0, g,
):  # fmt: skip
    """One run. ``q_out[0]`` holds the start; returns -1 or the step that diverged."""
    k_steps = noise.shape[0]
    m_uavs = q_out.shape[1]
    leader, dt, n = g.leader, g.dt, g.n_state
    u = np.empty((m_uavs, 2))
    vref = np.empty(2)
    ranges = np.empty(m_uavs)
    x = x0.copy()
    p_cov = p0.copy()
    x_new = np.empty(4)  # prediction work arrays, reused every step
    fp = np.empty((4, 4))
    eta_step = g.eta_rate * dt
    h2 = g.altitude * g.altitude
    for k in range(k_steps + 1):
        q = q_out[k]
        eta = eta_out[k]
        # The formation's goal: the UAVs' own estimate of the target, or the truth.
        if g.estimate:
            if k % g.every == 0:
                for m in range(m_uavs):
                    dx = s_true[k, 0] - q[m, 0]
                    dy = s_true[k, 1] - q[m, 1]
                    d2 = dx * dx + dy * dy + h2
                    ranges[m] = math.sqrt(d2) + d2 / math.sqrt(g.snr_constant) * range_noise[k, m]
                _iekf_update(x, p_cov, q, ranges, g, 3)
            sx, sy = x[0], x[1]
            tvx, tvy = (x[2], x[3]) if n == 4 else (0.0, 0.0)
            est_out[k, 0] = sx
            est_out[k, 1] = sy
            est_var_out[k] = p_cov[0, 0] + p_cov[1, 1]
        else:
            sx, sy = s_true[k, 0], s_true[k, 1]
            tvx, tvy = v_true[k, 0], v_true[k, 1]
        gx = sx + eta * delta[leader, 0]
        gy = sy + eta * delta[leader, 1]
        cx = 0.0
        cy = 0.0
        for m in range(m_uavs):
            cx += q[m, 0]
            cy += q[m, 1]
        cx /= m_uavs
        cy /= m_uavs
        vref[0], vref[1] = _reference(
            q[leader, 0], q[leader, 1], gx, gy, cx, cy, g.kg, g.vc, tvx, tvy,
            rects, circles, g.e_r, g.l_safe, eta * g.radius if g.steer else 0.0, dt,
        )  # fmt: skip
        vref_out[k, 0] = vref[0]
        vref_out[k, 1] = vref[1]
        v_out[k, leader, 0] = vref[0]
        v_out[k, leader, 1] = vref[1]
        clearance = math.inf
        for m in range(m_uavs):
            clearance = min(clearance, _clearance_point(q[m, 0], q[m, 1], rects, circles))
        clear_out[k] = clearance
        sep_out[k] = _min_separation(q)
        if k == k_steps:
            break
        # Eqs. (18)-(19) and the motion model, eq. (3).
        _formation(q, delta, eta, g.eps, indptr, indices, u)
        v = v_out[k]
        q_next = q_out[k + 1]
        for m in range(m_uavs):
            rx, ry = _repulsion_point(q[m, 0], q[m, 1], rects, circles, g.e_r, g.l_safe, g.u_max)
            q_next[m, 0] = q[m, 0] + u[m, 0] + rx + v[m, 0] * dt + noise[k, m, 0]
            q_next[m, 1] = q[m, 1] + u[m, 1] + ry + v[m, 1] * dt + noise[k, m, 1]
            if not (abs(q_next[m, 0]) < DIVERGENCE_LIMIT and abs(q_next[m, 1]) < DIVERGENCE_LIMIT):
                return k + 1
        cost_out[k] = _cost(q, q_next, delta, vref, dt, indptr, indices)
        # Corrected consensus, eq. (14).
        _consensus(v, vref, leader, indptr, indices, g.gamma, v_out[k + 1])
        # Scaling factor: rate-limited step toward the free-width rule.
        if g.eta_on:
            goal = _eta_goal(
                cx, cy, sx, sy, g.radius, rects, circles,
                g.margin, g.lookahead, g.n_samples, g.eta_min,
            )  # fmt: skip
            eta_out[k + 1] = eta + min(eta_step, max(-eta_step, goal - eta))
        else:
            eta_out[k + 1] = 1.0
        # Prediction of the target estimate with the target's motion model.
        if g.estimate:
            x_new[:] = 0.0
            for r in range(n):
                for c in range(n):
                    x_new[r] += f_mat[r, c] * x[c]
            fp[:, :] = 0.0
            for r in range(n):
                for c in range(n):
                    for j in range(n):
                        fp[r, c] += f_mat[r, j] * p_cov[j, c]
            for r in range(n):
                x[r] = x_new[r]
                for c in range(n):
                    acc = q_mat[r, c]
                    for j in range(n):
                        acc += fp[r, j] * f_mat[c, j]
                    p_cov[r, c] = acc
    return -1


@njit(cache=True, parallel=True)
def _mission_batch(
    q_out, v_out, vref_out, eta_out, clear_out, sep_out, cost_out, est_out, est_var_out,
    status, noise, range_noise, s_true, v_true, delta, indptr, indices, rects, circles,
    f_mat, q_mat, x0, p0, g,
):  # fmt: skip
    for b in prange(q_out.shape[0]):
        status[b] = _mission(
            q_out[b], v_out[b], vref_out[b], eta_out[b], clear_out[b], sep_out[b],
            cost_out[b], est_out[b], est_var_out[b], noise[b],
            range_noise[b], s_true[b],
            v_true[b], delta, indptr, indices, rects, circles, f_mat, q_mat, x0[b], p0, g,
        )  # fmt: skip


# ---------------------------------------------------------------------------------------
# Result
# ---------------------------------------------------------------------------------------
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
    positions : ndarray, shape (B, K+1, M, 2), or None
        UAV positions, m (``None`` if ``keep_trajectories=False``).
    velocities : ndarray, shape (B, K+1, M, 2), or None
        Consensus velocities :math:`\\mathbf v_{m,k}` (the leader's is :math:`\\mathbf v^*_k`),
        m/s (``None`` if ``keep_trajectories=False``).
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
    bound : float
        Theoretical bound :math:`4/\\sum_m w_m^*`, eq. (11), m^2.
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
    bound: float
    metrics: dict[str, np.ndarray] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "metrics", self._metrics())

    @property
    def n_runs(self) -> int:
        """Number of runs B."""
        return int(self.seeds.shape[0])

    @property
    def centroid_error(self) -> np.ndarray:
        """Distance from the formation centroid to the (true) target, m, shape (B, K+1)."""
        offset = self.centroid - self.target
        return np.hypot(offset[..., 0], offset[..., 1])

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
        ratio = self.crlb / self.bound
        centroid = self.centroid_error
        ok = (ratio <= 1.0 + CRLB_TOL) & (centroid <= CENTROID_TOL)
        # Converged from step k on: every later step is ok (reverse cumulative AND).
        settled = np.flip(np.logical_and.accumulate(np.flip(ok, axis=1), axis=1), axis=1)
        first = np.argmax(settled, axis=1)
        conv = np.where(settled[:, -1], self.time[first], np.nan)
        return {
            "seed": self.seeds,
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
        }

    def _estimation_metrics(self) -> dict[str, np.ndarray]:
        error = self.estimation_error
        if error is None:
            return {}
        # A contiguous suffix, so each run's reduction does not depend on the batch.
        k0 = int(np.argmax(self.steady_state))
        tail_error = np.ascontiguousarray(error[:, k0:])
        tail_std = np.sqrt(np.ascontiguousarray(self.estimate_variance[:, k0:]))
        return {
            "final_estimation_error_m": error[:, -1],
            "steady_rms_estimation_error_m": np.sqrt(np.mean(tail_error**2, axis=1)),
            "steady_max_error_over_sqrt_crlb": np.max(
                tail_error / np.sqrt(self.crlb[:, k0:]), axis=1
            ),
            "steady_max_error_over_filter_std": np.max(tail_error / tail_std, axis=1),
        }

    @property
    def steady_rmse_over_sqrt_pcrb(self) -> float | None:
        """Batch figure of tracking efficiency: the RMS over runs of the estimation error,
        divided by the square root of the PCRB, averaged over the steady-state steps (1 for
        an efficient tracker). ``None`` without estimation."""
        error = self.estimation_error
        if error is None:
            return None
        tail = self.steady_state
        rmse = np.sqrt(np.mean(error[:, tail] ** 2, axis=0))
        return float(np.mean(rmse / np.sqrt(self.pcrb[tail])))

    def _run_index(self, run: int) -> int:
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
        b = self._run_index(run)
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
        for m in range(self.positions.shape[2]):
            cols[f"x_uav{m + 1}"] = self.positions[b, :, m, 0]
            cols[f"y_uav{m + 1}"] = self.positions[b, :, m, 1]
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
        b = self._run_index(run)
        return {
            "time_s": self.time,
            "crlb_m2": self.crlb[b],
            "bound_m2": np.full(self.time.shape, self.bound),
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

    def summary(self) -> dict[str, Any]:
        """Aggregate figures over the runs, JSON-ready.

        Returns
        -------
        dict
            Scenario name, number of runs, steps, the bound, and for each metric its min,
            mean and max over the runs (NaN-aware for the convergence time, with the number
            of runs that converged).
        """
        out: dict[str, Any] = {
            "scenario": self.scenario.name,
            "runs": self.n_runs,
            "steps": int(self.time.shape[0] - 1),
            "duration_s": float(self.time[-1]),
            "bound_m2": float(self.bound),
            "converged_runs": int(np.sum(np.isfinite(self.metrics["convergence_time_s"]))),
        }
        if self.estimate is not None:
            out["steady_rmse_over_sqrt_pcrb"] = self.steady_rmse_over_sqrt_pcrb
        for name, values in self.metrics.items():
            if name == "seed":
                continue
            finite = values[np.isfinite(values)]
            out[name] = {
                "min": float(finite.min()) if finite.size else None,
                "mean": float(finite.mean()) if finite.size else None,
                "max": float(finite.max()) if finite.size else None,
            }
        return out


# ---------------------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------------------
def _streams(seed: int, count: int = 2) -> list[np.random.Generator]:
    """The run's independent streams: start, disturbance, ranges, target motion (in that
    order; spawning more children leaves the first ones unchanged)."""
    return [np.random.default_rng(ss) for ss in np.random.SeedSequence(seed).spawn(count)]


def _start(scenario: Scenario, rng: np.random.Generator) -> np.ndarray:
    if scenario.uavs.start is not None:
        return np.array(scenario.uavs.start, dtype=float)
    (x0, x1), (y0, y1) = scenario.uavs.start_region
    return rng.uniform((x0, y0), (x1, y1), size=(scenario.uavs.count, 2))


def start_positions(scenario: Scenario, seed: int) -> np.ndarray:
    """Start positions of the run with ``seed``: explicit, or uniform in the start region.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    seed : int
        Seed of the run.

    Returns
    -------
    ndarray, shape (M, 2)
        Start positions, m.
    """
    return _start(scenario, _streams(seed)[0])


def _seed_list(seed: int | None, seeds: Iterable[int] | None) -> np.ndarray:
    if seed is not None and seeds is not None:
        raise FieldError("seeds", "give either seed or seeds, not both")
    values = [0 if seed is None else seed] if seeds is None else list(seeds)
    if not values:
        raise FieldError("seeds", "need at least one seed")
    name = "seeds" if seeds is not None else "seed"
    for s in values:
        _v.count(s, name, 0)
        if s > MAX_SEED:
            raise FieldError(name, f"must be at most 2**63 - 1, got {s}")
    return np.array(values, dtype=np.int64)


def _physical_memory() -> int | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # pragma: no cover - not POSIX
        return None


def _check_memory(n_runs: int, k_steps: int, m_uavs: int, keep: bool) -> None:
    """Refuse, naming the cause, a batch whose arrays could not fit in memory."""
    series = n_runs * (k_steps + 1) * 14 * 8  # eta, crlb, cost, target, estimate, ... per step
    trajectories = 2 * n_runs * (k_steps + 1) * m_uavs * 2 * 8 if keep else 0
    total = series + trajectories
    limit = _physical_memory()
    if limit is not None and total > MEMORY_FRACTION * limit:
        hint = "keep_trajectories=False (--no-trajectories) or fewer" if keep else "fewer"
        raise FieldError(
            "seeds",
            f"{n_runs} runs of {k_steps} steps need about {total / 2**30:.1f} GiB, more "
            f"than half of this machine's {limit / 2**30:.0f} GiB; use {hint} runs per call",
        )


def simulate(
    scenario: Scenario,
    seed: int | None = None,
    *,
    seeds: Iterable[int] | None = None,
    keep_trajectories: bool = True,
    progress: Callable[[int], None] | None = None,
) -> MissionResult:
    """Run the mission of ``scenario`` for one seed or a batch of seeds.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario (see :func:`crlbswarm.load_scenario`).
    seed : int, optional
        Seed of a single run (default 0).
    seeds : iterable of int, optional
        Seeds of a batch of independent runs (instead of ``seed``). Run ``b`` is
        bit-identical to ``simulate(scenario, seed=seeds[b])``.
    keep_trajectories : bool, default True
        Keep positions and velocities of every step. With ``False`` they are dropped after
        each chunk of runs (``positions`` and ``velocities`` of the result are ``None``) and
        memory stays at a few arrays of shape (B, K+1): use it for large campaigns.
    progress : callable, optional
        Called with the number of runs finished after each chunk of runs (for progress bars).

    Returns
    -------
    MissionResult
        Trajectories, time series and per-run metrics.

    Raises
    ------
    SimulationDivergedError
        If a run produces NaN or positions beyond :data:`DIVERGENCE_LIMIT`, naming the run,
        its seed and the step.
    """
    if not isinstance(scenario, Scenario):
        raise FieldError(
            "scenario", f"expected a crlbswarm.Scenario, got {type(scenario).__name__}"
        )
    seed_arr = _seed_list(seed, seeds)
    sc = scenario
    n_runs, k_steps, m_uavs = seed_arr.shape[0], sc.time.steps, sc.uavs.count
    target = np.asarray(sc.target, dtype=float)
    delta = np.ascontiguousarray(sc.formation - target)
    radius = float(np.max(np.hypot(delta[:, 0], delta[:, 1])))
    adj, obstacles, ctl, eta = sc.adjacency, sc.obstacle_set, sc.control, sc.eta
    est, motion = sc.estimation, sc.target_motion
    radar = sc.radar.to_radar()
    f_mat, q_mat, n_state = motion_matrices(
        motion.model, sc.time.step, motion.turn_rate, motion.acceleration_noise
    )
    p0 = np.diag([est.prior_std**2] * 2 + [est.velocity_prior_std**2] * 2)
    gains = Gains(
        dt=sc.time.step,
        eps=ctl.epsilon,
        gamma=ctl.gamma,
        kg=ctl.guidance_gain,
        vc=ctl.cruise_speed,
        l_safe=ctl.safety_radius,
        e_r=ctl.repulsion_gain,
        u_max=ctl.repulsion_max_step,
        eta_on=eta.enabled,
        eta_min=eta.minimum,
        eta_rate=eta.rate,
        lookahead=eta.lookahead,
        n_samples=eta.samples,
        margin=ctl.safety_radius if eta.margin is None else eta.margin,
        radius=radius,
        steer=ctl.formation_steering,
        leader=sc.uavs.leader,
        estimate=est.enabled,
        n_state=n_state,
        every=est.measure_every,
        snr_constant=float(radar.snr_constant),
        altitude=sc.altitude,
    )

    traj_shape = (n_runs, k_steps + 1, m_uavs, 2)
    _check_memory(n_runs, k_steps, m_uavs, keep_trajectories)
    positions = np.empty(traj_shape) if keep_trajectories else None
    velocities = np.empty(traj_shape) if keep_trajectories else None
    series = np.empty((n_runs, k_steps + 1))
    centroid, vref, target_xy = (np.empty((n_runs, k_steps + 1, 2)) for _ in range(3))
    crlb_arr, eta_arr, clearance, separation = (np.empty_like(series) for _ in range(4))
    estimate = np.full((n_runs, k_steps + 1, 2), np.nan) if est.enabled else None
    estimate_var = np.full((n_runs, k_steps + 1), np.nan) if est.enabled else None
    fim_sum = np.zeros((k_steps + 1, 2, 2))
    cost = np.empty((n_runs, k_steps))
    status = np.empty(n_runs, dtype=np.int64)

    # Chunks: at most CHUNK_RUNS runs or CHUNK_BYTES of disturbance, and at least ~20 chunks
    # for long batches so that progress is reported often. Work buffers are reused across
    # chunks (page faults of fresh arrays cost as much as the work).
    per_run = k_steps * m_uavs * 2 * 8
    chunk_runs = max(1, min(CHUNK_RUNS, CHUNK_BYTES // per_run, -(-n_runs // 20), n_runs))
    noise_buf = np.empty((chunk_runs, k_steps, m_uavs, 2))
    range_buf = np.zeros((chunk_runs, k_steps + 1, m_uavs))  # stays zero without estimation
    est_buf = np.zeros((chunk_runs, k_steps + 1, 2))
    est_var_buf = np.zeros((chunk_runs, k_steps + 1))
    if not keep_trajectories:
        pos_buf = np.empty((chunk_runs, *traj_shape[1:]))
        vel_buf = np.empty_like(pos_buf)
    for lo in range(0, n_runs, chunk_runs):
        hi = min(lo + chunk_runs, n_runs)
        pos = positions[lo:hi] if keep_trajectories else pos_buf[: hi - lo]
        vel = velocities[lo:hi] if keep_trajectories else vel_buf[: hi - lo]
        noise = noise_buf[: hi - lo]
        range_noise = range_buf[: hi - lo]
        motion_rngs = []
        for i, s in enumerate(seed_arr[lo:hi]):
            start_rng, noise_rng, range_rng, motion_rng = _streams(int(s), 4)
            pos[i, 0] = _start(sc, start_rng)
            noise_rng.standard_normal(out=noise[i])
            if est.enabled:
                range_rng.standard_normal(out=range_noise[i])
            motion_rngs.append(motion_rng)
        noise *= sc.disturbance.sigma
        truth = target_trajectories(
            target, np.asarray(motion.velocity, dtype=float), motion.model, sc.time.step,
            k_steps, motion_rngs, motion.turn_rate, motion.acceleration_noise,
        )  # fmt: skip
        x0 = np.zeros((hi - lo, 4))
        x0[:, :2] = truth[:, 0, :2] + np.asarray(est.prior_offset)
        vel[:, 0] = 0.0
        eta_arr[lo:hi, 0] = 1.0
        _mission_batch(
            pos, vel, vref[lo:hi], eta_arr[lo:hi], clearance[lo:hi], separation[lo:hi],
            cost[lo:hi], est_buf[: hi - lo], est_var_buf[: hi - lo], status[lo:hi], noise,
            range_noise, np.ascontiguousarray(truth[..., :2]),
            np.ascontiguousarray(truth[..., 2:]), delta, adj.indptr, adj.indices,
            obstacles.rectangles, obstacles.circles, f_mat, q_mat, x0, p0, gains,
        )  # fmt: skip
        bad = np.flatnonzero(status[lo:hi] >= 0)
        if bad.size:
            b = lo + int(bad[0])
            raise SimulationDivergedError(
                f"run {b} (seed {seed_arr[b]}) diverged at step {status[b]} "
                f"(t = {status[b] * sc.time.step:g} s): NaN or positions beyond "
                f"{DIVERGENCE_LIMIT:g} m; check the gains and the disturbance of the scenario"
            )
        target_xy[lo:hi] = truth[..., :2]
        crlb_arr[lo:hi] = crlb(pos, target_xy[lo:hi], sc.altitude, radar)
        centroid[lo:hi] = pos.mean(axis=-2)
        if est.enabled:
            estimate[lo:hi] = est_buf[: hi - lo]
            estimate_var[lo:hi] = est_var_buf[: hi - lo]
            fim_sum += summed_range_information(pos, target_xy[lo:hi], sc.altitude, radar)
        if progress is not None:
            progress(hi)

    pcrb = None
    if est.enabled:
        pcrb = posterior_crlb(fim_sum / n_runs, f_mat, q_mat, p0, n_state, est.measure_every)
    return MissionResult(
        scenario=sc,
        seeds=seed_arr,
        time=np.arange(k_steps + 1) * sc.time.step,
        positions=positions,
        velocities=velocities,
        reference_velocity=vref,
        centroid=centroid,
        target=target_xy,
        estimate=estimate,
        estimate_variance=estimate_var,
        pcrb=pcrb,
        eta=eta_arr,
        crlb=crlb_arr,
        cost=cost,
        clearance=clearance,
        separation=separation,
        bound=float(crlb_bound(m_uavs, sc.altitude, radar)),
    )
