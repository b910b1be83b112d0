r"""Moving targets: motion models, simulated target trajectories and the posterior CRLB.

Not in the paper, whose target is static. The target state is
:math:`\mathbf x = (x, y, v_x, v_y)` and moves by a linear Gauss-Markov model

.. math:: \mathbf x_{k+1} = \mathbf F \mathbf x_k + \mathbf G \mathbf a_k,
          \qquad \mathbf a_k \sim \mathcal N(0, \sigma_a^2 \mathbf I_2),
          \qquad \mathbf Q = \sigma_a^2 \mathbf G \mathbf G^\top ,

with piecewise-constant white acceleration :math:`\mathbf a_k`
(:math:`\mathbf G = [\tfrac{\Delta T^2}{2}\mathbf I_2;\ \Delta T\,\mathbf I_2]`) and
:math:`\mathbf F` the constant-velocity model or the coordinated turn of known rate
:math:`\omega` (Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley 2001, Sec. 6.3 and 11.7). A static target is the 2-state model
:math:`\mathbf F = \mathbf I_2`, :math:`\mathbf Q = 0`.

The posterior CRLB (PCRB) of Tichavsky, Muravchik and Nehorai (IEEE Trans. Signal Process.
46(5), 1998, eq. (21)) for this linear-Gaussian motion and the range measurements is the
recursion

.. math:: \mathbf J_{k+1} = (\mathbf Q + \mathbf F \mathbf J_k^{-1}\mathbf F^\top)^{-1}
          + E[\mathbf J_z(\mathbf x_{k+1})],
          \qquad \mathbf J_0 = \mathbf P_0^{-1} + E[\mathbf J_z(\mathbf x_0)],

where :math:`\mathbf J_z` is the FIM of one set of ranges (eq. (8) in the position block,
zero elsewhere), added at the steps where ranges are measured; the expectation over the
target's (and the UAVs') trajectories is taken as the average over the simulated runs. The
bound on the mean squared position error at step :math:`k` is the trace of the position
block of :math:`\mathbf J_k^{-1}`.

As computed by the simulator the PCRB is an approximation of the bound, for three reasons:
the expectation is a Monte Carlo average over the runs of the batch (a batch of one run
gives the bound along that single trajectory); the UAV trajectories depend on past
measurements (closed loop), whereas the bound treats them as given; and the scenarios start
the filter from a fixed prior mean (``prior_offset``) rather than one drawn from
:math:`\mathcal N(\mathbf x_0, \mathbf P_0)`, so the first steps are a reference rather
than a strict bound. In steady state the last two no longer matter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from . import _validation as _v
from .errors import FieldError
from .fisher import fisher_information
from .radar import Radar

__all__ = [
    "filter_work",
    "motion_matrices",
    "posterior_crlb",
    "predict",
    "predict_covariance",
    "predict_into",
    "summed_range_information",
    "target_trajectories",
    "update",
    "update_into",
]


#: The target motion models.
MOTION_MODELS = ("static", "constant_velocity", "turning")

#: Smallest turn per step of the turning model, rad: below, the model is a constant-velocity
#: one within rounding (and sin(w dt)/w underflows for absurdly small rates).
MIN_TURN = 1e-9


def motion_matrices(
    model: str, dt: float, turn_rate: float = 0.0, acceleration_noise: float = 0.0
) -> tuple[np.ndarray, np.ndarray, int]:
    r"""Transition and process-noise matrices of a target motion model.

    Parameters
    ----------
    model : {"static", "constant_velocity", "turning"}
        Motion model.
    dt : float
        Time step, s.
    turn_rate : float, default 0
        Rate of turn of the ``turning`` model, rad/s.
    acceleration_noise : float, default 0
        Standard deviation :math:`\sigma_a` of the white acceleration per axis, m/s^2.

    Returns
    -------
    F : ndarray, shape (4, 4)
        Transition matrix (top-left 2x2 identity for ``static``).
    Q : ndarray, shape (4, 4)
        Process-noise covariance.
    n_state : int
        2 for ``static`` (position only), 4 otherwise.

    Raises
    ------
    FieldError
        On an unknown model, or a time step, acceleration noise or turn rate outside the
        model's ranges (``dt`` in (0, 1e4] s, noise up to 1e4 m/s^2, a turn rate with
        ``|turn_rate| dt >= 1e-9`` and ``|turn_rate| <= 1e3`` rad/s).
    """
    if not isinstance(model, str) or model not in MOTION_MODELS:
        raise FieldError(
            "model", f"expected static, constant_velocity or turning, got {_v.short(model)}"
        )
    step = _v.scalar(dt, "dt")
    if not 0 < step <= _v.MAX_TIME_STEP:
        raise FieldError(
            "dt",
            f"must be > 0 and at most {_v.MAX_TIME_STEP:g} s (the model's range), got {step:g}",
        )
    sigma = _v.scalar(acceleration_noise, "acceleration_noise")
    if not 0 <= sigma <= _v.MAX_ACCELERATION:
        raise FieldError(
            "acceleration_noise",
            f"must be between 0 and {_v.MAX_ACCELERATION:g} m/s^2 (the model's range), "
            f"got {sigma:g}",
        )
    f = np.eye(4)
    q = np.zeros((4, 4))
    if model == "static":
        return f, q, 2
    if model == "constant_velocity":
        f[0, 2] = f[1, 3] = step
    else:  # turning
        w = _v.scalar(turn_rate, "turn_rate")
        if not (abs(w) * step >= MIN_TURN and abs(w) <= _v.MAX_TURN_RATE):
            raise FieldError(
                "turn_rate",
                f"the turning model needs a rate with {MIN_TURN:g} rad <= |turn_rate| dt and "
                f"|turn_rate| <= {_v.MAX_TURN_RATE:g} rad/s, got {w:g} (for no turn, use "
                "constant_velocity)",
            )
        s, c = math.sin(w * step), math.cos(w * step)
        f[:2, 2:] = [[s / w, -(1.0 - c) / w], [(1.0 - c) / w, s / w]]
        f[2:, 2:] = [[c, -s], [s, c]]
    g = _noise_gain(step)
    q = sigma**2 * (g @ g.T)
    return f, q, 4


def _noise_gain(dt: float) -> np.ndarray:
    """G of the piecewise-constant white acceleration: position dt^2/2, velocity dt."""
    return np.vstack([0.5 * dt * dt * np.eye(2), dt * np.eye(2)])


def target_trajectories(
    start_xy: np.ndarray,
    velocity: np.ndarray,
    model: str,
    dt: float,
    n_steps: int,
    rngs: list[np.random.Generator],
    turn_rate: float = 0.0,
    acceleration_noise: float = 0.0,
) -> np.ndarray:
    r"""True target states of a batch of runs, one random stream per run.

    Parameters
    ----------
    start_xy : ndarray, shape (2,)
        Initial position, m.
    velocity : ndarray, shape (2,)
        Initial velocity, m/s.
    model : {"static", "constant_velocity", "turning"}
        Motion model (:func:`motion_matrices`).
    dt : float
        Time step, s.
    n_steps : int
        Number of steps K.
    rngs : list of numpy.random.Generator
        One stream per run (the acceleration noise); unused if the noise is zero.
    turn_rate : float, default 0
        Rate of turn of ``turning``, rad/s.
    acceleration_noise : float, default 0
        :math:`\sigma_a`, m/s^2.

    Returns
    -------
    ndarray, shape (B, K+1, 4)
        Position and velocity of the target at every step.

    Raises
    ------
    FieldError
        As :func:`motion_matrices`; on a start beyond +-1e7 m or a velocity beyond
        +-1e6 m/s; or if the trajectories would not fit in memory (refused before
        allocating).
    """
    f, _, _ = motion_matrices(model, dt, turn_rate, acceleration_noise)
    step = _v.scalar(dt, "dt")
    sigma = _v.scalar(acceleration_noise, "acceleration_noise")
    g = _noise_gain(step)
    n_steps = _v.count(n_steps, "n_steps", 0)
    if model == "static" and sigma > 0:
        raise FieldError("acceleration_noise", "a static target takes no acceleration noise")
    if isinstance(rngs, np.random.Generator) or not isinstance(rngs, Sequence):
        raise FieldError("rngs", "expected a list of numpy.random.Generator, one per run")
    rngs = list(rngs)
    if not rngs:
        raise FieldError("rngs", "expected at least one numpy.random.Generator (one per run)")
    if sigma > 0 and not all(isinstance(r, np.random.Generator) for r in rngs):
        raise FieldError("rngs", "expected one numpy.random.Generator per run")
    start = _v.location(start_xy, "start_xy")
    vel = _v.velocity(velocity, "velocity")
    if start.shape != (2,):
        raise FieldError("start_xy", f"expected shape (2,), got {start.shape}")
    if vel.shape != (2,):
        raise FieldError("velocity", f"expected shape (2,), got {vel.shape}")
    size = float(len(rngs)) * (n_steps + 1) * 4
    _v.check_elements(size, "n_steps", f"{len(rngs)} runs of {n_steps + 1} steps", copies=2)
    out = np.empty((len(rngs), n_steps + 1, 4))
    out[:, 0, :2] = start
    out[:, 0, 2:] = vel if model != "static" else 0.0
    if sigma > 0 and model != "static":
        accel = np.stack([r.standard_normal((n_steps, 2)) for r in rngs]) * sigma
    else:
        accel = np.zeros((len(rngs), n_steps, 2))
    # One run at a time with scalar arithmetic in a fixed order, so a run's trajectory does
    # not depend on the batch it is simulated in (a batched matrix product would).
    _propagate(f, g, accel, out)
    return out


@njit(cache=True)
def _propagate(f, g, accel, out):
    for b in range(out.shape[0]):
        for k in range(accel.shape[1]):
            for r in range(4):
                acc = 0.0
                for c in range(4):
                    acc += f[r, c] * out[b, k, c]
                out[b, k + 1, r] = acc + g[r, 0] * accel[b, k, 0] + g[r, 1] * accel[b, k, 1]


def summed_range_information(
    uav_xy: np.ndarray, target_xy: np.ndarray, altitude: float, radar: Radar
) -> np.ndarray:
    r"""Sum over runs of the FIM of one set of ranges at every step (:func:`posterior_crlb`).

    Parameters
    ----------
    uav_xy : ndarray, shape (B, K+1, M, 2)
        UAV positions, m.
    target_xy : ndarray, shape (B, K+1, 2)
        True target positions, m.
    altitude : float
        Flight altitude, m.
    radar : Radar
        Link parameters.

    Returns
    -------
    ndarray, shape (K+1, 2, 2)
        :math:`\sum_b \mathbf J_s` over the B runs (divide by B for the mean).
    """
    q = _v.coordinates(uav_xy, "uav_xy")
    if q.ndim != 4:
        raise FieldError("uav_xy", f"expected shape (B, K+1, M, 2), got {q.shape}")
    s = _v.location(target_xy, "target_xy")
    if s.ndim != 3:
        raise FieldError("target_xy", f"expected shape (B, K+1, 2), got {s.shape}")
    h = _v.scalar(altitude, "altitude")
    return fisher_information(q, s, h, radar).sum(axis=0)


def posterior_crlb(
    mean_fim: np.ndarray,
    f: np.ndarray,
    q: np.ndarray,
    p0: np.ndarray,
    n_state: int,
    measure_every: int = 1,
) -> np.ndarray:
    r"""Posterior CRLB of the target position over time (Tichavsky et al. 1998).

    Parameters
    ----------
    mean_fim : ndarray, shape (K+1, 2, 2)
        :math:`E[\mathbf J_z]` at every step: the FIM of one set of ranges (eq. (8)),
        averaged over runs.
    f : ndarray, shape (4, 4)
        Transition matrix (:func:`motion_matrices`).
    q : ndarray, shape (4, 4)
        Process-noise covariance (:func:`motion_matrices`).
    p0 : ndarray, shape (4, 4)
        Prior covariance of the state.
    n_state : int
        2 (static target, position only) or 4.
    measure_every : int, default 1
        Ranges are measured at the steps that are multiples of this.

    Returns
    -------
    ndarray, shape (K+1,)
        Bound on the mean squared position error after each step's measurement, m^2.
    """
    fim = _v.as_float_array(mean_fim, "mean_fim")
    if fim.ndim != 3 or fim.shape[1:] != (2, 2) or fim.shape[0] == 0:
        raise FieldError("mean_fim", f"expected shape (K+1, 2, 2), got {fim.shape}")
    _v.bounded(fim, "mean_fim", -MAX_ENTRY, MAX_ENTRY, "")
    n = _v.count(n_state, "n_state", 2, 4)
    if n == 3:
        raise FieldError("n_state", f"must be 2 or 4, got {n}")
    every = _v.count(measure_every, "measure_every", 1)
    f, q, p0 = (_matrix(x, name, n) for x, name in ((f, "f"), (q, "q"), (p0, "p0")))
    steps = fim.shape[0]
    try:
        np.linalg.cholesky(p0[:n, :n])
    except np.linalg.LinAlgError as exc:
        raise FieldError("p0", "the prior covariance must be positive definite") from exc
    out = np.empty(steps)
    if not _pcrb(
        np.require(fim, np.float64, ("C", "W")),
        np.require(f, np.float64, ("C", "W")),
        np.require(q, np.float64, ("C", "W")),
        np.require(p0, np.float64, ("C", "W")),
        n,
        every,
        out,
    ):
        raise FieldError("q", "the predicted information Q + F J^-1 F^T is singular")
    return _v.finite_result(
        out, "p0", "the bound over- or underflows: f, q, p0 or mean_fim out of range"
    )


@njit(cache=True, error_model="numpy")
def _pcrb(fim, f, q, p0, n, every, out):
    """The recursion of :func:`posterior_crlb` (n x n blocks of the 4 x 4 ``f``, ``q``,
    ``p0``; the bound of step k into ``out[k]``), allocation-free inside the loop. False if
    a matrix to invert is exactly singular (as :func:`numpy.linalg.inv` refuses)."""
    info = np.empty((4, 4))
    cov = np.empty((4, 4))
    fc = np.empty((4, 4))
    lu = np.empty((4, 4))
    if not _inverse_into(p0, n, info, lu):
        return False
    for k in range(fim.shape[0]):
        if k > 0:
            # info = (Q + F info^-1 F^T)^-1, with cov = info^-1 from the step before
            predict_covariance(cov, f, q, n, fc)
            if not _inverse_into(cov, n, info, lu):
                return False
        if k % every == 0:
            for r in range(2):
                for c in range(2):
                    info[r, c] += fim[k, r, c]
        if not _inverse_into(info, n, cov, lu):
            return False
        out[k] = cov[0, 0] + cov[1, 1]
    return True


#: Largest magnitude of an entry of the matrices :func:`posterior_crlb` takes.
MAX_ENTRY = 1e100


def _matrix(value: object, name: str, n_state: int) -> np.ndarray:
    """A finite square matrix of size ``n_state`` or 4, with entries of magnitude at most
    :data:`MAX_ENTRY`."""
    arr = _v.as_float_array(value, name)
    if arr.shape not in ((4, 4), (n_state, n_state)):
        raise FieldError(name, f"expected shape (4, 4) or ({n_state}, {n_state}), got {arr.shape}")
    return _v.bounded(arr, name, -MAX_ENTRY, MAX_ENTRY, "")


# ---------------------------------------------------------------------------------------
# The filter: Kalman prediction and iterated-EKF range update, as compiled functions. The
# mission kernel calls the in-place forms (``predict_into``/``update_into``) with a work
# array allocated once per run, so the hot path allocates nothing; ``predict``/``update``
# return new arrays and leave their inputs alone.
# ---------------------------------------------------------------------------------------
#: Number of (4, 4) scratch matrices of :func:`filter_work`.
FILTER_WORK = 6


@njit(cache=True)
def filter_work():
    """Scratch space of :func:`predict_into` and :func:`update_into` (any state size up
    to 4): allocate once, reuse for every step."""
    return np.empty((FILTER_WORK, 4, 4))


@njit(cache=True)
def predict(x, P, F, Q):
    r"""Kalman prediction with the target's motion model.

    .. math:: \mathbf x^- = \mathbf F \mathbf x, \qquad
              \mathbf P^- = \mathbf F \mathbf P \mathbf F^\top + \mathbf Q

    Compiled; no input checks. Returns new arrays (:func:`predict_into` is the in-place,
    allocation-free form the mission kernel calls every step).

    Parameters
    ----------
    x : ndarray, shape (n,)
        State estimate (position, and velocity for a moving target).
    P : ndarray, shape (n, n)
        Its covariance.
    F : ndarray, shape (n, n)
        Transition matrix (:func:`motion_matrices`, top-left n x n block).
    Q : ndarray, shape (n, n)
        Process-noise covariance (same block).

    Returns
    -------
    x : ndarray, shape (n,)
        Predicted state.
    P : ndarray, shape (n, n)
        Predicted covariance.
    """
    x_new = x.copy()
    p_new = P.copy()
    predict_into(x_new, p_new, F, Q, filter_work())
    return x_new, p_new


@njit(cache=True)
def predict_into(x, P, F, Q, work):
    """:func:`predict` in place: ``x`` and ``P`` (shapes (n,) and (n, n), n <= 4) are
    overwritten by the prediction; ``work`` from :func:`filter_work`. Allocates nothing."""
    n = x.shape[0]
    x_new = work[0, 0]
    fp = work[1]
    for r in range(n):
        acc = 0.0
        for c in range(n):
            acc += F[r, c] * x[c]
        x_new[r] = acc
    predict_covariance(P, F, Q, n, fp)
    for r in range(n):
        x[r] = x_new[r]


@njit(cache=True)
def predict_covariance(P, F, Q, n, fp):
    r"""The covariance prediction of the motion model, in place on the n x n blocks:
    :math:`\mathbf P \leftarrow \mathbf F\mathbf P\mathbf F^\top + \mathbf Q`
    (``fp``: n x n scratch). The filter's :func:`predict` and the recursion of
    :func:`posterior_crlb` both call it. Allocates nothing."""
    for r in range(n):
        for c in range(n):
            acc = 0.0
            for j in range(n):
                acc += F[r, j] * P[j, c]
            fp[r, c] = acc
    for r in range(n):
        for c in range(n):
            acc = Q[r, c]
            for j in range(n):
                acc += fp[r, j] * F[c, j]
            P[r, c] = acc


@njit(cache=True)
def update(x, P, uav_xy, ranges, altitude, snr_constant, n_iter):
    r"""Iterated EKF update of the target estimate with one range from every UAV.

    Gauss-Newton on the MAP objective of the prior and the ranges of eq. (2), in
    information form; each range is weighted by :math:`1/\sigma_m^2 = A/d_m^4` at the
    current iterate (Bell and Cathey's iterated EKF):

    .. math:: \mathbf x_{i+1} = \mathbf x_i + (\mathbf P^{-1} + \mathbf H_i^\top
              \mathbf W_i \mathbf H_i)^{-1} \bigl[\mathbf H_i^\top \mathbf W_i
              (\hat{\mathbf d} - \mathbf d(\mathbf x_i)) - \mathbf P^{-1}(\mathbf x_i -
              \mathbf x)\bigr],

    with :math:`\mathbf H_i` the Jacobian of the ranges (horizontal line-of-sight unit
    vectors, eq. (4); zero in the velocity columns). The updated covariance is the inverse
    of the last information matrix. Compiled; no checks. Returns new arrays
    (:func:`update_into` is the in-place, allocation-free form the mission kernel calls).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Prior state (position first), m (and m/s).
    P : ndarray, shape (n, n)
        Prior covariance.
    uav_xy : ndarray, shape (M, 2)
        Horizontal UAV positions, m.
    ranges : ndarray, shape (M,)
        Measured ranges, m.
    altitude : float
        Flight altitude H, m (the target is on the ground).
    snr_constant : float
        :math:`A` of the radar (:attr:`crlbswarm.Radar.snr_constant`).
    n_iter : int
        Gauss-Newton iterations (the mission kernel uses
        :data:`crlbswarm.mission_kernel.FILTER_ITERATIONS`).

    Returns
    -------
    x : ndarray, shape (n,)
        Updated state.
    P : ndarray, shape (n, n)
        Updated covariance.
    """
    x_new = x.copy()
    p_new = P.copy()
    update_into(x_new, p_new, uav_xy, ranges, altitude, snr_constant, n_iter, filter_work())
    return x_new, p_new


@njit(cache=True)
def update_into(x, P, uav_xy, ranges, altitude, snr_constant, n_iter, work):
    """:func:`update` in place: ``x`` and ``P`` (shapes (n,) and (n, n), n <= 4) are
    overwritten by the updated state and covariance; ``work`` from :func:`filter_work`.
    Allocates nothing."""
    n = x.shape[0]
    info0 = work[0]
    info = work[1]
    lu = work[2]  # the elimination's matrix
    xi = work[3, 0]
    rhs = work[3, 1]
    step = work[3, 2]
    _inverse_into(P, n, info0, lu)
    for r in range(n):
        xi[r] = x[r]
    h2 = altitude * altitude
    for _ in range(n_iter):
        for r in range(n):
            for c in range(n):
                info[r, c] = info0[r, c]
        # - P^-1 (x_i - x_prior)
        for r in range(n):
            acc = 0.0
            for c in range(n):
                acc -= info0[r, c] * (xi[c] - x[c])
            rhs[r] = acc
        for m in range(uav_xy.shape[0]):
            dx = xi[0] - uav_xy[m, 0]
            dy = xi[1] - uav_xy[m, 1]
            d2 = dx * dx + dy * dy + h2
            d = math.sqrt(d2)
            w = snr_constant / (d2 * d2)  # 1 / sigma^2 at the iterate
            hx = dx / d
            hy = dy / d
            res = ranges[m] - d
            info[0, 0] += w * hx * hx
            info[0, 1] += w * hx * hy
            info[1, 0] += w * hx * hy
            info[1, 1] += w * hy * hy
            rhs[0] += w * hx * res
            rhs[1] += w * hy * res
        _solve_into(info, rhs, n, lu, step)
        for r in range(n):
            xi[r] += step[r]
    for r in range(n):
        x[r] = xi[r]
    _inverse_into(info, n, P, lu)


@njit(cache=True)
def _eliminate(a, rhs, n, cols, m):
    """Solve the n x n system ``a X = rhs`` (n <= 4) for the first ``cols`` columns of
    ``rhs`` in place, by Gaussian elimination with partial pivoting (``m``: scratch of at
    least n x n; ``a`` is left alone). The same operations on every column, so one column
    solved alone has the bits of the same column solved with others. Returns False, the
    columns unfinished, if a pivot is exactly zero."""
    for r in range(n):
        for c in range(n):
            m[r, c] = a[r, c]
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if piv != c:
            for j in range(n):
                m[c, j], m[piv, j] = m[piv, j], m[c, j]
            for j in range(cols):
                rhs[c, j], rhs[piv, j] = rhs[piv, j], rhs[c, j]
        if m[c, c] == 0.0:  # exactly singular: no inverse (as numpy.linalg.inv refuses)
            return False
        for r in range(c + 1, n):
            f = m[r, c] / m[c, c]
            for j in range(c, n):
                m[r, j] -= f * m[c, j]
            for j in range(cols):
                rhs[r, j] -= f * rhs[c, j]
    for j in range(cols):
        for c in range(n - 1, -1, -1):
            acc = rhs[c, j]
            for i in range(c + 1, n):
                acc -= m[c, i] * rhs[i, j]
            rhs[c, j] = acc / m[c, c]
    return True


@njit(cache=True)
def _solve_into(a, b, n, m, x):
    """Solve the n x n system a x = b (n <= 4) into ``x`` (:func:`_eliminate`; ``m``:
    scratch of at least n x n; ``a`` and ``b`` are left alone)."""
    for r in range(n):
        x[r] = b[r]
    _eliminate(a, x[:n].reshape((n, 1)), n, 1, m)


@njit(cache=True)
def _inverse_into(a, n, out, m):
    """Inverse of the n x n matrix a (n <= 4) into ``out`` (which must not share memory
    with ``a``): :func:`_eliminate` on the n unit vectors (``m`` is scratch). Returns False
    if a pivot is exactly zero."""
    for r in range(n):
        for c in range(n):
            out[r, c] = 1.0 if r == c else 0.0
    return _eliminate(a, out, n, n, m)
