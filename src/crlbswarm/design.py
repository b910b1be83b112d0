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

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError
from .fisher import crlb
from .geometry import regular_polygon
from .radar import Radar, check_radar

__all__ = [
    "crlb_bound",
    "design_report",
    "information_weight",
    "optimal_elevation",
    "optimal_formation",
    "optimal_radius",
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


def _optimal_weights(n_uavs: ArrayLike, altitude: ArrayLike, radar: Radar) -> np.ndarray:
    """Optimal :math:`w^*_m`, shape ``(..., M)`` for altitude of shape ``(...)``."""
    n = _v.uav_count(n_uavs, "n_uavs")
    check_radar(radar, n)
    h = _v.altitude(altitude, "altitude")[..., None]
    _v.check_elements(float(h.size) * n, "n_uavs", f"{n} weights at {h.size} altitudes")
    w = information_weight(optimal_elevation(h, radar), h, radar)
    return np.broadcast_to(w, (*w.shape[:-1], n))


def crlb_bound(n_uavs: int, altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""Theoretical CRLB bound :math:`4 / \sum_m w_m^*`, eq. (11), m^2.

    No formation of ``n_uavs`` UAVs at this altitude has a lower CRLB; :math:`F^*` attains
    it. With per-UAV radar fields each UAV contributes its own optimal weight; the bound is
    then attainable only if no :math:`w_m^*` exceeds the sum of the others.

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
        The bound, m^2.

    Examples
    --------
    >>> from crlbswarm import crlb_bound
    >>> round(float(crlb_bound(6, 20.0)) * 1e3, 4)
    5.3476
    """
    return 4.0 / np.sum(_optimal_weights(n_uavs, altitude, radar), axis=-1)


def optimal_formation(
    n_uavs: int,
    target_xy: ArrayLike,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    rotation: float = 0.0,
) -> np.ndarray:
    r"""The CRLB-optimal formation :math:`F^*`: a regular M-gon over the target (Sec. III).

    UAV :math:`m = 1, \dots, M` sits at horizontal distance :math:`r^* = H/\tan\phi^*` from
    the target's projection, at azimuth :math:`\theta_0 + 2\pi(m-1)/M` seen from the target,
    so that :math:`\sum_m e^{j2\theta_m} = 0` and :math:`\mathbf J_s` is scalar (eq. (12b)).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs :math:`M \ge 3`.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m (a batch of targets gives a batch of formations).
    altitude : float or array_like, shape (...)
        Flight altitude :math:`H > 0`, m; broadcasts against the batch shape of ``target_xy``.
    radar : Radar, optional
        Link parameters. Per-UAV fields are accepted only when every UAV has the same
        :math:`A_m` (otherwise the regular polygon is not optimal; see the user guide).
    rotation : float, default 0
        Azimuth :math:`\theta_0` of UAV 1 seen from the target, rad.

    Returns
    -------
    ndarray, shape (..., M, 2)
        Horizontal positions, m. Row 0 is UAV 1 (the leader in the control scenarios).

    Raises
    ------
    FieldError
        If ``n_uavs`` is not an integer from 3 to 1 000 000, the altitude is outside
        [0.1, 1e5] m or the target beyond +-1e7 m (the model's ranges), or per-UAV radar
        fields give unequal :math:`A_m`.

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
    if radar.n_uavs is not None:
        if not np.allclose(a, a[0], rtol=1e-12, atol=0.0):
            raise FieldError(
                "radar",
                "per-UAV fields give unequal A = p G_p beta0 / (kappa sigma0^2); "
                "the regular polygon is optimal only for equal A",
            )
        radar = Radar(**{k: float(np.ravel(v)[0]) for k, v in radar.to_dict().items()})
    target = _v.location(target_xy, "target_xy")
    radius = optimal_radius(altitude, radar)
    _v.broadcast("altitude", target.shape[:-1], radius.shape)
    return regular_polygon(n, target, radius, rotation)


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
        ``elevation_deg`` (phi*), ``radius_m`` (r*), ``positions_m`` (M x [x, y], UAV 1
        first), ``crlb_m2`` (tr J^-1 of F*), ``bound_m2`` (4/sum w*), ``rmse_bound_m``
        (sqrt of the CRLB), ``radar`` (the link parameters in linear SI units).
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
    return {
        "n_uavs": n,
        "altitude_m": h,
        "target_m": target.tolist(),
        "rotation_deg": float(rotation_deg),
        "elevation_deg": float(np.degrees(optimal_elevation(h, radar))),
        "radius_m": float(optimal_radius(h, radar)),
        "positions_m": positions.tolist(),
        "crlb_m2": value,
        "bound_m2": float(crlb_bound(n, h, radar)),
        "rmse_bound_m": float(np.sqrt(value)),
        "radar": radar.to_dict(),
    }
