"""Monte Carlo validation of the CRLB (crlbswarm.montecarlo).

The CRLBs compared with are the ``ref`` fixture's (tests/conftest.py: the FIM from the
Gaussian likelihood built from the raw radar numbers), not crlbswarm's. Statistical checks
use intervals derived here (normal / Bonferroni), with a family-wise false-alarm rate of
1e-3; the tests are deterministic given their seeds.
"""

from __future__ import annotations

import copy
import inspect
import math

import numpy as np
import pytest
from scipy.stats import norm

import crlbswarm.montecarlo as montecarlo_module
from crlbswarm import (
    FORMATION_LABELS,
    EstimatorSweep,
    MonteCarloResult,
    Radar,
    arc_formation,
    estimate_target,
    estimator_vs_altitude,
    fixed_radius_polygon,
    line_formation,
    measure_ranges,
    monte_carlo_mse,
    optimal_formation,
    optimal_radius,
    random_disc_formations,
)

#: Family-wise false-alarm rate of each statistical test.
ALPHA = 1e-3
#: Two-sided 95 % normal quantile, from SciPy (not from crlbswarm).
Z95 = float(norm.ppf(0.975))

#: The paper scenario's target (the paper scenario of docs/scenarios.md).
TARGET = np.array([80.0, 90.0])
#: Seed of the 20 000-trial efficiency run of F* at 20 m.
SEED_FSTAR = 20_000


def reference_crlb(ref, uav_xy, target, altitude):
    return ref.crlb_of_fim(ref.fim_slepian_bangs(uav_xy, target, altitude, ref.radar_params()))


def reference_covariance(ref, uav_xy, target, altitude):
    """J^-1, the covariance of an efficient estimator."""
    return np.linalg.inv(ref.fim_slepian_bangs(uav_xy, target, altitude, ref.radar_params()))


def reference_optimal_radius(ref, altitude):
    """r* = H / tan(phi*) with phi* from the reference's numerical maximisation of w."""
    a = float(ref.snr_constant(ref.radar_params()))
    return altitude / math.tan(ref.optimal_elevation_numeric(altitude, a))


def reference_bound(ref, n_uavs, altitude):
    """4 / sum(w) at the optimal elevation (docs/optimal-formation.md)."""
    a = float(ref.snr_constant(ref.radar_params()))
    phi = ref.optimal_elevation_numeric(altitude, a)
    return 4.0 / (n_uavs * float(ref.information_weight(phi, altitude, a)))


def expected_ratio_half_width(ref, uav_xy, target, altitude, n_trials, ratio):
    """CLT half-width of the 95 % interval of MSE / CRLB for Gaussian errors of covariance
    ratio * J^-1: Var |e|^2 = 2 tr(C^2)."""
    cov = ratio * reference_covariance(ref, uav_xy, target, altitude)
    crlb = reference_crlb(ref, uav_xy, target, altitude)
    return Z95 * math.sqrt(2.0 * np.trace(cov @ cov) / n_trials) / crlb


# == statistical efficiency of the MLE =====================================================


@pytest.fixture(scope="module")
def fstar_20m():
    q = optimal_formation(6, TARGET, 20.0)
    result = monte_carlo_mse(
        q, TARGET, 20.0, n_trials=20_000, rng=np.random.default_rng(SEED_FSTAR)
    )
    return q, result


def test_fstar_mse_reaches_the_crlb(fstar_20m, ref):
    """F* at 20 m, paper radar, 20 000 trials: MSE / CRLB in [0.9, 1.1]; its 99.9 %
    interval (the reported 95 % one widened) contains 1."""
    q, res = fstar_20m
    assert res.n_trials == 20_000
    assert res.n_failed == 0
    assert res.crlb == pytest.approx(reference_crlb(ref, q, TARGET, 20.0), rel=1e-9)
    assert res.crlb == pytest.approx(5.3476e-3, rel=1e-4)  # docs/sensing-model.md
    assert 0.9 <= res.ratio <= 1.1
    half = 0.5 * (res.ratio_ci[1] - res.ratio_ci[0])
    assert abs(res.ratio - 1.0) <= half * norm.isf(ALPHA / 2) / Z95


def test_fstar_ratio_ci_brackets_ratio_with_clt_width(fstar_20m, ref):
    """The reported 95 % interval is centred on the ratio and has the CLT half-width
    1.96 sqrt(2 tr(C^2) / n) / CRLB (about 1.4 % for F*), within 5 % of it (the sample
    standard deviation of |e|^2 has a relative error of about 1 % at n = 20 000)."""
    q, res = fstar_20m
    low, high = res.ratio_ci
    assert low < res.ratio < high
    assert 0.5 * (low + high) == pytest.approx(res.ratio, rel=1e-12)
    expected = expected_ratio_half_width(ref, q, TARGET, 20.0, res.n_trials, res.ratio)
    assert 0.5 * (high - low) == pytest.approx(expected, rel=0.05)


BIAS_SEEDS = (101, 102, 103, 104, 105)


@pytest.mark.parametrize("seed", BIAS_SEEDS)
def test_fstar_unbiased(seed, ref):
    """F* at 20 m, 20 000 trials per seed: each bias component is 0 within its interval,
    Bonferroni-corrected over 5 seeds x 2 components (z = 3.9). The interval is also
    checked against the independent half-width 1.96 sqrt([J^-1]_kk / n), and is sharp: at
    most 3 % of the RMSE bound (about 2 mm)."""
    q = optimal_formation(6, TARGET, 20.0)
    res = monte_carlo_mse(q, TARGET, 20.0, n_trials=20_000, rng=np.random.default_rng(seed))
    low, high = res.bias_ci[:, 0], res.bias_ci[:, 1]
    np.testing.assert_allclose(0.5 * (low + high), res.bias, rtol=0, atol=1e-15)
    half95 = 0.5 * (high - low)
    cov = reference_covariance(ref, q, TARGET, 20.0)
    np.testing.assert_allclose(half95, Z95 * np.sqrt(np.diag(cov) * res.ratio / 2e4), rtol=0.05)
    z = norm.isf(ALPHA / (2 * 2 * len(BIAS_SEEDS)))
    half = half95 * z / Z95
    assert np.all(half <= 0.03 * math.sqrt(res.crlb))
    assert np.all(np.abs(res.bias) <= half)


BENCHMARKS = ("fixed_polygon", "arc", "line", "random_disc")


def benchmark_formation(name, altitude, rng):
    """(uav_xy, prior_std) of a benchmark around TARGET (formations of docs/optimal-formation.md).

    The line gets a prior of r*/8 per axis: a line of UAVs cannot tell the target from its
    mirror image, and the prior picks the wrong side only if it lands beyond the line
    (r* away, 8 standard deviations: probability 6e-16 per trial).
    """
    r_star = float(optimal_radius(altitude))
    if name == "fixed_polygon":
        return fixed_radius_polygon(6, TARGET, 5.0), None
    if name == "arc":
        return arc_formation(6, TARGET, r_star, span=0.5 * np.pi, heading=0.3), None
    if name == "line":
        return line_formation(6, TARGET, r_star, 2.0 * r_star, heading=1.1), r_star / 8.0
    return random_disc_formations(6, TARGET, 2.0 * r_star, 1, rng)[0], None


@pytest.mark.parametrize("altitude", [10.0, 20.0])
@pytest.mark.parametrize("name", BENCHMARKS)
def test_benchmark_mse_tracks_its_crlb(name, altitude, ref):
    """Every benchmark at high SNR, 5000 trials: MSE / CRLB in [0.9, 1.1] (about 5
    standard errors), the 95 % interval brackets the ratio, and CRLB is the reference's."""
    rng = np.random.default_rng([BENCHMARKS.index(name), int(altitude)])
    q, prior = benchmark_formation(name, altitude, rng)
    res = monte_carlo_mse(q, TARGET, altitude, n_trials=5000, rng=rng, prior_std=prior)
    assert res.crlb == pytest.approx(reference_crlb(ref, q, TARGET, altitude), rel=1e-9)
    assert res.n_failed == 0
    assert res.ratio_ci[0] < res.ratio < res.ratio_ci[1]
    assert 0.9 <= res.ratio <= 1.1


# == the summary against an independent replay ============================================


@pytest.mark.parametrize(
    ("case", "n_trials"), [("fstar", 3000), ("line_prior", 3000), ("weak_link", 400)]
)
def test_summary_matches_independent_replay(case, n_trials, ref):
    """Replaying the documented draws (ranges first, then the prior) with the same seed
    and summarising the errors here gives the same MSE, intervals, bias and failures.
    ``weak_link`` is a low-SNR case (tx_power 1e-6 W at 200 m: the MLE is biased)."""
    radar = Radar()
    altitude = 20.0
    r_star = float(optimal_radius(altitude))
    prior = None
    q = optimal_formation(6, TARGET, altitude)
    if case == "line_prior":
        q, prior = line_formation(6, TARGET, r_star, 2.0 * r_star), r_star / 4.0
    elif case == "weak_link":
        radar, altitude = Radar(tx_power=1e-6), 200.0
        q = optimal_formation(6, TARGET, altitude, radar)
    res = monte_carlo_mse(
        q, TARGET, altitude, radar, n_trials, np.random.default_rng(7), prior_std=prior
    )
    rng = np.random.default_rng(7)
    ranges = measure_ranges(np.broadcast_to(q, (n_trials, 6, 2)), TARGET, altitude, radar, rng)
    init = None if prior is None else TARGET + prior * rng.standard_normal((n_trials, 2))
    est = estimate_target(np.broadcast_to(q, (n_trials, 6, 2)), ranges, altitude, radar, init)
    err = est.position - TARGET
    sq = np.sum(err**2, axis=1)
    mse = sq.mean()
    half = Z95 * sq.std(ddof=1) / math.sqrt(n_trials)
    bias = err.mean(axis=0)
    bias_half = Z95 * err.std(axis=0, ddof=1) / math.sqrt(n_trials)
    assert res.n_trials == n_trials
    assert res.n_failed == int(np.sum(~est.converged))
    assert res.mse == pytest.approx(mse, rel=1e-12)
    np.testing.assert_allclose(res.mse_ci, (mse - half, mse + half), rtol=1e-12)
    np.testing.assert_allclose(res.bias, bias, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(
        res.bias_ci, np.stack([bias - bias_half, bias + bias_half], axis=-1), rtol=1e-12
    )
    assert res.crlb == pytest.approx(
        ref.crlb_of_fim(
            ref.fim_slepian_bangs(q, TARGET, altitude, ref.radar_params(tx_power=radar.tx_power))
        ),
        rel=1e-9,
    )
    assert np.isfinite(res.mse)


def test_failed_trials_are_counted_and_kept(monkeypatch):
    """With the estimator limited to one iteration (spy) every trial fails: all are
    counted in n_failed and kept, with their last iterate, in a finite MSE."""
    real = montecarlo_module.estimate_target
    calls = []

    def one_iteration(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs, max_iter=1)

    monkeypatch.setattr(montecarlo_module, "estimate_target", one_iteration)
    q = fixed_radius_polygon(6, TARGET, 5.0)
    res = monte_carlo_mse(q, TARGET, 20.0, n_trials=200, rng=np.random.default_rng(0))
    assert calls
    assert res.n_failed == 200
    assert np.isfinite(res.mse)
    assert res.mse > 0


def test_monte_carlo_result_ratio_and_ci_from_fields():
    res = MonteCarloResult(
        n_trials=10,
        n_failed=1,
        mse=2.0,
        mse_ci=(1.5, 2.6),
        crlb=4.0,
        bias=np.zeros(2),
        bias_ci=np.zeros((2, 2)),
    )
    assert res.ratio == 0.5
    assert res.ratio_ci == pytest.approx((0.375, 0.65), rel=1e-15)


def test_monte_carlo_result_ratio_consistent_with_mse_and_crlb(fstar_20m):
    _, res = fstar_20m
    assert res.ratio == pytest.approx(res.mse / res.crlb, rel=1e-15)
    np.testing.assert_allclose(res.ratio_ci, np.asarray(res.mse_ci) / res.crlb, rtol=1e-15)
    assert res.mse_ci[0] < res.mse < res.mse_ci[1]
    assert 0.5 * (res.mse_ci[0] + res.mse_ci[1]) == pytest.approx(res.mse, rel=1e-12)


# == determinism and inputs =================================================================


def test_monte_carlo_deterministic_for_a_seed():
    q = optimal_formation(5, TARGET, 30.0)
    first = monte_carlo_mse(q, TARGET, 30.0, n_trials=300, rng=np.random.default_rng(1))
    again = monte_carlo_mse(q, TARGET, 30.0, n_trials=300, rng=np.random.default_rng(1))
    other = monte_carlo_mse(q, TARGET, 30.0, n_trials=300, rng=np.random.default_rng(2))
    assert first.mse == again.mse
    assert first.mse_ci == again.mse_ci
    assert np.array_equal(first.bias, again.bias)
    assert np.array_equal(first.bias_ci, again.bias_ci)
    assert first.mse != other.mse


def test_monte_carlo_does_not_modify_read_only_inputs(make_readonly):
    q0 = optimal_formation(6, TARGET, 20.0)
    q, s = make_readonly(q0), make_readonly(TARGET)
    res = monte_carlo_mse(q, s, make_readonly(20.0), n_trials=50, rng=np.random.default_rng(0))
    assert np.isfinite(res.mse)
    np.testing.assert_array_equal(q, q0)
    res = monte_carlo_mse(q, s, 20.0, n_trials=50, rng=np.random.default_rng(0), prior_std=1.0)
    assert np.isfinite(res.mse)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"rng": None}, "rng"),
        ({"rng": 0}, "rng"),
        ({"rng": np.random.RandomState(0)}, "rng"),
        ({"uav_xy": np.zeros((2, 6, 2))}, "uav_xy"),
        ({"uav_xy": np.zeros((6, 3))}, "uav_xy"),
        ({"target_xy": np.zeros((2, 2))}, "target_xy"),
        ({"target_xy": (np.nan, 0.0)}, "target_xy"),
        ({"altitude": [20.0, 30.0]}, "altitude"),
        ({"altitude": 0.0}, "altitude"),
        ({"n_trials": 1}, "n_trials"),
        ({"n_trials": 0}, "n_trials"),
        ({"n_trials": 2.5}, "n_trials"),
        ({"n_trials": True}, "n_trials"),
        ({"prior_std": 0.0}, "prior_std"),
        ({"prior_std": -1.0}, "prior_std"),
        ({"prior_std": np.nan}, "prior_std"),
        ({"radar": None}, "radar"),
    ],
)
def test_monte_carlo_bad_inputs(kwargs, name):
    args = {
        "uav_xy": optimal_formation(6, TARGET, 20.0),
        "target_xy": TARGET,
        "altitude": 20.0,
        "n_trials": 10,
        "rng": np.random.default_rng(0),
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        monte_carlo_mse(**args)


# == estimator_vs_altitude ==================================================================

SWEEP_ALTITUDES = (10.0, 20.0)
SWEEP_TRIALS = 300


@pytest.fixture(scope="module")
def sweep():
    return estimator_vs_altitude(np.array(SWEEP_ALTITUDES), n_trials=SWEEP_TRIALS, seed=3)


def test_sweep_structure_and_columns(sweep):
    assert isinstance(sweep, EstimatorSweep)
    assert sweep.n_trials == SWEEP_TRIALS
    np.testing.assert_array_equal(sweep.altitude, SWEEP_ALTITUDES)
    assert list(sweep.results) == list(FORMATION_LABELS)
    for rows in sweep.results.values():
        assert len(rows) == len(SWEEP_ALTITUDES)
        for r in rows:
            assert isinstance(r, MonteCarloResult)
            assert r.n_trials == SWEEP_TRIALS
    cols = sweep.columns()
    expected = {"altitude_m"}
    for name in FORMATION_LABELS:
        expected |= {
            f"crlb_{name}_m2",
            f"mse_{name}_m2",
            f"mse_low_{name}_m2",
            f"mse_high_{name}_m2",
            f"failed_{name}",
        }
    assert set(cols) == expected
    for key, col in cols.items():
        assert np.shape(col) == (len(SWEEP_ALTITUDES),), key
        assert np.all(np.isfinite(col)), key
    for name, rows in sweep.results.items():
        np.testing.assert_array_equal(cols[f"crlb_{name}_m2"], [r.crlb for r in rows])
        np.testing.assert_array_equal(cols[f"mse_{name}_m2"], [r.mse for r in rows])
        np.testing.assert_array_equal(cols[f"mse_low_{name}_m2"], [r.mse_ci[0] for r in rows])
        np.testing.assert_array_equal(cols[f"mse_high_{name}_m2"], [r.mse_ci[1] for r in rows])
        np.testing.assert_array_equal(cols[f"failed_{name}"], [r.n_failed for r in rows])
        assert np.issubdtype(np.asarray(cols[f"failed_{name}"]).dtype, np.integer)


def test_sweep_crlb_per_formation_per_altitude(sweep, ref):
    """Each column holds its own formation at its own altitude: the reference CRLBs of the
    documented geometries (target at the origin; all rotation-invariant)."""
    origin = np.zeros(2)
    for k, h in enumerate(SWEEP_ALTITUDES):
        r_star = reference_optimal_radius(ref, h)
        expected = {
            "optimal": reference_bound(ref, 6, h),
            "fixed_polygon": reference_crlb(ref, fixed_radius_polygon(6, origin, 5.0), origin, h),
            "arc": reference_crlb(ref, arc_formation(6, origin, r_star, 0.5 * np.pi), origin, h),
            "line": reference_crlb(
                ref, line_formation(6, origin, r_star, 2.0 * r_star), origin, h
            ),
        }
        for name, value in expected.items():
            assert sweep.results[name][k].crlb == pytest.approx(value, rel=1e-9), (name, h)
        disc = sweep.results["random_disc"][k].crlb
        assert expected["optimal"] * (1 - 1e-9) <= disc < np.inf


def test_sweep_mse_tracks_crlb(sweep):
    """At 10 and 20 m every formation's MSE is near its CRLB even with 300 trials (the
    band [0.6, 1.6] is about 4 standard errors): in particular the line is not confused by
    the mirror image of the target."""
    for name, rows in sweep.results.items():
        for r in rows:
            assert 0.6 <= r.ratio <= 1.6, name


def test_sweep_passes_the_documented_formations_and_the_line_prior(monkeypatch, ref):
    """Spy on monte_carlo_mse: one call per formation and altitude, each with its own
    random stream and the documented geometry; only ``line`` gets a prior, of r*/8 (r*
    from the reference)."""
    real = montecarlo_module.monte_carlo_mse
    signature = inspect.signature(real)
    calls = []

    def spy(*args, **kwargs):
        arguments = signature.bind(*args, **kwargs).arguments
        # The first normals of a copy of the stream: independent streams differ.
        arguments["first_draws"] = copy.deepcopy(arguments["rng"]).standard_normal(4)
        calls.append(arguments)
        return real(*args, **kwargs)

    monkeypatch.setattr(montecarlo_module, "monte_carlo_mse", spy)
    result = estimator_vs_altitude(list(SWEEP_ALTITUDES), n_trials=20, seed=5)
    names = list(FORMATION_LABELS)
    assert len(calls) == len(names) * len(SWEEP_ALTITUDES)
    first_draws = np.array([call["first_draws"] for call in calls])
    assert len(np.unique(first_draws[:, 0])) == len(calls)
    for i, name in enumerate(names):
        for k, h in enumerate(SWEEP_ALTITUDES):
            call = calls[i * len(SWEEP_ALTITUDES) + k]
            q = np.asarray(call["uav_xy"])
            s = np.asarray(call["target_xy"])
            assert float(call["altitude"]) == h
            assert q.shape == (6, 2)
            r_star = reference_optimal_radius(ref, h)
            dist = np.linalg.norm(q - s, axis=1)
            prior = call.get("prior_std")
            if name == "line":
                assert prior == pytest.approx(r_star / 8.0, rel=1e-9)
                # Collinear, at distance r* from the target, length 2 r*.
                direction = (q[-1] - q[0]) / np.linalg.norm(q[-1] - q[0])
                normal = np.array([-direction[1], direction[0]])
                np.testing.assert_allclose((q - q[0]) @ normal, 0.0, atol=1e-9 * r_star)
                assert abs((q[0] - s) @ normal) == pytest.approx(r_star, rel=1e-9)
                assert np.linalg.norm(q[-1] - q[0]) == pytest.approx(2.0 * r_star, rel=1e-9)
            else:
                assert prior is None
            if name == "optimal":
                np.testing.assert_allclose(dist, r_star, rtol=1e-9)
            elif name == "fixed_polygon":
                np.testing.assert_allclose(dist, 5.0, rtol=1e-9)
            elif name == "arc":
                np.testing.assert_allclose(dist, r_star, rtol=1e-9)
                azimuth = np.unwrap(np.arctan2(q[:, 1] - s[1], q[:, 0] - s[0]))
                assert np.ptp(azimuth) == pytest.approx(0.5 * np.pi, rel=1e-9)
            elif name == "random_disc":
                assert np.all(dist <= 2.0 * r_star)
            assert result.results[name][k].crlb == pytest.approx(
                reference_crlb(ref, q, s, h), rel=1e-9
            )


def test_sweep_deterministic_for_a_seed(sweep):
    again = estimator_vs_altitude(np.array(SWEEP_ALTITUDES), n_trials=SWEEP_TRIALS, seed=3)
    other = estimator_vs_altitude(np.array(SWEEP_ALTITUDES), n_trials=SWEEP_TRIALS, seed=4)
    first_cols, again_cols, other_cols = sweep.columns(), again.columns(), other.columns()
    for key in first_cols:
        np.testing.assert_array_equal(first_cols[key], again_cols[key])
    for name in FORMATION_LABELS:
        assert np.all(first_cols[f"mse_{name}_m2"] != other_cols[f"mse_{name}_m2"])


def test_sweep_default_altitudes_and_copy():
    res = estimator_vs_altitude(n_trials=20, seed=1)
    np.testing.assert_allclose(res.altitude, np.geomspace(10.0, 3000.0, 12), rtol=1e-12)
    cols = res.columns()
    for name in FORMATION_LABELS:
        assert np.all(np.isfinite(cols[f"crlb_{name}_m2"]))
        assert np.all(np.isfinite(cols[f"mse_{name}_m2"]))
    heights = np.array([15.0, 25.0])
    res = estimator_vs_altitude(heights, n_trials=10, seed=1)
    heights[0] = 1e3
    assert res.altitude[0] == 15.0


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_trials": 1}, "n_trials"),
        ({"n_trials": 2.5}, "n_trials"),
        ({"altitudes": [10.0, -5.0]}, "altitudes"),
        ({"altitudes": [[10.0, 20.0]]}, "altitudes"),
        ({"seed": -1}, "seed"),
        ({"fixed_radius": 0.0}, "fixed_radius"),
        ({"arc_span": 4.0}, "arc_span"),
        ({"disc_factor": -1.0}, "disc_factor"),
        ({"radar": Radar(tx_power=[0.1] * 6)}, "radar"),
    ],
)
def test_sweep_bad_inputs(kwargs, name):
    args = {"altitudes": [10.0, 20.0], "n_trials": 10}
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        estimator_vs_altitude(**args)
