r"""Estimating the target from the ranges: measurements, a closed-form initialiser and the MLE.

The paper stops at the CRLB and assumes "a prior coarse estimate" of the target. This module
(not in the paper) draws range measurements from the model of Sec. II and estimates the
target position by maximum likelihood, so that the bound can be checked against an
estimator that reaches it.

Model (eq. (2) with the variance of Sec. II): :math:`\hat d_m = d_m(\mathbf s) + z_m`,
:math:`z_m \sim \mathcal N(0, \sigma_m^2)`, :math:`\sigma_m^2 = d_m^4 / A_m`, independent over
UAVs. The negative log-likelihood, up to a constant, is

.. math::

    \ell(\mathbf s) = \sum_m \Bigl[2\ln d_m(\mathbf s)
        + \frac{A_m\,(\hat d_m - d_m(\mathbf s))^2}{2\,d_m(\mathbf s)^4}\Bigr].

Both the mean and the variance depend on :math:`\mathbf s`, which is why the FIM of eq. (6)
has the extra term :math:`8/d_m^2`.

:func:`estimate_target` first runs a weighted least-squares fit of the ranges with frozen
weights (which cannot drift away: see its docstring), then minimises :math:`\ell` by a
Levenberg-Marquardt-damped Newton method: the step solves
:math:`(\nabla^2\ell + \mu\,\tfrac12\operatorname{tr}(\mathbf J_s)\,\mathbf I)\Delta =
-\nabla\ell` with the exact Hessian, and is accepted only if it
lowers :math:`\ell` (otherwise :math:`\mu` grows tenfold, which turns the step into a short
gradient step; an accepted step divides :math:`\mu` by ten). The damping is scaled by the
FIM of eq. (8) so that it is dimensionally right at every altitude. Near the optimum the
steps are Newton steps, so convergence is quadratic; the converged point is a local minimum
of the exact negative log-likelihood (checked: positive definite Hessian), the MLE within
its basin. At high SNR the basin of the start is that of the global maximum of the
likelihood; at low SNR a few trials can end in another local minimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, vectorize
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError
from .geometry import check_scene, target_offsets
from .radar import Radar, check_radar

__all__ = [
    "TargetEstimate",
    "damped_newton",
    "estimate_target",
    "linearised_estimate",
    "measure_ranges",
    "negative_log_likelihood",
    "noisy_range",
]

_DEFAULT_RADAR = Radar()

#: Largest ``max_iter`` of :func:`estimate_target`.
MAX_ITERATIONS = 1_000_000


def _ranges_array(measured_ranges: ArrayLike, n_uavs: int) -> np.ndarray:
    d = _v.as_float_array(measured_ranges, "measured_ranges")
    if d.ndim < 1 or d.shape[-1] != n_uavs:
        raise FieldError(
            "measured_ranges", f"expected shape (..., {n_uavs}) to match uav_xy, got {d.shape}"
        )
    lim = _v.MAX_MEASURED_RANGE
    return _v.bounded(d, "measured_ranges", -lim, lim, " m")


def _check_uavs(uav_xy: ArrayLike, altitude: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``check_scene`` without a target: the UAV positions and the altitude, checked."""
    q = _v.coordinates(uav_xy, "uav_xy")
    h = _v.altitude(altitude, "altitude")
    batch = _v.broadcast("altitude", q.shape[:-2], h.shape)
    n = float(np.prod(batch, dtype=float)) * q.shape[-2]
    _v.check_elements(n, "uav_xy", f"{n:.3g} UAV-target pairs", copies=8)
    return q, h


@vectorize(cache=True)
def noisy_range(d2, a, z):
    r"""One noisy range of eq. (2) from its squared distance: :math:`\hat d = d + \sigma z`
    with :math:`\sigma = d^2/\sqrt A` (the variance :math:`d^4/A` of Sec. II).

    The range model written once: a NumPy ufunc (broadcasting) used by
    :func:`measure_ranges`, and a compiled scalar function in the mission kernel.

    Parameters
    ----------
    d2 : float or array_like
        Squared slant range :math:`d^2`, m^2.
    a : float or array_like
        :math:`A` of the radar (:attr:`crlbswarm.Radar.snr_constant`).
    z : float or array_like
        Standard normal draw.

    Returns
    -------
    float or ndarray
        The measured range, m.
    """
    return math.sqrt(d2) + d2 / math.sqrt(a) * z


def measure_ranges(
    uav_xy: ArrayLike,
    target_xy: ArrayLike,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    r"""Noisy range measurements :math:`\hat d_m = d_m + z_m`, eq. (2).

    :math:`z_m \sim \mathcal N(0, d_m^4/A_m)` independently for every UAV and every batch
    element.

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        True target position, m.
    altitude : float or array_like, shape (...)
        Flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters (paper profile by default).
    rng : numpy.random.Generator
        Source of the noise (required: every random draw is seeded by the caller).

    Returns
    -------
    ndarray, shape (..., M)
        Measured ranges, m (may be negative with vanishing probability at very low SNR).

    Raises
    ------
    FieldError
        As :func:`crlbswarm.fisher_information` (shapes, the model's ranges), or if ``rng``
        is not a :class:`numpy.random.Generator`.
    """
    if not isinstance(rng, np.random.Generator):
        raise FieldError("rng", f"expected a numpy.random.Generator, got {type(rng).__name__}")
    q, s, h = check_scene(uav_xy, target_xy, altitude)
    a = check_radar(radar, q.shape[-2])
    diff = target_offsets(q, s)
    d2 = np.sum(diff * diff, axis=-1) + (h * h)[..., None]
    return np.asarray(noisy_range(d2, a, rng.standard_normal(d2.shape)))


def negative_log_likelihood(
    target_xy: ArrayLike,
    uav_xy: ArrayLike,
    measured_ranges: ArrayLike,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
) -> np.ndarray:
    r"""Negative log-likelihood :math:`\ell(\mathbf s)` of the ranges, up to a constant.

    .. math:: \ell(\mathbf s) = \sum_m \Bigl[2\ln d_m + \frac{A_m(\hat d_m - d_m)^2}
              {2 d_m^4}\Bigr]

    Parameters
    ----------
    target_xy : array_like, shape (..., 2)
        Candidate target position :math:`\mathbf s`, m.
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    measured_ranges : array_like, shape (..., M)
        Measured ranges :math:`\hat d_m`, m.
    altitude : float or array_like, shape (...)
        Flight altitude, m.
    radar : Radar, optional
        Link parameters.

    Returns
    -------
    ndarray, shape (...)
        :math:`\ell(\mathbf s)` (dimensionless up to the dropped constant).
    """
    q, s, h = check_scene(uav_xy, target_xy, altitude)
    a = check_radar(radar, q.shape[-2])
    d_hat = _ranges_array(measured_ranges, q.shape[-2])
    diff = target_offsets(q, s)
    d2 = np.sum(diff * diff, axis=-1) + (h * h)[..., None]
    r = d_hat - np.sqrt(d2)
    return np.sum(np.log(d2) + a * r * r / (2.0 * d2 * d2), axis=-1)


def linearised_estimate(
    uav_xy: ArrayLike, measured_ranges: ArrayLike, altitude: ArrayLike
) -> np.ndarray:
    r"""Closed-form linear least-squares estimate: an initialiser that needs no prior.

    Squaring the ranges, :math:`\hat d_m^2 - \lVert\mathbf q_m\rVert^2 - H^2 \approx
    -2\mathbf q_m^\top \mathbf s + R` with :math:`R = \lVert\mathbf s\rVert^2` treated as a
    third unknown: a linear system in :math:`(s_x, s_y, R)` solved by least squares for every
    batch element (positions are first centred on the UAVs' mean for conditioning).

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m (M >= 3, not all collinear).
    measured_ranges : array_like, shape (..., M)
        Measured ranges, m.
    altitude : float or array_like, shape (...)
        Flight altitude, m.

    Returns
    -------
    ndarray, shape (..., 2)
        Estimate, m. Where the system is singular (collinear UAVs) the UAVs' centroid is
        returned; the result is never NaN.
    """
    q, h = _check_uavs(uav_xy, altitude)
    if q.shape[-2] < 3:
        raise FieldError(
            "uav_xy", f"the linearised estimate needs at least 3 UAVs, got {q.shape[-2]}"
        )
    d_hat = _ranges_array(measured_ranges, q.shape[-2])
    return _linearised(q, d_hat, h)


def _linearised(q: np.ndarray, d_hat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """:func:`linearised_estimate` of checked arrays: broadcast to one batch, then
    :func:`_linearised_batch` trial by trial."""
    m_uavs = q.shape[-2]
    batch = _v.broadcast("measured_ranges", q.shape[:-2], d_hat.shape[:-1], h.shape)
    out = np.empty((*batch, 2))
    _linearised_batch(
        _batch_array(q, batch, (m_uavs, 2)),
        _batch_array(d_hat, batch, (m_uavs,)),
        _batch_array(h * h, batch),
        out.reshape(-1, 2),
    )
    return out


def _batch_array(x: ArrayLike, batch: tuple[int, ...], tail: tuple[int, ...] = ()) -> np.ndarray:
    """``x`` broadcast to ``batch + tail`` with the batch axes flattened into one, as a
    C-contiguous writable float64 array (the one array type the compiled loops take)."""
    shape = (*batch, *tail)
    if isinstance(x, np.ndarray) and x.shape == shape:
        arr = x.reshape(-1, *tail)
    elif np.ndim(x) == 0:
        return np.full((math.prod(batch), *tail), x, dtype=np.float64)
    else:
        arr = np.broadcast_to(x, shape).reshape(-1, *tail)
    if arr.dtype == np.float64 and arr.flags.c_contiguous and arr.flags.writeable:
        return arr
    return np.array(arr, dtype=np.float64, order="C")


@njit(cache=True, error_model="numpy")
def _linearised_batch(q, d_hat, h2, out):
    """The closed-form start of :func:`linearised_estimate`, one trial after the other
    (:func:`_linearised_trial`)."""
    work = np.empty((5, 3))
    for i in range(q.shape[0]):
        _linearised_trial(q[i], d_hat[i], h2[i], out[i], work)


@njit(cache=True, error_model="numpy")
def _linearised_trial(q, d_hat, h2, out, work):
    """One trial of :func:`linearised_estimate` into ``out`` (shape (2,)): the normal
    equations of the linear system in (s_x, s_y, R) on coordinates centred on the UAVs'
    mean, solved by Gaussian elimination with partial pivoting; the centroid where the
    system is singular (``|det| <= 1e-12 tr^3``) or anything is not finite. ``work``: (5, 3)
    scratch."""
    normal, moment, row = work[0:3], work[3], work[4]
    m_uavs = q.shape[0]
    cx = q[0, 0]
    cy = q[0, 1]
    for m in range(1, m_uavs):
        cx += q[m, 0]
        cy += q[m, 1]
    cx /= m_uavs
    cy /= m_uavs
    for r in range(3):
        moment[r] = 0.0
        for c in range(3):
            normal[r, c] = 0.0
    for m in range(m_uavs):
        x = q[m, 0] - cx
        y = q[m, 1] - cy
        row[0] = -2.0 * x
        row[1] = -2.0 * y
        row[2] = 1.0
        rhs = d_hat[m] * d_hat[m] - (x * x + y * y) - h2
        for r in range(3):
            moment[r] += row[r] * rhs
            for c in range(3):
                normal[r, c] += row[r] * row[c]
    scale = (normal[0, 0] + normal[1, 1] + normal[2, 2]) ** 3
    ok = True
    for r in range(3):
        ok = ok and math.isfinite(moment[r])
    det = 1.0
    if ok:
        for c in range(3):  # elimination with partial pivoting, on normal and moment
            piv = c
            for r in range(c + 1, 3):
                if abs(normal[r, c]) > abs(normal[piv, c]):
                    piv = r
            if piv != c:
                det = -det
                for j in range(3):
                    normal[c, j], normal[piv, j] = normal[piv, j], normal[c, j]
                moment[c], moment[piv] = moment[piv], moment[c]
            det *= normal[c, c]
            if normal[c, c] == 0.0:
                break
            for r in range(c + 1, 3):
                f = normal[r, c] / normal[c, c]
                for j in range(c, 3):
                    normal[r, j] -= f * normal[c, j]
                moment[r] -= f * moment[c]
        ok = abs(det) > 1e-12 * scale
    sx = 0.0
    sy = 0.0
    if ok:
        for c in range(2, -1, -1):
            acc = moment[c]
            for j in range(c + 1, 3):
                acc -= normal[c, j] * moment[j]
            moment[c] = acc / normal[c, c]
        if math.isfinite(moment[0]) and math.isfinite(moment[1]) and math.isfinite(moment[2]):
            sx = moment[0]
            sy = moment[1]
    out[0] = cx + sx
    out[1] = cy + sy


@dataclass(frozen=True, eq=False, init=False)
class TargetEstimate:
    """Result of :func:`estimate_target` for a batch of trials.

    Attributes
    ----------
    position : ndarray, shape (..., 2)
        Estimated target position, m. Never NaN: a failed trial keeps its last iterate.
    converged : ndarray of bool, shape (...)
        Whether the trial met the tolerance within ``max_iter`` iterations at a minimum of
        the negative log-likelihood (positive definite Hessian).
    iterations : ndarray of int, shape (...)
        Iterations used.
    nll : ndarray, shape (...)
        Negative log-likelihood at ``position``.
    """

    position: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    nll: np.ndarray

    def __init__(
        self,
        position: np.ndarray,
        converged: np.ndarray,
        iterations: np.ndarray,
        nll: np.ndarray,
    ) -> None:
        # The fields of a frozen dataclass, set once through the instance dict: half the
        # time of the generated __init__ (four object.__setattr__), which a batch of one
        # trial feels.
        fields = self.__dict__
        fields["position"] = position
        fields["converged"] = converged
        fields["iterations"] = iterations
        fields["nll"] = nll

    @property
    def failed(self) -> np.ndarray:
        """Trials that did not converge (report them; their position is not the MLE)."""
        return ~self.converged


def damped_newton(exact, s, q, d_hat, h2, a, w, n_iter, tolerance):
    r"""Levenberg-Marquardt-damped Newton minimisation, for every row of ``s``, of the
    weighted least squares of the ranges with frozen weights ``w`` (stage 1, ``exact``
    False) or of the exact negative log-likelihood (stage 2, True; module docstring), with
    k = 2 unknowns (the target's horizontal position, its height known: ``h2`` = H^2) or
    3 (its 3-D position: ``h2`` = 0): the rules of :func:`estimate_target`. Compiled, one
    trial after the other, so a trial's result does not depend on its batch.

    Parameters
    ----------
    exact : bool
        False: stage 1 (frozen weights, Gauss-Newton curvature); True: stage 2 (the exact
        likelihood and its exact Hessian).
    s : ndarray, shape (n, k)
        Starting points, m (updated in place and returned).
    q : ndarray, shape (n, M, k)
        UAV coordinates, m.
    d_hat : ndarray, shape (n, M)
        Measured ranges, m.
    h2 : ndarray, shape (n, 1), or float
        Known squared offset of every squared distance, m^2.
    a : ndarray or float
        :math:`A_m` (per trial and UAV, or one value).
    w : ndarray, shape (n, M)
        Frozen weights of stage 1, :math:`A_m/\hat d_m^4`.
    n_iter : int
        Largest number of iterations.
    tolerance : float
        Convergence when the nearly undamped step is below ``tolerance`` times (1 m + the
        distance from the UAVs' centroid).

    Returns
    -------
    s, cost, converged, iterations, positive_definite : ndarray
        ``s`` is updated only by steps that lower the cost, so it stays finite;
        ``positive_definite`` tells whether the curvature at the final ``s`` is positive
        definite (a minimum, not a maximum or saddle).
    """
    return _compiled_newton(bool(exact), s, q, d_hat, h2, a, w, n_iter, tolerance)


def _compiled_newton(exact, s, q, d_hat, h2, a, w, n_iter, tolerance):
    """:func:`damped_newton` (stage 1 if ``exact`` is False, else stage 2) by the compiled
    :func:`_newton_batch`; the arguments are brought to one array
    type (C-contiguous, writable float64) so that a single specialisation is compiled."""
    n, k = s.shape
    m_uavs = q.shape[1]
    s_out = _batch_array(s, (n,), (k,))
    cost = np.empty(n)
    converged = np.empty(n, dtype=np.bool_)
    iterations = np.empty(n, dtype=np.int64)
    definite = np.empty(n, dtype=np.bool_)
    h2_b = _batch_array(np.reshape(h2, (-1,)) if np.ndim(h2) else h2, (n,))
    _newton_batch(exact, s_out, _batch_array(q, (n,), (m_uavs, k)),
                  _batch_array(d_hat, (n,), (m_uavs,)), h2_b, _batch_array(a, (n,), (m_uavs,)),
                  _batch_array(w, (n,), (m_uavs,)), int(n_iter), float(tolerance), cost,
                  converged, iterations, definite)  # fmt: skip
    if s_out is not s:
        s[...] = s_out
    return s, cost, converged, iterations, definite


@njit(cache=True)
def _newton_work():
    """Scratch of :func:`_newton_trial`: six 3-vectors and three 3x3 matrices."""
    return np.zeros((15, 3))


@njit(cache=True, error_model="numpy")
def _newton_batch(exact, s, q, d_hat, h2, a, w, n_iter, tolerance, cost_out, conv_out, it_out,
                  pd_out):  # fmt: skip
    """The damped Newton of :func:`damped_newton`, one trial after the other; results into
    ``s`` (in place) and the ``*_out`` arrays. Scratch is allocated once per batch."""
    work = _newton_work()
    for i in range(s.shape[0]):
        cost_out[i], conv_out[i], it_out[i], pd_out[i] = _newton_trial(
            exact, s[i], q[i], d_hat[i], h2[i], a[i], w[i], n_iter, tolerance, work
        )


@njit(cache=True, error_model="numpy")
def _mle_batch(q, d_hat, h, a, s, start, n_iter, tolerance, nll_out, conv_out, it_out):
    r"""Both stages of :func:`estimate_target` for every trial, one after the other: the
    closed-form start (unless ``start`` is False: ``s`` holds the starts), stage 1
    (weighted least squares with the frozen weights of :func:`_stage1_weights`; loose
    tolerance), stage 2 (the exact likelihood). ``q``, the altitudes ``h`` and ``a`` have one
    row per trial or a single row. Results into ``s`` (in place) and the ``*_out`` arrays;
    returns whether every position and likelihood is finite. Both paths of
    :func:`estimate_target` run this function, so they give the same bits."""
    m_uavs = d_hat.shape[1]
    scratch = np.zeros((20 + (m_uavs + 2) // 3, 3))  # one allocation (small batches feel each)
    work, lin, w = scratch[:15], scratch[15:20], scratch[20:].reshape(-1)[:m_uavs]
    loose = max(tolerance, 1e-6)  # stage 1 only has to land in the basin of the MLE
    finite = True
    for i in range(s.shape[0]):
        qi = q[i if q.shape[0] > 1 else 0]
        hi = h[i if h.shape[0] > 1 else 0]
        ai = a[i if a.shape[0] > 1 else 0]
        di, si = d_hat[i], s[i]
        h2 = _stage1_weights(di, hi, ai, w)
        if start:
            _linearised_trial(qi, di, h2, si, lin)
        _, _, it1, _ = _newton_trial(False, si, qi, di, h2, ai, w, n_iter, loose, work)
        nll, converged, it2, minimum = _newton_trial(
            True, si, qi, di, h2, ai, w, n_iter, tolerance, work
        )
        nll_out[i] = nll
        # A zero gradient at a maximum or a saddle (for example by symmetry) is not the MLE.
        conv_out[i] = converged and minimum
        it_out[i] = it1 + it2
        finite = finite and math.isfinite(nll) and math.isfinite(si[0]) and math.isfinite(si[1])
    return finite


@njit(cache=True, error_model="numpy", inline="always")
def _stage1_weights(d_hat, h, a, w):
    r"""The frozen weights of stage 1 of one trial into ``w``: :math:`w_m = A_m/p_m^4` with
    :math:`p_m = \max(|\hat d_m|, H)` (a range measured near zero, at an absurd SNR, gets a
    finite weight), the fourth power computed as ``(p * p) * (p * p)``; returns
    :math:`H^2`. (Until the weights were computed here, NumPy's power gave :math:`p^4`: its
    vectorised pow, whose last bits these products do not always reproduce, so estimates
    may differ from those of earlier versions in the last bits.)"""
    h2 = h * h
    floor = math.sqrt(h2)
    for m in range(d_hat.shape[0]):
        p = max(abs(d_hat[m]), floor)
        p2 = p * p
        w[m] = a[m] / (p2 * p2)
    return h2


@njit(cache=True, error_model="numpy")
def _newton_trial(exact, s, q, d_hat, h2, a, w, n_iter, tolerance, work):
    """One trial of :func:`damped_newton` (``s`` updated in place); returns ``(cost,
    converged, iterations, positive definite)``. ``work``: :func:`_newton_work`."""
    k = s.shape[0]
    grad, t_grad, trial, step, centroid, u = work[0], work[1], work[2], work[3], work[4], work[5]
    hess, t_hess, damped = work[6:9], work[9:12], work[12:15]
    m_uavs = q.shape[0]
    for j in range(k):  # fixed: the convergence scale needs it every iteration
        acc = q[0, j]
        for m in range(1, m_uavs):
            acc += q[m, j]
        centroid[j] = acc / m_uavs
    cost, htr = _terms(exact, s, q, d_hat, h2, a, w, grad, hess, u, k)
    mu = 1e-3
    converged = False
    iterations = 0
    for _ in range(n_iter):
        iterations += 1
        # Damped Newton step: (Hess + mu tr/k I) delta = -grad, in closed form.
        lam = mu * htr / k
        for r in range(k):
            for c in range(k):
                damped[r, c] = hess[r, c] + lam * (1.0 if r == c else 0.0)
        descent = _solve_definite(damped, grad, step, k)
        for j in range(k):
            step[j] = -step[j]
            trial[j] = s[j] + step[j]
        t_cost, t_tr = _terms(exact, trial, q, d_hat, h2, a, w, t_grad, t_hess, u, k)
        # Accept a step that lowers the cost (see damped_newton); where the change of the
        # cost is at the level of its rounding error, a smaller gradient decides instead.
        rounding = 1e-12 * (abs(cost) + 1.0)
        flat = abs(t_cost - cost) <= rounding
        smaller_grad = _norm(t_grad, k) < _norm(grad, k)
        better = (
            descent
            and math.isfinite(t_cost)
            and ((t_cost < cost - rounding) or (flat and smaller_grad))
        )
        near_newton = mu <= 1e-2
        if better:
            for r in range(k):
                s[r] = trial[r]
                grad[r] = t_grad[r]
                for c in range(k):
                    hess[r, c] = t_hess[r, c]
            cost, htr = t_cost, t_tr
            mu = max(mu / 10.0, 1e-12)
        else:
            mu = mu * 10.0
        acc = 0.0
        for j in range(k):
            acc += (s[j] - centroid[j]) ** 2
        scale = 1.0 + math.sqrt(acc)
        # Converged when the nearly undamped Newton step is negligible, accepted or not.
        if _norm(step, k) <= tolerance * scale and near_newton:
            converged = True
            break
        if mu > 1e12:  # hopeless damping: give up, report failed
            break
    return cost, converged, iterations, _solve_definite(hess, grad, step, k)


@njit(cache=True, error_model="numpy", inline="always")
def _norm(x, k):
    acc = 0.0
    for j in range(k):
        acc += x[j] * x[j]
    return math.sqrt(acc)


@njit(cache=True, error_model="numpy")
def _terms(exact, s, q, d_hat, h2, a, w, grad, hess, u, k):
    """One trial's cost, gradient, Hessian and trace: the exact negative log-likelihood
    (``exact``; module docstring) or stage 1's weighted least squares, in scalar form, for
    the first ``k`` coordinates of ``s``, sums over the UAVs in order (``u``: scratch)."""
    for r in range(k):
        grad[r] = 0.0
        for c in range(k):
            hess[r, c] = 0.0
    cost = 0.0
    extra = 0.0  # sum of the terms l'_m / d_m (nll) added to the diagonal
    trace = 0.0
    for m in range(q.shape[0]):
        d2 = 0.0
        for j in range(k):
            u[j] = s[j] - q[m, j]  # s - q_m, so that d d_m / d s = diff / d_m
            d2 += u[j] * u[j]
        d2 += h2
        d = math.sqrt(d2)
        r = d_hat[m] - d
        uu = 0.0
        for j in range(k):
            u[j] = u[j] / d
            uu += u[j] * u[j]
        if exact:
            am = a[m]
            inv_d4 = 1.0 / (d2 * d2)
            cost += math.log(d2) + 0.5 * am * r * r * inv_d4
            # d nll / d d_m = 2/d - A r / d^4 - 2 A r^2 / d^5
            dl_dd = 2.0 / d - am * r * inv_d4 - 2.0 * am * r * r * inv_d4 / d
            # d^2 nll / d d_m^2 = -2/d^2 + A/d^4 + 8 A r/d^5 + 10 A r^2/d^6
            d2l_dd2 = -2.0 / d2 + am * inv_d4 * (1.0 + 8.0 * r / d + 10.0 * r * r / d2)
            # Hessian: sum_m l''_m u u^T + l'_m (I - u u^T) / d_m
            c_m = dl_dd / d
            g_m = d2l_dd2 - c_m
            for i in range(k):
                grad[i] += dl_dd * u[i]
                for j in range(k):
                    hess[i, j] += g_m * u[i] * u[j]
            extra += c_m
            trace += (am * inv_d4 + 8.0 / d2) * uu  # tr J of eq. (8)
        else:
            wm = w[m]
            cost += wm * r * r
            for i in range(k):
                grad[i] -= wm * r * u[i]
                for j in range(k):
                    hess[i, j] += wm * u[i] * u[j]
    if exact:
        for i in range(k):
            hess[i, i] += extra
        return cost, trace
    for i in range(k):
        trace += hess[i, i]
    return 0.5 * cost, trace


@njit(cache=True, error_model="numpy")
def _solve_definite(h, g, x, k):
    """``h^-1 g`` of one symmetric k x k matrix (k = 2 or 3) into ``x``, in closed form
    (cofactors; Sylvester's criterion for definiteness); returns whether ``h`` is positive
    definite."""
    if k == 2:
        a00, a11, a01 = h[0, 0], h[1, 1], h[0, 1]
        det = a00 * a11 - a01 * a01
        g0, g1 = g[0], g[1]
        x[0] = (a11 * g0 - a01 * g1) / det
        x[1] = (a00 * g1 - a01 * g0) / det
        definite = det > 0 and a00 > 0
    else:
        a00, a11, a22 = h[0, 0], h[1, 1], h[2, 2]
        a01, a02, a12 = h[0, 1], h[0, 2], h[1, 2]
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        det = a00 * c00 + a01 * c01 + a02 * c02
        g0, g1, g2 = g[0], g[1], g[2]
        x[0] = (c00 * g0 + c01 * g1 + c02 * g2) / det
        x[1] = (c01 * g0 + c11 * g1 + c12 * g2) / det
        x[2] = (c02 * g0 + c12 * g1 + c22 * g2) / det
        definite = a00 > 0 and c22 > 0 and det > 0
    for j in range(k):
        if not math.isfinite(x[j]):
            x[j] = 0.0
    return definite


def estimate_target(
    uav_xy: ArrayLike,
    measured_ranges: ArrayLike,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    init: ArrayLike | None = None,
    *,
    max_iter: int = 100,
    tol: float = 1e-10,
) -> TargetEstimate:
    r"""Maximum-likelihood estimate of the target from the ranges, for a batch of trials.

    Two stages, each a Levenberg-Marquardt-damped Newton iteration with its own damping per
    trial, compiled and run one trial after the other (a trial's result does not depend on
    the batch it is in):

    1. weighted least squares on the range residuals with the weights frozen at
       :math:`A_m/\hat d_m^4` (Gauss-Newton curvature), from ``init``. Its cost grows with
       distance, so it cannot slide into the spurious far-away basin of the exact
       likelihood (far from the UAVs the modelled variance :math:`d^4/A` is so large that it
       "explains" any range). The weights are computed in the compiled loop as
       :math:`A_m/((p_m p_m)(p_m p_m))` with :math:`p_m = \max(|\hat d_m|, H)`, the range
       floored at the altitude (earlier builds took :math:`p_m^4` from NumPy's power,
       whose last bits often differ, so a few trials' estimates differ from theirs in the
       last bits);
    2. the exact likelihood (module docstring) with its exact Hessian, from stage 1. Its
       result is the MLE; ``nll`` and ``converged`` refer to this stage.

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m (M >= 3 unless ``init`` is given).
    measured_ranges : array_like, shape (..., M)
        Measured ranges :math:`\hat d_m`, m (for example from :func:`measure_ranges`).
    altitude : float or array_like, shape (...)
        Flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters of the likelihood (paper profile by default).
    init : array_like, shape (..., 2), optional
        Starting point; by default :func:`linearised_estimate` (no prior needed). Give a
        coarse prior when the geometry is ambiguous (UAVs on a line cannot tell the target
        from its mirror image).
    max_iter : int, default 100
        Largest number of iterations of each stage.
    tol : float, default 1e-10
        Convergence when the step is below ``tol`` times (1 m + the distance of the
        estimate from the UAVs' centroid).

    Returns
    -------
    TargetEstimate
        Estimates, convergence flags, iterations (both stages) and the final negative
        log-likelihood.
    """
    est = _estimate_plain(uav_xy, measured_ranges, altitude, radar, init, max_iter, tol)
    if est is not None:
        return est
    q, h = _check_uavs(uav_xy, altitude)
    a = check_radar(radar, q.shape[-2])
    d_hat = _ranges_array(measured_ranges, q.shape[-2])
    n_iter = _v.count(max_iter, "max_iter", 1, MAX_ITERATIONS)
    tolerance = _v.scalar(tol, "tol")
    if not tolerance > 0:
        raise FieldError("tol", f"must be > 0, got {tolerance!r}")
    if init is None and q.shape[-2] < 3:
        raise FieldError(
            "uav_xy", f"the linearised estimate needs at least 3 UAVs, got {q.shape[-2]}"
        )
    s0 = None if init is None else _v.location(init, "init")
    # Absurd inputs (ranges whose squares overflow) make the costs infinite: every step is
    # then rejected and the trial is reported as failed (compiled: no warning).
    return _estimate(q, d_hat, h, a, s0, n_iter, tolerance)


#: The error of :func:`estimate_target` when a position or a likelihood is not finite.
_OVERFLOW = "so far from the ranges the geometry can produce that the likelihood overflows"


def _estimate(q, d_hat, h, a, s0, n_iter, tolerance) -> TargetEstimate:
    """Both stages for every trial, compiled (:func:`_mle_batch`), from ``s0`` or (None)
    the closed-form start of :func:`linearised_estimate`."""
    batch = _v.broadcast("measured_ranges", q.shape[:-2], d_hat.shape[:-1])
    batch = _v.broadcast("altitude", batch, h.shape)
    s = np.empty((*batch, 2))
    if s0 is not None:
        batch = _v.broadcast("init", batch, s0.shape[:-1])
        s = np.array(np.broadcast_to(s0, (*batch, 2)), dtype=np.float64, order="C")
    m_uavs = q.shape[-2]
    nll = np.empty(batch)
    converged = np.empty(batch, dtype=np.bool_)
    iterations = np.empty(batch, dtype=np.int64)
    finite = _mle_batch(_batch_array(q, batch, (m_uavs, 2)),
                        _batch_array(d_hat, batch, (m_uavs,)), _batch_array(h, batch),
                        _batch_array(a, batch, (m_uavs,)), s.reshape(-1, 2), s0 is None,
                        n_iter, tolerance, nll.reshape(-1), converged.reshape(-1),
                        iterations.reshape(-1))  # fmt: skip
    if not finite:
        raise FieldError("measured_ranges", _OVERFLOW)
    return TargetEstimate(position=s, converged=converged, iterations=iterations, nll=nll)


_F8 = np.dtype(np.float64)
_BOOL = np.dtype(np.bool_)
_I8 = np.dtype(np.int64)
_DEFAULT_A = _DEFAULT_RADAR.snr_constant
#: :math:`A` of the default radar, one (1, M) array per number of UAVs M.
_DEFAULT_ROWS: dict[int, np.ndarray] = {}
#: The last altitudes given as numbers, as arrays of one entry.
_ALTITUDES: dict[float, np.ndarray] = {}
_NO_INIT = np.empty((0, 2))

#: The ranges :func:`_mle_plain` checks: coordinates, measured ranges, altitudes. (An
#: argument, not globals frozen into the compiled code, whose cache would not see a change
#: of :mod:`crlbswarm._validation`.)
_LIMITS = np.array([_v.MAX_COORDINATE, _v.MAX_MEASURED_RANGE, _v.MIN_ALTITUDE, _v.MAX_ALTITUDE])

#: Largest number of ranges :func:`_estimate_plain` takes: above, the general path checks
#: the memory first (:func:`crlbswarm._validation.check_elements`, 8 copies).
_PLAIN_RANGES = _v.SMALL_REQUEST // 64


def _plain(x: np.ndarray) -> np.ndarray:
    """``x`` if C-contiguous, aligned and writable (the one array type of the compiled
    loops), else a copy that is."""
    return x if x.flags.carray else x.copy()


def _estimate_plain(q, d, altitude, radar, init, max_iter, tol) -> TargetEstimate | None:
    """:func:`estimate_target` of the common call without its Python checks, or None.

    The common call: float64 NumPy arrays of ranges, shape (M,) or (n, M), and of UAVs,
    shape (M, 2) or that of the ranges plus 2 (a formation broadcast over the trials, stride
    0, is read once); a float altitude or one per trial; a :class:`Radar`; ``init`` None or a
    float64 array of shape (2,) or (n, 2); an int ``max_iter`` and a float ``tol`` in range.
    One compiled call, :func:`_mle_plain`, then checks the values and runs both stages
    (:func:`_mle_batch`, the general path's). Anything else, or any value or result it
    refuses, returns None: the general path of :func:`estimate_target` then computes (the
    same, bit for bit: the same compiled loops) or raises its error. This path exists for
    small batches, whose time was the general path's checks (about 40 µs per call,
    docs/performance.md).
    """
    if (type(d) is not np.ndarray or type(q) is not np.ndarray or d.dtype is not _F8
            or q.dtype is not _F8 or type(max_iter) is not int
            or not isinstance(tol, float)):  # fmt: skip
        return None
    shape = d.shape
    if len(shape) == 2:
        n, m_uavs = shape
    elif len(shape) == 1:
        n, m_uavs = 1, shape[0]
        d = d[None]
    else:
        return None
    if q.shape == (m_uavs, 2):
        q = q[None]
    elif q.shape != (*shape, 2):
        return None
    elif n > 1 and q.strides[0] == 0:  # one formation broadcast over the trials
        q = q[:1].copy()
    if not (0 < n * m_uavs < _PLAIN_RANGES and 1 <= max_iter <= MAX_ITERATIONS
            and 0.0 < tol < math.inf and (m_uavs >= 3 or init is not None)):  # fmt: skip
        return None
    # (the common cases inline, the others by helpers: a small batch feels every call)
    a = _DEFAULT_ROWS.get(m_uavs) if radar is _DEFAULT_RADAR else None
    if a is None:
        a = _plain_radar(radar, m_uavs)
    h = _ALTITUDES.get(altitude) if type(altitude) is float else None
    if h is None:
        h = _plain_altitude(altitude, shape[:-1])
    s_init = _NO_INIT if init is None else _plain_init(init, shape[:-1])
    if a is None or h is None or s_init is None:
        return None
    if not q.flags.carray:  # (C-contiguous, aligned and writable)
        q = q.copy()
    if not d.flags.carray:
        d = d.copy()
    s = np.empty((n, 2))
    nll = np.empty(n)
    converged = np.empty(n, _BOOL)
    iterations = np.empty(n, _I8)
    if not _mle_plain(q, d, h, a, s_init, s, _LIMITS, max_iter, tol, nll, converged,
                      iterations):  # fmt: skip
        return None
    if len(shape) == 1:  # one trial: the shapes of the general path, (2,) and ()
        s, nll = s.reshape(2), nll.reshape(())
        converged, iterations = converged.reshape(()), iterations.reshape(())
    return TargetEstimate(s, converged, iterations, nll)


def _plain_radar(radar: object, m_uavs: int) -> np.ndarray | None:
    """:math:`A` of a :class:`Radar` as a (1, ``m_uavs``) array, or None (not a radar, or
    per-UAV fields of another length: the general path raises). Those of the default radar
    are kept (the compiled loops only read them)."""
    if radar is _DEFAULT_RADAR:
        row = _DEFAULT_ROWS.get(m_uavs)
        if row is None:
            if len(_DEFAULT_ROWS) > 16:
                _DEFAULT_ROWS.clear()
            row = _DEFAULT_ROWS[m_uavs] = np.full((1, m_uavs), _DEFAULT_A)
        return row
    if not isinstance(radar, Radar):
        return None
    a = radar.snr_constant
    if not (isinstance(a, float) or a.shape[0] == m_uavs):
        return None
    row = np.empty((1, m_uavs))
    row[0] = a
    return row


def _plain_altitude(h: object, batch: tuple[int, ...]) -> np.ndarray | None:
    """The altitude as an array of 1 entry (kept for the next call: the compiled loops only
    read it) or of one per trial, or None: a float, an int in range, or float64 of shape ()
    or ``batch``."""
    if isinstance(h, float) or (type(h) is int and 0 < h <= _v.MAX_ALTITUDE):
        arr = _ALTITUDES.get(h)
        if arr is None:
            if len(_ALTITUDES) > 16:
                _ALTITUDES.clear()
            arr = _ALTITUDES[h] = np.array((float(h),))
        return arr
    if type(h) is np.ndarray and h.dtype is _F8 and (h.ndim == 0 or h.shape == batch):
        return _plain(h.reshape(-1))
    return None


def _plain_init(init: object, batch: tuple[int, ...]) -> np.ndarray | None:
    """``init`` as an array of shape (1, 2) or (n, 2), or None: float64 of shape (2,) or
    ``batch`` + (2,)."""
    if (
        type(init) is np.ndarray
        and init.dtype is _F8
        and (init.shape == (2,) or init.shape == (*batch, 2))
    ):
        return _plain(init.reshape(-1, 2))
    return None


@njit(cache=True, error_model="numpy")
def _mle_plain(q, d_hat, h, a, init, s, limits, n_iter, tolerance, nll_out, conv_out, it_out):
    r"""The plain path of :func:`estimate_target` in one compiled call: the value checks of
    its general path (in one pass: UAVs and ``init`` within +-``limits[0]`` m, ranges within
    +-``limits[1]`` m, altitudes ``h`` in [``limits[2]``, ``limits[3]``] m, all finite), then
    the starts ``init`` copied into ``s`` (none if it has no rows: the closed-form starts)
    and both stages by :func:`_mle_batch`, the general path's. ``q``, ``h``, ``a`` and
    ``init`` have one row per trial or a single row. Returns False if a check fails (having
    computed nothing) or a result is not finite, else True."""
    coordinate, measured = limits[0], limits[1]
    for i in range(q.shape[0]):
        for m in range(q.shape[1]):
            if not (abs(q[i, m, 0]) <= coordinate and abs(q[i, m, 1]) <= coordinate):
                return False
    for i in range(init.shape[0]):
        if not (abs(init[i, 0]) <= coordinate and abs(init[i, 1]) <= coordinate):
            return False
    for i in range(h.shape[0]):
        if not limits[2] <= h[i] <= limits[3]:
            return False
    for i in range(d_hat.shape[0]):
        for m in range(d_hat.shape[1]):
            if not abs(d_hat[i, m]) <= measured:
                return False
    start = init.shape[0] == 0
    if not start:
        for i in range(s.shape[0]):
            row = init[i if init.shape[0] > 1 else 0]
            s[i, 0] = row[0]
            s[i, 1] = row[1]
    return _mle_batch(q, d_hat, h, a, s, start, n_iter, tolerance, nll_out, conv_out, it_out)
