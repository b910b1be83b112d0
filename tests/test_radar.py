"""The radar parameters (crlbswarm.radar): defaults, derived constants, value semantics."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from crlbswarm import (
    SPEED_OF_LIGHT,
    Radar,
    crlb,
    crlb_bound,
    db_to_linear,
    dbm_to_watts,
    optimal_formation,
)

FIELDS = [
    "tx_power",
    "noise_power",
    "processing_gain",
    "tx_gain",
    "rx_gain",
    "rcs",
    "carrier_frequency",
    "kappa",
]


def test_defaults_are_the_paper_profile(ref):
    """Every default equals the table of the paper profile of docs/sensing-model.md."""
    radar = Radar()
    for name, value in ref.PAPER_PROFILE.items():
        assert getattr(radar, name) == value
    assert SPEED_OF_LIGHT == 299_792_458.0
    assert radar.per_uav is False
    assert radar.n_uavs is None


def test_snr_constant_from_raw_numbers():
    """A = p G_p beta0 / (kappa sigma0^2) ~ 1.3463e8 m^4, computed here from the table."""
    wavelength = 299_792_458.0 / 5.8e9
    beta0 = 1.0 * 1.0 * 1.0 * wavelength**2 / (4.0 * math.pi) ** 3
    a = 0.1 * 1000.0 * beta0 / (1.0 * 1e-12)
    radar = Radar()
    assert radar.wavelength == pytest.approx(wavelength, rel=1e-15)
    assert radar.beta0 == pytest.approx(beta0, rel=1e-12)
    assert radar.snr_constant == pytest.approx(a, rel=1e-12)
    assert radar.snr_constant == pytest.approx(1.3463e8, rel=1e-4)


def test_from_db_defaults_equal_linear_defaults():
    """The dB constructor's defaults are the same link as the linear defaults."""
    assert Radar.from_db() == Radar()
    assert Radar.from_db(tx_power_dbm=30.0, processing_gain_db=20.0) == Radar(
        tx_power=1.0, processing_gain=100.0
    )


def test_db_conversions():
    """10^(x/10) and 10^((x - 30)/10) at known points."""
    np.testing.assert_allclose(db_to_linear([0.0, 10.0, 30.0, -3.0]), [1, 10, 1000, 10**-0.3])
    np.testing.assert_allclose(dbm_to_watts([20.0, -90.0, 30.0]), [0.1, 1e-12, 1.0], rtol=1e-15)


@pytest.mark.parametrize("seed", [0, 1])
def test_range_variance_is_d4_over_a(seed, ref):
    """sigma^2 = kappa sigma0^2 d^4 / (p G_p beta0) from the raw numbers; also per UAV."""
    rng = np.random.default_rng(seed)
    d = np.exp(rng.uniform(0.0, np.log(1e4), size=(3, 4)))
    np.testing.assert_allclose(
        Radar().range_variance(d), ref.range_var(d, ref.radar_params()), 1e-13
    )
    np.testing.assert_allclose(Radar().range_variance(d), d**4 / Radar().snr_constant, 1e-15)
    powers = rng.uniform(0.01, 1.0, size=4)
    np.testing.assert_allclose(
        Radar(tx_power=powers).range_variance(d),
        ref.range_var(d, ref.radar_params(tx_power=powers)),
        rtol=1e-13,
    )


def test_range_variance_bad_distance():
    """Negative or non-finite ranges and a per-UAV length mismatch are rejected."""
    for bad in (-1.0, np.nan, [1.0, np.inf]):
        with pytest.raises(ValueError, match=r"^distance"):
            Radar().range_variance(bad)
    with pytest.raises(ValueError, match=r"^radar"):
        Radar(tx_power=[0.1, 0.2]).range_variance([1.0, 2.0, 3.0])


def test_paper_scenario_crlb_value(ref):
    """M = 6, H = 20 m: optimal CRLB 5.3476e-3 m^2, computed here from the reference FIM of
    a hexagon at the numerically optimal elevation, then compared with the library."""
    altitude, n_uavs = 20.0, 6
    prm = ref.radar_params()
    phi = ref.optimal_elevation_numeric(altitude, float(ref.snr_constant(prm)))
    theta = 2 * np.pi * np.arange(n_uavs) / n_uavs
    uav = altitude / np.tan(phi) * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    expected = ref.crlb_of_fim(ref.fim_slepian_bangs(uav, np.zeros(2), altitude, prm))
    assert f"{expected:.4e}" == "5.3476e-03"
    target = np.array([80.0, 90.0])
    np.testing.assert_allclose(crlb_bound(n_uavs, altitude), expected, rtol=1e-10)
    f = optimal_formation(n_uavs, target, altitude)
    np.testing.assert_allclose(crlb(f, target, altitude), expected, rtol=1e-10)
    assert np.sqrt(expected) == pytest.approx(0.073, abs=5e-4)  # RMSE bound ~ 7.3 cm


# -- value semantics --------------------------------------------------------------------------


@pytest.mark.parametrize("name", FIELDS)
def test_frozen(name):
    """Assigning any field raises, also on a per-UAV radar."""
    radar = Radar(tx_power=[0.1, 0.2, 0.3])
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(radar, name, 1.0)


def test_per_uav_arrays_are_read_only():
    """Per-UAV fields and A cannot be changed in place."""
    radar = Radar(tx_power=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="read-only"):
        radar.tx_power[0] = 5.0
    a = radar.snr_constant
    with pytest.raises(ValueError, match="read-only"):
        a[0] = 5.0


def test_arrays_are_copied():
    """Changing the caller's array after construction does not change the Radar."""
    powers = np.array([0.1, 0.2, 0.3])
    radar = Radar(tx_power=powers)
    a_before = np.array(radar.snr_constant)
    powers[0] = 5.0
    np.testing.assert_array_equal(radar.tx_power, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(radar.snr_constant, a_before)
    assert not np.shares_memory(radar.tx_power, powers)


def test_read_only_input_array_is_unchanged(make_readonly):
    """Read-only inputs are accepted and left unchanged."""
    powers = make_readonly([0.1, 0.2, 0.3])
    distance = make_readonly([10.0, 20.0, 30.0])
    radar = Radar(tx_power=powers, kappa=powers)
    radar.range_variance(distance)
    Radar.from_db(tx_power_dbm=make_readonly([20.0, 23.0, 17.0]))
    np.testing.assert_array_equal(powers, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(distance, [10.0, 20.0, 30.0])


def test_equality_and_hash_with_per_uav_arrays():
    """Value equality and a consistent hash, whether fields came as lists or arrays."""
    a = Radar(tx_power=[0.1, 0.2, 0.3], kappa=np.array([1.0, 2.0, 1.0]))
    b = Radar(tx_power=np.array([0.1, 0.2, 0.3]), kappa=[1.0, 2.0, 1.0])
    c = Radar(tx_power=[0.1, 0.2, 0.4], kappa=[1.0, 2.0, 1.0])
    assert a == b
    assert hash(a) == hash(b)
    assert a != c
    assert Radar(tx_power=[0.1, 0.1, 0.1]) != Radar()
    assert Radar() != "Radar()"
    assert len({a, b, c, Radar(), Radar()}) == 3
    assert {a: 1}[b] == 1


def test_replace_validates_and_keeps_the_original():
    """replace() returns a validated copy and leaves the original alone."""
    radar = Radar()
    louder = radar.replace(tx_power=1.0)
    assert louder.snr_constant == pytest.approx(10 * radar.snr_constant, rel=1e-14)
    assert radar == Radar()
    with pytest.raises(ValueError, match=r"^radar\.tx_power"):
        radar.replace(tx_power=-1.0)


def test_per_uav_properties_and_to_dict():
    """per_uav, n_uavs, the shape of A, and a to_dict() round trip."""
    radar = Radar(tx_power=[0.1, 0.2, 0.3, 0.4])
    assert radar.per_uav is True
    assert radar.n_uavs == 4
    assert np.shape(radar.snr_constant) == (4,)
    d = radar.to_dict()
    assert d["tx_power"] == [0.1, 0.2, 0.3, 0.4]
    assert d["kappa"] == 1.0
    assert Radar(**d) == radar


# -- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize("name", FIELDS)
@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, np.inf, [0.1, -0.1], "loud", [[1.0]]])
def test_bad_field_raises_naming_the_field(name, bad):
    """Non-positive, non-finite, non-numeric or 2-D fields: ValueError naming the field."""
    with pytest.raises(ValueError, match=rf"^radar\.{name}"):
        Radar(**{name: bad})


def test_named_bad_fields_from_the_issue():
    """The three bad radars quoted in the issue."""
    with pytest.raises(ValueError, match=r"^radar\.tx_power"):
        Radar(tx_power=0)
    with pytest.raises(ValueError, match=r"^radar\.noise_power"):
        Radar(noise_power=-1)
    with pytest.raises(ValueError, match=r"^radar\.processing_gain"):
        Radar(processing_gain=np.nan)


def test_per_uav_length_mismatch():
    """Per-UAV fields of different lengths are rejected."""
    with pytest.raises(ValueError, match=r"^radar"):
        Radar(tx_power=[0.1, 0.2, 0.3], rx_gain=[1.0, 1.0])


@pytest.mark.parametrize("name", ["tx_power_dbm", "noise_power_dbm", "processing_gain_db"])
def test_from_db_rejects_non_finite(name):
    """NaN dB values are rejected with the dB argument's name."""
    with pytest.raises(ValueError, match=rf"^radar\.{name}"):
        Radar.from_db(**{name: np.nan})


def test_empty_per_uav_field_is_rejected():
    """A per-UAV field needs at least one UAV."""
    with pytest.raises(ValueError, match=r"^radar\.tx_power"):
        Radar(tx_power=[])


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"tx_power": "0.1"}, "radar.tx_power"),
        ({"rcs": True}, "radar.rcs"),
        ({"tx_power": 1e300, "noise_power": 1e-300}, "radar"),
    ],
)
def test_non_numbers_and_overflowing_constants_are_rejected(kwargs, name):
    """Strings and booleans are not powers; a constant A that overflows is out of range."""
    with pytest.raises(ValueError, match=rf"^{re.escape(name)}"):
        Radar(**kwargs)


def test_from_db_out_of_range_names_the_db_argument():
    with pytest.raises(ValueError, match=r"^radar\.tx_power_dbm"):
        Radar.from_db(tx_power_dbm=1e4)
