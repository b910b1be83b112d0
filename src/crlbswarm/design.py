r"""The CRLB-optimal formation in closed form (paper Sec. III, eqs. (9)-(12)).

By the arithmetic-harmonic mean inequality (eq. (11)),
:math:`\operatorname{tr}\mathbf J_s^{-1} \ge 4 / \operatorname{tr}\mathbf J_s = 4/\sum_m w_m`,
with equality iff :math:`\mathbf J_s` is a scalar matrix. The bound depends only on the
elevations :math:`\phi_m` through the information weights

.. math::

    w_m = \Bigl(\frac{A_m \sin^4\phi_m}{H^4} + \frac{8 \sin^2\phi_m}{H^2}\Bigr)\cos^2\phi_m ,

each maximised by the same elevation :math:`\phi^*`; a regular polygon of radius
:math:`r^* = H/\tan\phi^*` then makes :math:`\mathbf J_s` scalar and attains the bound.

Closed-form elevation (derivation omitted in the paper). With :math:`t = \tan^2\phi` and
:math:`b = 8H^2/A`, dividing :math:`D_m = 0` (Sec. III) by :math:`\cos^4\phi` gives

.. math::

    (2t - t^2) + b\,(1 - t^2) = 0
    \iff (1 + b)\,t^2 - 2t - b = 0
    \iff t^* = \frac{1 + \sqrt{1 + b + b^2}}{1 + b},

the positive root (the other is negative). As :math:`H \to 0`, :math:`b \to 0` and
:math:`t^* \to 2` (:math:`\phi^* \to \arctan\sqrt2 = 54.7356^\circ`); as
:math:`H \to \infty`, :math:`t^* \to 1` (:math:`45^\circ`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError
from .fisher import MAX_FIM, MIN_FIM, crlb
from .geometry import regular_polygon
from .radar import Radar, check_radar

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = [
    "attainable_crlb",
    "best_eigenvalues",
    "crlb_bound",
    "design_report",
    "formation_labels",
    "information_weight",
    "isotropic_azimuths",
    "optimal_elevation",
    "optimal_formation",
    "optimal_radius",
    "optimal_weights",
]

_DEFAULT_RADAR = Radar()


def information_weight(
    elevation: ArrayLike, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR
) -> np.ndarray:
    r"""Information weight :math:`w_m` of a UAV at elevation :math:`\phi_m`, eq. (9).

    .. math::

        w_m = \Bigl(\frac{A_m \sin^4\phi_m}{H^4} + \frac{8\sin^2\phi_m}{H^2}\Bigr)
              \cos^2\phi_m = [\mathbf J_d]_{mm} \cos^2\phi_m ,

    the trace of UAV :math:`m`'s contribution to :math:`\mathbf J_s`.

    Parameters
    ----------
    elevation : array_like
        Elevation angles :math:`\phi_m \in [0, \pi/2]`, rad.
    altitude : float or array_like
        Flight altitude :math:`H > 0`, m; broadcasts against ``elevation``.
    radar : Radar, optional
        Link parameters; per-UAV fields broadcast over the last axis of ``elevation``.

    Returns
    -------
    ndarray
        :math:`w_m`, m^-2, of the broadcast shape of the inputs.
    """
    phi = _v.finite(elevation, "elevation")
    if np.any((phi < 0) | (phi > 0.5 * np.pi)):
        raise FieldError("elevation", "must lie in [0, pi/2] rad")
    h = _v.altitude(altitude, "altitude")
    a = check_radar(radar, None)
    _v.broadcast("radar", np.shape(a), _v.broadcast("altitude", phi.shape, h.shape))
    r = np.sin(phi) ** 2 / h / h  # sin^2(phi) / H^2 = 1 / d^2, formed without overflow
    return (a * r * r + 8.0 * r) * np.cos(phi) ** 2


def _tan2_optimal(altitude: ArrayLike, radar: Radar) -> tuple[np.ndarray, np.ndarray]:
    """``(t*, H)`` with ``t* = tan^2(phi*)`` from the quadratic in the module docstring."""
    h = _v.altitude(altitude, "altitude")
    a = check_radar(radar, None)
    _v.broadcast("radar", np.shape(a), h.shape)
    # t* = (1 + sqrt(1 + b + b^2)) / (1 + b) with b = 8H^2/A, or the same with c = 1/b,
    # t* = (c + sqrt(c^2 + c + 1)) / (c + 1): evaluate the form whose variable is <= 1, and
    # sqrt(x^2 + x + 1) as hypot(x + 1/2, sqrt(3)/2), so no altitude overflows.
    with np.errstate(over="ignore"):  # an absurd altitude gives ratio = inf, handled below
        ratio = 8.0 * (h / np.sqrt(a)) ** 2
    small = ratio <= 1.0
    x = np.where(small, ratio, 1.0 / np.where(small, 1.0, ratio))
    root = np.hypot(x + 0.5, 0.5 * np.sqrt(3.0))
    return np.where(small, (1.0 + root) / (1.0 + x), (x + root) / (x + 1.0)), h


def optimal_elevation(altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""CRLB-optimal elevation :math:`\phi^*` in closed form, rad (Sec. III).

    :math:`\phi^* = \arctan\sqrt{t^*}` with
    :math:`t^* = \bigl(1 + \sqrt{1 + b + b^2}\bigr)/(1 + b)` and :math:`b = 8H^2/A`: the
    positive root of :math:`(1+b)t^2 - 2t - b = 0`, which is :math:`D_m = 0` divided by
    :math:`\cos^4\phi` (derivation in the module docstring and the user guide).

    Parameters
    ----------
    altitude : float or array_like
        Flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters; per-UAV fields broadcast over the last axis of ``altitude``.

    Returns
    -------
    ndarray
        :math:`\phi^* \in (\pi/4, \arctan\sqrt 2)`, rad; 54.7356 deg as :math:`H \to 0`,
        45 deg as :math:`H \to \infty`.

    Examples
    --------
    >>> import numpy as np
    >>> from crlbswarm import optimal_elevation
    >>> round(float(np.degrees(optimal_elevation(20.0))), 3)
    54.735
    """
    t, _ = _tan2_optimal(altitude, radar)
    return np.arctan(np.sqrt(t))


def optimal_radius(altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""Radius :math:`r^* = H / \tan\phi^*` of the optimal formation, m (Sec. III).

    Parameters
    ----------
    altitude : float or array_like
        Flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters; per-UAV fields broadcast over the last axis of ``altitude``.

    Returns
    -------
    ndarray
        Horizontal distance from the target's projection to every UAV of :math:`F^*`, m.
    """
    t, h = _tan2_optimal(altitude, radar)
    return h / np.sqrt(t)


def optimal_weights(n_uavs: int, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""Each UAV's largest information weight :math:`w_m^* = \max_\phi w_m(\phi)`, eq. (9).

    Every UAV reaches its own maximum at its own optimal elevation (:func:`optimal_elevation`
    with its own :math:`A_m`), whatever the others do; the weights then fix the best CRLB
    (:func:`attainable_crlb`).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs :math:`M \ge 3`.
    altitude : float or array_like, shape (...)
        Flight altitude :math:`H`, m.
    radar : Radar, optional
        Link parameters; per-UAV fields must have length ``n_uavs``.

    Returns
    -------
    ndarray, shape (..., M)
        :math:`w_m^*`, m^-2.
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    check_radar(radar, n)
    h = _v.altitude(altitude, "altitude")[..., None]
    _v.check_elements(float(h.size) * n, "n_uavs", f"{n} weights at {h.size} altitudes")
    w = information_weight(optimal_elevation(h, radar), h, radar)
    return np.broadcast_to(w, (*w.shape[:-1], n))


def attainable_crlb(weights: ArrayLike) -> np.ndarray:
    r"""The smallest :math:`\operatorname{tr}\mathbf J_s^{-1}` over the UAVs' azimuths, for
    given information weights, m^2.

    With :math:`\mathbf J_s = \sum_m w_m \mathbf u_m \mathbf u_m^\top` and
    :math:`z = \sum_m w_m e^{j2\theta_m}`, the eigenvalues of :math:`\mathbf J_s` are
    :math:`(W \pm |z|)/2` with :math:`W = \sum_m w_m`, so
    :math:`\operatorname{tr}\mathbf J_s^{-1} = 4W/(W^2 - |z|^2)`. The azimuths are free,
    and the smallest :math:`|z|` of vectors of lengths :math:`w_m` is
    :math:`\max(0,\, 2w_{\max} - W)` (a closed polygon exists iff no side exceeds the
    sum of the others). Hence

    .. math::

        \min_\theta \operatorname{tr}\mathbf J_s^{-1} =
        \begin{cases} 4/W & w_{\max} \le W - w_{\max} \text{ (eq. (11), attained)}\\
        1/w_{\max} + 1/(W - w_{\max}) & \text{otherwise (one dominant UAV).}\end{cases}

    Parameters
    ----------
    weights : array_like, shape (..., M)
        Information weights :math:`w_m > 0`, m^-2, M >= 2.

    Returns
    -------
    ndarray, shape (...)
        The attainable CRLB, m^2.

    Examples
    --------
    >>> from crlbswarm import attainable_crlb
    >>> float(attainable_crlb([1.0, 1.0, 1.0]))  # 4 / 3: isotropic
    1.3333333333333333
    >>> float(attainable_crlb([10.0, 1.0, 1.0]))  # 1/10 + 1/2: the first UAV dominates
    0.6
    """
    lam_max, lam_min = best_eigenvalues(weights)
    return 1.0 / lam_max + 1.0 / lam_min  # (4/W when both are W/2: the same bits)


def best_eigenvalues(weights: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    r"""The eigenvalues of :math:`\mathbf J_s` at the best azimuths for given weights
    (:func:`attainable_crlb`): both :math:`W/2` when no weight exceeds the sum of the
    others, else :math:`w_{\max}` and :math:`W - w_{\max}` (:math:`(W \pm |z|)/2` with the
    smallest :math:`|z|`). Every design criterion of the best geometry follows from them:
    A :math:`= 1/\lambda_{\max} + 1/\lambda_{\min}`, D :math:`= 1/(\lambda_{\max}
    \lambda_{\min})`, E :math:`= 1/\lambda_{\min}`.

    Parameters
    ----------
    weights : array_like, shape (..., M)
        Information weights :math:`w_m > 0`, m^-2, M >= 2.

    Returns
    -------
    lam_max, lam_min : ndarray, shape (...)
        The two eigenvalues, m^-2.
    """
    w = _check_weights(weights, "(..., M)")
    ordered = np.sort(w, axis=-1)
    largest = ordered[..., -1]
    rest = np.sum(ordered[..., :-1], axis=-1)  # (not total - largest: no cancellation)
    half = 0.5 * np.sum(w, axis=-1)  # (as eq. (11) was always evaluated: the same bits)
    isotropic = largest <= rest
    return np.where(isotropic, half, largest), np.where(isotropic, half, rest)


def _check_weights(weights: ArrayLike, shape: str) -> np.ndarray:
    """Information weights: positive, within the range of a Fisher information (the
    model's range, :data:`crlbswarm.fisher.MAX_FIM`), at least two on the last axis."""
    w = _v.positive(weights, "weights")
    if w.ndim < 1 or w.shape[-1] < 2:
        raise FieldError("weights", f"expected shape {shape} with M >= 2, got {w.shape}")
    if np.any(w > MAX_FIM) or np.any(w < MIN_FIM):
        raise FieldError(
            "weights", f"must be between {MIN_FIM:g} and {MAX_FIM:g} m^-2 (the model's range)"
        )
    return w


def crlb_bound(n_uavs: int, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""The smallest CRLB any formation of ``n_uavs`` UAVs at this altitude attains, m^2.

    Each UAV at its own optimal elevation gives the weights :math:`w_m^*`
    (:func:`optimal_weights`), and :func:`attainable_crlb` the best azimuths for them: the
    bound :math:`4/\sum_m w_m^*` of eq. (11) when no :math:`w_m^*` exceeds the sum of the
    others (always with equal UAVs, the paper's case: :math:`F^*` attains it), else
    :math:`1/w^*_{\max} + 1/(\sum_m w_m^* - w^*_{\max})` (one UAV dominates; eq. (11) is
    not attainable). :func:`optimal_formation` attains this value in both cases.

    Parameters
    ----------
    n_uavs : int
        Number of UAVs :math:`M \ge 3` (the paper's setting).
    altitude : float or array_like, shape (...)
        Flight altitude :math:`H > 0`, m.
    radar : Radar, optional
        Link parameters; per-UAV fields must have length ``n_uavs``.

    Returns
    -------
    ndarray, shape (...)
        The attainable optimum, m^2.

    Examples
    --------
    >>> from crlbswarm import crlb_bound
    >>> round(float(crlb_bound(6, 20.0)) * 1e3, 4)
    5.3476
    """
    weights = optimal_weights(n_uavs, altitude, radar)
    if not radar.per_uav:  # equal UAVs: eq. (11), attained (no sorting over a large batch)
        return 4.0 / np.sum(weights, axis=-1)
    return attainable_crlb(weights)


def isotropic_azimuths(weights: ArrayLike, rotation: float = 0.0) -> np.ndarray:
    r"""Azimuths :math:`\theta_m` that minimise :math:`|\sum_m w_m e^{j2\theta_m}|`, rad.

    When no weight exceeds the sum of the others the sum is made zero (a weighted
    isotropic geometry: :math:`\mathbf J_s` scalar); otherwise the dominant UAV's double
    angle is opposite to all the others' (:math:`|z| = 2w_{\max} - W`). Construction
    (the user guide derives it): sort the weights in decreasing order; going from the
    smallest, each new weight either dominates the ones already placed (they are turned
    opposite to it) or not, and then the placed ones, their double angles scaled by a
    factor :math:`t \in [0, 1]` found by Brent's method, are bent until their resultant
    has exactly its length, and the new weight closes the polygon. Deterministic; equal
    weights are not given a regular polygon here (:func:`optimal_formation` keeps it).

    Parameters
    ----------
    weights : array_like, shape (M,)
        Information weights :math:`w_m > 0`, M >= 2.
    rotation : float, default 0
        Azimuth given to the first UAV, rad.

    Returns
    -------
    ndarray, shape (M,)
        Azimuths, rad, the first equal to ``rotation``.
    """
    from scipy.optimize import brentq

    w = _check_weights(weights, "(M,)")
    if w.ndim != 1:
        raise FieldError("weights", f"expected shape (M,) with M >= 2, got {w.shape}")
    rot = _v.angle(rotation, "rotation")
    order = np.argsort(-w, kind="stable")
    lengths = w[order]
    alpha = np.zeros(lengths.shape[0])  # double angles 2 theta, in sorted order
    for j in range(lengths.shape[0] - 2, -1, -1):  # add the j-th largest to the placed ones
        placed_len, placed = lengths[j + 1 :], alpha[j + 1 :].copy()
        if lengths[j] >= placed_len.sum():  # it dominates: the others all opposite to it
            alpha[j + 1 :] = np.pi
            alpha[j] = 0.0
            continue

        def excess(t: float, lens: np.ndarray = placed_len, ang: np.ndarray = placed,
                   target: float = float(lengths[j])) -> float:  # fmt: skip
            return float(np.abs(np.sum(lens * np.exp(1j * t * ang)))) - target

        # t = 0: all aligned, resultant = their sum > the new length; t = 1: their own
        # smallest resultant, which is at most the second largest length <= the new one.
        t = 1.0 if excess(1.0) >= 0.0 else brentq(excess, 0.0, 1.0, xtol=1e-15, rtol=1e-15)
        alpha[j + 1 :] = t * placed
        resultant = np.sum(placed_len * np.exp(1j * alpha[j + 1 :]))
        alpha[j] = np.angle(-resultant)
    theta = np.empty_like(alpha)
    theta[order] = 0.5 * alpha
    theta = np.mod(theta - theta[0] + rot + np.pi, 2.0 * np.pi) - np.pi
    return _spread_bearings(theta)


def _spread_bearings(theta: np.ndarray) -> np.ndarray:
    r"""The UAVs, in the order of their lines through the target (:math:`\theta \bmod \pi`),
    put on the two sides of the target in turn (:math:`\theta` and :math:`\theta + \pi`
    give the same :math:`\mathbf u\mathbf u^\top`): the formation surrounds the target and
    UAVs on one line are on opposite sides. The information is unchanged, and the first UAV
    keeps its bearing."""
    line = np.mod(theta, np.pi)
    order = np.argsort(line, kind="stable")
    rank = np.empty(theta.shape[0], dtype=np.int64)
    rank[order] = np.arange(theta.shape[0])
    side = (rank - rank[0]) % 2  # the first UAV on side 0: its own bearing
    own = (np.mod(theta, 2.0 * np.pi) >= np.pi).astype(np.int64)
    target_side = (own[0] + side) % 2
    flip = target_side != own
    return np.where(flip, np.where(theta > 0, theta - np.pi, theta + np.pi), theta)


def optimal_formation(
    n_uavs: int,
    target_xy: ArrayLike,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    rotation: float = 0.0,
) -> np.ndarray:
    r"""The CRLB-optimal formation :math:`F^*` (Sec. III), for equal or unequal UAVs.

    Equal UAVs (the paper): a regular M-gon. UAV :math:`m = 1, \dots, M` sits at horizontal
    distance :math:`r^* = H/\tan\phi^*` from the target's projection, at azimuth
    :math:`\theta_0 + 2\pi(m-1)/M` seen from the target, so that
    :math:`\sum_m e^{j2\theta_m} = 0` and :math:`\mathbf J_s` is scalar (eq. (12b)).

    Unequal UAVs (per-UAV radar fields with unequal :math:`A_m`): each UAV at its own
    optimal elevation and radius :math:`r_m^* = H/\tan\phi_m^*`, which maximises its own
    weight :math:`w_m^*`, and azimuths from :func:`isotropic_azimuths`: a weighted isotropic
    geometry when no :math:`w_m^*` exceeds the sum of the others, else the dominant UAV
    opposite (in double angle) to all the others. Its CRLB is :func:`crlb_bound` in both
    cases, the smallest of any formation at this altitude.

    Parameters
    ----------
    n_uavs : int
        Number of UAVs :math:`M \ge 3`.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m (a batch of targets gives a batch of formations).
    altitude : float or array_like, shape (...)
        Flight altitude :math:`H > 0`, m; broadcasts against the batch shape of ``target_xy``.
    radar : Radar, optional
        Link parameters; per-UAV fields (length ``n_uavs``) give unequal UAVs.
    rotation : float, default 0
        Azimuth :math:`\theta_0` of UAV 1 seen from the target, rad.

    Returns
    -------
    ndarray, shape (..., M, 2)
        Horizontal positions, m. Row 0 is UAV 1 (the leader in the control scenarios).

    Raises
    ------
    FieldError
        If ``n_uavs`` is not an integer from 3 to 100 000, the altitude is outside
        [0.1, 1e5] m or the target beyond +-1e7 m (the model's ranges), or per-UAV radar
        fields have another length than ``n_uavs``.

    Examples
    --------
    >>> from crlbswarm import optimal_formation
    >>> optimal_formation(4, (0.0, 0.0), 20.0).round(2)
    array([[ 14.14,   0.  ],
           [  0.  ,  14.14],
           [-14.14,   0.  ],
           [ -0.  , -14.14]])
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    a = np.asarray(check_radar(radar, n))
    target = _v.location(target_xy, "target_xy")
    if radar.n_uavs is not None and np.all(a == a[0]):  # per-UAV fields, but equal A
        radar = Radar(**{k: float(np.ravel(v)[0]) for k, v in radar.to_dict().items()})
    if radar.n_uavs is None:  # equal UAVs: the regular polygon of the paper
        radius = optimal_radius(altitude, radar)
        _v.broadcast("altitude", target.shape[:-1], radius.shape)
        return regular_polygon(n, target, radius, rotation)
    h = _v.altitude(altitude, "altitude")
    batch = _v.broadcast("altitude", target.shape[:-1], h.shape)
    rot = _v.angle(rotation, "rotation")
    h = np.broadcast_to(h, batch)
    out = np.empty((*batch, n, 2))
    for index in np.ndindex(*batch):  # each altitude has its own weights and azimuths
        radius = optimal_radius(h[index], radar)  # (M,): each UAV at its own elevation
        theta = isotropic_azimuths(optimal_weights(n, h[index], radar), rot)
        centre = np.broadcast_to(target, (*batch, 2))[index]
        out[index] = centre + radius[:, None] * np.stack([np.cos(theta), np.sin(theta)], -1)
    return out


def design_report(
    n_uavs: int,
    altitude: float,
    target_xy: ArrayLike = (0.0, 0.0),
    radar: Radar = _DEFAULT_RADAR,
    rotation_deg: float = 0.0,
) -> dict[str, Any]:
    """The CRLB-optimal formation of a scene and its figures, as a JSON-ready dict.

    What ``crlbswarm design`` prints (as a table, or as JSON with ``--json``).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs M >= 3.
    altitude : float
        Flight altitude H, m.
    target_xy : array_like, shape (2,), default (0, 0)
        Target position, m.
    radar : Radar, optional
        Link parameters (paper profile by default).
    rotation_deg : float, default 0
        Azimuth of UAV 1 seen from the target, degrees (a report for display, so in
        degrees like its output).

    Returns
    -------
    dict
        Keys: ``n_uavs``, ``altitude_m``, ``target_m`` ([x, y]), ``rotation_deg``,
        ``elevation_deg`` (phi*; a list, one per UAV, for a per-UAV radar), ``radius_m``
        (r*; likewise), ``positions_m`` (M x [x, y], UAV 1 first), ``crlb_m2`` (tr J^-1 of
        F*), ``bound_m2`` (the attainable optimum, :func:`crlb_bound`), ``isotropic``
        (whether it is eq. (11), 4/sum w*, i.e. no UAV dominates), ``rmse_bound_m`` (sqrt
        of the CRLB), ``radar`` (the link parameters in linear SI units).
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    target = _v.location(target_xy, "target_xy")
    if target.shape != (2,):
        raise FieldError("target_xy", f"expected shape (2,), got {target.shape}")
    h = _v.scalar(altitude, "altitude")
    _v.altitude(h, "altitude")
    rotation_deg = _v.angle(rotation_deg, "rotation_deg", " deg")
    positions = optimal_formation(n, target, h, radar, np.radians(rotation_deg))
    value = float(crlb(positions, target, h, radar))
    weights = optimal_weights(n, h, radar)
    elevation = np.degrees(optimal_elevation(h, radar))
    radius = optimal_radius(h, radar)
    return {
        "n_uavs": n,
        "altitude_m": h,
        "target_m": target.tolist(),
        "rotation_deg": float(rotation_deg),
        "elevation_deg": elevation.tolist() if radar.per_uav else float(elevation),
        "radius_m": radius.tolist() if radar.per_uav else float(radius),
        "positions_m": positions.tolist(),
        "crlb_m2": value,
        "bound_m2": float(crlb_bound(n, h, radar)),
        "isotropic": bool(np.max(weights) <= np.sum(weights) - np.max(weights)),
        "rmse_bound_m": float(np.sqrt(value)),
        "radar": radar.to_dict(),
    }


def formation_labels(scenario: Scenario) -> dict[str, str]:
    r"""What the views of a mission (figures, animation, replay page) call the formation
    flown over the target and the bound its CRLB converges to.

    The words follow :attr:`crlbswarm.Scenario.formation_design`: :math:`F^*` in closed
    form whose bound is eq. (11), :math:`4/\sum_m w_m^*` (equal UAVs, or unequal ones none
    of which dominates); :math:`F^*` whose bound is :math:`1/w^*_{\max} + 1/(\sum_m w_m^* -
    w^*_{\max})` (one UAV dominates: :func:`attainable_crlb`); or the constrained design
    flown when :math:`F^*` is blocked, whose bound is its own CRLB.

    Parameters
    ----------
    scenario : Scenario
        A scenario with one target (a group's scenario for several).

    Returns
    -------
    dict of str to str
        ``formation`` (the slots' name in a legend) and ``bound`` (the bound's).

    Examples
    --------
    >>> import crlbswarm
    >>> from crlbswarm.design import formation_labels
    >>> formation_labels(crlbswarm.load_scenario("paper"))["bound"]
    'bound 4/Σw* (eq. 11)'
    """
    design = scenario.formation_design
    if design.method != "closed form":
        return {
            "formation": f"constrained design ({design.criterion}-optimal, F* blocked)",
            "bound": "bound: CRLB of the constrained design (F* blocked)",
        }
    weights = optimal_weights(scenario.uavs.count, scenario.altitude, scenario.radar_model)
    largest = float(np.max(weights))
    if largest <= float(np.sum(weights)) - largest:
        return {"formation": "F* (CRLB-optimal)", "bound": "bound 4/Σw* (eq. 11)"}
    return {
        "formation": "F* (CRLB-optimal; one UAV dominates)",
        "bound": "bound 1/w*max + 1/(Σw* − w*max) (one UAV dominates)",
    }
