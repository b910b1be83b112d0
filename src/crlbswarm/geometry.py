r"""Geometry of UAVs at a common altitude over a ground target (paper Sec. II-III).

UAV :math:`m` flies at horizontal position :math:`\mathbf q_m` and altitude :math:`H`; the
target is the ground point :math:`\mathbf s`. Every function takes positions of shape
``(..., M, 2)`` and a target of shape ``(..., 2)``; leading batch dimensions broadcast
(NumPy rules), as does the altitude, of shape ``(...)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError

__all__ = [
    "azimuth_angles",
    "clip_norm",
    "elevation_angles",
    "fitted_turn",
    "outline_order",
    "regular_polygon",
    "slant_ranges",
]


@njit(cache=True, inline="always")
def clip_norm(x, y, limit):
    """The vector (x, y), scaled down to length ``limit`` if it is longer: the saturation of
    the leader's speed and the cap on the repulsive step. A vector so long that its squared
    length overflows is still scaled to ``limit`` (its direction kept). Compiled kernel, no
    checks."""
    norm = math.sqrt(x * x + y * y)
    if norm > limit:
        if norm == math.inf:  # the squares overflowed: measure the scaled vector instead
            big = max(abs(x), abs(y))  # (an infinite component gives NaN: no direction)
            x /= big
            y /= big
            norm = math.sqrt(x * x + y * y)
        x *= limit / norm
        y *= limit / norm
    return x, y


def check_scene(
    uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a scene and return ``(q, s, h)`` as float arrays (not part of the API)."""
    q = _v.coordinates(uav_xy, "uav_xy")
    s = _v.location(target_xy, "target_xy")
    h = _v.altitude(altitude, "altitude")
    batch = _v.broadcast("target_xy", q.shape[:-2], s.shape[:-1])
    batch = _v.broadcast("altitude", batch, h.shape)
    n = float(np.prod(batch, dtype=float)) * q.shape[-2]
    _v.check_elements(n, "uav_xy", f"{n:.3g} UAV-target pairs", copies=8)
    return q, s, h


def target_offsets(q: np.ndarray, s: np.ndarray) -> np.ndarray:
    r"""Horizontal offsets :math:`\mathbf s - \mathbf q_m`, shape ``(..., M, 2)`` (unchecked)."""
    return s[..., None, :] - q


def slant_ranges(uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike) -> np.ndarray:
    r"""Slant range from each UAV to the target, eq. (1).

    .. math:: d_m = \sqrt{\lVert \mathbf q_m - \mathbf s \rVert^2 + H^2}

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    altitude : float or array_like, shape (...)
        Common flight altitude :math:`H > 0`, m.

    Returns
    -------
    ndarray, shape (..., M)
        The ranges :math:`d_m`, m.

    Raises
    ------
    FieldError
        As :func:`crlbswarm.fisher_information`: wrong shapes, numbers that are not real and
        finite, coordinates or altitudes outside the model's ranges.
    """
    q, s, h = check_scene(uav_xy, target_xy, altitude)
    diff = target_offsets(q, s)
    return np.sqrt(np.sum(diff * diff, axis=-1) + (h * h)[..., None])


def elevation_angles(uav_xy: ArrayLike, target_xy: ArrayLike, altitude: ArrayLike) -> np.ndarray:
    r"""Elevation :math:`\phi_m` of each UAV seen from the target, rad (Sec. III).

    :math:`\sin\phi_m = H / d_m`; :math:`\phi_m \in (0, \pi/2]`, equal to :math:`\pi/2`
    for a UAV straight above the target.

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    altitude : float or array_like, shape (...)
        Common flight altitude :math:`H > 0`, m.

    Returns
    -------
    ndarray, shape (..., M)
        Elevation angles, rad.
    """
    q, s, h = check_scene(uav_xy, target_xy, altitude)
    diff = target_offsets(q, s)
    return np.arctan2(h[..., None], np.hypot(diff[..., 0], diff[..., 1]))


def azimuth_angles(uav_xy: ArrayLike, target_xy: ArrayLike) -> np.ndarray:
    r"""Azimuth :math:`\theta_m` of the line from UAV :math:`m` to the target, rad, eq. (7).

    Eq. (7) writes :math:`(x_s - x_m)/d_m = \cos\phi_m\cos\theta_m`, so :math:`\theta_m` is
    the bearing *from the UAV to the target*, :math:`\operatorname{atan2}(y_s - y_m,
    x_s - x_m)`, in :math:`(-\pi, \pi]`. The Fisher information depends only on
    :math:`2\theta_m`, so the bearing from the target to the UAV (which differs by
    :math:`\pi`) gives the same FIM. A UAV straight above the target gets azimuth 0.

    Parameters
    ----------
    uav_xy : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.

    Returns
    -------
    ndarray, shape (..., M)
        Azimuth angles, rad.
    """
    q, s, _ = check_scene(uav_xy, target_xy, 1.0)
    diff = target_offsets(q, s)
    return np.arctan2(diff[..., 1], diff[..., 0])


def regular_polygon(
    n_uavs: int, center_xy: ArrayLike, radius: ArrayLike, rotation: float = 0.0
) -> np.ndarray:
    r"""Vertices of a regular polygon, the shape of the optimal formation (Sec. III).

    Vertex :math:`m = 1, \dots, M` sits at azimuth
    :math:`\theta_0 + 2\pi(m-1)/M` (measured from the centre, counter-clockwise from the
    x-axis) and distance ``radius`` from ``center_xy``.

    Parameters
    ----------
    n_uavs : int
        Number of vertices :math:`M \ge 1`.
    center_xy : array_like, shape (..., 2)
        Centre, m.
    radius : float or array_like, shape (...)
        Circumradius, m (>= 0); broadcasts against the batch shape of ``center_xy``.
    rotation : float, default 0
        Azimuth :math:`\theta_0` of the first vertex, rad.

    Returns
    -------
    ndarray, shape (..., M, 2)
        The vertices, first vertex at azimuth ``rotation``.

    Raises
    ------
    FieldError
        If ``n_uavs`` is not an integer from 1 to 1 000 000, the result would not fit in
        memory (refused before allocating, with the estimate), or an argument is outside
        the model's ranges (centre within +-1e7 m, radius up to 3e7 m, rotation within
        +-1e6 rad).
    """
    n = _v.count(n_uavs, "n_uavs", 1, _v.MAX_UAVS)
    c = _v.location(center_xy, "center_xy")
    r = _v.bounded(_v.as_float_array(radius, "radius"), "radius", 0.0, _v.MAX_DISTANCE, " m")
    theta0 = _v.angle(rotation, "rotation")
    batch = _v.broadcast("radius", c.shape[:-1], r.shape)
    size = float(np.prod(batch, dtype=float)) * n
    _v.check_elements(2.0 * size, "n_uavs", f"{size:.3g} vertices", copies=3)
    theta = theta0 + 2.0 * np.pi * np.arange(n) / n
    unit = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    return c[..., None, :] + r[..., None, None] * unit


def outline_order(points: ArrayLike) -> np.ndarray:
    """Order in which to join points (the UAVs of a formation) into a polygon that never
    crosses itself.

    The points are taken by their angle around their centroid (the nearer first on a tie):
    the outline of a polygon star-shaped about the centroid, which does not cross itself for
    any number of points and any layout. For a formation at (or near) a regular polygon,
    this is the ring order of its slots, whatever the UAVs' indices. The figures
    (:mod:`crlbswarm.plots`) and the animation (:mod:`crlbswarm.animation`) draw the
    formation in this order; the replay page sorts the same way in its script.

    Parameters
    ----------
    points : array_like, shape (M, 2)
        Horizontal positions, m.

    Returns
    -------
    ndarray of int, shape (M,)
        Indices into ``points``, in the order to draw them.

    Raises
    ------
    FieldError
        If ``points`` is not of shape (M, 2) (field ``points``).

    Examples
    --------
    >>> from crlbswarm.geometry import outline_order
    >>> outline_order([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]).tolist()
    [3, 0, 2, 1]
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise FieldError("points", f"expected shape (M, 2), got {p.shape}")
    d = p - p.mean(axis=0)
    return np.lexsort((np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])))


def fitted_turn(offsets: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """The rotation that brings ``offsets`` (M, 2) closest to ``positions`` (M, 2) in least
    squares (both about the same centre): the 2-D case of the orthogonal Procrustes
    problem, angle ``atan2(sum(d x p), sum(d . p))``.

    Parameters
    ----------
    offsets : ndarray, shape (M, 2)
        The slots, m.
    positions : ndarray, shape (M, 2)
        The UAVs, m.

    Returns
    -------
    ndarray, shape (2, 2)
        The rotation matrix.
    """
    cross = np.sum(offsets[:, 0] * positions[:, 1] - offsets[:, 1] * positions[:, 0])
    dot = np.sum(offsets * positions)
    angle = math.atan2(cross, dot)
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])
