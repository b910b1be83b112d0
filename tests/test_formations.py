"""Benchmark formations (crlbswarm.formations): shapes and the documented geometry.

Geometry is checked with plain trigonometry in the test (distances, azimuths, projections),
not with crlbswarm.geometry.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st

from crlbswarm import (
    arc_formation,
    crlb,
    crlb_bound,
    fixed_radius_polygon,
    line_formation,
    optimal_radius,
    random_disc_formations,
)

TARGET = np.array([80.0, 90.0])


def polar(offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distance, azimuth) of horizontal offsets seen from the target."""
    return np.hypot(offsets[..., 0], offsets[..., 1]), np.arctan2(offsets[..., 1], offsets[..., 0])


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angle wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * angle))


# -- fixed-radius polygon -----------------------------------------------------------------------


@given(n_uavs=st.integers(3, 20), radius=st.floats(0.1, 1e3), rotation=st.floats(-7.0, 7.0))
def test_fixed_radius_polygon_geometry(n_uavs, radius, rotation):
    """Distance `radius` from the target, azimuths rotation + 2 pi m / M."""
    f = fixed_radius_polygon(n_uavs, TARGET, radius, rotation)
    assert f.shape == (n_uavs, 2)
    dist, azimuth = polar(f - TARGET)
    np.testing.assert_allclose(dist, radius, rtol=1e-12)
    expected = rotation + 2 * np.pi * np.arange(n_uavs) / n_uavs
    np.testing.assert_allclose(wrap(azimuth - expected), 0.0, atol=1e-9)


def test_fixed_radius_polygon_default_radius_is_5m():
    """The documented default radius, 5 m."""
    dist, _ = polar(fixed_radius_polygon(6, TARGET) - TARGET)
    np.testing.assert_allclose(dist, 5.0, rtol=1e-13)


# -- arc ------------------------------------------------------------------------------------------


@given(
    n_uavs=st.integers(3, 20),
    radius=st.floats(0.1, 1e3),
    span=st.floats(0.01, np.pi),
    heading=st.floats(-7.0, 7.0),
)
def test_arc_geometry(n_uavs, radius, span, heading):
    """Radius r, azimuths evenly spaced from heading - span/2 to heading + span/2 (ends in)."""
    f = arc_formation(n_uavs, TARGET, radius, span=span, heading=heading)
    assert f.shape == (n_uavs, 2)
    dist, azimuth = polar(f - TARGET)
    np.testing.assert_allclose(dist, radius, rtol=1e-12)
    expected = heading - span / 2 + span * np.arange(n_uavs) / (n_uavs - 1)
    np.testing.assert_allclose(wrap(azimuth - expected), 0.0, atol=1e-9)


def test_arc_default_span_is_quarter_turn():
    """Default span pi/2 centred on heading 0: azimuths -45 to +45 deg."""
    f = arc_formation(5, TARGET, 10.0)
    _, azimuth = polar(f - TARGET)
    np.testing.assert_allclose(azimuth, np.linspace(-np.pi / 4, np.pi / 4, 5), atol=1e-12)


@pytest.mark.parametrize("span", [0.0, -0.5, 3.2, np.nan])
def test_arc_bad_span(span):
    """The span must lie in (0, pi]."""
    with pytest.raises(ValueError, match=r"^span"):
        arc_formation(4, TARGET, 10.0, span=span)


# -- line -----------------------------------------------------------------------------------------


@given(
    n_uavs=st.integers(3, 20),
    offset=st.floats(0.1, 1e3),
    length=st.floats(0.1, 1e3),
    heading=st.floats(-7.0, 7.0),
)
def test_line_geometry(n_uavs, offset, length, heading):
    """Collinear UAVs, perpendicular distance `offset` from the target along `heading`,
    evenly spaced over `length`, centred on the foot of the perpendicular."""
    f = line_formation(n_uavs, TARGET, offset, length, heading=heading)
    assert f.shape == (n_uavs, 2)
    normal = np.array([np.cos(heading), np.sin(heading)])
    along = np.array([-np.sin(heading), np.cos(heading)])
    rel = f - TARGET
    scale = offset + length
    np.testing.assert_allclose(rel @ normal, offset, rtol=0, atol=1e-12 * scale)
    expected_along = length * (np.arange(n_uavs) / (n_uavs - 1) - 0.5)
    np.testing.assert_allclose(rel @ along, expected_along, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(np.hypot(*(f[-1] - f[0])), length, rtol=1e-9)


@pytest.mark.parametrize(
    ("offset", "length", "match"), [(0.0, 5.0, r"^offset"), (5.0, -1.0, r"^length")]
)
def test_line_bad_offset_or_length(offset, length, match):
    """A line through the target (offset 0) or of negative length is rejected."""
    with pytest.raises(ValueError, match=match):
        line_formation(4, TARGET, offset, length)


# -- random disc ---------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_disc_shape_and_radius(seed):
    """Shape (n_draws, M, 2), inside the disc, and uniform in area and azimuth."""
    f = random_disc_formations(6, TARGET, 12.0, 500, np.random.default_rng(seed))
    assert f.shape == (500, 6, 2)
    dist, azimuth = polar(f - TARGET)
    assert np.all(dist <= 12.0)
    # Uniform in the disc: P(dist < r/2) = 1/4, azimuth uniform; 3000 points, 5 sigma.
    n = dist.size
    assert abs(np.mean(dist < 6.0) - 0.25) < 5 * np.sqrt(0.25 * 0.75 / n)
    assert abs(np.mean(azimuth > 0) - 0.5) < 5 * np.sqrt(0.25 / n)


def test_random_disc_is_deterministic_given_the_seed():
    """Same seed, same draws; another seed, other draws."""
    a = random_disc_formations(5, TARGET, 10.0, 20, np.random.default_rng(42))
    b = random_disc_formations(5, TARGET, 10.0, 20, np.random.default_rng(42))
    c = random_disc_formations(5, TARGET, 10.0, 20, np.random.default_rng(43))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_random_disc_batch_of_radii_reuses_the_draws():
    """One unit-disc draw scaled by each radius (common random numbers)."""
    radii = np.array([1.0, 2.0, 10.0])
    f = random_disc_formations(4, np.zeros(2), radii, 7, np.random.default_rng(3))
    assert f.shape == (3, 7, 4, 2)
    np.testing.assert_allclose(f / radii[:, None, None, None], np.broadcast_to(f[0], f.shape))
    np.testing.assert_allclose(
        f[1], random_disc_formations(4, np.zeros(2), 2.0, 7, np.random.default_rng(3))
    )


def test_random_disc_rejects_global_random_state():
    """Only a Generator is accepted (no global state); n_draws >= 1."""
    with pytest.raises(ValueError, match=r"^rng"):
        random_disc_formations(4, TARGET, 10.0, 5, np.random)
    with pytest.raises(ValueError, match=r"^n_draws"):
        random_disc_formations(4, TARGET, 10.0, 0, np.random.default_rng(0))


# -- common properties ----------------------------------------------------------------------------


def all_formations(n_uavs, target, radius):
    rng = np.random.default_rng(0)
    return {
        "fixed_polygon": fixed_radius_polygon(n_uavs, target, radius),
        "arc": arc_formation(n_uavs, target, radius),
        "line": line_formation(n_uavs, target, radius, 2 * radius),
        "random_disc": random_disc_formations(n_uavs, target, radius, 3, rng),
    }


def test_batches_of_targets_and_radii():
    """Batches of targets and radii give batches of formations."""
    targets = np.array([[0.0, 0.0], [10.0, -3.0]])
    radii = np.array([5.0, 8.0])
    for name, f in all_formations(4, targets, radii).items():
        extra = (3,) if name == "random_disc" else ()
        assert f.shape == (2, *extra, 4, 2)
    single = all_formations(4, targets[1], radii[1])
    for name, f in all_formations(4, targets, radii).items():
        if name != "random_disc":
            np.testing.assert_allclose(f[1], single[name], rtol=1e-15)


@pytest.mark.parametrize("altitude", [10.0, 20.0, 100.0, 200.0])
def test_arc_and_line_at_optimal_radius_are_worse_than_bound(altitude):
    """Right elevation, poor angular diversity: strictly above the bound."""
    radius = float(optimal_radius(altitude))
    bound = crlb_bound(6, altitude)
    assert crlb(arc_formation(6, TARGET, radius), TARGET, altitude) > bound * (1 + 1e-3)
    assert crlb(line_formation(6, TARGET, radius, 2 * radius), TARGET, altitude) > bound * (
        1 + 1e-3
    )


@pytest.mark.parametrize("n_uavs", [2, 0, 2.0])
def test_too_few_uavs(n_uavs):
    """Every benchmark needs an integer n_uavs >= 3."""
    for call in (
        lambda: fixed_radius_polygon(n_uavs, TARGET),
        lambda: arc_formation(n_uavs, TARGET, 5.0),
        lambda: line_formation(n_uavs, TARGET, 5.0, 5.0),
        lambda: random_disc_formations(n_uavs, TARGET, 5.0, 3, np.random.default_rng(0)),
    ):
        with pytest.raises(ValueError, match=r"^n_uavs"):
            call()


@pytest.mark.parametrize("target", [(np.nan, 0.0), (0.0, 0.0, 0.0)])
def test_bad_target(target):
    """Non-finite or wrongly shaped targets name target_xy."""
    for call in (
        lambda: arc_formation(4, target, 5.0),
        lambda: line_formation(4, target, 5.0, 5.0),
        lambda: random_disc_formations(4, target, 5.0, 3, np.random.default_rng(0)),
    ):
        with pytest.raises(ValueError, match=r"^target_xy"):
            call()


@pytest.mark.parametrize("radius", [0.0, -1.0, np.inf])
def test_bad_radius(radius):
    """Radii must be positive and finite."""
    for call in (
        lambda: fixed_radius_polygon(4, TARGET, radius),
        lambda: arc_formation(4, TARGET, radius),
        lambda: random_disc_formations(4, TARGET, radius, 3, np.random.default_rng(0)),
    ):
        with pytest.raises(ValueError, match=r"^radius"):
            call()


def test_read_only_inputs_are_accepted_and_unchanged(make_readonly):
    """Read-only inputs are accepted, unchanged, and not aliased by the output."""
    targets = make_readonly([[0.0, 0.0], [10.0, -3.0]])
    radii = make_readonly([5.0, 8.0])
    outputs = all_formations(4, targets, radii)
    np.testing.assert_array_equal(targets, [[0.0, 0.0], [10.0, -3.0]])
    np.testing.assert_array_equal(radii, [5.0, 8.0])
    for f in outputs.values():
        assert not np.shares_memory(f, targets)
        assert not np.shares_memory(f, radii)


def test_line_offset_shape_mismatch_names_offset():
    """A batch of offsets that does not fit the targets names ``offset``."""
    with pytest.raises(ValueError, match=r"^offset"):
        line_formation(4, np.zeros((3, 2)), np.ones(4), 1.0)
