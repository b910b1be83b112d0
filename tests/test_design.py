"""Closed-form design (crlbswarm.design) against numerical optimisation and the reference.

The optimal elevation is checked against a root of dw/dphi found by brentq (the derivative by
complex step of w written in the test), the optimal formation and the bound against the
reference FIM of tests/conftest.py, and the claim "no formation beats the bound" against
random and numerically optimised formations.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st
from scipy.optimize import minimize, minimize_scalar

from crlbswarm import (
    Radar,
    crlb,
    crlb_bound,
    information_weight,
    optimal_elevation,
    optimal_formation,
    optimal_radius,
)

ARCTAN_SQRT2 = np.arctan(np.sqrt(2.0))  # 54.7356 deg, the H -> 0 limit
ALTITUDES_1M_20KM = np.geomspace(1.0, 2.0e4, 50)


@pytest.fixture(scope="module")
def a_default(ref) -> float:
    """A of the paper profile, from the raw numbers."""
    return float(ref.snr_constant(ref.radar_params()))


# -- optimal elevation ----------------------------------------------------------------------------


def test_optimal_elevation_matches_root_of_dw_dphi(ref, a_default):
    """phi* in closed form = brentq root of dw/dphi, to 1e-8 rad, H from 1 m to 20 km."""
    expected = [ref.optimal_elevation_numeric(h, a_default) for h in ALTITUDES_1M_20KM]
    np.testing.assert_allclose(optimal_elevation(ALTITUDES_1M_20KM), expected, rtol=0, atol=1e-8)


def test_optimal_elevation_matches_derivative_free_maximum(ref, a_default):
    """Cross-check without derivatives: bounded Brent on -w. A maximum is flat, so function
    values locate it only to about sqrt(eps) ~ 1e-8 rad; 1e-7 is asked here."""
    for h in ALTITUDES_1M_20KM[::5]:
        w_scale = ref.information_weight(np.pi / 4, h, a_default)
        res = minimize_scalar(
            lambda phi, h=h, w_scale=w_scale: -ref.information_weight(phi, h, a_default) / w_scale,
            bounds=(0.0, 0.5 * np.pi),
            method="bounded",
            options={"xatol": 1e-12},
        )
        assert abs(float(optimal_elevation(h)) - res.x) < 1e-7


@pytest.mark.parametrize("tx_power", [1e-4, 0.1, 10.0])
@pytest.mark.parametrize("carrier_frequency", [2.4e9, 28e9])
def test_optimal_elevation_other_radars(ref, tx_power, carrier_frequency):
    """The closed form holds for any A, not only the paper profile."""
    radar = Radar(tx_power=tx_power, carrier_frequency=carrier_frequency)
    a = float(
        ref.snr_constant(ref.radar_params(tx_power=tx_power, carrier_frequency=carrier_frequency))
    )
    altitudes = np.geomspace(1.0, 2.0e4, 12)
    expected = [ref.optimal_elevation_numeric(h, a) for h in altitudes]
    np.testing.assert_allclose(optimal_elevation(altitudes, radar), expected, rtol=0, atol=1e-8)


def test_optimal_elevation_limits():
    """54.7356 deg = arctan(sqrt 2) as H -> 0, 45 deg as H -> infinity (to 1e-4 deg): the
    limits are those of 8 H^2 / A, reached at the ends of the altitude range (0.1 m, and
    1e5 m with a weak link)."""
    assert abs(np.degrees(optimal_elevation(0.1)) - 54.7356) < 1e-4
    assert abs(np.degrees(optimal_elevation(0.1)) - np.degrees(ARCTAN_SQRT2)) < 1e-4
    weak = Radar(noise_power=1e-2)  # A ~ 1.3e-2
    assert abs(np.degrees(optimal_elevation(1e5, weak)) - 45.0) < 1e-4


def test_optimal_elevation_strictly_between_limits_and_decreasing():
    """phi* in (45 deg, 54.7356 deg], decreasing with H, over the altitude range."""
    altitudes = np.geomspace(0.1, 1e5, 200)
    phi = optimal_elevation(altitudes)
    assert np.all(phi > 0.25 * np.pi)
    assert np.all(phi <= ARCTAN_SQRT2)
    assert np.all(np.diff(phi) < 0)


def test_optimal_radius_is_altitude_over_tan_elevation():
    """r* = H / tan(phi*), from 1 m to 20 km."""
    np.testing.assert_allclose(
        optimal_radius(ALTITUDES_1M_20KM),
        ALTITUDES_1M_20KM / np.tan(optimal_elevation(ALTITUDES_1M_20KM)),
        rtol=1e-12,
    )


# -- information weight and bound -----------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_information_weight_is_trace_of_one_uav_fim(seed, ref):
    """w(phi) = tr of the FIM of a single UAV at elevation phi, from the reference likelihood."""
    rng = np.random.default_rng(seed)
    radar_fields = {"tx_power": float(rng.uniform(0.01, 1.0))}
    prm = ref.radar_params(**radar_fields)
    for _ in range(20):
        altitude = float(np.exp(rng.uniform(np.log(1.0), np.log(2e4))))
        phi = rng.uniform(0.01, 0.5 * np.pi - 0.01)
        azimuth = rng.uniform(-np.pi, np.pi)
        uav = altitude / np.tan(phi) * np.array([[np.cos(azimuth), np.sin(azimuth)]])
        fim = ref.fim_slepian_bangs(uav, np.zeros(2), altitude, prm)
        np.testing.assert_allclose(
            information_weight(phi, altitude, Radar(**radar_fields)), np.trace(fim), rtol=1e-12
        )


def test_information_weight_per_uav_radar_broadcasts(ref):
    """Per-UAV powers broadcast over the last axis of the elevations."""
    powers = np.array([0.05, 0.1, 0.4])
    prm = ref.radar_params(tx_power=powers)
    phi = np.array([[0.7, 0.8, 0.9], [0.3, 1.0, 1.2]])
    np.testing.assert_allclose(
        information_weight(phi, 30.0, Radar(tx_power=powers)),
        ref.information_weight(phi, 30.0, ref.snr_constant(prm)),
        rtol=1e-13,
    )


@pytest.mark.parametrize("n_uavs", [3, 6, 17])
def test_crlb_bound_matches_reference(n_uavs, ref, a_default):
    """4 / (M w(phi*)) with phi* from brentq and w written in the test."""
    for h in ALTITUDES_1M_20KM[::7]:
        phi = ref.optimal_elevation_numeric(h, a_default)
        expected = 4.0 / (n_uavs * ref.information_weight(phi, h, a_default))
        np.testing.assert_allclose(crlb_bound(n_uavs, h), expected, rtol=1e-12)


@pytest.mark.parametrize("n_uavs", [3, 6, 11])
@pytest.mark.parametrize("altitude", [5.0, 20.0, 300.0, 5000.0])
def test_optimal_formation_attains_bound_in_reference_model(n_uavs, altitude, ref, a_default):
    """A regular M-gon of radius H / tan(phi*_numeric) built in the test has the reference
    CRLB equal to crlb_bound."""
    phi = ref.optimal_elevation_numeric(altitude, a_default)
    theta = 0.3 + 2 * np.pi * np.arange(n_uavs) / n_uavs
    uav = altitude / np.tan(phi) * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    fim = ref.fim_slepian_bangs(uav, np.zeros(2), altitude, ref.radar_params())
    np.testing.assert_allclose(ref.crlb_of_fim(fim), crlb_bound(n_uavs, altitude), rtol=1e-10)


def test_crlb_bound_per_uav_radar(ref):
    """With per-UAV powers each UAV contributes its own optimal weight."""
    powers = np.array([0.05, 0.1, 0.2, 0.1])
    a = ref.snr_constant(ref.radar_params(tx_power=powers))
    for h in (10.0, 200.0, 4000.0):
        w = [ref.information_weight(ref.optimal_elevation_numeric(h, am), h, am) for am in a]
        np.testing.assert_allclose(
            crlb_bound(4, h, Radar(tx_power=powers)), 4.0 / np.sum(w), 1e-12
        )


# -- the optimal formation ------------------------------------------------------------------------

formation_args = {
    "n_uavs": st.integers(3, 40),
    "rotation": st.floats(-10.0, 10.0),
    "target": st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    "altitude": st.floats(1.0, 2e4),
}


@given(**formation_args)
def test_optimal_formation_attains_bound(n_uavs, rotation, target, altitude):
    """crlb(F*) = crlb_bound to 1e-12 for any M, rotation, target and altitude."""
    f = optimal_formation(n_uavs, target, altitude, rotation=rotation)
    np.testing.assert_allclose(crlb(f, target, altitude), crlb_bound(n_uavs, altitude), rtol=1e-12)


@given(**formation_args)
def test_optimal_formation_is_regular_polygon_at_optimal_radius(
    n_uavs, rotation, target, altitude
):
    """Row m is at distance r* from the target, at azimuth rotation + 2 pi m / M."""
    f = optimal_formation(n_uavs, target, altitude, rotation=rotation)
    assert f.shape == (n_uavs, 2)
    offset = f - np.array(target)
    radius = float(optimal_radius(altitude))
    np.testing.assert_allclose(np.hypot(offset[:, 0], offset[:, 1]), radius, rtol=1e-12)
    unit = (offset[:, 0] + 1j * offset[:, 1]) / radius
    expected = np.exp(1j * (rotation + 2 * np.pi * np.arange(n_uavs) / n_uavs))
    np.testing.assert_allclose(unit, expected, rtol=0, atol=1e-11)
    # Elevation seen from the target is phi* (computed here with arctan2, not the library).
    np.testing.assert_allclose(
        np.arctan2(altitude, np.hypot(offset[:, 0], offset[:, 1])),
        optimal_elevation(altitude),
        rtol=1e-12,
    )


@given(
    n_uavs=st.integers(3, 12),
    altitude=st.floats(1.0, 1e4),
    unit_positions=st.lists(
        st.tuples(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0)), min_size=12, max_size=12
    ),
    target=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
)
def test_no_random_formation_beats_the_bound(n_uavs, altitude, unit_positions, target):
    """Any formation (positions within 4 r* of the target) has crlb >= bound (1 - 1e-9)."""
    radius = float(optimal_radius(altitude))
    uav_xy = np.array(target) + radius * np.array(unit_positions[:n_uavs])
    bound = crlb_bound(n_uavs, altitude)
    assert crlb(uav_xy, target, altitude) >= bound * (1 - 1e-9)


@given(
    powers=st.lists(st.floats(1e-3, 10.0), min_size=3, max_size=8),
    altitude=st.floats(1.0, 1e4),
    seed=st.integers(0, 2**32 - 1),
)
def test_no_random_formation_beats_the_per_uav_bound(powers, altitude, seed, ref):
    """The bound with per-UAV powers is also a lower bound (AM-HM holds for any weights)."""
    radar = Radar(tx_power=powers)
    rng = np.random.default_rng(seed)
    uav_xy = ref.random_formation(rng, len(powers), 4 * float(optimal_radius(altitude)))
    bound = crlb_bound(len(powers), altitude, radar)
    assert crlb(uav_xy, np.zeros(2), altitude, radar) >= bound * (1 - 1e-9)


@pytest.mark.parametrize(("n_uavs", "altitude"), [(3, 20.0), (5, 800.0), (8, 20.0), (12, 150.0)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_locally_optimised_formations_do_not_beat_the_bound(seed, n_uavs, altitude, ref):
    """BFGS on log(crlb / bound) over the positions (in units of r*) from a random start.

    The minimiser must not go below the bound (it is a bound), and should reach it (sanity:
    the CRLB landscape has no spurious local minima near the start).
    """
    rng = np.random.default_rng([seed, n_uavs])
    radius = float(optimal_radius(altitude))
    bound = float(crlb_bound(n_uavs, altitude))
    target = rng.uniform(-100.0, 100.0, size=2)

    def objective(u):
        return np.log(crlb(target + radius * u.reshape(n_uavs, 2), target, altitude) / bound)

    start = ref.random_formation(rng, n_uavs, 2.0).ravel()
    res = minimize(objective, start, method="BFGS", options={"gtol": 1e-10})
    visited = np.exp(res.fun)
    assert visited >= 1 - 1e-9
    assert visited <= 1 + 1e-8


# -- batches --------------------------------------------------------------------------------------


def test_design_functions_broadcast_over_altitude():
    """Array altitudes give element-wise results of the same shape."""
    altitudes = np.array([[5.0, 20.0, 80.0], [300.0, 1e3, 5e3]])
    for function in (optimal_elevation, optimal_radius):
        out = function(altitudes)
        assert out.shape == altitudes.shape
        np.testing.assert_array_equal(out.ravel(), [function(h) for h in altitudes.ravel()])
    bound = crlb_bound(5, altitudes)
    assert bound.shape == altitudes.shape
    np.testing.assert_allclose(bound.ravel(), [crlb_bound(5, h) for h in altitudes.ravel()], 1e-15)


def test_optimal_formation_batches_targets_and_altitudes():
    """Batches of targets and altitudes equal one call per element."""
    targets = np.array([[0.0, 0.0], [80.0, 90.0], [-5.0, 3.0]])
    altitudes = np.array([10.0, 20.0, 400.0])
    batch = optimal_formation(6, targets, altitudes, rotation=0.4)
    assert batch.shape == (3, 6, 2)
    for f, s, h in zip(batch, targets, altitudes, strict=True):
        np.testing.assert_allclose(f, optimal_formation(6, s, h, rotation=0.4), rtol=1e-15)
    # One target, several altitudes.
    assert optimal_formation(4, (1.0, 2.0), altitudes).shape == (3, 4, 2)
    np.testing.assert_allclose(
        crlb(batch, targets, altitudes), crlb_bound(6, altitudes), rtol=1e-12
    )


def test_optimal_formation_per_uav_radar_with_equal_a():
    """Per-UAV fields that give equal A (power x2, noise x2) are accepted: same F*."""
    radar = Radar(tx_power=[0.1, 0.2, 0.4], noise_power=[1e-12, 2e-12, 4e-12])
    np.testing.assert_allclose(
        optimal_formation(3, (1.0, 2.0), 20.0, radar), optimal_formation(3, (1.0, 2.0), 20.0)
    )
    np.testing.assert_allclose(crlb_bound(3, 20.0, radar), crlb_bound(3, 20.0), rtol=1e-13)


# -- bad input ------------------------------------------------------------------------------------


@pytest.mark.parametrize("n_uavs", [2, 1, 0, -3, 2.5, 3.0, True, "6"])
def test_too_few_or_non_integer_uavs(n_uavs):
    """n_uavs must be an integer >= 3."""
    with pytest.raises(ValueError, match=r"^n_uavs"):
        crlb_bound(n_uavs, 20.0)
    with pytest.raises(ValueError, match=r"^n_uavs"):
        optimal_formation(n_uavs, (0.0, 0.0), 20.0)


@pytest.mark.parametrize("altitude", [0.0, -1.0, np.nan, np.inf, [20.0, -5.0]])
def test_non_positive_altitude(altitude):
    """Zero, negative or non-finite altitudes name the altitude."""
    for call in (
        lambda: optimal_elevation(altitude),
        lambda: optimal_radius(altitude),
        lambda: crlb_bound(6, altitude),
        lambda: optimal_formation(6, (0.0, 0.0), altitude),
        lambda: information_weight(0.9, altitude),
    ):
        with pytest.raises(ValueError, match=r"^altitude"):
            call()


@pytest.mark.parametrize("target", [(np.nan, 0.0), (0.0, np.inf), (0.0, 0.0, 0.0), 5.0])
def test_bad_target(target):
    """Non-finite or wrongly shaped targets name target_xy."""
    with pytest.raises(ValueError, match=r"^target_xy"):
        optimal_formation(6, target, 20.0)


def test_target_and_altitude_batches_that_do_not_broadcast():
    """Incompatible batch shapes name an argument of optimal_formation (the message must not
    name ``radius``, a parameter of the internal regular_polygon call)."""
    with pytest.raises(ValueError, match=r"^(target_xy|altitude)"):
        optimal_formation(6, np.zeros((3, 2)), np.full(4, 20.0))


def test_per_uav_radar_length_mismatch():
    """Per-UAV radars must match n_uavs (unequal A is designed: tests/test_heterogeneous.py)."""
    with pytest.raises(ValueError, match=r"^radar"):
        crlb_bound(6, 20.0, Radar(tx_power=[0.1] * 5))
    with pytest.raises(ValueError, match=r"^radar"):
        optimal_formation(6, (0.0, 0.0), 20.0, Radar(tx_power=[0.1] * 7))
    assert optimal_formation(3, (0.0, 0.0), 20.0, Radar(tx_power=[0.1, 0.2, 0.1])).shape == (3, 2)


@pytest.mark.parametrize("elevation", [-0.1, 2.0, np.nan])
def test_information_weight_bad_elevation(elevation):
    """Elevations outside [0, pi/2] (or NaN) are rejected."""
    with pytest.raises(ValueError, match=r"^elevation"):
        information_weight(elevation, 20.0)


# -- inputs are never modified --------------------------------------------------------------------


def test_read_only_inputs_are_accepted_and_unchanged(make_readonly):
    """Read-only inputs are accepted, unchanged, and not aliased by the output."""
    altitudes = make_readonly([10.0, 20.0, 500.0])
    targets = make_readonly([[0.0, 0.0], [80.0, 90.0], [1.0, -1.0]])
    phi = make_readonly([0.5, 0.9, 1.2])
    copies = [a.copy() for a in (altitudes, targets, phi)]
    outputs = [
        optimal_elevation(altitudes),
        optimal_radius(altitudes),
        crlb_bound(4, altitudes),
        optimal_formation(4, targets, altitudes),
        information_weight(phi, altitudes),
    ]
    for arr, copy in zip((altitudes, targets, phi), copies, strict=True):
        np.testing.assert_array_equal(arr, copy)
        assert not any(np.shares_memory(out, arr) for out in outputs)
