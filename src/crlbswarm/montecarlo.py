"""Monte Carlo validation of the CRLB: the MLE's mean squared error beside the bound.

Not in the paper (it stops at the bound). For a formation, many independent sets of ranges
are drawn (:func:`crlbswarm.measure_ranges`), the target is estimated from each by maximum
likelihood (:func:`crlbswarm.estimate_target`, started from the closed-form linearised
estimate, so no prior is used), and the mean squared error is compared with
tr(J^-1). An efficient estimator has MSE / CRLB -> 1; at low SNR the MLE is biased and
its MSE may fall below the CRLB, which bounds unbiased estimators only.

Confidence intervals are the normal (central-limit) intervals of a mean,
``mean +- z * std / sqrt(n)``, for the MSE and for each component of the bias.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .design import optimal_radius
from .errors import FieldError
from .estimation import estimate_target, measure_ranges
from .experiments import FIXED_DISC_RADIUS, FORMATION_LABELS, formations_over_altitude
from .fisher import crlb
from .radar import Radar

__all__ = [
    "EstimatorSweep",
    "MonteCarloResult",
    "check_trials",
    "estimator_vs_altitude",
    "monte_carlo_mse",
    "summarise",
]

_DEFAULT_RADAR = Radar()

#: z-value of the two-sided 95 % normal confidence interval.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class MonteCarloResult:
    """MSE of the MLE over independent trials for one formation, beside its CRLB.

    Attributes
    ----------
    n_trials : int
        Trials run.
    n_failed : int
        Trials whose estimator did not converge; they are kept in the MSE (a failed trial
        counts with its last iterate) so that failures are not hidden.
    mse : float
        Mean squared error :math:`E\\lVert\\hat{\\mathbf s} - \\mathbf s\\rVert^2`, m^2.
    mse_ci : (float, float)
        95 % confidence interval of the MSE, m^2.
    crlb : float
        tr(J^-1) of the formation at the true target, m^2.
    bias : ndarray, shape (2,)
        Mean error, m (shape (3,) from :func:`crlbswarm.monte_carlo_mse_3d`).
    bias_ci : ndarray, shape (2, 2)
        95 % confidence interval of each bias component (rows x, y (, z); columns low,
        high), m.
    """

    n_trials: int
    n_failed: int
    mse: float
    mse_ci: tuple[float, float]
    crlb: float
    bias: np.ndarray
    bias_ci: np.ndarray

    @property
    def ratio(self) -> float:
        """MSE / CRLB."""
        return self.mse / self.crlb

    @property
    def ratio_ci(self) -> tuple[float, float]:
        """95 % confidence interval of MSE / CRLB."""
        return self.mse_ci[0] / self.crlb, self.mse_ci[1] / self.crlb


def check_trials(n_trials: int, n_uavs: int) -> None:
    """Refuse, before allocating, trials whose arrays would not fit in memory (the
    estimator holds a few dozen arrays of ``n_trials x n_uavs``).

    Parameters
    ----------
    n_trials : int
        Number of trials.
    n_uavs : int
        Number of UAVs (ranges per trial).

    Raises
    ------
    FieldError
        Naming ``n_trials``, if the request would take more than half of the memory this
        process may still allocate.
    """
    size = float(n_trials) * n_uavs
    _v.check_elements(size, "n_trials", f"{n_trials} trials of {n_uavs} ranges", copies=40)


def summarise(errors: np.ndarray, failed: np.ndarray, bound: float) -> MonteCarloResult:
    """The statistics of a Monte Carlo run: MSE, bias and their 95 % normal intervals.

    Parameters
    ----------
    errors : ndarray, shape (n, D)
        Estimation errors of ``n >= 2`` trials (D = 2 or 3 coordinates), m.
    failed : ndarray of bool, shape (n,)
        Trials whose estimator did not converge (counted, and kept in the MSE).
    bound : float
        The CRLB of the geometry, m^2.

    Returns
    -------
    MonteCarloResult
        The summary.
    """
    n = errors.shape[0]
    sq = np.sum(errors * errors, axis=-1)
    mse = float(sq.mean())
    half = Z95 * float(sq.std(ddof=1)) / np.sqrt(n)  # n >= 2 (checked by the callers)
    bias = errors.mean(axis=0)
    bias_half = Z95 * errors.std(axis=0, ddof=1) / np.sqrt(n)
    return MonteCarloResult(
        n_trials=n,
        n_failed=int(failed.sum()),
        mse=mse,
        mse_ci=(mse - half, mse + half),
        crlb=float(bound),
        bias=bias,
        bias_ci=np.stack([bias - bias_half, bias + bias_half], axis=-1),
    )


def monte_carlo_mse(
    uav_xy: ArrayLike,
    target_xy: ArrayLike,
    altitude: float,
    radar: Radar = _DEFAULT_RADAR,
    n_trials: int = 20_000,
    rng: np.random.Generator | None = None,
    prior_std: float | None = None,
) -> MonteCarloResult:
    """MSE of the MLE over ``n_trials`` independent sets of ranges, with its CRLB.

    Parameters
    ----------
    uav_xy : array_like, shape (M, 2)
        One formation, m.
    target_xy : array_like, shape (2,)
        True target, m.
    altitude : float
        Flight altitude, m.
    radar : Radar, optional
        Link parameters (paper profile by default).
    n_trials : int, default 20000
        Number of independent trials (at least 2).
    rng : numpy.random.Generator
        Source of the measurement noise (required).
    prior_std : float, optional
        If given, each trial starts from a coarse prior, the true target plus Gaussian noise
        of this standard deviation per axis (m), drawn from ``rng`` after the ranges, as the
        paper assumes; otherwise from the closed-form linearised estimate (no prior). A
        prior is needed when the geometry is ambiguous: UAVs on a line give the same ranges
        for the target and its mirror image across the line.

    Returns
    -------
    MonteCarloResult
        MSE with its 95 % confidence interval, the CRLB, the bias and failures.
    """
    q = _v.coordinates(uav_xy, "uav_xy")
    if q.ndim != 2:
        raise FieldError("uav_xy", f"expected one formation of shape (M, 2), got {q.shape}")
    s = _v.location(target_xy, "target_xy")
    if s.shape != (2,):
        raise FieldError("target_xy", f"expected shape (2,), got {s.shape}")
    h = _v.scalar(altitude, "altitude")
    _v.altitude(h, "altitude")
    n = _v.count(n_trials, "n_trials", 2)
    check_trials(n, q.shape[0])
    if not isinstance(rng, np.random.Generator):
        raise FieldError("rng", f"expected a numpy.random.Generator, got {type(rng).__name__}")
    spread = None if prior_std is None else _v.scalar(prior_std, "prior_std")
    if spread is not None and not 0 < spread <= _v.MAX_DISTANCE:
        raise FieldError(
            "prior_std", f"must be > 0 and at most {_v.MAX_DISTANCE:g} m, got {spread!r}"
        )
    batch = np.broadcast_to(q, (n, *q.shape))
    ranges = measure_ranges(batch, s, h, radar, rng)
    assert rng is not None  # (measure_ranges refuses anything but a Generator)
    init = None
    if spread is not None:
        init = s + spread * rng.standard_normal((n, 2))
        # (kept within the coordinate range the estimator accepts; a no-op for any prior
        # that is not absurdly wide)
        init = np.clip(init, -_v.MAX_COORDINATE, _v.MAX_COORDINATE)
    est = estimate_target(batch, ranges, h, radar, init=init)
    return summarise(est.position - s, est.failed, float(crlb(q, s, h, radar)))


@dataclass(frozen=True)
class EstimatorSweep:
    """MSE of the MLE and the CRLB against altitude for F* and the benchmarks.

    Attributes
    ----------
    altitude : ndarray, shape (K,)
        Altitudes, m.
    n_trials : int
        Trials per altitude and formation.
    results : dict of str to list of MonteCarloResult
        For each formation (keys of :data:`crlbswarm.FORMATION_LABELS`), one result per
        altitude. ``random_disc`` is one seeded draw per altitude (its own CRLB), not a
        mean over draws (the same unit-disc draw, scaled by :math:`2r^*`, at every
        altitude); ``fixed_disc`` is that same draw at a fixed radius in metres. ``line``
        starts every trial from a coarse prior (true target plus N(0, (r*/8)^2) per axis):
        a line of UAVs cannot tell the target from its mirror image, so without a prior the
        MLE picks either at random. All other formations start from the closed-form
        linearised estimate.
    """

    altitude: np.ndarray
    n_trials: int
    results: dict[str, list[MonteCarloResult]]

    def columns(self) -> dict[str, np.ndarray]:
        """Flat CSV columns: altitude, then per formation CRLB, MSE and its 95 % interval.

        Returns
        -------
        dict of str to ndarray, shape (K,)
            ``altitude_m``, and for each formation ``crlb_<name>_m2``, ``mse_<name>_m2``,
            ``mse_low_<name>_m2``, ``mse_high_<name>_m2``, ``failed_<name>``.
        """
        cols: dict[str, np.ndarray] = {"altitude_m": self.altitude}
        for name, rows in self.results.items():
            cols[f"crlb_{name}_m2"] = np.array([r.crlb for r in rows])
            cols[f"mse_{name}_m2"] = np.array([r.mse for r in rows])
            cols[f"mse_low_{name}_m2"] = np.array([r.mse_ci[0] for r in rows])
            cols[f"mse_high_{name}_m2"] = np.array([r.mse_ci[1] for r in rows])
            cols[f"failed_{name}"] = np.array([r.n_failed for r in rows])
        return cols


def estimator_vs_altitude(
    altitudes: ArrayLike | None = None,
    n_uavs: int = 6,
    radar: Radar = _DEFAULT_RADAR,
    *,
    n_trials: int = 2000,
    seed: int = 0,
    fixed_radius: float = 5.0,
    arc_span: float = 0.5 * np.pi,
    disc_factor: float = 2.0,
    fixed_disc_radius: float = FIXED_DISC_RADIUS,
) -> EstimatorSweep:
    """MSE of the MLE beside the CRLB over altitude, for F* and every benchmark formation.

    Parameters
    ----------
    altitudes : array_like, shape (K,), optional
        Altitudes, m; by default 12 log-spaced values from 10 m to 3 km.
    n_uavs : int, default 6
        Number of UAVs.
    radar : Radar, optional
        Link parameters (scalar fields).
    n_trials : int, default 2000
        Trials per altitude and formation.
    seed : int, default 0
        Seed: the random formations and, through spawned streams, every trial's noise.
    fixed_radius : float, default 5
        Radius of the fixed-radius polygon, m.
    arc_span : float, default pi/2
        Span of the arc, rad.
    disc_factor : float, default 2
        Radius of the random disc in units of r*.
    fixed_disc_radius : float, default 10
        Radius of the fixed random disc (``fixed_disc``), m, whatever the altitude.

    Returns
    -------
    EstimatorSweep
        One :class:`MonteCarloResult` per formation and altitude.
    """
    if altitudes is None:
        altitudes = np.geomspace(10.0, 3000.0, 12)
    n = _v.count(n_trials, "n_trials", 2)
    check_trials(n, _v.uav_count(n_uavs, "n_uavs"))
    seed = _v.seed(seed, "seed")
    h, formations = formations_over_altitude(
        altitudes, n_uavs, radar, fixed_radius, arc_span, disc_factor, 1, seed, fixed_disc_radius
    )
    for name in ("random_disc", "fixed_disc"):
        formations[name] = formations[name][:, 0]
    streams = np.random.SeedSequence(seed).spawn(len(formations) * h.size)
    results: dict[str, list[MonteCarloResult]] = {name: [] for name in FORMATION_LABELS}
    origin = np.zeros(2)
    r_star = optimal_radius(h, radar)
    for i, (name, shapes) in enumerate(formations.items()):
        for k in range(h.size):
            rng = np.random.default_rng(streams[i * h.size + k])
            prior = r_star[k] / 8.0 if name == "line" else None
            results[name].append(
                monte_carlo_mse(shapes[k], origin, h[k], radar, n, rng, prior_std=prior)
            )
    return EstimatorSweep(altitude=h, n_trials=n, results=results)
