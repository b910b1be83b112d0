r"""Experiments behind the paper's figures: data only, no plotting and no files.

* :func:`crlb_vs_altitude` — Fig. 2, the CRLB of :math:`F^*` and of every benchmark
  formation (:mod:`crlbswarm.formations`) against the flight altitude.
* :func:`optimal_elevation_curve` — :math:`\phi^*(H)` and :math:`r^*(H)` over a wide altitude
  range (1 m to 20 km by default), showing the limits 54.74 deg and 45 deg of Sec. III.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .design import crlb_bound, optimal_elevation, optimal_formation, optimal_radius
from .errors import FieldError
from .fisher import crlb
from .formations import (
    MIN_SPAN,
    arc_formation,
    fixed_radius_polygon,
    line_formation,
    random_disc_formations,
)
from .radar import Radar, check_radar

__all__ = [
    "FIXED_DISC_RADIUS",
    "FORMATION_LABELS",
    "AltitudeSweep",
    "ElevationCurve",
    "crlb_vs_altitude",
    "formations_over_altitude",
    "optimal_elevation_curve",
]

#: Altitudes of Fig. 2 by default: 10 m to 200 m in steps of 5 m.
DEFAULT_ALTITUDES = np.arange(10.0, 200.0 + 1e-9, 5.0)

#: Legend labels of the formations of Fig. 2, F* first (keys are CSV column stems).
FORMATION_LABELS: dict[str, str] = {
    "optimal": "F* (CRLB-optimal)",
    "fixed_polygon": "regular polygon, fixed radius",
    "arc": "one-sided 90° arc at r*",
    "line": "line at distance r*",
    "random_disc": "random in disc of radius 2r* (mean)",
    "fixed_disc": "random in a fixed disc, r = 10 m (mean)",
}

#: Radius of the ``fixed_disc`` benchmark by default, m: the disc of the paper mission's
#: 20 m x 20 m start square, the same whatever the altitude.
FIXED_DISC_RADIUS = 10.0

_DEFAULT_RADAR = Radar()


@dataclass(frozen=True)
class AltitudeSweep:
    """Data of Fig. 2: CRLB against altitude for :math:`F^*` and the benchmarks.

    Attributes
    ----------
    altitude : ndarray, shape (K,)
        Flight altitudes, m.
    n_uavs : int
        Number of UAVs M.
    bound : ndarray, shape (K,)
        Theoretical bound :math:`4/\\sum_m w_m^*`, eq. (11), m^2.
    crlb : dict of str to ndarray, shape (K,)
        CRLB of each formation, m^2, keyed as :data:`FORMATION_LABELS`; for
        ``random_disc`` the mean over the draws.
    sem : dict of str to ndarray, shape (K,)
        Standard error of each entry of ``crlb`` (zero for deterministic formations).
    parameters : dict
        The benchmark parameters used (fixed radius, arc span, disc factor, draws, seed).
    """

    altitude: np.ndarray
    n_uavs: int
    bound: np.ndarray
    crlb: dict[str, np.ndarray]
    sem: dict[str, np.ndarray]
    parameters: dict[str, float]

    def columns(self) -> dict[str, np.ndarray]:
        """Flat CSV columns: altitude, bound, then ``crlb_<name>`` and ``sem_<name>``.

        Returns
        -------
        dict of str to ndarray, shape (K,)
            ``altitude_m``, ``bound_m2``, ``crlb_<formation>_m2`` for every formation, and
            ``sem_<formation>_m2`` for the random ones.
        """
        cols = {"altitude_m": self.altitude, "bound_m2": self.bound}
        for name, values in self.crlb.items():
            cols[f"crlb_{name}_m2"] = values
        for name, values in self.sem.items():
            if np.any(values):
                cols[f"sem_{name}_m2"] = values
        return cols


@dataclass(frozen=True)
class ElevationCurve:
    """Optimal elevation and radius against altitude (Sec. III).

    Attributes
    ----------
    altitude : ndarray, shape (K,)
        Flight altitudes, m.
    elevation : ndarray, shape (K,)
        :math:`\\phi^*`, rad.
    radius : ndarray, shape (K,)
        :math:`r^* = H/\\tan\\phi^*`, m.
    """

    altitude: np.ndarray
    elevation: np.ndarray
    radius: np.ndarray

    def columns(self) -> dict[str, np.ndarray]:
        """Flat columns for a CSV file (elevation in degrees, as at every edge).

        Returns
        -------
        dict of str to ndarray, shape (K,)
            ``altitude_m``, ``elevation_deg``, ``radius_m``.
        """
        return {
            "altitude_m": self.altitude,
            "elevation_deg": np.degrees(self.elevation),
            "radius_m": self.radius,
        }


#: Largest radius of the random disc in units of r* (r* <= H <= MAX_ALTITUDE, so that the
#: disc stays within the coordinate range).
MIN_DISC_FACTOR = 1e-3
MAX_DISC_FACTOR = 30.0


def _altitudes(altitudes: ArrayLike) -> np.ndarray:
    """A non-empty 1-D array of altitudes within the model's range."""
    h = _v.altitude(altitudes, "altitudes")
    if h.ndim != 1 or h.size == 0:
        raise FieldError("altitudes", f"expected a non-empty 1-D array, got shape {h.shape}")
    return h


def formations_over_altitude(
    altitudes: ArrayLike,
    n_uavs: int,
    radar: Radar,
    fixed_radius: float,
    arc_span: float,
    disc_factor: float,
    n_random: int,
    seed: int,
    fixed_disc_radius: float = FIXED_DISC_RADIUS,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """F* and every benchmark formation over a range of altitudes, target at the origin.

    Parameters
    ----------
    altitudes : array_like, shape (K,)
        Altitudes, m.
    n_uavs : int
        Number of UAVs M.
    radar : Radar
        Link parameters (scalar fields).
    fixed_radius : float
        Radius of the fixed-radius polygon, m.
    arc_span : float
        Angular span of the arc, rad, in (0, pi].
    disc_factor : float
        Radius of the random disc as a multiple of r*.
    n_random : int
        Number of random formations per altitude.
    seed : int
        Seed of the random formations.
    fixed_disc_radius : float, default 10
        Radius of the ``fixed_disc`` benchmark, m: the same at every altitude.

    Returns
    -------
    altitudes : ndarray, shape (K,)
        The validated altitudes (a copy).
    formations : dict of str to ndarray
        By :data:`FORMATION_LABELS` key: shape (K, M, 2) for the deterministic formations,
        (K, n_random, M, 2) for ``random_disc`` and ``fixed_disc`` (the same unit-disc
        draws, scaled by ``disc_factor`` :math:`r^*` and by ``fixed_disc_radius``).
    """
    h = _altitudes(altitudes)
    check_radar(radar, None)
    if radar.per_uav:
        raise FieldError("radar", "the altitude sweeps need scalar radar fields")
    n = _v.uav_count(n_uavs, "n_uavs")
    factor = _v.scalar(disc_factor, "disc_factor")
    if not MIN_DISC_FACTOR <= factor <= MAX_DISC_FACTOR:
        raise FieldError(
            "disc_factor",
            f"must be between {MIN_DISC_FACTOR:g} and {MAX_DISC_FACTOR:g}, got {factor!r}",
        )
    _v.length(_v.scalar(fixed_radius, "fixed_radius"), "fixed_radius")
    name = "fixed_disc_radius"
    disc_radius = float(_v.length(_v.scalar(fixed_disc_radius, name), name))
    span = _v.scalar(arc_span, "arc_span")
    if not MIN_SPAN <= span <= np.pi:
        raise FieldError("arc_span", f"must lie in [{MIN_SPAN:g}, pi] rad, got {span!r}")
    draws = _v.count(n_random, "n_random", 1)
    seed = _v.seed(seed, "seed")
    size = float(h.size) * (2 * draws + 4) * n
    _v.check_elements(2.0 * size, "n_random", f"{size:.3g} UAV positions", copies=4)
    h = h.copy()  # results must not share memory with the caller's array
    origin = np.zeros(2)
    r_star = optimal_radius(h, radar)
    return h, {
        "optimal": optimal_formation(n, origin, h, radar),
        "fixed_polygon": fixed_radius_polygon(n, np.zeros((h.size, 2)), fixed_radius),
        "arc": arc_formation(n, origin, r_star, span=span),
        "line": line_formation(n, origin, r_star, 2.0 * r_star),
        "random_disc": random_disc_formations(
            n, origin, factor * r_star, draws, np.random.default_rng(seed)
        ),
        # The same unit-disc draws (same seed), at a fixed size in metres.
        "fixed_disc": random_disc_formations(
            n, origin, np.full(h.size, disc_radius), draws, np.random.default_rng(seed)
        ),
    }


def crlb_vs_altitude(
    altitudes: ArrayLike = DEFAULT_ALTITUDES,
    n_uavs: int = 6,
    radar: Radar = _DEFAULT_RADAR,
    *,
    fixed_radius: float = 5.0,
    arc_span: float = 0.5 * np.pi,
    disc_factor: float = 2.0,
    n_random: int = 200,
    seed: int = 0,
    fixed_disc_radius: float = FIXED_DISC_RADIUS,
) -> AltitudeSweep:
    """CRLB against altitude for :math:`F^*` and the benchmark formations (Fig. 2).

    The target sits at the origin (the CRLB is invariant to translation). The benchmarks
    are those of :mod:`crlbswarm.formations`: ``fixed_polygon`` (radius ``fixed_radius``),
    ``arc`` (span ``arc_span`` at :math:`r^*`), ``line`` (length :math:`2r^*` at distance
    :math:`r^*`), ``random_disc`` (radius ``disc_factor`` :math:`r^*`, mean over
    ``n_random`` draws; the same draws, scaled, at every altitude) and ``fixed_disc`` (the
    same draws in a disc of radius ``fixed_disc_radius`` whatever the altitude).

    Parameters
    ----------
    altitudes : array_like, shape (K,), default 10 m to 200 m in steps of 5 m
        Flight altitudes, m (> 0).
    n_uavs : int, default 6
        Number of UAVs, at least 3.
    radar : Radar, optional
        Link parameters (scalar fields).
    fixed_radius : float, default 5
        Radius of the fixed-radius polygon, m. It equals :math:`F^*` at the altitude where
        :math:`r^*(H)` equals it (about 7.1 m for 5 m).
    arc_span : float, default pi/2
        Angle covered by the arc, rad.
    disc_factor : float, default 2
        Radius of the random disc in units of :math:`r^*`.
    n_random : int, default 200
        Number of random formations per altitude.
    seed : int, default 0
        Seed of the random formations.
    fixed_disc_radius : float, default 10
        Radius of the fixed random disc, m (:data:`FIXED_DISC_RADIUS`).

    Returns
    -------
    AltitudeSweep
        The data of Fig. 2.
    """
    h, formations = formations_over_altitude(
        altitudes,
        n_uavs,
        radar,
        fixed_radius,
        arc_span,
        disc_factor,
        n_random,
        seed,
        fixed_disc_radius,
    )
    origin = np.zeros(2)
    values: dict[str, np.ndarray] = {}
    sem: dict[str, np.ndarray] = {}
    for name, f in formations.items():
        if f.ndim == 3:  # one deterministic formation per altitude
            values[name] = crlb(f, origin, h, radar)
            sem[name] = np.zeros_like(h)
            continue
        draws = crlb(f, origin, h[:, None], radar)  # (K, n_random)
        values[name] = draws.mean(axis=-1)
        sem[name] = (
            draws.std(axis=-1, ddof=1) / np.sqrt(n_random) if n_random > 1 else np.zeros_like(h)
        )
    return AltitudeSweep(
        altitude=h,
        n_uavs=n_uavs,
        bound=crlb_bound(n_uavs, h, radar),
        crlb=values,
        sem=sem,
        parameters={
            "fixed_radius_m": float(fixed_radius),
            "arc_span_rad": float(arc_span),
            "disc_factor": float(disc_factor),
            "n_random": int(n_random),
            "seed": int(seed),
            "fixed_disc_radius_m": float(fixed_disc_radius),
        },
    )


def optimal_elevation_curve(
    altitudes: ArrayLike | None = None, radar: Radar = _DEFAULT_RADAR
) -> ElevationCurve:
    """Optimal elevation :math:`\\phi^*` and radius :math:`r^*` over altitude (Sec. III).

    Parameters
    ----------
    altitudes : array_like, shape (K,), optional
        Flight altitudes, m; by default 241 log-spaced values from 1 m to 20 km.
    radar : Radar, optional
        Link parameters (scalar fields).

    Returns
    -------
    ElevationCurve
        Altitude, elevation (rad) and radius (m).
    """
    if altitudes is None:
        altitudes = np.geomspace(1.0, 2.0e4, 241)
    h = _altitudes(altitudes)
    check_radar(radar, None)
    if radar.per_uav:
        raise FieldError("radar", "optimal_elevation_curve needs scalar radar fields")
    h = h.copy()  # the result must not share memory with the caller's array
    return ElevationCurve(
        altitude=h,
        elevation=optimal_elevation(h, radar),
        radius=optimal_radius(h, radar),
    )
