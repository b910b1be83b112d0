r"""Fisher information of the target position and the CRLB (paper Sec. III, eqs. (4)-(11)).

The ranges are independent Gaussians whose mean *and* variance depend on the target
position, so each range carries information through both (eqs. (5)-(6)):

.. math::

    [\mathbf J_d]_{mm} = \frac{1}{\sigma_m^2}
        + \frac{1}{2\sigma_m^4}\Bigl(\frac{\partial \sigma_m^2}{\partial d_m}\Bigr)^2
        = \frac{A_m}{d_m^4} + \frac{8}{d_m^2},
    \qquad A_m = \frac{p_m G_p \beta_0}{\kappa \sigma_0^2}.

The chain rule with the Jacobian :math:`\mathbf Q` of eq. (4), whose rows are the horizontal
parts :math:`(\mathbf s - \mathbf q_m)^\top / d_m` of the unit line-of-sight vectors (the
target's height is known), gives the :math:`2 \times 2` FIM of eq. (8),

.. math::

    \mathbf J_s = \mathbf Q^\top \mathbf J_d \mathbf Q
        = \sum_m [\mathbf J_d]_{mm}
          \frac{(\mathbf s - \mathbf q_m)(\mathbf s - \mathbf q_m)^\top}{d_m^2},

whose entries are eq. (9). The CRLB (A-optimality) is :math:`\operatorname{tr}\mathbf J_s^{-1}`
in m^2, eq. (10); the D- and E-optimality figures are :math:`\det \mathbf J_s^{-1}` (m^4) and
:math:`\lambda_{\max}(\mathbf J_s^{-1})` (m^2).

Singular geometry (fewer than two UAVs with a horizontal offset, or all UAVs collinear with
the target's projection) gives ``+inf`` for every criterion, never NaN and never a warning.
Not in the paper: :math:`\mathbf J_s` is treated as singular when
:math:`\det \mathbf J_s \le 10^{-13} (\operatorname{tr} \mathbf J_s)^2`, i.e. when its
condition number exceeds about :math:`10^{13}`; beyond that the computed determinant is
dominated by rounding error and no finite value would be meaningful.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from . import _validation as _v
from ._numba import leaf
from .errors import FieldError
from .geometry import check_scene
from .radar import Radar, check_radar

__all__ = [
    "crlb",
    "crlb_from_fim",
    "d_optimality",
    "d_optimality_from_fim",
    "e_optimality",
    "e_optimality_from_fim",
    "fim_entries_at",
    "fisher_information",
    "inverse_figures_at",
    "range_information",
]

#: Relative threshold on det(J) / tr(J)^2 below which the FIM is treated as singular.
SINGULAR_RTOL = 1e-13

#: Range of the information matrices :func:`crlb_from_fim` and its siblings accept, m^-2:
#: entries at most MAX_FIM and a trace of 0 or at least MIN_FIM, so that the determinant and
#: the inverse neither overflow nor underflow. Every FIM of the model's ranges lies inside.
MAX_FIM = 1e150
MIN_FIM = 1e-150

_DEFAULT_RADAR = Radar()


def range_information(distance: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""Fisher information of each range about itself, :math:`[\mathbf J_d]_{mm}`, eq. (6).

    .. math:: [\mathbf J_d]_{mm} = \frac{A_m}{d_m^4} + \frac{8}{d_m^2}

    The first term is the information in the mean (:math:`1/\sigma_m^2`); the second comes
    from the range dependence of the variance, :math:`\sigma_m^2 \propto d_m^4`.

    Parameters
    ----------
    distance : array_like, shape (..., M)
        Slant ranges :math:`d_m > 0`, m.
    radar : Radar, optional
        Link parameters; per-UAV fields broadcast over the last axis.

    Returns
    -------
    ndarray, shape (..., M)
        Information per range, m^-2.

    Raises
    ------
    FieldError
        If a distance lies outside [0.1 m, 3e7 m] (the model's range) or is not a real
        finite number, or ``radar`` is not a :class:`~crlbswarm.Radar`.
    """
    d = _v.bounded(
        _v.as_float_array(distance, "distance"), "distance", _v.MIN_ALTITUDE, _v.MAX_DISTANCE, " m"
    )
    a = check_radar(radar, None)
    _v.broadcast("radar", np.shape(a), d.shape)
    d2 = d * d
    return a / d2 / d2 + 8.0 / d2


def _fim_entries(
    uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike, radar: Radar
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated ``(J_xx, J_yy, J_xy)``, each of the broadcast batch shape, eq. (9)
    (:func:`fim_entries_at` on every formation of the batch)."""
    q, s, h = check_scene(uav_xy, target_xy, altitude)
    m_uavs = q.shape[-2]
    a = np.broadcast_to(np.asarray(check_radar(radar, m_uavs), dtype=np.float64), (m_uavs,))
    batch = np.broadcast_shapes(q.shape[:-2], s.shape[:-1], h.shape)
    qb = np.broadcast_to(q, (*batch, m_uavs, 2)).reshape(-1, m_uavs, 2)
    sb = np.broadcast_to(s, (*batch, 2)).reshape(-1, 2)
    hb = np.broadcast_to(h, batch).reshape(-1)
    out = np.empty((qb.shape[0], 3))
    _fim_batch(qb, sb, hb, np.ascontiguousarray(a), out)
    return out[:, 0].reshape(batch), out[:, 1].reshape(batch), out[:, 2].reshape(batch)


@leaf
def fim_entries_at(q, sx, sy, altitude, snr):
    r"""Eq. (9) for one formation: ``(J_xx, J_yy, J_xy)`` of the UAVs ``q`` (M, 2) at
    ``altitude`` about the target (sx, sy), with each UAV's :math:`A_m` in ``snr`` (M,):
    :math:`\mathbf J_s = \sum_m (A_m/d_m^4 + 8/d_m^2)(\mathbf s - \mathbf q_m)
    (\mathbf s - \mathbf q_m)^\top / d_m^2`. Compiled kernel, no checks: the one
    writing of the law, called by :func:`fisher_information` and the mission kernel.

    :math:`A_m = 0` marks a UAV that does not sense (a lost UAV, :mod:`crlbswarm.faults`;
    a radar's :math:`A_m` is always positive): it adds nothing, not even the term
    :math:`8/d_m^2` of the variance, which does not depend on :math:`A_m`."""
    h2 = altitude * altitude
    jxx = 0.0
    jyy = 0.0
    jxy = 0.0
    for m in range(q.shape[0]):
        dx = sx - q[m, 0]
        dy = sy - q[m, 1]
        d2 = dx * dx + dy * dy + h2
        # [J_d]_mm / d_m^2 = (A/d^4 + 8/d^2) / d^2: the weight of the outer product of the
        # horizontal offsets (eq. (8) with Q_m = (s - q_m)^T / d_m); none when A = 0.
        w = (snr[m] / d2 + (8.0 if snr[m] > 0.0 else 0.0)) / d2 / d2
        wx = w * dx
        jxx += wx * dx
        jxy += wx * dy
        jyy += w * dy * dy
    return jxx, jyy, jxy


@njit(cache=True)
def _fim_batch(q, s, h, snr, out):
    for b in range(q.shape[0]):
        out[b, 0], out[b, 1], out[b, 2] = fim_entries_at(q[b], s[b, 0], s[b, 1], h[b], snr)


def fisher_information(
    uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR
) -> np.ndarray:
    r"""Fisher information matrix of the target position, eqs. (8)-(9).

    .. math::

        \mathbf J_s = \sum_{m=1}^M w_m
            \begin{bmatrix}\cos^2\theta_m & \sin\theta_m\cos\theta_m \\
                           \sin\theta_m\cos\theta_m & \sin^2\theta_m\end{bmatrix},
        \qquad w_m = [\mathbf J_d]_{mm} \cos^2\phi_m .

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m; broadcasts against the batch shape of ``uav_xy``.
    altitude : float or array_like, shape (...)
        Common flight altitude :math:`H > 0`, m; broadcasts against the batch shape.
    radar : Radar, optional
        Link parameters (paper profile by default). Per-UAV fields must have length M.

    Returns
    -------
    ndarray, shape (..., 2, 2)
        The symmetric FIM, m^-2. The batch shape is the broadcast of ``uav_xy.shape[:-2]``,
        ``target_xy.shape[:-1]`` and ``altitude.shape``.

    Raises
    ------
    FieldError
        (a ValueError) On wrong shapes, numbers that are not real (complex, booleans), NaN
        or inf, coordinates beyond +-1e7 m, an altitude outside [0.1, 1e5] m (the model's
        ranges, ``docs/sensing-model.md``), a request too large for the memory, or a
        per-UAV radar whose length differs from M. One line naming the argument.

    Examples
    --------
    >>> import numpy as np
    >>> from crlbswarm import fisher_information, optimal_formation
    >>> f = optimal_formation(6, (80.0, 90.0), 20.0)
    >>> J = fisher_information(f, (80.0, 90.0), 20.0)
    >>> bool(np.isclose(J[0, 0], J[1, 1]) and abs(J[0, 1]) < 1e-9 * J[0, 0])
    True
    """
    jxx, jyy, jxy = _fim_entries(uav_xy, target_xy, altitude, radar)
    return np.stack([np.stack([jxx, jxy], axis=-1), np.stack([jxy, jyy], axis=-1)], axis=-2)


@leaf
def inverse_figures_at(jxx, jyy, jxy):
    r"""The A-, D- and E-optimality figures of one symmetric 2x2 FIM:
    :math:`(\operatorname{tr}\mathbf J^{-1}, \det\mathbf J^{-1},
    \lambda_{\max}(\mathbf J^{-1}))` (eq. (10) and its D/E companions), each ``+inf``
    when the matrix is singular (module docstring). Compiled kernel, no checks: the one
    writing of the criteria, called by :func:`crlb` and its companions (through a compiled
    loop) and by the mission kernel at every step.

    The singularity test is made on the trace-normalised matrix,
    :math:`\det\mathbf J / (\operatorname{tr}\mathbf J)^2`, so that it neither underflows
    nor overflows for FIMs of extreme magnitude. The quotients may overflow to ``+inf``:
    the right answer. :math:`\lambda_{\max}(\mathbf J^{-1}) = \lambda_{\max}(\mathbf J)
    / \det\mathbf J` (no cancellation)."""
    tr = jxx + jyy
    det = jxx * jyy - jxy * jxy
    scale = 1.0 / tr if tr > 0.0 else 0.0
    nxx, nyy, nxy = jxx * scale, jyy * scale, jxy * scale
    if not nxx * nyy - nxy * nxy > SINGULAR_RTOL or not det > 0.0:
        return math.inf, math.inf, math.inf
    lam_max = 0.5 * tr + math.hypot(0.5 * (jxx - jyy), jxy)
    return tr / det, 1.0 / det, lam_max / det


@njit(cache=True)
def _criteria_batch(jxx, jyy, jxy, which, out):
    for i in range(out.shape[0]):
        out[i] = inverse_figures_at(jxx[i], jyy[i], jxy[i])[which]


#: The position of each criterion in the figures of :func:`inverse_figures_at`.
_A, _D, _E = 0, 1, 2


def _criterion(which: int, jxx: ArrayLike, jyy: ArrayLike, jxy: ArrayLike) -> np.ndarray:
    """Criterion ``which`` (:data:`_A`, :data:`_D` or :data:`_E`) of a batch of FIMs given by
    their entries (broadcast together): :func:`inverse_figures_at` on each."""
    shape = np.broadcast_shapes(np.shape(jxx), np.shape(jyy), np.shape(jxy))
    flat = [
        np.ascontiguousarray(np.broadcast_to(np.asarray(j, dtype=np.float64), shape)).reshape(-1)
        for j in (jxx, jyy, jxy)
    ]
    out = np.empty(flat[0].shape[0])
    _criteria_batch(flat[0], flat[1], flat[2], which, out)
    return out.reshape(shape)


def _fim_parts(fim: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    j = _v.as_float_array(fim, "fim")
    if j.ndim < 2 or j.shape[-2:] != (2, 2):
        raise FieldError("fim", f"expected shape (..., 2, 2), got {j.shape}")
    _v.check_finite(j, "fim")
    out_of_range = bool(np.any(np.abs(j) > MAX_FIM))  # first: the trace could overflow
    if not out_of_range:
        tr = np.abs(j[..., 0, 0]) + np.abs(j[..., 1, 1])
        out_of_range = bool(np.any((tr > 0) & (tr < MIN_FIM)))
    if out_of_range:
        raise FieldError(
            "fim",
            f"entries must be at most {MAX_FIM:g} m^-2 and the trace 0 (singular) or at least "
            f"{MIN_FIM:g} m^-2 (the model's range; beyond, the inverse over- or underflows)",
        )
    jxx, jyy = j[..., 0, 0], j[..., 1, 1]
    jxy = 0.5 * (j[..., 0, 1] + j[..., 1, 0])
    scale = np.maximum(np.abs(jxx) + np.abs(jyy), np.finfo(float).tiny)
    asym = np.abs(j[..., 0, 1] - j[..., 1, 0]) > 1e-9 * scale
    not_psd = (jxx < 0) | (jyy < 0) | (jxx * jyy - jxy * jxy < -1e-9 * scale * scale)
    if np.any(asym) or np.any(not_psd):
        raise FieldError("fim", "must be symmetric positive semi-definite")
    return jxx, jyy, jxy


def crlb_from_fim(fim: ArrayLike) -> np.ndarray:
    r"""A-optimality figure :math:`\operatorname{tr}(\mathbf J^{-1})` of 2x2 FIMs, eq. (10).

    Parameters
    ----------
    fim : array_like, shape (..., 2, 2)
        Symmetric positive semi-definite information matrices.

    Returns
    -------
    ndarray, shape (...)
        The trace of the inverse; ``+inf`` where the matrix is singular.

    Raises
    ------
    FieldError
        If ``fim`` is not symmetric positive semi-definite, not finite, or outside the
        model's range (entries up to ``MAX_FIM``, trace 0 or at least ``MIN_FIM``).
    """
    return _criterion(_A, *_fim_parts(fim))


def d_optimality_from_fim(fim: ArrayLike) -> np.ndarray:
    r"""D-optimality figure :math:`\det(\mathbf J^{-1})` of 2x2 FIMs.

    Parameters
    ----------
    fim : array_like, shape (..., 2, 2)
        Symmetric positive semi-definite information matrices.

    Returns
    -------
    ndarray, shape (...)
        The determinant of the inverse; ``+inf`` where the matrix is singular.
    """
    return _criterion(_D, *_fim_parts(fim))


def e_optimality_from_fim(fim: ArrayLike) -> np.ndarray:
    r"""E-optimality figure :math:`\lambda_{\max}(\mathbf J^{-1})` of 2x2 FIMs.

    Parameters
    ----------
    fim : array_like, shape (..., 2, 2)
        Symmetric positive semi-definite information matrices.

    Returns
    -------
    ndarray, shape (...)
        The largest eigenvalue of the inverse; ``+inf`` where the matrix is singular.
    """
    return _criterion(_E, *_fim_parts(fim))


def crlb(
    uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR
) -> np.ndarray:
    r"""CRLB of the target position, :math:`\operatorname{tr}(\mathbf J_s^{-1})`, eq. (10), m^2.

    A lower bound on the mean squared error :math:`E\lVert\hat{\mathbf s} - \mathbf s\rVert^2`
    of any unbiased estimator. Its square root is the RMSE bound in metres.

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m; broadcasts against the batch shape of ``uav_xy``.
    altitude : float or array_like, shape (...)
        Common flight altitude :math:`H > 0`, m; broadcasts against the batch shape.
    radar : Radar, optional
        Link parameters (paper profile by default). Per-UAV fields must have length M.

    Returns
    -------
    ndarray, shape (...)
        CRLB in m^2, finite inside the model's ranges, except ``+inf`` for a singular
        geometry, by design: the target is not identifiable when every UAV is straight
        above it (or all at one point over it) or all are collinear with its projection
        (module docstring).

    Raises
    ------
    ValueError
        As :func:`fisher_information`.

    Examples
    --------
    >>> from crlbswarm import crlb, optimal_formation
    >>> f = optimal_formation(6, (80.0, 90.0), 20.0)
    >>> round(float(crlb(f, (80.0, 90.0), 20.0)) * 1e3, 4)
    5.3476
    """
    return _criterion(_A, *_fim_entries(uav_xy, target_xy, altitude, radar))


def d_optimality(
    uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR
) -> np.ndarray:
    r"""D-optimality figure :math:`\det(\mathbf J_s^{-1})`, m^4.

    Proportional to the squared area of the error ellipse of an efficient estimator.

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    altitude : float or array_like, shape (...)
        Common flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters (paper profile by default).

    Returns
    -------
    ndarray, shape (...)
        :math:`\det(\mathbf J_s^{-1})` in m^4; ``+inf`` for a singular geometry (as
        :func:`crlb`).

    Raises
    ------
    FieldError
        As :func:`fisher_information`.
    """
    return _criterion(_D, *_fim_entries(uav_xy, target_xy, altitude, radar))


def e_optimality(
    uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR
) -> np.ndarray:
    r"""E-optimality figure :math:`\lambda_{\max}(\mathbf J_s^{-1})`, m^2.

    The variance bound along the worst direction (the major axis of the error ellipse).

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    altitude : float or array_like, shape (...)
        Common flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters (paper profile by default).

    Returns
    -------
    ndarray, shape (...)
        :math:`\lambda_{\max}(\mathbf J_s^{-1})` in m^2; ``+inf`` for a singular
        geometry (as :func:`crlb`).

    Raises
    ------
    FieldError
        As :func:`fisher_information`.
    """
    return _criterion(_E, *_fim_entries(uav_xy, target_xy, altitude, radar))
