"""UAVs at individual altitudes, target height known or unknown (issue 11, item 3).

The references are written here from the model, not from crlbswarm's code: the FIM by
finite differences of each range's mean and variance, the CRLB by an explicit loop and
``numpy.linalg.inv``, and the optimum by a multistart L-BFGS-B over all horizontal
positions (heights fixed) with the exact gradient of log tr J^-1. The acceptance of the
issue: the closed form (where one exists) and the numerical design agree to 1e-6
(relative). ``CRLBSWARM_LONG_TESTS=1`` runs 200 starts for every case (by default 200 for
two cases and for the mixed-elevation check, 24 or 8 for the others).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import minimize

import crlbswarm as cs
from crlbswarm import FieldError

LONG = os.environ.get("CRLBSWARM_LONG_TESTS") == "1"
PAPER = cs.Radar()
WEAK = cs.Radar(tx_power=1e-6)  # A = 1346: kappa = A/H^2 near 1 at tens of metres
STRONG = cs.Radar(noise_power=1e-20)  # A = 1.3e16


# -- independent references ------------------------------------------------------------------
def fim_by_differences(uav_xyz, target, a, known, step=1e-4):
    """sum_m [grad d grad d^T / sigma^2 + grad sigma^2 grad sigma^2^T / (2 sigma^4)] with
    the gradients of d(s) = |q_m - s| and sigma^2(s) = d^4/A by central differences."""
    dims = 2 if known else 3
    q = np.asarray(uav_xyz, float)
    s = np.asarray(target, float)
    a = np.broadcast_to(a, q.shape[:1])
    j = np.zeros((dims, dims))
    for m in range(q.shape[0]):
        grad_d, grad_v = np.zeros(dims), np.zeros(dims)
        for i in range(dims):
            e = np.zeros(3)
            e[i] = step
            dp, dm = np.linalg.norm(q[m] - s - e), np.linalg.norm(q[m] - s + e)
            grad_d[i] = (dp - dm) / (2 * step)
            grad_v[i] = (dp**4 - dm**4) / a[m] / (2 * step)
        var = np.linalg.norm(q[m] - s) ** 4 / a[m]
        j += np.outer(grad_d, grad_d) / var + np.outer(grad_v, grad_v) / (2 * var * var)
    return j


def crlb_by_loop(uav_xyz, target, a, known):
    dims = 2 if known else 3
    a = np.broadcast_to(a, (len(uav_xyz),))
    j = np.zeros((dims, dims))
    for m, p in enumerate(uav_xyz):
        rho = np.asarray(p, float) - np.asarray(target, float)
        d = float(np.sqrt(rho @ rho))
        info = a[m] / d**4 + 8.0 / d**2
        u = rho[:dims] / d
        j += info * np.outer(u, u)
    return float(np.trace(np.linalg.inv(j)))


def log_trace_and_gradient(x, a, dh, known):
    """log tr J^-1 over the horizontal offsets rho_m (heights dh_m fixed) and its gradient:
    J = sum k_m(d) v v^T with k = A/d^6 + 8/d^4, v = rho (3-D) or its horizontal part."""
    xy = x.reshape(-1, 2)
    rho = np.column_stack([xy, dh])
    d2 = np.sum(rho**2, axis=1)
    d = np.sqrt(d2)
    k = a / d2**3 + 8.0 / d2**2
    dk = -6.0 * a / d**7 - 32.0 / d**5
    v = rho[:, :2] if known else rho
    j = np.einsum("m,mi,mj->ij", k, v, v)
    try:
        inv = np.linalg.inv(j)
    except np.linalg.LinAlgError:
        return 1e3, np.zeros_like(x)
    trace = np.trace(inv)
    if not np.isfinite(trace) or trace <= 0:
        return 1e3, np.zeros_like(x)
    b = inv @ inv
    quad = np.einsum("mi,ij,mj->m", v, b, v)
    grad = -((dk / d * quad)[:, None] * xy + 2.0 * k[:, None] * (v @ b)[:, :2])
    return float(np.log(trace)), (grad / trace).ravel()


def numerical_best(a, dh, known, starts, seed):
    rng = np.random.default_rng(seed)
    scale = float(np.max(dh))
    a = np.broadcast_to(a, dh.shape).astype(float)
    best = np.inf
    for _ in range(starts):
        x0 = rng.uniform(-2.5 * scale, 2.5 * scale, (dh.shape[0], 2)).ravel()
        res = minimize(log_trace_and_gradient, x0, args=(a, dh, known), jac=True,
                       method="L-BFGS-B",
                       options={"maxiter": 3000, "ftol": 1e-13, "gtol": 1e-10})  # fmt: skip
        best = min(best, float(np.exp(res.fun)))
    return best


def scene(seed, m=6):
    rng = np.random.default_rng(seed)
    target = rng.uniform(-50, 50, 3)
    xy = target[:2] + rng.uniform(-60, 60, (m, 2))
    z = target[2] + rng.uniform(5, 80, m)
    return np.column_stack([xy, z]), target


# -- the Fisher information ------------------------------------------------------------------
@pytest.mark.parametrize("known", [False, True])
@pytest.mark.parametrize(("seed", "radar"), [(0, PAPER), (1, WEAK), (2, cs.Radar(
    tx_power=[0.1, 0.3, 0.05, 0.2, 0.1, 1.0]))])  # fmt: skip
def test_fim_equals_finite_differences_of_the_likelihood_model(seed, radar, known):
    uavs, target = scene(seed)
    j = cs.fisher_information_3d(uavs, target, radar, "known" if known else "unknown")
    ref = fim_by_differences(uavs, target, radar.snr_constant, known)
    np.testing.assert_allclose(j, ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
    value = cs.crlb_3d(uavs, target, radar, "known" if known else "unknown")
    assert value == pytest.approx(crlb_by_loop(uavs, target, radar.snr_constant, known), 1e-12)


@pytest.mark.parametrize("radar", [PAPER, WEAK, cs.Radar(tx_power=[0.1, 0.2, 0.4, 0.1, 0.1])])
@pytest.mark.parametrize("altitude", [0.5, 20.0, 300.0, 5e4])
def test_known_height_at_one_altitude_is_the_paper_fim(radar, altitude):
    nudge = np.array([[1.0, 0.0], [0.0, 2.0], [0, 0], [3, 3], [0, 1]])
    xy = cs.optimal_formation(5, (80.0, 90.0), altitude, radar) + nudge
    uavs = np.column_stack([xy, np.full(5, 7.0 + altitude)])
    target = (80.0, 90.0, 7.0)
    j2 = cs.fisher_information(xy, (80.0, 90.0), altitude, radar)
    j3 = cs.fisher_information_3d(uavs, target, radar, target_height="known")
    np.testing.assert_allclose(j3, j2, rtol=1e-12, atol=1e-12 * np.abs(j2).max())
    c2 = cs.crlb(xy, (80.0, 90.0), altitude, radar)
    assert cs.crlb_3d(uavs, target, radar, "known") == pytest.approx(c2, rel=1e-12)


def test_batches_broadcast():
    uavs, target = scene(3)
    batch = np.stack([uavs, uavs + np.array([1.0, 2.0, 3.0])])
    j = cs.fisher_information_3d(batch, target)
    assert j.shape == (2, 3, 3)
    np.testing.assert_allclose(j[0], cs.fisher_information_3d(uavs, target), rtol=1e-15)
    assert cs.crlb_3d(batch, np.stack([target, target]), target_height="known").shape == (2,)


def test_singular_geometries_are_inf_never_nan():
    target = np.zeros(3)
    plane = np.array([[10.0, 0, 20], [-15, 0, 30], [30, 0, 25], [5, 0, 40]])  # y = 0 plane
    assert cs.crlb_3d(plane, target) == np.inf
    assert cs.crlb_3d(plane, target, target_height="known") == np.inf
    above = np.array([[0.0, 0, 20], [0, 0, 30], [0, 0, 40]])
    assert cs.crlb_3d(above, target, target_height="known") == np.inf
    assert cs.crlb_3d(above, target) == np.inf
    two = np.array([[10.0, 0, 20], [0, 10, 30]])
    assert cs.crlb_3d(two, target) == np.inf
    assert np.isfinite(cs.crlb_3d(two, target, target_height="known"))


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), angle=st.floats(-np.pi, np.pi),
       shift=st.tuples(*[st.floats(-1e3, 1e3)] * 3))  # fmt: skip
def test_crlb_is_invariant_to_rotation_about_the_vertical_and_translation(seed, angle, shift):
    uavs, target = scene(seed)
    r = rotation_z(angle)
    for case in ("known", "unknown"):
        a = cs.crlb_3d(uavs, target, target_height=case)
        b = cs.crlb_3d(uavs @ r.T + shift, target @ r.T + shift, target_height=case)
        assert b == pytest.approx(a, rel=1e-9)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(3, 9))
def test_unknown_height_costs_information_and_respects_the_bound(seed, m):
    """tr J^-1 >= tr J_h^-1 + 1/J_zz >= 4/a + 1/b, and the horizontal part of the 3-D
    CRLB is at least the known-height CRLB."""
    uavs, target = scene(seed, m)
    j = cs.fisher_information_3d(uavs, target)
    full = cs.crlb_3d(uavs, target)
    horizontal = cs.crlb_3d(uavs, target, target_height="known")
    assert np.trace(np.linalg.inv(j)[:2, :2]) >= horizontal * (1 - 1e-9)
    assert full >= horizontal + 1.0 / j[2, 2] * (1 - 1e-9)
    assert full >= 4.0 / (j[0, 0] + j[1, 1]) + 1.0 / j[2, 2] * (1 - 1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_designs_beat_random_formations_at_the_same_heights(seed):
    uavs, target = scene(seed)
    full = cs.crlb_3d(uavs, target)
    horizontal = cs.crlb_3d(uavs, target, target_height="known")
    design = cs.design_3d(uavs[:, 2], target, starts=4)
    assert design.crlb <= full * (1 + 1e-9)
    assert design.crlb >= design.bound * (1 - 1e-9)
    known = cs.design_3d(uavs[:, 2], target, target_height="known")
    assert known.crlb <= horizontal * (1 + 1e-9)


# -- the closed forms ------------------------------------------------------------------------
@pytest.mark.parametrize("altitude", [0.1, 1.0, 20.0, 100.0, 1e3, 1e4, 1e5])
@pytest.mark.parametrize("radar", [PAPER, WEAK])
def test_optimal_elevation_is_the_cubic_root_and_the_minimum(altitude, radar):
    kappa = radar.snr_constant / altitude**2
    roots = np.roots([9 * kappa, 48 - 2 * kappa, -3 * kappa, -16])
    s_ref = [r.real for r in roots if abs(r.imag) < 1e-9 and 0 < r.real < 1]
    s = np.sin(cs.optimal_elevation_3d(altitude, radar)) ** 2
    assert len(s_ref) == 1
    assert s == pytest.approx(s_ref[0], rel=1e-9)
    grid = np.linspace(0.01, 0.99, 200_001)
    objective = (1 + 3 * grid) / (grid**2 * (1 - grid) * (kappa * grid + 8))
    assert abs(grid[np.argmin(objective)] - s) < 1e-5


def test_optimal_elevation_limits():
    high = np.sin(cs.optimal_elevation_3d(0.1, cs.Radar(noise_power=1e-32))) ** 2
    low = np.sin(cs.optimal_elevation_3d(1e5, cs.Radar(noise_power=1e-6))) ** 2
    assert high == pytest.approx((1 + np.sqrt(28)) / 9, rel=1e-9)
    assert low == pytest.approx(1 / np.sqrt(3), rel=1e-6)


@pytest.mark.parametrize("m", [3, 4, 6, 12])
@pytest.mark.parametrize("radar", [PAPER, WEAK, cs.Radar(tx_power=np.full(4, 0.1))])
def test_known_height_at_one_altitude_is_the_paper_design_exactly(m, radar):
    if radar.n_uavs not in (None, m):
        radar = cs.Radar(tx_power=np.full(m, 0.1))
    d = cs.design_3d(np.full(m, 25.0), (80.0, 90.0, 5.0), radar, "known", rotation=0.3)
    expected = cs.optimal_formation(m, (80.0, 90.0), 20.0, radar, 0.3)
    np.testing.assert_array_equal(d.positions[:, :2], expected)
    np.testing.assert_array_equal(d.positions[:, 2], 25.0)
    assert d.method == "closed form"
    assert d.attained
    assert d.crlb == pytest.approx(float(cs.crlb_bound(m, 20.0, radar)), rel=1e-12)


def test_unknown_height_equal_uavs_is_a_regular_polygon():
    d = cs.design_3d(np.full(5, 45.0), (1.0, 2.0, 5.0), WEAK, rotation=0.2)
    phi = cs.optimal_elevation_3d(40.0, WEAK)
    expected = cs.regular_polygon(5, (1.0, 2.0), 40.0 / np.tan(phi), 0.2)
    np.testing.assert_allclose(d.positions[:, :2], expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(d.elevations, phi, rtol=1e-12)
    assert d.method == "closed form"
    assert d.attained
    assert d.ratio == pytest.approx(1, abs=1e-12)


# (M, heights above the target, radar, known, 200 starts by default)
UNEQUAL5 = cs.Radar(tx_power=[0.1, 0.2, 0.1, 0.3, 0.05])
UNEQUAL12 = cs.Radar(tx_power=np.linspace(0.05, 0.2, 12))
CLOSED_FORM_CASES = [
    (3, [20.0] * 3, PAPER, False, True),
    (6, [60.0] * 6, WEAK, False, True),
    (4, [500.0] * 4, PAPER, False, False),
    (9, [8.0] * 9, WEAK, False, False),
    (12, [3000.0] * 12, PAPER, False, False),
    (5, [20.0, 25.0, 30.0, 22.0, 40.0], UNEQUAL5, True, False),
    (3, [20.0, 60.0, 35.0], WEAK, True, False),
    (8, list(np.linspace(10, 90, 8)), PAPER, True, False),
    (12, list(np.linspace(50, 60, 12)), UNEQUAL12, True, False),
    (7, [20.0, 20.5, 21.0, 21.5, 22.0, 20.2, 21.2], PAPER, False, False),
    (10, list(np.linspace(30, 34, 10)), WEAK, False, False),
]  # fmt: skip


@pytest.mark.parametrize(("m", "heights", "radar", "known", "long"), CLOSED_FORM_CASES)
def test_design_equals_the_best_of_a_multistart_search(m, heights, radar, known, long):
    """The closed form (or a numerical design that attains the bound) against the best of
    independent L-BFGS-B searches over all horizontal positions: agreement to 1e-6, and no
    search does better."""
    dh = np.asarray(heights)
    d = cs.design_3d(dh + 3.0, (10.0, -4.0, 3.0), radar, "known" if known else "unknown")
    assert d.attained
    assert d.crlb == pytest.approx(crlb_by_loop(d.positions, (10.0, -4.0, 3.0),
                                                radar.snr_constant, known), rel=1e-10)  # fmt: skip
    starts = 200 if (long or LONG) else (8 if known else 24)
    best = numerical_best(radar.snr_constant, dh, known, starts, seed=m)
    assert abs(best - d.crlb) <= 1e-6 * d.crlb
    assert best >= d.crlb * (1 - 1e-9)


def test_common_elevation_beats_mixed_elevations():
    """Equal UAVs at one height: 200 searches over every elevation and azimuth (any mix)
    find nothing better than the common elevation phi_3*, and every search that reaches
    the optimum has all its elevations equal to phi_3*."""
    dh = np.full(6, 20.0)
    d = cs.design_3d(dh, np.zeros(3), WEAK)
    rng = np.random.default_rng(5)
    values, spreads = [], []
    for _ in range(200):
        x0 = rng.uniform(-50, 50, 12)
        res = minimize(log_trace_and_gradient, x0, args=(np.full(6, WEAK.snr_constant), dh,
                       False), jac=True, method="L-BFGS-B",
                       options={"maxiter": 3000, "ftol": 1e-13, "gtol": 1e-10})  # fmt: skip
        values.append(np.exp(res.fun))
        phi = np.arctan2(dh, np.hypot(*res.x.reshape(-1, 2).T))
        spreads.append(np.ptp(phi))
    values = np.array(values)
    assert values.min() >= d.crlb * (1 - 1e-9)
    at_optimum = values <= d.crlb * (1 + 1e-7)
    assert at_optimum.sum() >= 10
    assert np.max(np.array(spreads)[at_optimum]) < 1e-3


def test_lagrangian_bound_is_below_every_search():
    """A dominant low UAV: the bound 4/a* + 1/b* is not attained, and the numerical design
    is the best found by independent searches too (to 1e-6)."""
    dh = np.array([20.0, 40.0, 45.0, 50.0])
    d = cs.design_3d(dh, np.zeros(3), PAPER, starts=32, seed=1)
    assert d.method == "numerical"
    assert not d.attained
    assert d.ratio > 1.01
    best = numerical_best(PAPER.snr_constant, dh, False, 24, seed=2)
    assert best >= d.bound
    assert abs(best - d.crlb) <= 1e-6 * d.crlb


def test_design_rotation_and_report():
    a = cs.design_3d([20.0, 21.0, 22.0, 23.0, 24.0, 25.0], np.zeros(3), rotation=0.7)
    b = cs.design_3d([20.0, 21.0, 22.0, 23.0, 24.0, 25.0], np.zeros(3), rotation=0.0)
    assert a.crlb == pytest.approx(b.crlb, rel=1e-9)
    assert np.arctan2(a.positions[0, 1], a.positions[0, 0]) == pytest.approx(0.7)
    np.testing.assert_array_equal(a.positions[:, 2], [20.0, 21.0, 22.0, 23.0, 24.0, 25.0])
    f = cs.optimal_formation_3d([20.0, 21.0, 22.0, 23.0, 24.0, 25.0], np.zeros(3), rotation=0.7)
    np.testing.assert_array_equal(f, a.positions)


# -- the estimator and Monte Carlo -----------------------------------------------------------
@pytest.mark.parametrize("heights", [[20.0] * 5, [20.0, 30.0, 25.0, 40.0, 22.0]])
def test_noiseless_ranges_give_the_target(heights):
    target = np.array([4.0, -3.0, 2.0])
    uavs = cs.optimal_formation_3d(np.asarray(heights) + 2.0, target)
    d = np.linalg.norm(uavs - target, axis=-1)
    # (the MLE of exact ranges is off by about d^3/A, the pull of the 2 ln d term: a strong
    # radar makes it negligible)
    est = cs.estimate_target_3d(uavs, d, STRONG)
    np.testing.assert_allclose(est.position, target, atol=1e-7)
    assert est.converged


def test_mirror_target_is_reflected_below_the_uavs():
    """UAVs at one height H: the ranges of z and 2H - z are the same; a start above the
    UAVs still ends below them."""
    target = np.array([0.0, 0.0, 0.0])
    uavs = cs.optimal_formation_3d([20.0] * 6, target)
    d = np.linalg.norm(uavs - target, axis=-1)
    est = cs.estimate_target_3d(uavs, d, STRONG, init=[1.0, 1.0, 37.0])
    np.testing.assert_allclose(est.position, target, atol=1e-7)


def test_measurements_use_the_range_model():
    uavs, target = scene(4)
    radar = cs.Radar(tx_power=1e-3)
    n = 40_000
    d = cs.measure_ranges_3d(np.broadcast_to(uavs, (n, *uavs.shape)), target, radar,
                             np.random.default_rng(0))  # fmt: skip
    true = np.linalg.norm(uavs - target, axis=-1)
    sigma = true**2 / np.sqrt(radar.snr_constant)
    assert np.all(np.abs(d.mean(axis=0) - true) < 5 * sigma / np.sqrt(n))
    np.testing.assert_allclose(d.std(axis=0), sigma, rtol=0.03)


def mc_geometries():
    target = np.array([80.0, 90.0, 0.0])
    rng = np.random.default_rng(11)
    spread = np.column_stack([target[:2] + rng.uniform(-40, 40, (7, 2)),
                              rng.uniform(20.0, 100.0, 7)])  # fmt: skip
    return target, {
        "optimal, one height 20 m": cs.optimal_formation_3d([20.0] * 6, target),
        "optimal, heights 40-100 m": cs.optimal_formation_3d(np.linspace(40, 100, 6), target),
        "known-height design, 20-60 m": cs.optimal_formation_3d(
            np.linspace(20, 60, 5), target, target_height="known"),
        "random, 20-100 m": spread,
    }  # fmt: skip


@pytest.mark.parametrize("seed", [0, 1])
def test_monte_carlo_mse_meets_the_crlb(seed):
    """20 000 trials at high SNR (paper radar, 20-100 m): MSE / CRLB in [0.9, 1.1] (about
    0.4 s per geometry on an idle core)."""
    target, geometries = mc_geometries()
    for name, uavs in geometries.items():
        r = cs.monte_carlo_mse_3d(uavs, target, n_trials=20_000, rng=np.random.default_rng(seed))
        assert r.n_failed == 0, name
        assert 0.9 <= r.ratio <= 1.1, (name, r.ratio, r.ratio_ci)
        assert r.bias.shape == (3,)


# -- errors ----------------------------------------------------------------------------------
def _error(call, field):
    with pytest.raises(FieldError) as info:
        call()
    assert info.value.field == field, str(info.value)
    assert "\n" not in str(info.value)
    return info.value


def test_errors_are_one_line_and_name_the_argument():
    uavs, target = scene(0)
    below = uavs.copy()
    below[0, 2] = target[2] - 1.0
    err = _error(lambda: cs.crlb_3d(below, target), "uav_xyz")
    assert "above the target" in err.reason
    _error(lambda: cs.crlb_3d(uavs[:, :2], target), "uav_xyz")
    _error(lambda: cs.crlb_3d(uavs, target[:2]), "target_xyz")
    _error(lambda: cs.crlb_3d(uavs, target, target_height="maybe"), "target_height")
    _error(lambda: cs.fisher_information_3d(uavs, target, cs.Radar(tx_power=[1.0, 2.0])),
           "radar")  # fmt: skip
    _error(lambda: cs.design_3d([20.0, 30.0], np.zeros(3)), "altitudes")
    _error(lambda: cs.design_3d([20.0, 30.0, 0.05], np.zeros(3)), "altitudes")
    _error(lambda: cs.design_3d([[20.0, 30.0, 40.0]], np.zeros(3)), "altitudes")
    _error(lambda: cs.design_3d([20.0] * 3, np.zeros(2)), "target_xyz")
    _error(lambda: cs.design_3d([20.0, 25.0, 30.0], np.zeros(3), starts=0), "starts")
    _error(lambda: cs.measure_ranges_3d(uavs, target, rng=None), "rng")
    _error(lambda: cs.estimate_target_3d(uavs[:2], np.ones(2)), "uav_xyz")
    _error(lambda: cs.estimate_target_3d(uavs, np.ones(5)), "measured_ranges")
    _error(lambda: cs.monte_carlo_mse_3d(uavs, target, n_trials=1, rng=np.random.default_rng()),
           "n_trials")  # fmt: skip
