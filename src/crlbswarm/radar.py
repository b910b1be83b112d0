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
import re
import textwrap
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError

__all__ = [
    "SPEED_OF_LIGHT",
    "Radar",
    "RadarParameter",
    "check_radar",
    "db_to_linear",
    "dbm_to_watts",
    "radar_field_names",
    "radar_parameters",
]

#: Speed of light in vacuum, m/s (exact, SI definition).
SPEED_OF_LIGHT = 299_792_458.0


def _from_db(value: object, name: str, offset: float) -> np.ndarray:
    """``10 ** ((value - offset) / 10)``, refusing values whose result is not a normal,
    finite, positive number (overflow to inf or underflow to 0 or subnormals)."""
    x = _v.finite(value, name)
    with np.errstate(over="ignore", under="ignore"):
        out = 10.0 ** ((x - offset) / 10.0)
    if not np.all(np.isfinite(out) & (out >= np.finfo(float).tiny)):
        low, high = _DB_RANGE[0] + offset, _DB_RANGE[1] + offset
        bad = x[~(np.isfinite(out) & (out >= np.finfo(float).tiny))].flat[0]
        raise FieldError(
            name,
            f"must be between {low:.0f} and {high:.0f} (10^(x/10) must be a finite, normal "
            f"number), got {bad:g}",
        )
    return out


#: Decibel values whose linear ratio is a finite, normal double: [-3076, 3082] dB.
_DB_RANGE = (
    10.0 * math.log10(np.finfo(float).tiny) + 0.01,
    10.0 * math.log10(np.finfo(float).max) - 0.01,
)


def _db_offset(db_unit: str) -> float:
    """30 for dBm (a power in watts), 0 for the other decibel forms."""
    return 30.0 if db_unit == "dBm" else 0.0


def db_to_linear(value_db: float | np.ndarray) -> float | np.ndarray:
    """Convert decibels to a linear power ratio, :math:`10^{x/10}`.

    Parameters
    ----------
    value_db : float or array_like
        Value in dB, between about -3076 and 3082 dB (the ratio must be a finite, normal
        double).

    Returns
    -------
    ndarray
        The linear ratio.

    Raises
    ------
    FieldError
        If ``value_db`` is not a real finite number (or array of them), or lies outside that
        range; the field is ``value_db``.
    """
    return _from_db(value_db, "value_db", 0.0)


def dbm_to_watts(value_dbm: float | np.ndarray) -> float | np.ndarray:
    """Convert dBm to watts, :math:`10^{(x - 30)/10}`.

    Parameters
    ----------
    value_dbm : float or array_like
        Power in dBm, between about -3046 and 3112 dBm (the power in watts must be a finite,
        normal double).

    Returns
    -------
    ndarray
        Power in W.

    Raises
    ------
    FieldError
        If ``value_dbm`` is not a real finite number (or array of them), or lies outside
        that range; the field is ``value_dbm``.
    """
    return _from_db(value_dbm, "value_dbm", 30.0)


def _field_value(value: object, name: str) -> float | np.ndarray:
    if isinstance(value, str | bytes | bool | np.bool_) or (
        isinstance(value, np.ndarray) and value.dtype.kind not in "iuf"
    ):
        raise FieldError(
            f"radar.{name}", f"expected a number or an array of numbers, got {_v.short(value)}"
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


def _parameter(default: float, unit: str, doc: str, db: str = "", short: str = "") -> Any:
    """Declare a radar field: its default (linear SI), unit, one line of doc, the unit of its
    decibel form (``dBm``, ``dB``, ``dBi`` or ``dBsm``; none if empty) and a short name for
    the command line. Everything else (the docstring, :meth:`Radar.from_db`, the scenario's
    ``[radar]`` table, the CLI options) is derived from these declarations."""
    return field(default=default, metadata={"unit": unit, "doc": doc, "db": db, "short": short})


@dataclass(frozen=True)
class RadarParameter:
    """One declared field of :class:`Radar` (see :func:`radar_parameters`).

    Parameters
    ----------
    name : str
        Field name, e.g. ``"tx_power"``.
    default : float
        Default value, linear SI units.
    unit : str
        Unit of the linear value (empty for a pure ratio).
    doc : str
        One line of documentation (reStructuredText).
    db_unit : str
        Unit of the decibel form (``"dBm"``, ``"dB"``, ``"dBi"``, ``"dBsm"``), or empty.
    short : str
        Short name of the command-line option, or empty.
    """

    name: str
    default: float
    unit: str
    doc: str
    db_unit: str
    short: str

    @property
    def label(self) -> str:
        """The doc as a short plain-text label: no maths, up to the first colon, lower case
        (``"transmit power per UAV"``)."""
        text = re.sub(r"\s*:math:`[^`]*`", "", self.doc).split(":")[0].strip()
        return text[:1].lower() + text[1:]

    @property
    def db_name(self) -> str:
        """Name of the decibel form (``tx_power_dbm``), or empty."""
        return f"{self.name}_{self.db_unit.lower()}" if self.db_unit else ""

    def db_to_linear(self, value: ArrayLike) -> np.ndarray:
        """Convert the decibel form to linear SI units.

        Parameters
        ----------
        value : float or array_like
            Value in ``db_unit``.

        Returns
        -------
        ndarray
            The linear value.
        """
        return np.asarray(_from_db(value, "value", _db_offset(self.db_unit)))

    @property
    def db_default(self) -> float:
        """The default in the decibel form (the inverse of :meth:`db_to_linear`); NaN if the
        field has no decibel form."""
        if not self.db_unit:
            return math.nan
        return 10.0 * math.log10(self.default) + (30.0 if self.db_unit == "dBm" else 0.0)


@dataclass(frozen=True, eq=False)
class Radar:
    r"""Parameters of the range-sensing link (paper Sec. II; defaults: the paper profile).

    The paper gives only :math:`p`, :math:`\sigma_0^2` and :math:`H`; the other defaults are
    crlbswarm's "paper profile" (``docs/sensing-model.md``) and are used by every figure and
    every quoted number.

    Each field is a positive number, or a 1-D array with one entry per UAV (per-UAV
    powers or gains). Array fields broadcast over the UAV axis of the positions passed
    to :func:`crlbswarm.fisher_information`; scalars apply to every UAV.

    Parameters
    ----------
    {parameters}

    Raises
    ------
    FieldError
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

    tx_power: float | np.ndarray = _parameter(
        0.1, "W", r"Transmit power per UAV :math:`p_m`", db="dBm", short="power"
    )
    noise_power: float | np.ndarray = _parameter(
        1e-12, "W", r"Receiver noise power :math:`\sigma_0^2`", db="dBm", short="noise"
    )
    processing_gain: float | np.ndarray = _parameter(
        1000.0, "", r"Processing gain :math:`G_p`", db="dB"
    )
    tx_gain: float | np.ndarray = _parameter(
        1.0, "", r"Transmit antenna gain :math:`G_T`", db="dBi"
    )
    rx_gain: float | np.ndarray = _parameter(
        1.0, "", r"Receive antenna gain :math:`G_r`", db="dBi"
    )
    rcs: float | np.ndarray = _parameter(
        1.0, "m^2", r"Radar cross section of the target :math:`\sigma_\mathrm{rcs}`", db="dBsm"
    )
    carrier_frequency: float | np.ndarray = _parameter(
        5.8e9, "Hz", r"Carrier frequency :math:`f_c`", short="frequency"
    )
    kappa: float | np.ndarray = _parameter(
        1.0,
        "m^2",
        r"Range-estimation constant :math:`\kappa`: the range variance at unit SNR, which "
        "depends on the waveform and the estimator (the paper leaves it unnamed)",
    )
    _snr_constant: float | np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lengths = set()
        for name in radar_field_names():
            value = _field_value(getattr(self, name), name)
            object.__setattr__(self, name, value)
            if isinstance(value, np.ndarray):
                lengths.add(value.shape[0])
        if len(lengths) > 1:
            raise FieldError(
                "radar",
                f"per-UAV fields must all have the same length, got lengths {sorted(lengths)}",
            )
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            try:
                a = (
                    self.tx_power
                    * self.processing_gain
                    * self.beta0
                    / (self.kappa * self.noise_power)
                )
            except (OverflowError, ZeroDivisionError):  # Python floats raise instead
                a = math.inf
        low, high = _v.MIN_SNR_CONSTANT, _v.MAX_SNR_CONSTANT
        if not np.all(np.isfinite(a) & (np.asarray(a) >= low) & (np.asarray(a) <= high)):
            arr = np.ravel(a)
            value = arr[~(np.isfinite(arr) & (arr >= low) & (arr <= high))][0]
            raise FieldError(
                "radar",
                f"A = p G_p beta0 / (kappa sigma0^2) must be between {low:g} and {high:g} "
                "(a range standard deviation at 1 m between 1e-15 and 1e+15 m, the model's "
                f"range), got {float(value):.3g}",
            )
        a = float(a) if np.ndim(a) == 0 else _readonly(np.asarray(a))
        object.__setattr__(self, "_snr_constant", a)

    # -- constructors -------------------------------------------------------------
    @classmethod
    def from_db(cls, **values: Any) -> Radar:
        """Build a :class:`Radar` from decibel values (and linear ones).

        Each keyword is a field's decibel form or the field itself in linear SI units;
        fields not given keep their defaults (the paper profile).

        Parameters
        ----------
        {db_parameters}

        Returns
        -------
        Radar
            The same link in linear SI units.

        Raises
        ------
        FieldError
            For an unknown keyword, a field given twice (linear and in dB), or a value that
            is not finite or out of range in linear units; the field is ``radar.<keyword>``.

        Examples
        --------
        >>> from crlbswarm import Radar
        >>> Radar.from_db(tx_power_dbm=20.0) == Radar()
        True
        """
        linear: dict[str, Any] = {}
        by_db = {p.db_name: p for p in radar_parameters() if p.db_unit}
        for key, value in values.items():
            if key in by_db:
                param = by_db[key]
                lin = _from_db(value, f"radar.{key}", _db_offset(param.db_unit))
                name = param.name
            elif key in radar_field_names():
                lin, name = value, key
            else:
                known = ", ".join([*by_db, *radar_field_names()])
                raise FieldError(f"radar.{key}", f"unknown parameter (known: {known})")
            if name in linear:
                raise FieldError(f"radar.{key}", f"{name} is given twice (linear and in dB)")
            linear[name] = lin
        return cls(**linear)

    def take(self, indices: ArrayLike) -> Radar:
        """The radar of some UAVs: per-UAV fields restricted to ``indices`` (scalar fields
        kept).

        Parameters
        ----------
        indices : array_like of int
            UAV indices.

        Returns
        -------
        Radar
            The radar of those UAVs (itself if no field is per UAV).

        Raises
        ------
        FieldError
            If an index is out of range.
        """
        if not self.per_uav:
            return self
        idx = np.asarray(indices)
        n = self.n_uavs or 0
        if idx.ndim != 1 or idx.dtype.kind not in "iu" or np.any((idx < 0) | (idx >= n)):
            raise FieldError("indices", f"expected UAV indices in 0..{n - 1}, got {idx!r}")
        return dataclasses.replace(
            self,
            **{
                name: value[idx]
                for name in radar_field_names()
                if isinstance(value := getattr(self, name), np.ndarray)
            },
        )

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
        return any(isinstance(getattr(self, name), np.ndarray) for name in radar_field_names())

    @property
    def n_uavs(self) -> int | None:
        """Length of the per-UAV fields, or ``None`` if every field is a scalar."""
        for name in radar_field_names():
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
        (in m^4 if :math:`\kappa` is taken as a pure number; with :math:`\kappa` in m^2,
        :math:`A` is in m^2 and :math:`\sigma_m^2` in m^2; see
        ``docs/paper-defaults-and-errata.md``).
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
        _v.bounded(d, "distance", 0.0, _v.MAX_DISTANCE, " m")
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
        for name in radar_field_names():
            value = getattr(self, name)
            out[name] = value.tolist() if isinstance(value, np.ndarray) else float(value)
        return out

    # -- value semantics (fields may be arrays) ------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Radar):
            return NotImplemented
        return all(
            np.array_equal(getattr(self, name), getattr(other, name))
            for name in radar_field_names()
        )

    def __hash__(self) -> int:
        return hash(
            tuple(tuple(np.ravel(getattr(self, name)).tolist()) for name in radar_field_names())
        )


def check_radar(radar: object, n_uavs: int | None) -> float | np.ndarray:
    """The constant :math:`A` of ``radar`` for ``n_uavs`` UAVs, after checking both.

    Parameters
    ----------
    radar : Radar
        The radar.
    n_uavs : int or None
        Number of UAVs its per-UAV fields must match (None: not checked).

    Returns
    -------
    float or ndarray, shape (n_uavs,)
        :attr:`Radar.snr_constant`.

    Raises
    ------
    FieldError
        If ``radar`` is not a :class:`Radar` or its per-UAV fields have another length.
    """
    if not isinstance(radar, Radar):
        raise FieldError("radar", f"expected a crlbswarm.Radar, got {type(radar).__name__}")
    if n_uavs is not None and radar.n_uavs is not None and radar.n_uavs != n_uavs:
        raise FieldError(
            "radar", f"per-UAV fields have length {radar.n_uavs} but there are {n_uavs} UAVs"
        )
    return radar.snr_constant


def radar_parameters() -> tuple[RadarParameter, ...]:
    """The declared fields of :class:`Radar`, in order, with default, unit and doc.

    Returns
    -------
    tuple of RadarParameter
        One entry per field.
    """
    return _PARAMETERS


def radar_field_names() -> tuple[str, ...]:
    """Names of the fields of :class:`Radar`, in order.

    Returns
    -------
    tuple of str
        ``("tx_power", "noise_power", ...)``.
    """
    return _NAMES


_PARAMETERS = tuple(
    RadarParameter(
        name=f.name,
        default=float(f.default),  # type: ignore[arg-type]
        unit=f.metadata["unit"],
        doc=f.metadata["doc"],
        db_unit=f.metadata["db"],
        short=f.metadata["short"],
    )
    for f in dataclasses.fields(Radar)
    if f.init
)
_NAMES = tuple(p.name for p in _PARAMETERS)


def _fill(doc: str | None, placeholder: str, entries: list[tuple[str, str, str]]) -> str:
    """Replace the line ``{placeholder}`` of a docstring by a numpydoc Parameters block."""
    text = doc or ""
    line = next(x for x in text.splitlines() if x.strip() == placeholder)
    indent = line[: len(line) - len(line.lstrip())]
    block = []
    for name, kind, description in entries:
        block.append(f"{indent}{name} : {kind}")
        block += textwrap.wrap(
            description, 92 - len(indent), initial_indent=indent + "    ",
            subsequent_indent=indent + "    ", break_on_hyphens=False,
        )  # fmt: skip
    return text.replace(line, "\n".join(block))


def _default_text(p: RadarParameter) -> str:
    """``default 1e-12 (-90 dBm)``: the default, and its decibel form where there is one."""
    text = f"default {p.default:g}"
    if p.db_unit:
        text += f" ({p.db_default:g} {p.db_unit})"
    return text


def _with_unit(p: RadarParameter) -> str:
    return f"{p.doc}, {p.unit or 'linear'}."


Radar.__doc__ = _fill(
    Radar.__doc__,
    "{parameters}",
    [(p.name, f"float or array_like, {_default_text(p)}", _with_unit(p)) for p in _PARAMETERS],
)
Radar.from_db.__func__.__doc__ = _fill(  # type: ignore[attr-defined]
    Radar.from_db.__doc__,
    "{db_parameters}",
    [
        (p.db_name, "float or array_like, optional", f"{p.doc}, {p.db_unit} (or ``{p.name}``).")
        for p in _PARAMETERS
        if p.db_unit
    ]
    + [(p.name, "float or array_like, optional", _with_unit(p)) for p in _PARAMETERS],
)


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.flags.writeable = False
    return arr
