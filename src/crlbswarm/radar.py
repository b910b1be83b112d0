r"""Range (time-of-arrival) sensing model of the paper, Sec. II.

Wu, Jin, Su, Li, Pan, Chan, "Formation Control for CRLB-Optimal Cooperative Sensing
in Low-Altitude Wireless Networks", arXiv:2602.23990 (2026), referred to as "the
paper" throughout crlbswarm.

UAV :math:`m` measures the slant range :math:`d_m` to a ground target with additive
Gaussian noise (eq. (2)) whose variance grows with the fourth power of the range,

.. math::

    \sigma_m^2 = \frac{\kappa \sigma_0^2 d_m^4}{p_m G_p \beta_0},
    \qquad
    \beta_0 = \frac{G_T G_r \sigma_\mathrm{rcs} \lambda^2}{(4\pi)^3},
    \qquad \lambda = c / f_c .

All quantities are linear SI units (watts, metres, hertz, linear gains); dB values are
accepted only by :meth:`Radar.from_db`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _validation as _v
from .errors import FieldError

__all__ = [
    "SPEED_OF_LIGHT",
    "Radar",
    "db_to_linear",
    "dbm_to_watts",
]

#: Speed of light in vacuum, m/s (exact, SI definition).
SPEED_OF_LIGHT = 299_792_458.0

_FIELDS = (
    "tx_power",
    "noise_power",
    "processing_gain",
    "tx_gain",
    "rx_gain",
    "rcs",
    "carrier_frequency",
    "kappa",
)


def db_to_linear(value_db: float | np.ndarray) -> float | np.ndarray:
    """Convert decibels to a linear power ratio, :math:`10^{x/10}`.

    Parameters
    ----------
    value_db : float or array_like
        Value in dB.

    Returns
    -------
    ndarray
        The linear ratio.
    """
    return 10.0 ** (np.asarray(value_db, dtype=float) / 10.0)


def dbm_to_watts(value_dbm: float | np.ndarray) -> float | np.ndarray:
    """Convert dBm to watts, :math:`10^{(x - 30)/10}`.

    Parameters
    ----------
    value_dbm : float or array_like
        Power in dBm.

    Returns
    -------
    ndarray
        Power in W.
    """
    return 10.0 ** ((np.asarray(value_dbm, dtype=float) - 30.0) / 10.0)


def _field_value(value: object, name: str) -> float | np.ndarray:
    if isinstance(value, str | bytes | bool | np.bool_) or (
        isinstance(value, np.ndarray) and value.dtype.kind not in "iuf"
    ):
        raise FieldError(
            f"radar.{name}", f"expected a number or an array of numbers, got {value!r}"
        )
    arr = _v.positive(value, f"radar.{name}")
    if arr.ndim == 0:
        return float(arr)
    if arr.ndim != 1 or arr.shape[0] == 0:
        raise FieldError(
            f"radar.{name}",
            f"expected a number or a non-empty 1-D per-UAV array, got shape {arr.shape}",
        )
    arr = arr.copy()
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class Radar:
    r"""Parameters of the range-sensing link (paper Sec. II; defaults: PAPER_NOTES sec. 1).

    The paper gives only :math:`p`, :math:`\sigma_0^2` and :math:`H`; the other defaults are
    crlbswarm's "paper profile" and are used by every figure and every quoted number.

    Each field is a positive number, or a 1-D array with one entry per UAV (per-UAV
    powers or gains). Array fields broadcast over the UAV axis of the positions passed
    to :func:`crlbswarm.fisher_information`; scalars apply to every UAV.

    Parameters
    ----------
    tx_power : float or array_like, default 0.1
        Transmit power per UAV :math:`p_m`, W.
    noise_power : float or array_like, default 1e-12
        Receiver noise power :math:`\sigma_0^2`, W (-90 dBm).
    processing_gain : float or array_like, default 1000
        Processing gain :math:`G_p`, linear (30 dB).
    tx_gain : float or array_like, default 1
        Transmit antenna gain :math:`G_T`, linear (0 dBi).
    rx_gain : float or array_like, default 1
        Receive antenna gain :math:`G_r`, linear (0 dBi).
    rcs : float or array_like, default 1
        Radar cross section of the target :math:`\sigma_\mathrm{rcs}`, m^2.
    carrier_frequency : float or array_like, default 5.8e9
        Carrier frequency :math:`f_c`, Hz.
    kappa : float or array_like, default 1
        Range-estimation constant :math:`\kappa`: the range variance at unit SNR, which
        depends on the waveform and the estimator (m^2; the paper leaves it unnamed).

    Raises
    ------
    ValueError
        If a field is not positive and finite, or is not a number or a 1-D array.

    Examples
    --------
    >>> from crlbswarm import Radar
    >>> radar = Radar()
    >>> round(radar.snr_constant / 1e8, 4)
    1.3463
    >>> Radar(tx_power=[0.1, 0.2, 0.1]).per_uav
    True
    """

    tx_power: float | np.ndarray = 0.1
    noise_power: float | np.ndarray = 1e-12
    processing_gain: float | np.ndarray = 1000.0
    tx_gain: float | np.ndarray = 1.0
    rx_gain: float | np.ndarray = 1.0
    rcs: float | np.ndarray = 1.0
    carrier_frequency: float | np.ndarray = 5.8e9
    kappa: float | np.ndarray = 1.0
    _snr_constant: float | np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lengths = set()
        for name in _FIELDS:
            value = _field_value(getattr(self, name), name)
            object.__setattr__(self, name, value)
            if isinstance(value, np.ndarray):
                lengths.add(value.shape[0])
        if len(lengths) > 1:
            raise FieldError(
                "radar",
                f"per-UAV fields must all have the same length, got lengths {sorted(lengths)}",
            )
        with np.errstate(over="ignore", under="ignore"):
            a = self.tx_power * self.processing_gain * self.beta0 / (self.kappa * self.noise_power)
        if not np.all(np.isfinite(a) & (np.asarray(a) > 0)):
            raise FieldError(
                "radar",
                "A = p G_p beta0 / (kappa sigma0^2) is not a positive finite number "
                f"({a!r}); the parameters are out of range",
            )
        a = float(a) if np.ndim(a) == 0 else _readonly(a)
        object.__setattr__(self, "_snr_constant", a)

    # -- constructors -------------------------------------------------------------
    @classmethod
    def from_db(
        cls,
        tx_power_dbm: float | np.ndarray = 20.0,
        noise_power_dbm: float | np.ndarray = -90.0,
        processing_gain_db: float | np.ndarray = 30.0,
        tx_gain_dbi: float | np.ndarray = 0.0,
        rx_gain_dbi: float | np.ndarray = 0.0,
        rcs_dbsm: float | np.ndarray = 0.0,
        carrier_frequency: float | np.ndarray = 5.8e9,
        kappa: float | np.ndarray = 1.0,
    ) -> Radar:
        """Build a :class:`Radar` from decibel values.

        Parameters
        ----------
        tx_power_dbm : float or array_like, default 20
            Transmit power per UAV, dBm (20 dBm = 0.1 W).
        noise_power_dbm : float or array_like, default -90
            Receiver noise power, dBm.
        processing_gain_db : float or array_like, default 30
            Processing gain, dB.
        tx_gain_dbi : float or array_like, default 0
            Transmit antenna gain, dBi.
        rx_gain_dbi : float or array_like, default 0
            Receive antenna gain, dBi.
        rcs_dbsm : float or array_like, default 0
            Radar cross section, dBsm (dB relative to 1 m^2).
        carrier_frequency : float or array_like, default 5.8e9
            Carrier frequency, Hz (linear).
        kappa : float or array_like, default 1
            Range-estimation constant (linear).

        Returns
        -------
        Radar
            The same link in linear SI units.
        """
        linear = {}
        for name, value, field_name, convert in (
            ("tx_power_dbm", tx_power_dbm, "tx_power", dbm_to_watts),
            ("noise_power_dbm", noise_power_dbm, "noise_power", dbm_to_watts),
            ("processing_gain_db", processing_gain_db, "processing_gain", db_to_linear),
            ("tx_gain_dbi", tx_gain_dbi, "tx_gain", db_to_linear),
            ("rx_gain_dbi", rx_gain_dbi, "rx_gain", db_to_linear),
            ("rcs_dbsm", rcs_dbsm, "rcs", db_to_linear),
        ):
            _v.finite(value, f"radar.{name}")
            with np.errstate(over="ignore", under="ignore"):
                lin = convert(value)
            if not np.all(np.isfinite(lin) & (lin > 0)):
                raise FieldError(f"radar.{name}", f"{value!r} is out of range in linear units")
            linear[field_name] = lin
        return cls(**linear, carrier_frequency=carrier_frequency, kappa=kappa)

    def replace(self, **changes: Any) -> Radar:
        """Return a copy with some fields changed (validated like the constructor).

        Parameters
        ----------
        **changes
            New values of fields, by name.

        Returns
        -------
        Radar
            The modified copy.
        """
        return dataclasses.replace(self, **changes)

    # -- derived quantities -----------------------------------------------------------
    @property
    def per_uav(self) -> bool:
        """Whether any field holds one value per UAV."""
        return any(isinstance(getattr(self, name), np.ndarray) for name in _FIELDS)

    @property
    def n_uavs(self) -> int | None:
        """Length of the per-UAV fields, or ``None`` if every field is a scalar."""
        for name in _FIELDS:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                return int(value.shape[0])
        return None

    @property
    def wavelength(self) -> float | np.ndarray:
        r"""Carrier wavelength :math:`\lambda = c / f_c`, m."""
        return SPEED_OF_LIGHT / self.carrier_frequency

    @property
    def beta0(self) -> float | np.ndarray:
        r"""Two-way channel gain at unit distance, :math:`\beta_0` of Sec. II, m^4."""
        return self.tx_gain * self.rx_gain * self.rcs * self.wavelength**2 / (4.0 * math.pi) ** 3

    @property
    def snr_constant(self) -> float | np.ndarray:
        r"""The constant :math:`A = p G_p \beta_0 / (\kappa \sigma_0^2)`.

        The SNR at range :math:`d` is :math:`\kappa A / d^4` and the range variance is
        :math:`d^4 / A` (Sec. II). With the paper profile :math:`A \approx 1.3463 \times 10^8`
        (PAPER_NOTES quotes it in m^4, treating :math:`\kappa` as a pure number; with
        :math:`\kappa` in m^2, :math:`A` is in m^2 and :math:`\sigma_m^2` in m^2).
        """
        return self._snr_constant

    def range_variance(self, distance: float | np.ndarray) -> np.ndarray:
        r"""Range-noise variance :math:`\sigma_m^2 = d_m^4 / A_m`, m^2 (Sec. II).

        Parameters
        ----------
        distance : float or array_like, shape (..., M)
            Slant ranges :math:`d_m`, m. Per-UAV radar fields broadcast over the last axis.

        Returns
        -------
        ndarray, shape (..., M)
            The variance of each range measurement, m^2.
        """
        d = _v.as_float_array(distance, "distance")
        _v.check_finite(d, "distance")
        if np.any(d < 0):
            raise FieldError("distance", "must be >= 0")
        a = self.snr_constant
        _v.broadcast("radar", np.shape(a), d.shape)
        return d**4 / a

    def to_dict(self) -> dict[str, float | list[float]]:
        """The fields as plain Python numbers (lists for per-UAV fields), for JSON or TOML.

        Returns
        -------
        dict of str to float or list of float
            Field name to value, linear SI units.
        """
        out: dict[str, float | list[float]] = {}
        for name in _FIELDS:
            value = getattr(self, name)
            out[name] = value.tolist() if isinstance(value, np.ndarray) else float(value)
        return out

    # -- value semantics (fields may be arrays) ------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Radar):
            return NotImplemented
        return all(np.array_equal(getattr(self, name), getattr(other, name)) for name in _FIELDS)

    def __hash__(self) -> int:
        return hash(tuple(tuple(np.ravel(getattr(self, name)).tolist()) for name in _FIELDS))


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.flags.writeable = False
    return arr
