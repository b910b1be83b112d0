"""Range measurements, likelihood, linearised initialiser and MLE (crlbswarm.estimation).

Every reference here is independent of crlbswarm:

* the SNR constant ``A = p G_p beta0 / (kappa sigma0^2)`` is computed below from the raw
  paper-profile numbers (docs/sensing-model.md), not taken from :class:`crlbswarm.Radar`;
* the negative log-likelihood is ``-sum scipy.stats.norm.logpdf(d_hat; d, d^2 / sqrt(A))``;
* the MLE is found by :func:`scipy.optimize.minimize` (BFGS) on an objective written in the
  test (the ``ref`` fixture's Gaussian log-likelihood, built from the raw radar numbers),
  polished by :func:`scipy.optimize.root` on its gradient, which BFGS cannot resolve below
  the rounding of the objective;
* gradients are complex-step derivatives of that objective (no truncation or cancellation
  error), Hessians central differences of those gradients, both in coordinates whitened
  by the reference FIM so that one step size suits every altitude.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, strategies as st
from scipy.optimize import minimize, root
from scipy.stats import chi2, norm

from crlbswarm import (
    FieldError,
    Radar,
    TargetEstimate,
    estimate_target,
    fixed_radius_polygon,
    line_formation,
    linearised_estimate,
    measure_ranges,
    negative_log_likelihood,
    optimal_formation,
    optimal_radius,
    random_disc_formations,
)

# -- independent reference numbers -------------------------------------------------------

#: Speed of light, m/s.
C_LIGHT = 299_792_458.0


def snr_constant(tx_power=0.1):
    """A = p G_p beta0 / (kappa sigma0^2), m^4, from the raw paper-profile numbers."""
    wavelength = C_LIGHT / 5.8e9  # f_c = 5.8 GHz
    beta0 = 1.0 * 1.0 * 1.0 * wavelength**2 / (4.0 * math.pi) ** 3  # G_T G_r rcs lambda^2/(4pi)^3
    return np.asarray(tx_power) * 1000.0 * beta0 / (1.0 * 1e-12)  # p G_p beta0 / (kappa sigma0^2)


A_PAPER = float(snr_constant())

#: Family-wise false-alarm rate of every statistical check in this file.
ALPHA = 1e-3


def true_ranges(uav_xy, target_xy, altitude):
    """d_m = sqrt(|q_m - s|^2 + H^2), written out here."""
    q = np.asarray(uav_xy, dtype=float)
    s = np.asarray(target_xy, dtype=float)
    return np.sqrt((q[..., 0] - s[0]) ** 2 + (q[..., 1] - s[1]) ** 2 + altitude**2)


def nll_scipy_stats(target_xy, uav_xy, d_hat, altitude, a=A_PAPER):
    """-sum_m log N(d_hat_m; d_m, d_m^4 / A_m) with scipy.stats."""
    d = true_ranges(uav_xy, target_xy, altitude)
    return -np.sum(norm.logpdf(d_hat, loc=d, scale=d * d / np.sqrt(a)), axis=-1)


def test_reference_constant_matches_paper_notes():
    """Guard of the reference itself: A is about 1.3463e8 m^4 (docs/sensing-model.md)."""
    assert abs(A_PAPER / 1.3463e8 - 1.0) < 1e-4


# -- helpers on the independent likelihood (ref fixture) --------------------------------


class Likelihood:
    """The reference negative log-likelihood of one set of ranges, with its derivatives.

    Coordinates are whitened by the reference FIM ``J`` at ``anchor``: ``s = anchor + T x``
    with ``T^T J T = I``, so that near the MLE the Hessian in ``x`` is close to identity.
    """

    def __init__(self, ref, uav_xy, d_hat, altitude, anchor, prm=None):
        self.ref = ref
        self.q = np.asarray(uav_xy, dtype=float)
        self.d_hat = np.asarray(d_hat, dtype=float)
        self.altitude = float(altitude)
        self.prm = ref.radar_params() if prm is None else prm
        self.anchor = np.asarray(anchor, dtype=float)
        fim = ref.fim_slepian_bangs(self.q, self.anchor, self.altitude, self.prm)
        self.T = np.linalg.inv(np.linalg.cholesky(fim)).T

    def nll(self, s):
        terms = self.ref.log_likelihood_terms(self.d_hat, self.q, s, self.altitude, self.prm)
        return -np.sum(terms)

    def grad(self, s):
        """Complex-step gradient in metres^-1."""
        return self.ref.complex_step_grad(self.nll, np.asarray(s, dtype=float))

    def to_s(self, x):
        return self.anchor + self.T @ np.asarray(x, dtype=float)

    def white_grad(self, x):
        return self.T.T @ self.grad(self.to_s(x))

    def white_hess(self, x, step=1e-4):
        cols = [
            (self.white_grad(x + step * e) - self.white_grad(x - step * e)) / (2.0 * step)
            for e in np.eye(2)
        ]
        h = np.stack(cols, axis=-1)
        return 0.5 * (h + h.T)

    def newton_displacement(self, s):
        """(|H^-1 g| in metres, eigenvalues of the whitened Hessian) at ``s``."""
        x = np.linalg.solve(self.T, np.asarray(s, dtype=float) - self.anchor)
        h = self.white_hess(x)
        eig = np.linalg.eigvalsh(h)
        if eig[0] <= 0:
            return np.inf, eig
        return float(np.linalg.norm(self.T @ np.linalg.solve(h, self.white_grad(x)))), eig

    def minimise(self, start):
        """SciPy's local minimiser from ``start`` (BFGS, then a root polish of the gradient)."""
        x0 = np.linalg.solve(self.T, np.asarray(start, dtype=float) - self.anchor)
        res = minimize(
            lambda x: self.nll(self.to_s(x)),
            x0,
            jac=self.white_grad,
            method="BFGS",
            options={"gtol": 1e-9, "maxiter": 1000},
        )
        polished = root(self.white_grad, res.x, jac=self.white_hess, method="hybr", tol=1e-15)
        s = self.to_s(polished.x)
        # The reference must itself be a precise local minimum, or the comparison is void.
        disp, eig = self.newton_displacement(s)
        assert eig[0] > 0
        assert disp < 1e-9 * (1.0 + np.linalg.norm(s - self.q.mean(axis=0)))
        return s


def rotation(theta):
    return np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])


# == measure_ranges ======================================================================

NOISE_GEOMETRY = np.array([[0.0, 0.0], [30.0, 0.0], [0.0, -60.0], [-120.0, 40.0], [250.0, 250.0]])


@pytest.mark.parametrize(
    ("altitude", "tx_power"),
    [(20.0, 0.1), (150.0, 0.1), (60.0, [0.05, 0.1, 0.4, 0.2, 1.0])],
)
def test_measure_ranges_noise_statistics(altitude, tx_power):
    """200k draws: per UAV, mean error 0 (normal bound) and variance d^4/A (chi-square).

    The UAVs sit at very different ranges (about 20 m to 360 m), so the variance check
    tells d^4 apart from any other power of d; the last case has per-UAV powers (A_m).
    """
    target = np.array([10.0, -5.0])
    n = 200_000
    n_uavs = NOISE_GEOMETRY.shape[0]
    radar = Radar(tx_power=tx_power)
    draws = measure_ranges(
        np.broadcast_to(NOISE_GEOMETRY, (n, n_uavs, 2)),
        target,
        altitude,
        radar,
        rng=np.random.default_rng(20240601),
    )
    assert draws.shape == (n, n_uavs)
    d = true_ranges(NOISE_GEOMETRY, target, altitude)
    var = d**4 / snr_constant(tx_power)
    err = draws - d
    # Bonferroni over the 2 checks of each of the M UAVs.
    alpha = ALPHA / (2 * n_uavs)
    z = norm.isf(alpha / 2)
    assert np.all(np.abs(err.mean(axis=0)) <= z * np.sqrt(var / n))
    stat = (n - 1) * err.var(axis=0, ddof=1) / var
    assert np.all(stat > chi2.ppf(alpha / 2, n - 1))
    assert np.all(stat < chi2.isf(alpha / 2, n - 1))
    # The check is sharp: the chi-square band is about +-1.2 % of the variance.
    assert chi2.isf(alpha / 2, n - 1) / (n - 1) < 1.013


def test_measure_ranges_batch_shapes():
    rng = np.random.default_rng(3)
    q = rng.uniform(-50.0, 50.0, (4, 6, 2))
    out = measure_ranges(q, rng.uniform(-5, 5, (4, 2)), [10.0, 20.0, 30.0, 40.0], rng=rng)
    assert out.shape == (4, 6)
    assert np.all(np.isfinite(out))
    out = measure_ranges(q[0], (0.0, 0.0), np.array([10.0, 20.0, 30.0]), rng=rng)
    assert out.shape == (3, 6)


def test_measure_ranges_same_seed_identical_other_seed_differs():
    q = optimal_formation(6, (3.0, 4.0), 20.0)
    first = measure_ranges(
        np.broadcast_to(q, (100, 6, 2)), (3.0, 4.0), 20.0, rng=np.random.default_rng(5)
    )
    again = measure_ranges(
        np.broadcast_to(q, (100, 6, 2)), (3.0, 4.0), 20.0, rng=np.random.default_rng(5)
    )
    other = measure_ranges(
        np.broadcast_to(q, (100, 6, 2)), (3.0, 4.0), 20.0, rng=np.random.default_rng(6)
    )
    assert np.array_equal(first, again)
    assert np.all(first != other)


@pytest.mark.parametrize(
    "rng", [None, 0, np.random.RandomState(0), np.random.default_rng, np.random.SeedSequence(0)]
)
def test_measure_ranges_rng_must_be_a_generator(rng):
    with pytest.raises(ValueError, match="rng"):
        measure_ranges(optimal_formation(6, (0.0, 0.0), 20.0), (0.0, 0.0), 20.0, rng=rng)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"uav_xy": np.zeros((6, 3))}, "uav_xy"),
        ({"uav_xy": [[0.0, np.nan], [1.0, 1.0], [2.0, 0.0]]}, "uav_xy"),
        ({"target_xy": (0.0, 0.0, 0.0)}, "target_xy"),
        ({"altitude": 0.0}, "altitude"),
        ({"altitude": -20.0}, "altitude"),
        ({"radar": "paper"}, "radar"),
    ],
)
def test_measure_ranges_bad_inputs(kwargs, name):
    args = {"uav_xy": optimal_formation(6, (0.0, 0.0), 20.0), "target_xy": (0.0, 0.0)}
    args.update({"altitude": 20.0, "rng": np.random.default_rng(0)})
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        measure_ranges(**args)


def test_measure_ranges_does_not_modify_read_only_inputs(make_readonly):
    q = make_readonly(optimal_formation(5, (1.0, 2.0), 30.0))
    s = make_readonly([1.0, 2.0])
    h = make_readonly(30.0)
    out = measure_ranges(q, s, h, rng=np.random.default_rng(0))
    assert out.shape == (5,)
    np.testing.assert_array_equal(q, optimal_formation(5, (1.0, 2.0), 30.0))


# == negative_log_likelihood ==============================================================


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize(
    ("altitude", "tx_power"),
    [(10.0, 0.1), (20.0, 0.1), (300.0, 0.1), (50.0, [0.02, 0.1, 0.3, 0.05, 0.2, 1.0])],
)
def test_nll_matches_scipy_stats_up_to_a_constant(seed, altitude, tx_power):
    """Differences of the NLL between candidate positions agree with scipy.stats to 1e-9."""
    rng = np.random.default_rng([seed, int(altitude)])
    a = snr_constant(tx_power)
    radar = Radar(tx_power=tx_power)
    target = rng.uniform(-100.0, 100.0, 2)
    radius = float(optimal_radius(altitude))
    q = target + 2.0 * radius * rng.uniform(-1.0, 1.0, (6, 2))
    d_hat = true_ranges(q, target, altitude) + true_ranges(q, target, altitude) ** 2 / np.sqrt(
        a
    ) * rng.standard_normal(6)
    candidates = target + radius * rng.uniform(-1.0, 1.0, (20, 2))
    lib = negative_log_likelihood(candidates, q, d_hat, altitude, radar)
    assert lib.shape == (20,)
    ref = np.array([nll_scipy_stats(c, q, d_hat, altitude, a) for c in candidates])
    lib_diff = lib[1:] - lib[0]
    ref_diff = ref[1:] - ref[0]
    np.testing.assert_allclose(lib_diff, ref_diff, rtol=1e-9)
    # Scalar calls give the same numbers as the batch.
    for c, value in zip(candidates[:3], lib[:3], strict=True):
        assert float(negative_log_likelihood(c, q, d_hat, altitude, radar)) == pytest.approx(
            value, rel=1e-12
        )


def test_nll_batches_over_formations_ranges_and_altitudes():
    rng = np.random.default_rng(11)
    q = rng.uniform(-40.0, 40.0, (5, 4, 2))
    h = rng.uniform(10.0, 50.0, 5)
    s = rng.uniform(-5.0, 5.0, (5, 2))
    d_hat = true_ranges(q, np.zeros(2), h[:, None]) + rng.normal(0.0, 0.1, (5, 4))
    lib = negative_log_likelihood(s, q, d_hat, h)
    assert lib.shape == (5,)
    for k in range(5):
        assert float(negative_log_likelihood(s[k], q[k], d_hat[k], h[k])) == pytest.approx(
            lib[k], rel=1e-12
        )
    # The constant is the same for every batch element: differences still match scipy.stats.
    ref = np.array([nll_scipy_stats(s[k], q[k], d_hat[k], h[k]) for k in range(5)])
    lib_other = negative_log_likelihood(s + 1.0, q, d_hat, h)
    ref_other = np.array([nll_scipy_stats(s[k] + 1.0, q[k], d_hat[k], h[k]) for k in range(5)])
    np.testing.assert_allclose(lib_other - lib, ref_other - ref, rtol=1e-9)


@pytest.mark.parametrize(
    ("ranges", "name"),
    [
        (np.ones(5), "measured_ranges"),
        (np.ones((3, 7)), "measured_ranges"),
        (1.0, "measured_ranges"),
        ([1.0, 2.0, np.nan, 4.0, 5.0, 6.0], "measured_ranges"),
        ([1.0, 2.0, np.inf, 4.0, 5.0, 6.0], "measured_ranges"),
    ],
)
def test_nll_bad_ranges(ranges, name):
    with pytest.raises(ValueError, match=name):
        negative_log_likelihood((0.0, 0.0), optimal_formation(6, (0.0, 0.0), 20.0), ranges, 20.0)


# == linearised_estimate ===================================================================


def disc_scene(seed, n_uavs, scale, altitude_ratio, center, target_offset):
    rng = np.random.default_rng(seed)
    rho = scale * np.sqrt(rng.random(n_uavs))
    theta = 2.0 * np.pi * rng.random(n_uavs)
    q = np.asarray(center) + np.stack([rho * np.cos(theta), rho * np.sin(theta)], axis=-1)
    return q, np.asarray(center) + scale * np.asarray(target_offset), scale * altitude_ratio


@given(
    seed=st.integers(0, 2**32 - 1),
    n_uavs=st.integers(3, 12),
    scale=st.floats(1.0, 1000.0),
    altitude_ratio=st.floats(0.1, 10.0),
    center=st.tuples(st.floats(-1000.0, 1000.0), st.floats(-1000.0, 1000.0)),
    target_offset=st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)),
)
def test_linearised_estimate_exact_with_noise_free_ranges(
    seed, n_uavs, scale, altitude_ratio, center, target_offset
):
    """Noise-free ranges: the closed form is exact (1e-9 m) for non-collinear formations."""
    q, target, altitude = disc_scene(seed, n_uavs, scale, altitude_ratio, center, target_offset)
    # Not (nearly) collinear: the smallest spread of the UAVs is at least 5 % of the disc.
    assume(np.linalg.svd(q - q.mean(axis=0), compute_uv=False)[-1] >= 0.05 * scale)
    est = linearised_estimate(q, true_ranges(q, target, altitude), altitude)
    assert est.shape == (2,)
    assert np.linalg.norm(est - target) <= 1e-9


@given(
    seed=st.integers(0, 2**32 - 1),
    n_uavs=st.integers(3, 12),
    heading=st.floats(0.0, 2.0 * np.pi),
    spacing=st.floats(0.01, 100.0),
    center=st.tuples(st.floats(-1000.0, 1000.0), st.floats(-1000.0, 1000.0)),
    noise=st.sampled_from([0.0, 1.0, 1e3]),
)
def test_linearised_estimate_collinear_returns_centroid(
    seed, n_uavs, heading, spacing, center, noise
):
    rng = np.random.default_rng(seed)
    t = spacing * rng.uniform(-1.0, 1.0, n_uavs)
    q = np.asarray(center) + t[:, None] * np.array([np.cos(heading), np.sin(heading)])
    target = np.asarray(center) + rng.uniform(-50.0, 50.0, 2)
    d_hat = true_ranges(q, target, 20.0) + noise * rng.standard_normal(n_uavs)
    est = linearised_estimate(q, d_hat, 20.0)
    centroid = q.mean(axis=0)
    assert np.all(np.isfinite(est))
    np.testing.assert_allclose(est, centroid, rtol=0, atol=1e-9 * (1.0 + np.abs(centroid).max()))


def test_linearised_estimate_line_formation_returns_centroid():
    q = line_formation(6, (5.0, -3.0), 14.0, 28.0, heading=0.7)
    est = linearised_estimate(q, true_ranges(q, (5.0, -3.0), 20.0), 20.0)
    np.testing.assert_allclose(est, q.mean(axis=0), rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "d_hat",
    [
        np.zeros(6),
        np.full(6, 1e-9),
        np.full(6, 30.0),
        -np.arange(1.0, 7.0),
        np.array([1e8, 1.0, 1e5, 3.0, 1e12, 2.0]),
        np.array([1e-12, 1e12, 1e-12, 1e12, 1e-12, 1e12]),
    ],
)
def test_linearised_estimate_never_nan(d_hat):
    est = linearised_estimate(optimal_formation(6, (1.0, 2.0), 20.0), d_hat, 20.0)
    assert np.all(np.isfinite(est))


def test_linearised_estimate_batch_equals_loop_and_handles_mixed_batches():
    rng = np.random.default_rng(2)
    q = rng.uniform(-30.0, 30.0, (6, 5, 2))
    q[2] = line_formation(5, (0.0, 0.0), 10.0, 20.0)  # a collinear element in the batch
    h = rng.uniform(10.0, 40.0, 6)
    d_hat = true_ranges(q, (1.0, 1.0), h[:, None]) + rng.normal(0.0, 0.5, (6, 5))
    batch = linearised_estimate(q, d_hat, h)
    assert batch.shape == (6, 2)
    for k in range(6):
        np.testing.assert_allclose(batch[k], linearised_estimate(q[k], d_hat[k], h[k]), atol=1e-12)
    np.testing.assert_allclose(batch[2], q[2].mean(axis=0), atol=1e-12)
    # One formation, a (2, 3) batch of range sets: leading shapes are kept.
    sets = true_ranges(q[0], (1.0, 1.0), h[0]) + rng.normal(0.0, 0.5, (2, 3, 5))
    many = linearised_estimate(q[0], sets, h[0])
    assert many.shape == (2, 3, 2)
    for i, j in np.ndindex(2, 3):
        np.testing.assert_allclose(many[i, j], linearised_estimate(q[0], sets[i, j], h[0]))


@pytest.mark.parametrize("seed", range(3))
def test_linearised_estimate_equivariant_under_rotation_and_translation(seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-30.0, 30.0, (7, 2))
    d_hat = true_ranges(q, (2.0, 3.0), 25.0) + rng.normal(0.0, 0.3, 7)
    rot = rotation(rng.uniform(0.0, 2.0 * np.pi))
    shift = rng.uniform(-500.0, 500.0, 2)
    est = linearised_estimate(q, d_hat, 25.0)
    moved = linearised_estimate(q @ rot.T + shift, d_hat, 25.0)
    np.testing.assert_allclose(moved, rot @ est + shift, atol=1e-9)


def test_linearised_estimate_needs_three_uavs():
    with pytest.raises(ValueError, match="uav_xy"):
        linearised_estimate([[0.0, 0.0], [10.0, 0.0]], [20.0, 20.0], 20.0)


@pytest.mark.parametrize(
    "ranges", [np.ones(5), np.ones((2, 7)), [1.0, 2.0, np.nan, 4.0, 5.0, 6.0]]
)
def test_linearised_estimate_bad_ranges(ranges):
    with pytest.raises(ValueError, match="measured_ranges"):
        linearised_estimate(optimal_formation(6, (0.0, 0.0), 20.0), ranges, 20.0)


# == estimate_target: exactness ============================================================


@given(
    n_uavs=st.integers(3, 12),
    altitude=st.floats(5.0, 1000.0),
    radius_ratio=st.floats(0.2, 5.0),
    theta0=st.floats(0.0, 2.0 * np.pi),
    target=st.tuples(st.floats(-1000.0, 1000.0), st.floats(-1000.0, 1000.0)),
    start=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)),
)
def test_estimate_noise_free_symmetric_formation_is_exact(
    n_uavs, altitude, radius_ratio, theta0, target, start
):
    """A regular polygon centred on the target, noise-free ranges: the MLE is the target.

    (For a formation symmetric about the target the gradient of sum ln d_m^2 vanishes at
    the target, so it is the exact MLE; see the next test for asymmetric formations.) The
    estimator starts either from its own initialiser or from a point up to half a radius
    away.
    """
    s = np.asarray(target)
    radius = radius_ratio * altitude
    q = fixed_radius_polygon(n_uavs, s, radius, rotation=theta0)
    d = true_ranges(q, s, altitude)
    for init in (None, s + radius * np.asarray(start)):
        est = estimate_target(q, d, altitude, init=init)
        assert bool(est.converged)
        assert np.linalg.norm(est.position - s) <= 1e-8


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("altitude", [10.0, 20.0, 100.0])
def test_estimate_noise_free_is_exact_at_very_high_snr(seed, altitude):
    """Any non-collinear formation: with noise-free ranges and a very strong link (A about
    1e18 m^4) the MLE is the target to 1e-8 m. (At the paper's SNR the noise-free MLE of an
    asymmetric formation is *not* the target: the variance term ln d^2 moves it by up to
    ~CRLB / d; test_estimate_matches_scipy covers those cases.)"""
    rng = np.random.default_rng([seed, int(altitude)])
    radar = Radar(tx_power=1e9)
    s = rng.uniform(-100.0, 100.0, 2)
    q = random_disc_formations(6, s, 2.0 * float(optimal_radius(altitude)), 1, rng)[0]
    d = true_ranges(q, s, altitude)
    for init in (None, s + rng.uniform(-1.0, 1.0, 2)):
        est = estimate_target(q, d, altitude, radar, init=init)
        assert bool(est.converged)
        assert np.linalg.norm(est.position - s) <= 1e-8


# == estimate_target against SciPy =========================================================

FORMATIONS = ("optimal", "random_disc", "fixed_polygon")
ALTITUDES = (10.0, 20.0, 100.0, 500.0)
N_SCIPY_TRIALS = 25


_SCIPY_CACHE: dict = {}


def scipy_comparison(formation, altitude, ref):
    """Seeded trials of one formation at one altitude, each estimated by crlbswarm and by
    SciPy (from the true target). Returns a dict of per-trial arrays (computed once)."""
    key = (formation, altitude)
    if key in _SCIPY_CACHE:
        return _SCIPY_CACHE[key]
    rng = np.random.default_rng([FORMATIONS.index(formation), int(altitude), 7])
    target = rng.uniform(-100.0, 100.0, 2)
    r_star = float(optimal_radius(altitude))
    if formation == "optimal":
        q = optimal_formation(6, target, altitude, rotation=rng.uniform(0.0, 2.0 * np.pi))
    elif formation == "random_disc":
        q = random_disc_formations(6, target, 2.0 * r_star, 1, rng)[0]
    else:
        q = fixed_radius_polygon(6, target, 5.0)
    ranges = measure_ranges(np.broadcast_to(q, (N_SCIPY_TRIALS, 6, 2)), target, altitude, rng=rng)
    est = estimate_target(q, ranges, altitude)
    out = {"q": q, "ranges": ranges, "est": est, "gap": [], "step": [], "min_eig": []}
    for k in range(N_SCIPY_TRIALS):
        model = Likelihood(ref, q, ranges[k], altitude, anchor=target)
        out["gap"].append(np.linalg.norm(model.minimise(target) - est.position[k]))
        step, eig = model.newton_displacement(est.position[k])
        out["step"].append(step)
        out["min_eig"].append(eig[0])
    for name in ("gap", "step", "min_eig"):
        out[name] = np.array(out[name])
    out["rmse_bound"] = math.sqrt(
        ref.crlb_of_fim(ref.fim_slepian_bangs(q, target, altitude, ref.radar_params()))
    )
    _SCIPY_CACHE[key] = out
    return out


SCIPY_GRID = [(f, h) for f in FORMATIONS for h in ALTITUDES]
# Regression: the grid once hit a bug where a heavily damped (hence short) step passed the
# convergence test, leaving one F* trial at 500 m 1.46e-6 m from the MLE.
SCIPY_GRID_STRICT = SCIPY_GRID


@pytest.mark.parametrize(("formation", "altitude"), SCIPY_GRID_STRICT)
def test_estimate_matches_scipy(formation, altitude, ref):
    """The MLE agrees to 1e-6 m with SciPy's minimiser (BFGS + root polish, started from
    the true target) of the independent likelihood, on every one of 25 trials."""
    cmp = scipy_comparison(formation, altitude, ref)
    assert np.all(cmp["est"].converged)
    assert cmp["gap"].max() <= 1e-6


@pytest.mark.parametrize(("formation", "altitude"), SCIPY_GRID_STRICT)
def test_estimate_gradient_of_independent_nll_vanishes(formation, altitude, ref):
    """At every estimate the Newton step of the independent NLL (complex-step gradient,
    finite-difference Hessian) is below 1e-6 m."""
    assert scipy_comparison(formation, altitude, ref)["step"].max() <= 1e-6


@pytest.mark.parametrize(("formation", "altitude"), SCIPY_GRID)
def test_estimate_is_the_same_local_minimum_as_scipy(formation, altitude, ref):
    """Every estimate is a local minimum of the independent NLL (positive definite
    Hessian), the one SciPy finds from the true target (within 1e-4 of the RMSE bound: the
    basin, not the precision, which the two tests above check), and ``nll`` is the
    library's own NLL at the estimate."""
    cmp = scipy_comparison(formation, altitude, ref)
    assert np.all(cmp["min_eig"] > 0)
    assert cmp["gap"].max() <= 1e-4 * cmp["rmse_bound"]
    est = cmp["est"]
    lib_nll = negative_log_likelihood(est.position, cmp["q"], cmp["ranges"], altitude)
    np.testing.assert_allclose(est.nll, lib_nll, rtol=1e-12)


def test_estimate_matches_scipy_with_per_uav_powers(ref):
    powers = np.array([0.05, 0.1, 0.2, 0.1, 0.3, 0.15])
    radar = Radar(tx_power=powers)
    prm = ref.radar_params(tx_power=powers)
    rng = np.random.default_rng(99)
    target = np.array([12.0, -7.0])
    q = optimal_formation(6, target, 20.0)
    ranges = measure_ranges(np.broadcast_to(q, (10, 6, 2)), target, 20.0, radar, rng=rng)
    est = estimate_target(q, ranges, 20.0, radar)
    for k in range(10):
        model = Likelihood(ref, q, ranges[k], 20.0, anchor=target, prm=prm)
        assert np.linalg.norm(model.minimise(target) - est.position[k]) <= 1e-6


# Stored input (an F* trial at H = 500 m: 6 UAVs, target (63.40, 99.72)), found by
# comparing with SciPy over 7200 seeded trials (F*, random disc, fixed polygon at 10, 20,
# 100, 500 m): 9 of the 1800 trials at 500 m (and none below) were 1e-6 to 2e-5 m off.
BUG_DAMPED_Q = np.array(
    [
        [101.21730917616058, -253.7628466830897],
        [388.43897267840816, -44.27286362693016],
        [350.626157264526, 309.2133850113219],
        [25.5916783483965, 453.20965059341415],
        [-261.62998515385107, 243.7196675372547],
        [-223.81716973996905, -109.7665811009974],
    ]
)
BUG_DAMPED_RANGES = np.array(
    [603.9716522706734, 579.858402778673, 651.187381901695, 629.621356842835,
     604.1300374115561, 559.5209428709006]
)  # fmt: skip
BUG_DAMPED_TARGET = np.array([63.40449376227852, 99.72340195516225])


# BUG: estimate_target reports converged=True on a step shortened by the Levenberg-
# Marquardt damping. Near the optimum the cost change of a Newton step is below the
# rounding of the NLL, the step may be rejected, mu grows tenfold per rejection, and the
# next (heavily damped, hence tiny) step passes "step_len <= tol * scale" and is declared
# converged. Input: BUG_DAMPED_* at H = 500 m, paper radar, default init/tol. Expected: the
# estimate within 1e-6 m of the likelihood's minimiser (SciPy: (33.181035, 54.890606)),
# i.e. its own Newton step below tol * (1 m + 54 m) = 5.5e-9 m. Got: 2.6e-6 m away,
# converged=True; calling estimate_target again with init=<its estimate> moves it the
# missing 2.6e-6 m.
def test_estimate_converged_flag_not_set_by_damped_step(ref):
    est = estimate_target(BUG_DAMPED_Q, BUG_DAMPED_RANGES, 500.0)
    assert bool(est.converged)
    model = Likelihood(ref, BUG_DAMPED_Q, BUG_DAMPED_RANGES, 500.0, anchor=BUG_DAMPED_TARGET)
    assert np.linalg.norm(model.minimise(BUG_DAMPED_TARGET) - est.position) <= 1e-6


# Stored input: a fixed polygon (radius 5 m) at H = 100 m (CRLB 199 m^2, low SNR).
BUG_BASIN_TARGET = np.array([6.477286582667645, -75.96648225315839])
BUG_BASIN_RANGES = np.array(
    [101.78320241026306, 101.0730167730825, 100.20353500494109, 100.94180910569084,
     101.89279681201214, 99.3566852697389]
)  # fmt: skip


# DOUBT (design limitation rather than a hard bug): started *at the true target*, stage 1
# (weighted least squares with frozen weights) moves the iterate into another basin of the
# exact likelihood, and stage 2 returns a local minimum whose NLL is higher than the one
# SciPy's BFGS reaches from the same start. Input: fixed_radius_polygon(6, target, 5.0),
# H = 100 m, BUG_BASIN_*, init = target. Expected: the library's NLL <= SciPy's (+1e-9).
# Got: estimate (11.33, -86.22), 22.6 m from SciPy's minimiser (-0.22, -66.75), with an
# NLL higher by 0.057. (The library's own default init ends at the same point.)
@pytest.mark.xfail(
    strict=True, reason="DOUBT: stage 1 can leave the likelihood's basin of the start point"
)
def test_estimate_from_the_truth_reaches_the_best_nearby_minimum(ref):
    q = fixed_radius_polygon(6, BUG_BASIN_TARGET, 5.0)
    est = estimate_target(q, BUG_BASIN_RANGES, 100.0, init=BUG_BASIN_TARGET)
    model = Likelihood(ref, q, BUG_BASIN_RANGES, 100.0, anchor=BUG_BASIN_TARGET)
    best = model.minimise(BUG_BASIN_TARGET)
    assert model.nll(est.position) <= model.nll(best) + 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_estimate_invariant_to_uav_order_rotation_and_translation(seed):
    rng = np.random.default_rng(seed)
    altitude = 20.0
    target = rng.uniform(-50.0, 50.0, 2)
    q = random_disc_formations(6, target, 2.0 * float(optimal_radius(altitude)), 1, rng)[0]
    ranges = measure_ranges(np.broadcast_to(q, (20, 6, 2)), target, altitude, rng=rng)
    est = estimate_target(q, ranges, altitude).position
    perm = rng.permutation(6)
    np.testing.assert_allclose(
        estimate_target(q[perm], ranges[:, perm], altitude).position, est, atol=1e-7
    )
    rot = rotation(rng.uniform(0.0, 2.0 * np.pi))
    shift = rng.uniform(-1000.0, 1000.0, 2)
    moved = estimate_target(q @ rot.T + shift, ranges, altitude).position
    np.testing.assert_allclose(moved, est @ rot.T + shift, atol=1e-7)


# == estimate_target: robustness ===========================================================


def absurd_case(name):
    """(uav_xy, ranges, altitude, radar) of one absurd input (F* M = 6 at H = 20 m)."""
    q = optimal_formation(6, (0.0, 0.0), 20.0)
    d = true_ranges(q, (0.0, 0.0), 20.0)
    rng = np.random.default_rng(17)
    radar = Radar()
    if name == "huge_noise":
        ranges = d + 1e4 * rng.standard_normal((8, 6))
    elif name == "weak_link":  # A about 1.3e-3 m^4: sigma ~ 2e4 m at 25 m range
        radar = Radar(tx_power=1e-12)
        ranges = measure_ranges(np.broadcast_to(q, (8, 6, 2)), (0.0, 0.0), 20.0, radar, rng=rng)
    elif name == "equal_30":
        ranges = np.full(6, 30.0)
    elif name == "equal_1":
        ranges = np.full(6, 1.0)
    elif name == "near_zero":
        ranges = np.full(6, 1e-9)
    elif name == "zero":
        ranges = np.zeros(6)
    elif name == "negative":
        ranges = -np.arange(1.0, 7.0)
    elif name == "huge_spread":
        ranges = np.array([1e8, 1.0, 1e5, 3.0, 1e12, 2.0])
    elif name == "collinear_no_init":
        q = line_formation(6, (0.0, 0.0), 10.0, 20.0)
        ranges = true_ranges(q, (0.0, 0.0), 20.0)
    elif name == "collinear_noisy_no_init":
        q = line_formation(6, (0.0, 0.0), 10.0, 20.0, heading=0.4)
        ranges = true_ranges(q, (0.0, 0.0), 20.0) + 0.05 * rng.standard_normal((8, 6))
    else:
        raise AssertionError(name)
    return q, ranges, 20.0, radar


ABSURD = (
    "huge_noise",
    "weak_link",
    "equal_30",
    "equal_1",
    "near_zero",
    "zero",
    "negative",
    "huge_spread",
    "collinear_no_init",
    "collinear_noisy_no_init",
)


@pytest.mark.parametrize("name", ABSURD)
def test_estimate_absurd_inputs_give_finite_results(name):
    q, ranges, altitude, radar = absurd_case(name)
    est = estimate_target(q, ranges, altitude, radar)
    assert isinstance(est, TargetEstimate)
    batch = np.shape(ranges)[:-1]
    assert est.position.shape == (*batch, 2)
    assert est.converged.shape == batch
    assert est.converged.dtype == bool
    assert np.all(np.isfinite(est.position))
    assert np.all(np.isfinite(est.nll))
    assert np.array_equal(est.failed, ~est.converged)


def _converged_means_local_minimum(name, ref):
    q, ranges, altitude, radar = absurd_case(name)
    est = estimate_target(q, ranges, altitude, radar)
    prm = ref.radar_params(tx_power=radar.tx_power)
    ranges2 = np.atleast_2d(ranges)
    pos = est.position.reshape(-1, 2)
    conv = est.converged.reshape(-1)
    checked = 0
    for k in np.flatnonzero(conv):
        # Whitened by the FIM at the true target (the origin): at a point on the line of a
        # line formation the FIM is singular.
        model = Likelihood(ref, q, ranges2[k], altitude, anchor=np.zeros(2), prm=prm)
        disp, eig = model.newton_displacement(pos[k])
        scale = 1.0 + np.linalg.norm(pos[k] - q.mean(axis=0))
        assert eig[0] > 0, f"trial {k}: converged=True at a non-minimum, eig {eig}"
        assert disp <= 1e-6 * scale
        checked += 1
    return checked


@pytest.mark.parametrize(
    "name", ["huge_noise", "weak_link", "equal_30", "collinear_noisy_no_init"]
)
def test_estimate_converged_means_local_minimum(name, ref):
    """Where ``converged`` is True the position is a local minimum of the independent NLL
    (positive definite Hessian, Newton step below 1e-6 m per metre of scale)."""
    assert _converged_means_local_minimum(name, ref) >= 1


# BUG: converged=True at a point that is not a minimum of the likelihood. By symmetry the
# gradient vanishes exactly at the centre of F* (equal ranges) and on the line of a line
# formation (started from the linearised estimate, which is the UAVs' centroid); the Newton
# iteration stops there. Inputs (F* M = 6, H = 20 m, paper radar, default init):
#   equal_1 / zero: ranges all 1.0 m / all 0 m. Expected converged=False (or a minimum).
#     Got position (0, 0), converged=True, NLL Hessian negative definite (eig ~ -700 m^-2):
#     a local *maximum* of the NLL.
#   collinear_no_init: line_formation(6, (0, 0), 10, 20), noise-free ranges, no init.
#     Got position (10, 0) on the line, converged=True, Hessian eigenvalues ~(-548, +160):
#     a saddle, NLL 1e4 against 38 at the true target.
@pytest.mark.parametrize("name", ["equal_1", "zero", "collinear_no_init"])
def test_estimate_converged_at_symmetric_stationary_point(name, ref):
    _converged_means_local_minimum(name, ref)


def test_estimate_failed_trials_are_flagged_and_finite():
    """With max_iter = 1 no trial can converge: all are flagged, positions stay finite."""
    q = optimal_formation(6, (0.0, 0.0), 20.0)
    rng = np.random.default_rng(4)
    ranges = measure_ranges(np.broadcast_to(q, (20, 6, 2)), (0.0, 0.0), 20.0, rng=rng)
    est = estimate_target(q, ranges, 20.0, init=np.full((20, 2), 3.0), max_iter=1)
    assert not np.any(est.converged)
    assert np.all(est.failed)
    assert np.all(np.isfinite(est.position))
    assert np.all(est.iterations <= 2)


def test_estimate_astronomical_ranges_do_not_warn():
    """Absurd ranges at the edge of their range: a finite position and likelihood, flagged
    failed, and no warning; beyond it (squares near overflow), one line naming them."""
    est = estimate_target(optimal_formation(6, (0.0, 0.0), 20.0), np.full(6, 1e30), 20.0)
    assert np.all(np.isfinite(est.position))
    assert np.isfinite(est.nll)
    assert not bool(est.converged)
    with pytest.raises(FieldError, match=r"^measured_ranges: .*model's range"):
        estimate_target(optimal_formation(6, (0.0, 0.0), 20.0), np.full(6, 1e160), 20.0)


# == estimate_target: batches, inputs ======================================================


def test_estimate_batch_equals_loop():
    rng = np.random.default_rng(5)
    k_trials = 30
    h = rng.uniform(10.0, 100.0, k_trials)
    targets = rng.uniform(-50.0, 50.0, (k_trials, 2))
    q = np.stack(
        [
            random_disc_formations(6, targets[k], 2.0 * float(optimal_radius(h[k])), 1, rng)[0]
            for k in range(k_trials)
        ]
    )
    ranges = measure_ranges(q, targets, h, rng=rng)
    batch = estimate_target(q, ranges, h)
    assert batch.position.shape == (k_trials, 2)
    for k in range(k_trials):
        one = estimate_target(q[k], ranges[k], h[k])
        np.testing.assert_allclose(one.position, batch.position[k], rtol=0, atol=1e-9)
        assert bool(one.converged) == bool(batch.converged[k])
        assert float(one.nll) == pytest.approx(float(batch.nll[k]), rel=1e-12)
    # One formation, a (2, 3) batch of range sets: leading shapes are kept.
    sets = measure_ranges(np.broadcast_to(q[0], (2, 3, 6, 2)), targets[0], h[0], rng=rng)
    grid = estimate_target(q[0], sets, h[0])
    assert grid.position.shape == (2, 3, 2)
    assert grid.converged.shape == (2, 3)
    for i, j in np.ndindex(2, 3):
        one = estimate_target(q[0], sets[i, j], h[0])
        np.testing.assert_allclose(grid.position[i, j], one.position, rtol=0, atol=1e-9)


def test_estimate_does_not_modify_read_only_inputs(make_readonly):
    rng = np.random.default_rng(6)
    q0 = optimal_formation(6, (1.0, 1.0), 20.0)
    r0 = measure_ranges(np.broadcast_to(q0, (4, 6, 2)), (1.0, 1.0), 20.0, rng=rng)
    i0 = np.full((4, 2), 1.5)
    q, r, h, i = make_readonly(q0), make_readonly(r0), make_readonly(20.0), make_readonly(i0)
    for init in (None, i):
        est = estimate_target(q, r, h, init=init)
        assert np.all(est.converged)
    np.testing.assert_array_equal(q, q0)
    np.testing.assert_array_equal(r, r0)
    np.testing.assert_array_equal(i, i0)
    assert negative_log_likelihood(i, q, r, h).shape == (4,)
    assert linearised_estimate(q, r, h).shape == (4, 2)
    # Writable inputs are not modified either.
    q1, r1, i1 = q0.copy(), r0.copy(), i0.copy()
    estimate_target(q1, r1, 20.0, init=i1)
    estimate_target(q1, r1, 20.0)
    negative_log_likelihood(i1, q1, r1, 20.0)
    linearised_estimate(q1, r1, 20.0)
    np.testing.assert_array_equal(q1, q0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(i1, i0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"measured_ranges": np.ones(5)}, "measured_ranges"),
        ({"measured_ranges": np.ones((3, 7))}, "measured_ranges"),
        ({"measured_ranges": 20.0}, "measured_ranges"),
        ({"measured_ranges": [20.0, 21, np.nan, 20, 20, 20]}, "measured_ranges"),
        ({"measured_ranges": [20.0, 21, np.inf, 20, 20, 20]}, "measured_ranges"),
        ({"measured_ranges": ["a"] * 6}, "measured_ranges"),
        ({"tol": 0.0}, "tol"),
        ({"tol": -1e-9}, "tol"),
        ({"tol": np.nan}, "tol"),
        ({"tol": [1e-9, 1e-9]}, "tol"),
        ({"max_iter": 0}, "max_iter"),
        ({"max_iter": -3}, "max_iter"),
        ({"max_iter": 2.5}, "max_iter"),
        ({"max_iter": True}, "max_iter"),
        ({"init": (0.0, 0.0, 0.0)}, "init"),
        ({"init": (np.nan, 0.0)}, "init"),
        ({"uav_xy": np.zeros((6, 3))}, "uav_xy"),
        ({"altitude": 0.0}, "altitude"),
        ({"radar": None}, "radar"),
        ({"radar": Radar(tx_power=[0.1, 0.1, 0.1])}, "radar"),
    ],
)
def test_estimate_bad_inputs_raise_naming_the_argument(kwargs, name):
    args = {
        "uav_xy": optimal_formation(6, (0.0, 0.0), 20.0),
        "measured_ranges": np.full(6, 24.5),
        "altitude": 20.0,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        estimate_target(**args)
