r"""Benchmark formations for Fig. 2 of the paper (not named in the paper; our choices).

The paper compares :math:`F^*` with unnamed "benchmark formations". crlbswarm provides five,
each a plausible formation a designer might fly without the CRLB analysis, and each strictly
worse than :math:`F^*` at every altitude of Fig. 2 (reasons below and in the user guide):

``fixed_polygon``
    A regular polygon of fixed radius (5 m by default) whatever the altitude: the right
    shape at the wrong size. It coincides with :math:`F^*` only at the altitude where
    :math:`r^*(H)` equals its radius (about 7 m for 5 m), below the plotted range.
``arc``
    UAVs evenly spaced on a one-sided arc (azimuths within a quarter turn, 90 deg, inclusive
    ends) at the optimal radius: the right elevation with poor angular diversity. A
    half-turn arc with spacing :math:`\pi/M` is *not* a benchmark: since the FIM depends on
    :math:`2\theta_m` it is exactly as good as :math:`F^*`.
``line``
    UAVs evenly spaced on a straight line (length :math:`2r^*`) at distance :math:`r^*` from
    the target, perpendicular to the line of sight: the formation of a sweep.
``random_disc``
    UAVs drawn uniformly in a disc of radius :math:`2r^*` centred on the target; Fig. 2
    shows the mean CRLB over seeded draws.
``fixed_disc``
    The same draws in a disc of a fixed radius (10 m by default, the paper mission's start
    square) whatever the altitude, also built by :func:`random_disc_formations`: with the
    fixed polygon, the benchmark whose gap to :math:`F^*` grows with the altitude.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError
from .geometry import regular_polygon

__all__ = [
    "arc_formation",
    "fixed_radius_polygon",
    "line_formation",
    "random_disc_formations",
]


#: Smallest span of an arc, rad: narrower, the UAVs are on one line through the target
#: and the CRLB (about 1/span^2) overflows.
MIN_SPAN = 1e-6


def _check_size(batch: tuple[int, ...], n: int, name: str) -> None:
    """Refuse, before allocating, formations that would not fit in memory."""
    size = float(np.prod(batch, dtype=float)) * n
    _v.check_elements(2.0 * size, name, f"{size:.3g} UAV positions", copies=3)


def fixed_radius_polygon(
    n_uavs: int, target_xy: ArrayLike, radius: ArrayLike = 5.0, rotation: float = 0.0
) -> np.ndarray:
    """Regular polygon of a fixed radius centred on the target (benchmark ``fixed_polygon``).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs, at least 3.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    radius : float or array_like, shape (...), default 5
        Radius of the polygon, m (> 0).
    rotation : float, default 0
        Azimuth of UAV 1 seen from the target, rad.

    Returns
    -------
    ndarray, shape (..., M, 2)
        Horizontal positions, m.
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    s = _v.location(target_xy, "target_xy")
    r = _v.length(radius, "radius")
    return regular_polygon(n, s, r, rotation)


def arc_formation(
    n_uavs: int,
    target_xy: ArrayLike,
    radius: ArrayLike,
    span: float = 0.5 * np.pi,
    heading: float = 0.0,
) -> np.ndarray:
    r"""UAVs evenly spaced on a one-sided arc around the target (benchmark ``arc``).

    Azimuths (seen from the target) run from ``heading - span/2`` to ``heading + span/2``,
    both ends included.

    Parameters
    ----------
    n_uavs : int
        Number of UAVs, at least 3.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    radius : float or array_like, shape (...)
        Arc radius, m (> 0).
    span : float, default pi/2
        Angle covered by the arc, rad, in (0, pi]. For ``span <= pi/2`` the doubled
        azimuths lie in a half plane, so the FIM cannot be isotropic and the CRLB is strictly
        above the bound.
    heading : float, default 0
        Azimuth of the middle of the arc, rad.

    Returns
    -------
    ndarray, shape (..., M, 2)
        Horizontal positions, m.
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    s = _v.location(target_xy, "target_xy")
    r = _v.length(radius, "radius")
    width = _v.scalar(span, "span")
    if not MIN_SPAN <= width <= np.pi:
        raise FieldError("span", f"must lie in [{MIN_SPAN:g}, pi] rad, got {width!r}")
    psi = _v.angle(heading, "heading")
    batch = _v.broadcast("radius", s.shape[:-1], r.shape)
    _check_size(batch, n, "n_uavs")
    theta = psi + width * (np.arange(n) / (n - 1) - 0.5)
    unit = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    return s[..., None, :] + r[..., None, None] * unit


def line_formation(
    n_uavs: int,
    target_xy: ArrayLike,
    offset: ArrayLike,
    length: ArrayLike,
    heading: float = 0.0,
) -> np.ndarray:
    """UAVs evenly spaced on a straight line beside the target (benchmark ``line``).

    The line is perpendicular to the direction ``heading`` (seen from the target), at
    horizontal distance ``offset`` from the target; the UAVs span ``length`` centred on the
    foot of the perpendicular.

    Parameters
    ----------
    n_uavs : int
        Number of UAVs, at least 3.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    offset : float or array_like, shape (...)
        Distance from the target to the line, m (> 0: a line through the target's
        projection makes the FIM singular).
    length : float or array_like, shape (...)
        Distance between the first and the last UAV, m (> 0).
    heading : float, default 0
        Azimuth of the foot of the perpendicular seen from the target, rad.

    Returns
    -------
    ndarray, shape (..., M, 2)
        Horizontal positions, m.
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    s = _v.location(target_xy, "target_xy")
    off = _v.length(offset, "offset")
    size = _v.length(length, "length")
    psi = _v.angle(heading, "heading")
    batch = _v.broadcast("offset", s.shape[:-1], off.shape)
    batch = _v.broadcast("length", batch, size.shape)
    _check_size(batch, n, "n_uavs")
    normal = np.array([np.cos(psi), np.sin(psi)])
    along = np.array([-np.sin(psi), np.cos(psi)])
    t = np.arange(n) / (n - 1) - 0.5
    return (
        s[..., None, :] + off[..., None, None] * normal + (size[..., None] * t)[..., None] * along
    )


def random_disc_formations(
    n_uavs: int,
    target_xy: ArrayLike,
    radius: ArrayLike,
    n_draws: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """UAVs uniform in a disc centred on the target (benchmark ``random_disc``).

    The same unit-disc draws are scaled by ``radius``, so a batch of radii (for example one
    per altitude) reuses one set of random numbers (common random numbers: smooth curves).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs, at least 3.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    radius : float or array_like, shape (...)
        Disc radius, m (> 0).
    n_draws : int
        Number of independent formations, at least 1.
    rng : numpy.random.Generator
        Source of the draws.

    Returns
    -------
    ndarray, shape (..., n_draws, M, 2)
        Horizontal positions, m.
    """
    n = _v.uav_count(n_uavs, "n_uavs")
    k = _v.count(n_draws, "n_draws", 1)
    s = _v.location(target_xy, "target_xy")
    r = _v.length(radius, "radius")
    if not isinstance(rng, np.random.Generator):
        raise FieldError("rng", f"expected a numpy.random.Generator, got {type(rng).__name__}")
    batch = _v.broadcast("radius", s.shape[:-1], r.shape)
    _check_size((*batch, k), n, "n_draws")
    rho = np.sqrt(rng.random((k, n)))
    theta = 2.0 * np.pi * rng.random((k, n))
    unit = np.stack([rho * np.cos(theta), rho * np.sin(theta)], axis=-1)
    return s[..., None, None, :] + r[..., None, None, None] * unit
