r"""UAVs at individual altitudes and a target whose height may be unknown (beyond the paper).

Not in the paper (issue 11, item 3): the paper flies every UAV at one altitude :math:`H`
and knows the target's height. Here UAV :math:`m` flies at its own height
:math:`z_m`, at :math:`\Delta H_m = z_m - z_t \ge 0.1` m above the target
:math:`\mathbf s = (x_t, y_t, z_t)`; the range model of eqs. (1)-(2) is unchanged,
:math:`\hat d_m = d_m + \mathcal N(0, d_m^4/A_m)` with the 3-D distance
:math:`d_m = \lVert\mathbf q_m - \mathbf s\rVert`, and so is the information of one range,
:math:`[\mathbf J_d]_{mm} = A_m/d_m^4 + 8/d_m^2` (eq. (6)). With the unit line of sight
:math:`\mathbf u_m = (\cos\phi_m\cos\theta_m, \cos\phi_m\sin\theta_m, \sin\phi_m)`
(elevation :math:`\phi_m`, azimuth :math:`\theta_m`; the sign is immaterial),

.. math::

    \mathbf J = \sum_m [\mathbf J_d]_{mm}\,\mathbf u_m \mathbf u_m^\top
      = \begin{bmatrix} \mathbf J_h & \mathbf c \\ \mathbf c^\top & J_{zz}\end{bmatrix},

the :math:`3 \times 3` FIM of the target's position (height unknown). With the height known
the FIM is the horizontal block :math:`\mathbf J_h`, eq. (8) with each UAV at its own
:math:`\Delta H_m`. The CRLB is :math:`\operatorname{tr}\mathbf J^{-1}` in both cases
(eq. (10)).

**The bound (height unknown).** With :math:`g_m = [\mathbf J_d]_{mm}` at
:math:`d_m = \Delta H_m/\sin\phi_m`, :math:`a = \operatorname{tr}\mathbf J_h =
\sum_m g_m\cos^2\phi_m` and :math:`b = J_{zz} = \sum_m g_m \sin^2\phi_m`,

.. math::

    \operatorname{tr}\mathbf J^{-1} \;\ge\; \operatorname{tr}\mathbf J_h^{-1}
        + \frac{1}{J_{zz}} \;\ge\; \frac{4}{a} + \frac{1}{b},

the first by the block inverse (the Schur complements :math:`\mathbf J_h -
\mathbf c\mathbf c^\top/J_{zz} \preceq \mathbf J_h` and :math:`J_{zz} -
\mathbf c^\top\mathbf J_h^{-1}\mathbf c \le J_{zz}`), with equality iff
:math:`\mathbf c = \sum_m g_m\sin\phi_m\cos\phi_m(\cos\theta_m, \sin\theta_m) = 0`; the
second is eq. (11), equality iff :math:`\sum_m g_m\cos^2\phi_m e^{j2\theta_m} = 0`.

**Optimal elevations.** With :math:`s = \sin^2\phi` and :math:`\kappa_m = A_m/\Delta H_m^2`,
UAV :math:`m` contributes :math:`(x_m, y_m) = \bigl(s(1-s), s^2\bigr)(\kappa_m s + 8) /
\Delta H_m^2` to :math:`(a, b)`, and along this curve
:math:`x'y'' - y'x'' = 2(P^2 + \kappa sP + \kappa^2 s^2)/\Delta H_m^4 > 0`
(:math:`P = \kappa s + 8`): its upper-right (Pareto) part is concave. So the set of
reachable :math:`(a, b)` below that frontier is convex, :math:`4/a + 1/b` is convex and
decreasing, and the minimum over the elevations is a convex problem whose optimality
conditions decouple: every UAV maximises :math:`x_m + \rho y_m` with one common
:math:`\rho = a^2/(4b^2)` (the ratio of the multipliers :math:`4/a^2` and :math:`1/b^2`).
Each maximisation is a quadratic in :math:`s` (:func:`design_3d`), and :math:`\rho` is the
one root of an increasing function on :math:`(0, 1)` (Brent's method): the *Lagrangian
elevations* and the bound :math:`4/a^* + 1/b^*` below every formation at these heights.

For equal UAVs at one height the elevations are equal, :math:`\phi_3^*`
(:func:`optimal_elevation_3d`): :math:`s^*` minimises
:math:`(1+3s)/\bigl(s^2(1-s)(\kappa s + 8)\bigr)`, whose log-derivative vanishes at the root
of the cubic :math:`9\kappa s^3 + (48 - 2\kappa)s^2 - 3\kappa s - 16 = 0`, and a regular
M-gon (M >= 3 cancels the first and second harmonics) attains the bound: a closed form.
A single common elevation is therefore optimal: no mixture of elevations does better
(checked numerically, ``docs/three-d.md``). With unequal UAVs or heights the bound is
attained when azimuths cancel both harmonics for the Lagrangian elevations (generically
possible from M = 5: four real equations); otherwise the design is numerical.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .design import (
    attainable_crlb,
    information_weight,
    isotropic_azimuths,
    optimal_elevation,
    optimal_formation as optimal_formation_2d,
)
from .errors import FieldError
from .estimation import (
    TargetEstimate,
    damped_newton,
    linearised_estimate,
    noisy_range,
)
from .fisher import SINGULAR_RTOL
from .geometry import regular_polygon
from .montecarlo import MonteCarloResult, check_trials, summarise
from .radar import Radar, check_radar

__all__ = [
    "TARGET_HEIGHTS",
    "Design3D",
    "crlb_3d",
    "design_3d",
    "estimate_target_3d",
    "fisher_information_3d",
    "measure_ranges_3d",
    "monte_carlo_mse_3d",
    "optimal_elevation_3d",
    "optimal_formation_3d",
]

_DEFAULT_RADAR = Radar()

#: The two cases of the target's height: ``"known"`` (the paper's, a 2x2 FIM) and
#: ``"unknown"`` (a 3x3 FIM).
TARGET_HEIGHTS = ("known", "unknown")

#: Largest ``max_iter`` of :func:`estimate_target_3d` and ``starts`` of :func:`design_3d`.
MAX_ITERATIONS = 1_000_000
MAX_STARTS = 100_000

#: A design attains the bound when its CRLB is within this relative distance of it.
ATTAINED_RTOL = 1e-9

#: Smallest elevation the numerical design may use, rad (the UAV then stands about 1000
#: relative heights away; the optimum is always near 45-60 degrees).
MIN_ELEVATION = 1e-3


# -- validation -----------------------------------------------------------------------------
def _target_height(value: object) -> str:
    if not isinstance(value, str) or value not in TARGET_HEIGHTS:
        raise FieldError("target_height", f"expected 'known' or 'unknown', got {_v.short(value)}")
    return value


def _points(value: object, name: str, shape: str, min_ndim: int) -> np.ndarray:
    """3-D points ``(..., 3)`` (``min_ndim`` 1) or ``(..., M, 3)`` (``min_ndim`` 2), each
    coordinate within +-:data:`~crlbswarm._validation.MAX_COORDINATE` m."""
    arr = _v.as_float_array(value, name)
    if arr.ndim < min_ndim or arr.shape[-1] != 3 or (min_ndim == 2 and arr.shape[-2] < 1):
        raise FieldError(name, f"expected shape {shape}, got {arr.shape}")
    return _v.bounded(arr, name, -_v.MAX_COORDINATE, _v.MAX_COORDINATE, " m")


def _heights(dh: np.ndarray, name: str) -> np.ndarray:
    """Refuse UAVs less than 0.1 m or more than 1e5 m above the target (the model's range
    of the altitude)."""
    low, high = _v.MIN_ALTITUDE, _v.MAX_ALTITUDE
    bad = (dh < low) | (dh > high)
    if np.any(bad):
        raise FieldError(
            name,
            f"every UAV must fly {low:g} to {high:g} m above the target (the model's range), "
            f"got a height difference of {dh[bad].flat[0]:g} m",
        )
    return dh


def _scene(
    uav_xyz: ArrayLike, target_xyz: ArrayLike, radar: Radar
) -> tuple[np.ndarray, np.ndarray, float | np.ndarray]:
    """Validated ``(s - q_m, A)``: the offsets from each UAV to the target, shape
    ``(..., M, 3)``, and the radar's constant."""
    q = _points(uav_xyz, "uav_xyz", "(..., M, 3)", 2)
    s = _points(target_xyz, "target_xyz", "(..., 3)", 1)
    batch = _v.broadcast("target_xyz", q.shape[:-2], s.shape[:-1])
    n = float(np.prod(batch, dtype=float)) * q.shape[-2]
    _v.check_elements(n, "uav_xyz", f"{n:.3g} UAV-target pairs", copies=12)
    a = check_radar(radar, q.shape[-2])
    diff = s[..., None, :] - q
    _heights(-diff[..., 2], "uav_xyz")
    return diff, q, a


# -- Fisher information and CRLB ------------------------------------------------------------
def fisher_information_3d(
    uav_xyz: ArrayLike,
    target_xyz: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    target_height: str = "unknown",
) -> np.ndarray:
    r"""Fisher information of the target's position, UAVs at individual altitudes.

    .. math::

        \mathbf J = \sum_m \Bigl(\frac{A_m}{d_m^4} + \frac{8}{d_m^2}\Bigr)
            \mathbf u_m\mathbf u_m^\top, \qquad
            \mathbf u_m = \frac{\mathbf s - \mathbf q_m}{d_m},

    the range information of eq. (6) through the 3-D line of sight (height unknown,
    3x3), or through its horizontal part only (height known, 2x2: eq. (8) with each UAV at
    its own height above the target; with one common height it equals
    :func:`crlbswarm.fisher_information`).

    Parameters
    ----------
    uav_xyz : array_like, shape (..., M, 3)
        UAV positions (x, y, z), m; each UAV at least 0.1 m above the target.
    target_xyz : array_like, shape (..., 3)
        Target position, m; broadcasts against the batch shape of ``uav_xyz``.
    radar : Radar, optional
        Link parameters (paper profile by default). Per-UAV fields must have length M.
    target_height : {"unknown", "known"}, default "unknown"
        Whether the target's height is estimated (3x3 FIM) or known (2x2).

    Returns
    -------
    ndarray, shape (..., 3, 3) or (..., 2, 2)
        The symmetric FIM, m^-2.

    Raises
    ------
    FieldError
        On wrong shapes, numbers that are not real and finite, coordinates beyond
        +-1e7 m, a UAV less than 0.1 m or more than 1e5 m above the target (the model's
        ranges), a per-UAV radar of another length than M, or an unknown
        ``target_height``. One line naming the argument.

    Examples
    --------
    >>> import numpy as np
    >>> from crlbswarm import fisher_information_3d
    >>> uavs = [[10.0, 0.0, 20.0], [-5.0, 8.7, 25.0], [-5.0, -8.7, 30.0]]
    >>> fisher_information_3d(uavs, [0.0, 0.0, 0.0]).shape
    (3, 3)
    """
    case = _target_height(target_height)
    diff, _, a = _scene(uav_xyz, target_xyz, radar)
    d2 = np.sum(diff * diff, axis=-1)  # the 3-D distance in both cases
    if case == "known":
        diff = diff[..., :2]  # the horizontal part of the line of sight only
    # [J_d]_mm / d_m^2: the weight of the outer product of the offsets (u = diff / d).
    w = (a / d2 + 8.0) / d2 / d2
    return np.einsum("...m,...mi,...mj->...ij", w, diff, diff)


def _trace_inverse(j: np.ndarray) -> np.ndarray:
    r""":math:`\operatorname{tr}\mathbf J^{-1}` of symmetric positive semi-definite
    matrices ``(..., n, n)``, ``+inf`` where singular.

    Computed on the Jacobi-scaled matrix :math:`\mathbf C = \mathbf D^{-1/2}\mathbf J
    \mathbf D^{-1/2}` (:math:`\mathbf D` the diagonal, so :math:`C_{ii} = 1`) by its
    eigen-decomposition, :math:`\operatorname{tr}\mathbf J^{-1} = \sum_i
    (\mathbf C^{-1})_{ii}/J_{ii}`: the scaling removes the disparity between the
    horizontal and the vertical information, so the result is accurate to about
    :math:`\operatorname{cond}(\mathbf C)` ulps. Singular when a diagonal entry is zero or
    :math:`\lambda_{\min}(\mathbf C) \le` ``SINGULAR_RTOL`` :math:`\lambda_{\max}(\mathbf C)`
    (the condition number of :math:`\mathbf C` beyond about 1e13, the threshold of
    :mod:`crlbswarm.fisher`).
    """
    diag = np.einsum("...ii->...i", j)
    positive = np.all(diag > 0, axis=-1)
    inv_sqrt = 1.0 / np.sqrt(np.where(positive[..., None], diag, 1.0))
    c = j * inv_sqrt[..., :, None] * inv_sqrt[..., None, :]
    lam, vec = np.linalg.eigh(c)
    singular = ~positive | ~(lam[..., 0] > SINGULAR_RTOL * lam[..., -1])
    lam = np.where(singular[..., None], 1.0, lam)
    inv_diag = np.einsum("...ik,...k->...i", vec * vec, 1.0 / lam)
    with np.errstate(over="ignore"):  # (an overflow to +inf is the right answer)
        tr = np.sum(inv_diag * inv_sqrt * inv_sqrt, axis=-1)
    return np.where(singular, np.inf, tr)


def crlb_3d(
    uav_xyz: ArrayLike,
    target_xyz: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    target_height: str = "unknown",
) -> np.ndarray:
    r"""CRLB :math:`\operatorname{tr}\mathbf J^{-1}` of the target's position, m^2, eq. (10).

    The FIM of :func:`fisher_information_3d`: with the height unknown, the bound on
    :math:`E\lVert\hat{\mathbf s} - \mathbf s\rVert^2` in 3-D; with it known, on the
    horizontal error (equal to :func:`crlbswarm.crlb` when every UAV flies at one height).

    Parameters
    ----------
    uav_xyz : array_like, shape (..., M, 3)
        UAV positions, m; each UAV at least 0.1 m above the target.
    target_xyz : array_like, shape (..., 3)
        Target position, m.
    radar : Radar, optional
        Link parameters (paper profile by default).
    target_height : {"unknown", "known"}, default "unknown"
        Whether the target's height is estimated or known.

    Returns
    -------
    ndarray, shape (...)
        CRLB in m^2; ``+inf`` for a singular geometry (fewer UAVs than unknowns, all
        UAVs in one vertical plane through the target, all straight above it), never NaN.
        The FIM is treated as singular when its diagonally scaled form has a condition
        number beyond about 1e13 (where no finite value would be meaningful).

    Raises
    ------
    FieldError
        As :func:`fisher_information_3d`.

    Examples
    --------
    >>> from crlbswarm import crlb_3d, optimal_formation_3d
    >>> f = optimal_formation_3d([20.0] * 6, (0.0, 0.0, 0.0))
    >>> round(float(crlb_3d(f, (0.0, 0.0, 0.0))) * 1e3, 4)
    5.9668
    """
    return _trace_inverse(fisher_information_3d(uav_xyz, target_xyz, radar, target_height))


# -- the optimal design ---------------------------------------------------------------------
def _cubic_root(kappa: np.ndarray) -> np.ndarray:
    r""":math:`s^* = \sin^2\phi_3^*`: the root in :math:`(1/2, 3/4)` of the cubic of
    :func:`optimal_elevation_3d` divided by :math:`\kappa + 48`,
    :math:`\tilde p(s) = 9\mu s^3 + (\nu - 2\mu)s^2 - 3\mu s - \nu/3` with
    :math:`\mu = \kappa/(\kappa+48)`, :math:`\nu = 48/(\kappa+48)` (bounded coefficients
    for every :math:`\kappa`). :math:`\tilde p(1/2) < 0 < \tilde p(3/4)`, and
    :math:`\tilde p' > 0`, :math:`\tilde p'' > 0` on :math:`[1/2, 3/4]`, so Newton's method
    from :math:`3/4` decreases monotonically to the root (quadratically: about 6 steps)."""
    mu = kappa / (kappa + 48.0)
    nu = 48.0 / (kappa + 48.0)
    s = np.full(np.shape(kappa), 0.75)
    for _ in range(100):  # (never reached: the sequence stalls after about 6 steps)
        p = ((9.0 * mu * s + (nu - 2.0 * mu)) * s - 3.0 * mu) * s - nu / 3.0
        dp = (27.0 * mu * s + 2.0 * (nu - 2.0 * mu)) * s - 3.0 * mu
        new = np.minimum(s, s - p / dp)
        if np.array_equal(new, s):
            break
        s = new
    return s


def optimal_elevation_3d(altitude: ArrayLike, radar: Radar = _DEFAULT_RADAR) -> np.ndarray:
    r"""CRLB-optimal common elevation :math:`\phi_3^*` when the target's height is unknown, rad.

    For M equal UAVs at one height :math:`\Delta H` above the target, on a regular
    polygon at a common elevation :math:`\phi` (:math:`s = \sin^2\phi`,
    :math:`\kappa = A/\Delta H^2`),

    .. math::

        \operatorname{tr}\mathbf J^{-1} = \frac{4}{a} + \frac{1}{b}
        = \frac{\Delta H^2}{M}\,\frac{1 + 3s}{s^2(1-s)(\kappa s + 8)},

    and the log-derivative :math:`3/(1+3s) - 2/s + 1/(1-s) - \kappa/(\kappa s + 8)`
    vanishes at the root of

    .. math:: 9\kappa s^3 + (48 - 2\kappa)s^2 - 3\kappa s - 16 = 0,

    the only positive one (one sign change of the coefficients), a minimum (the objective
    tends to infinity at both ends), in :math:`(1/2, 3/4)`. As :math:`\kappa \to \infty`
    (high SNR) the cubic tends to :math:`9s^2 - 2s - 3 = 0`,
    :math:`s = (1 + \sqrt{28})/9`, :math:`\phi_3^* \to 56.73^\circ`
    (:func:`crlbswarm.optimal_elevation`: :math:`54.74^\circ`); as :math:`\kappa \to 0`,
    :math:`s = 1/\sqrt 3`, :math:`\phi_3^* \to 49.46^\circ` (45 degrees). The unknown height
    asks for steeper lines of sight. Evaluated by the monotone Newton iteration from
    :math:`s = 3/4` (module docstring), to the last bit.

    Parameters
    ----------
    altitude : float or array_like
        Height :math:`\Delta H` of the UAVs above the target, m, in [0.1, 1e5].
    radar : Radar, optional
        Link parameters; per-UAV fields broadcast over the last axis of ``altitude``.

    Returns
    -------
    ndarray
        :math:`\phi_3^*`, rad.

    Raises
    ------
    FieldError
        If the altitude is outside [0.1, 1e5] m or does not broadcast with the radar.

    Examples
    --------
    >>> import numpy as np
    >>> from crlbswarm import optimal_elevation_3d
    >>> round(float(np.degrees(optimal_elevation_3d(20.0))), 3)
    56.73
    """
    h = _v.altitude(altitude, "altitude")
    a = check_radar(radar, None)
    _v.broadcast("radar", np.shape(a), h.shape)
    s = _cubic_root(a / h / h)
    return np.arctan2(np.sqrt(s), np.sqrt(1.0 - s))


def _lagrangian_sines(rho: float, mu: np.ndarray, nu: np.ndarray) -> np.ndarray:
    r"""Each UAV's :math:`s_m = \sin^2\phi_m` maximising :math:`x_m + \rho y_m`.

    :math:`(\kappa s^2 + 8s)(1 + \beta s)` with :math:`\beta = \rho - 1` has the derivative
    :math:`3\kappa\beta s^2 + (2\kappa + 16\beta)s + 8`; divided by :math:`\kappa + 8`,
    :math:`3\mu\beta s^2 + 2(\mu + \beta\nu)s + \nu` with :math:`\mu = \kappa/(\kappa+8)`,
    :math:`\nu = 8/(\kappa+8)`. For :math:`\beta < 0` its one positive root (taken in the
    form without cancellation), capped at 1 (straight above the target); for
    :math:`\beta \ge 0` the derivative is positive and :math:`s = 1`."""
    beta = rho - 1.0
    a2 = 3.0 * mu * beta  # <= 0
    a1 = 2.0 * (mu + beta * nu)
    disc = np.sqrt(a1 * a1 - 4.0 * a2 * nu)  # >= |a1|
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(a1 >= 0.0, (a1 + disc) / (2.0 * np.abs(a2)), 2.0 * nu / (disc - a1))
    return np.minimum(np.where(np.isnan(s), 1.0, s), 1.0)


def _information_ab(s: np.ndarray, dh: np.ndarray, a: Any) -> tuple[float, float]:
    r""":math:`(a, b) = (\sum_m g_m\cos^2\phi_m, \sum_m g_m\sin^2\phi_m)` at
    :math:`s_m = \sin^2\phi_m` (:math:`g_m = A_m/d_m^4 + 8/d_m^2`, :math:`1/d_m^2 =
    s_m/\Delta H_m^2`)."""
    r = s / dh / dh
    g = a * r * r + 8.0 * r
    return float(np.sum(g * (1.0 - s))), float(np.sum(g * s))


def _lagrangian(dh: np.ndarray, a: Any) -> tuple[np.ndarray, float]:
    r"""The Lagrangian elevations' :math:`s_m` and the bound :math:`4/a^* + 1/b^*` (module
    docstring): :math:`\rho - a(\rho)^2/(4b(\rho)^2)` increases from below 0 at
    :math:`\rho = 0` to 1 at :math:`\rho = 1` (every UAV overhead, :math:`a = 0`)."""
    from scipy.optimize import brentq

    kappa = a / dh / dh
    mu, nu = kappa / (kappa + 8.0), 8.0 / (kappa + 8.0)

    def excess(rho: float) -> float:
        x, y = _information_ab(_lagrangian_sines(rho, mu, nu), dh, a)
        return rho - (x / (2.0 * y)) ** 2

    rho = brentq(excess, 0.0, 1.0, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500)
    s = _lagrangian_sines(rho, mu, nu)
    x, y = _information_ab(s, dh, a)
    return s, 4.0 / x + 1.0 / y


@dataclass(frozen=True, eq=False)
class Design3D:
    """An optimal design of UAVs at given heights (:func:`design_3d`).

    Attributes
    ----------
    positions : ndarray, shape (M, 3)
        UAV positions (x, y, z), m; z are the given heights, UAV 1 first.
    crlb : float
        :math:`\\operatorname{tr}\\mathbf J^{-1}` of the design, m^2
        (:func:`crlb_3d`).
    bound : float
        A lower bound on the CRLB of every formation at these heights, m^2: with the
        height known the attainable optimum (:func:`crlbswarm.attainable_crlb` of each
        UAV's best weight, always attained); with it unknown :math:`4/a^* + 1/b^*` at the
        Lagrangian elevations (module docstring).
    attained : bool
        Whether ``crlb`` equals ``bound`` to ``ATTAINED_RTOL`` = 1e-9 (then the design is
        the global optimum).
    method : str
        ``"closed form"`` or ``"numerical"``.
    elevations : ndarray, shape (M,)
        Elevation of each UAV seen from the target, rad.
    target_height : str
        ``"known"`` or ``"unknown"``.
    starts : int
        Starts of the numerical search that were run (0 for a closed form).
    """

    positions: np.ndarray
    crlb: float
    bound: float
    attained: bool
    method: str
    elevations: np.ndarray
    target_height: str
    starts: int

    @property
    def ratio(self) -> float:
        """CRLB / bound (1 when attained)."""
        return self.crlb / self.bound


def _place(target: np.ndarray, dh: np.ndarray, phi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Positions ``(M, 3)`` of UAVs at elevations ``phi`` and azimuths ``theta`` (seen from
    the target) and heights ``dh`` above it."""
    radius = dh * np.cos(phi) / np.sin(phi)
    xy = target[:2] + radius[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    return np.column_stack([xy, target[2] + dh])


def _log_crlb(x: np.ndarray, dh: np.ndarray, a: Any) -> tuple[float, np.ndarray]:
    r""":math:`\log\operatorname{tr}\mathbf J^{-1}` (height unknown) over
    :math:`x = (\phi_1..\phi_M, \theta_1..\theta_M)` and its exact gradient,
    :math:`\partial\operatorname{tr}\mathbf J^{-1} = -\operatorname{tr}(\mathbf J^{-2}
    \partial\mathbf J)`."""
    m = dh.shape[0]
    phi, theta = x[:m], x[m:]
    sp, cp, st, ct = np.sin(phi), np.cos(phi), np.sin(theta), np.cos(theta)
    r = sp * sp / dh / dh  # 1/d^2
    g = a * r * r + 8.0 * r
    dg = (4.0 * a * r * r + 16.0 * r) * cp / sp  # dg/dphi
    u = np.stack([cp * ct, cp * st, sp], axis=-1)
    u_phi = np.stack([-sp * ct, -sp * st, cp], axis=-1)
    u_theta = np.stack([-cp * st, cp * ct, np.zeros(m)], axis=-1)
    j = np.einsum("m,mi,mj->ij", g, u, u)
    with np.errstate(all="ignore"):
        try:
            inv = np.linalg.inv(j)
        except np.linalg.LinAlgError:
            return 1e300, np.zeros_like(x)
        tr = float(np.trace(inv))
        if not (np.isfinite(tr) and tr > 0):
            return 1e300, np.zeros_like(x)
        bu = u @ (inv @ inv)
        grad_phi = -(dg * np.sum(u * bu, axis=-1) + 2.0 * g * np.sum(u_phi * bu, axis=-1))
        grad_theta = -2.0 * g * np.sum(u_theta * bu, axis=-1)
    return float(np.log(tr)), np.concatenate([grad_phi, grad_theta]) / tr


def _harmonic_azimuths(phi: np.ndarray, dh: np.ndarray, a: Any) -> np.ndarray:
    r"""Azimuths that cancel (or least-squares reduce) both harmonics of the bound's
    equality conditions at the elevations ``phi``: :math:`\sum_m g_m\sin\phi_m\cos\phi_m
    e^{j\theta_m}` and :math:`\sum_m g_m\cos^2\phi_m e^{j2\theta_m}`, each normalised by
    its weights' sum; from the weighted isotropic azimuths of the second
    (:func:`crlbswarm.isotropic_azimuths`). UAV 1 keeps azimuth 0."""
    from scipy.optimize import least_squares

    r = np.sin(phi) ** 2 / dh / dh
    g = a * r * r + 8.0 * r
    p = g * np.sin(phi) * np.cos(phi)
    q = g * np.cos(phi) ** 2
    p_sum, q_sum = max(float(p.sum()), 1e-300), max(float(q.sum()), 1e-300)
    ok = q > 1e-12 * q_sum  # (UAVs straight above the target have no horizontal weight)
    theta = np.zeros(phi.shape[0])
    if np.count_nonzero(ok) >= 2:
        theta[ok] = isotropic_azimuths(q[ok] / q_sum)

    def residual(t: np.ndarray) -> np.ndarray:
        full = np.concatenate([[0.0], t])
        z1 = np.sum(p * np.exp(1j * full)) / p_sum
        z2 = np.sum(q * np.exp(2j * full)) / q_sum
        return np.array([z1.real, z1.imag, z2.real, z2.imag])

    res = least_squares(residual, theta[1:] - theta[0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return np.concatenate([[0.0], res.x])


def _numerical_design(
    dh: np.ndarray, a: Any, bound: float, phi0: np.ndarray, starts: int, seed: int
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Multistart L-BFGS-B on :func:`_log_crlb`: start 0 at the Lagrangian elevations
    ``phi0`` with :func:`_harmonic_azimuths`, the others uniform (elevations in
    [0.2, 1.5] rad, azimuths in [-pi, pi]) from ``seed``. Stops at the first start that
    attains ``bound`` (nothing can do better). Returns ``(phi, theta, crlb, starts run)``."""
    from scipy.optimize import minimize

    m = dh.shape[0]
    rng = np.random.default_rng(seed)
    lower = [(MIN_ELEVATION, 0.5 * np.pi)] * m + [(None, None)] * m
    best_x, best = np.empty(2 * m), np.inf
    for k in range(starts):
        if k == 0:
            x0 = np.concatenate([phi0, _harmonic_azimuths(phi0, dh, a)])
        else:
            x0 = np.concatenate([rng.uniform(0.2, 1.5, m), rng.uniform(-np.pi, np.pi, m)])
        value = float(np.exp(_log_crlb(x0, dh, a)[0]))
        if value > bound * (1.0 + ATTAINED_RTOL):  # (start 0 is often the optimum itself)
            res = minimize(_log_crlb, x0, args=(dh, a), jac=True, method="L-BFGS-B",
                           bounds=lower, options={"maxiter": 5000, "ftol": 1e-15,
                                                  "gtol": 1e-12})  # fmt: skip
            x0, value = res.x, float(np.exp(res.fun))
        if value < best:
            best_x, best = x0, value
        if best <= bound * (1.0 + ATTAINED_RTOL):
            return best_x[:m], best_x[m:], best, k + 1
    return best_x[:m], best_x[m:], best, starts


def _design_inputs(
    altitudes: ArrayLike, target_xyz: ArrayLike, radar: Radar
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """Validated ``(z, target, dh, A)`` of :func:`design_3d`."""
    z = _v.as_float_array(altitudes, "altitudes")
    if z.ndim != 1:
        raise FieldError("altitudes", f"expected shape (M,), got {z.shape}")
    _v.uav_count(z.shape[0], "altitudes")
    _v.bounded(z, "altitudes", -_v.MAX_COORDINATE, _v.MAX_COORDINATE, " m")
    target = _points(target_xyz, "target_xyz", "(3,)", 1)
    if target.shape != (3,):
        raise FieldError("target_xyz", f"expected shape (3,), got {target.shape}")
    dh = _heights(z - target[2], "altitudes")
    return z, target, dh, check_radar(radar, z.shape[0])


def design_3d(
    altitudes: ArrayLike,
    target_xyz: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    target_height: str = "unknown",
    rotation: float = 0.0,
    *,
    starts: int = 32,
    seed: int = 0,
) -> Design3D:
    r"""The CRLB-optimal formation of UAVs at given heights, with its CRLB and a bound.

    Each UAV keeps its height :math:`z_m`; the design chooses where it stands
    horizontally (its elevation :math:`\phi_m` and azimuth :math:`\theta_m` seen from the
    target).

    * Height known (eq. (8) with per-UAV heights :math:`\Delta H_m = z_m - z_t`): every
      UAV at its own optimal elevation for its own height,
      :func:`crlbswarm.optimal_elevation` (eq. (9)'s weight :math:`w_m^*` at its maximum),
      and the azimuths of :func:`crlbswarm.isotropic_azimuths` (weighted isotropy, or the
      dominant UAV opposite the others); the value is :func:`crlbswarm.attainable_crlb`
      of the :math:`w_m^*`, the optimum. With one common height this is
      :func:`crlbswarm.optimal_formation` itself. Closed form.
    * Height unknown, equal UAVs at one height: the regular polygon at the elevation
      :func:`optimal_elevation_3d`, attaining :math:`4/a + 1/b` (module docstring).
      Closed form.
    * Height unknown otherwise: numerical. ``starts`` L-BFGS-B searches of
      :math:`\log\operatorname{tr}\mathbf J^{-1}` over all elevations and azimuths (exact
      gradient); start 0 at the Lagrangian elevations with azimuths that cancel the two
      harmonics, the others random (seeded). The search stops at the first start whose
      CRLB equals the bound :math:`4/a^* + 1/b^*` (a certificate of the global optimum);
      ``attained`` is False when no start reaches it (generically with M = 3 or 4 unequal
      UAVs or heights, where four real equations in M - 1 free azimuths have no
      solution, or a UAV that dominates).

    Parameters
    ----------
    altitudes : array_like, shape (M,)
        Height :math:`z_m` of each UAV, m (absolute, like ``target_xyz``), 0.1 to 1e5 m
        above the target; M >= 3.
    target_xyz : array_like, shape (3,)
        Target position, m.
    radar : Radar, optional
        Link parameters; per-UAV fields (length M) give unequal UAVs.
    target_height : {"unknown", "known"}, default "unknown"
        Whether the target's height is estimated or known.
    rotation : float, default 0
        Azimuth of UAV 1 seen from the target, rad.
    starts : int, default 32
        Largest number of starts of the numerical design (1 to 100 000).
    seed : int, default 0
        Seed of the random starts.

    Returns
    -------
    Design3D
        Positions, CRLB, bound, whether it is attained, method, elevations.

    Raises
    ------
    FieldError
        If fewer than 3 heights are given (or more than 100 000, or more than 500 for a
        numerical design), a UAV is not 0.1 to 1e5 m above the target, a coordinate is
        beyond +-1e7 m, a per-UAV radar has another length, or ``target_height``,
        ``rotation``, ``starts`` or ``seed`` is invalid. One line naming the argument.

    Examples
    --------
    >>> from crlbswarm import design_3d
    >>> d = design_3d([20.0] * 6, (0.0, 0.0, 0.0))
    >>> d.method, d.attained, round(d.crlb * 1e3, 4)
    ('closed form', True, 5.9668)
    >>> d = design_3d([20.0] * 6, (0.0, 0.0, 0.0), target_height="known")
    >>> round(d.crlb * 1e3, 4)  # crlbswarm.crlb_bound(6, 20.0)
    5.3476
    """
    case = _target_height(target_height)
    z, target, dh, a = _design_inputs(altitudes, target_xyz, radar)
    rot = _v.angle(rotation, "rotation")
    n_starts = _v.count(starts, "starts", 1, MAX_STARTS)
    rng_seed = _v.seed(seed, "seed")
    m = z.shape[0]
    equal_height = bool(np.all(dh == dh[0]))
    equal_uavs = bool(np.all(np.asarray(a) == np.ravel(a)[0]))
    if case == "known":
        phi = np.broadcast_to(optimal_elevation(dh, radar), (m,))
        bound = float(attainable_crlb(information_weight(phi, dh, radar)))
        if equal_height:  # the paper's design, exactly (regular polygon for equal UAVs)
            xy = optimal_formation_2d(m, target[:2], dh[0], radar, rot)
            positions = np.column_stack([xy, z])
        else:
            theta = isotropic_azimuths(information_weight(phi, dh, radar), rot)
            positions = _place(target, dh, phi, theta)
        return _result(positions, target, radar, case, bound, "closed form", 0)
    if equal_height and equal_uavs:
        s = _cubic_root(np.ravel(a)[0] / dh[0] ** 2)
        x, y = _information_ab(np.full(m, s), dh, a)
        radius = dh[0] * np.sqrt((1.0 - s) / s)
        xy = regular_polygon(m, target[:2], radius, rot)
        positions = np.column_stack([xy, z])
        return _result(positions, target, radar, case, 4.0 / x + 1.0 / y, "closed form", 0)
    if m > _v.MAX_DESIGN_UAVS:
        raise FieldError(
            "altitudes", f"a numerical design takes at most {_v.MAX_DESIGN_UAVS} UAVs, got {m}"
        )
    s_star, bound = _lagrangian(dh, a)
    phi0 = np.maximum(np.arctan2(np.sqrt(s_star), np.sqrt(1.0 - s_star)), MIN_ELEVATION)
    phi, theta, _, runs = _numerical_design(dh, a, bound, phi0, n_starts, rng_seed)
    positions = _place(target, dh, phi, theta - theta[0] + rot)
    return _result(positions, target, radar, case, bound, "numerical", runs)


def _result(
    positions: np.ndarray,
    target: np.ndarray,
    radar: Radar,
    case: str,
    bound: float,
    method: str,
    starts: int,
) -> Design3D:
    if not np.all(np.abs(positions) <= _v.MAX_COORDINATE):
        raise FieldError(
            "target_xyz",
            f"the formation around it would reach beyond +-{_v.MAX_COORDINATE:g} m (the "
            "model's range of coordinates)",
        )
    value = float(crlb_3d(positions, target, radar, case))
    diff = positions - target
    return Design3D(
        positions=positions,
        crlb=value,
        bound=float(bound),
        attained=bool(value <= bound * (1.0 + ATTAINED_RTOL)),
        method=method,
        elevations=np.arctan2(diff[:, 2], np.hypot(diff[:, 0], diff[:, 1])),
        target_height=case,
        starts=starts,
    )


def optimal_formation_3d(
    altitudes: ArrayLike,
    target_xyz: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    target_height: str = "unknown",
    rotation: float = 0.0,
    *,
    starts: int = 32,
    seed: int = 0,
) -> np.ndarray:
    """The positions of :func:`design_3d`'s optimal formation.

    Parameters
    ----------
    altitudes : array_like, shape (M,)
        Height of each UAV, m (0.1 to 1e5 m above the target), M >= 3.
    target_xyz : array_like, shape (3,)
        Target position, m.
    radar : Radar, optional
        Link parameters; per-UAV fields give unequal UAVs.
    target_height : {"unknown", "known"}, default "unknown"
        Whether the target's height is estimated or known.
    rotation : float, default 0
        Azimuth of UAV 1 seen from the target, rad.
    starts : int, default 32
        Largest number of starts of a numerical design.
    seed : int, default 0
        Seed of its random starts.

    Returns
    -------
    ndarray, shape (M, 3)
        UAV positions (x, y, z), m.

    Raises
    ------
    FieldError
        As :func:`design_3d`.
    """
    return design_3d(
        altitudes, target_xyz, radar, target_height, rotation, starts=starts, seed=seed
    ).positions


# -- measurements and the estimator ---------------------------------------------------------
def measure_ranges_3d(
    uav_xyz: ArrayLike,
    target_xyz: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    r"""Noisy ranges :math:`\hat d_m = d_m + z_m`, :math:`z_m \sim \mathcal N(0, d_m^4/A_m)`
    (eq. (2)), with 3-D distances.

    The range model of :func:`crlbswarm.estimation.noisy_range` (written once), fed with
    :math:`d_m^2 = \lVert\mathbf q_m - \mathbf s\rVert^2`.

    Parameters
    ----------
    uav_xyz : array_like, shape (..., M, 3)
        UAV positions, m; each at least 0.1 m above the target.
    target_xyz : array_like, shape (..., 3)
        True target position, m.
    radar : Radar, optional
        Link parameters (paper profile by default).
    rng : numpy.random.Generator
        Source of the noise (required).

    Returns
    -------
    ndarray, shape (..., M)
        Measured ranges, m.

    Raises
    ------
    FieldError
        As :func:`fisher_information_3d`, or if ``rng`` is not a Generator.
    """
    if not isinstance(rng, np.random.Generator):
        raise FieldError("rng", f"expected a numpy.random.Generator, got {type(rng).__name__}")
    diff, _, a = _scene(uav_xyz, target_xyz, radar)
    d2 = np.sum(diff * diff, axis=-1)
    return np.asarray(noisy_range(d2, a, rng.standard_normal(d2.shape)))


def _ranges(measured_ranges: ArrayLike, n_uavs: int) -> np.ndarray:
    d = _v.as_float_array(measured_ranges, "measured_ranges")
    if d.ndim < 1 or d.shape[-1] != n_uavs:
        raise FieldError(
            "measured_ranges", f"expected shape (..., {n_uavs}) to match uav_xyz, got {d.shape}"
        )
    lim = _v.MAX_MEASURED_RANGE
    return _v.bounded(d, "measured_ranges", -lim, lim, " m")


def _initial(q: np.ndarray, d_hat: np.ndarray) -> np.ndarray:
    r"""Closed-form start ``(n, 3)``. With the UAVs at 2 or more heights (and not
    coplanar), the linear least squares of :math:`\hat d_m^2 - \lVert\mathbf q_m\rVert^2
    \approx -2\mathbf q_m^\top\mathbf s + \lVert\mathbf s\rVert^2` in
    :math:`(\mathbf s, \lVert\mathbf s\rVert^2)`; otherwise (one height: the height column
    is then the constant one) the horizontal solve of
    :func:`crlbswarm.linearised_estimate` and the height from the ranges,
    :math:`z_t = \overline{z_m - \sqrt{\max(\hat d_m^2 - r_m^2, 0.01)}}` (below the UAVs).
    A start above the lowest UAV takes the latter height."""
    xy = linearised_estimate(q[..., :2], d_hat, 1.0)  # the height is absorbed in |s|^2
    center = q.mean(axis=-2)
    qc = q - center[:, None, :]
    rows = np.concatenate([-2.0 * qc, np.ones((*qc.shape[:-1], 1))], axis=-1)
    rhs = d_hat * d_hat - np.sum(qc * qc, axis=-1)
    normal = np.einsum("nmi,nmj->nij", rows, rows)
    moment = np.einsum("nmi,nm->ni", rows, rhs)
    # Hadamard's ratio det / prod(diag) (invariant to the columns' units) measures how far
    # the columns are from dependent: zero for UAVs at one height.
    diag = np.prod(np.einsum("nii->ni", normal), axis=-1)
    ok = np.linalg.det(normal) > 1e-12 * diag
    safe = np.where(ok[:, None, None], normal, np.eye(4))
    sol = np.linalg.solve(safe, np.where(np.isfinite(moment), moment, 0.0)[..., None])[..., 0]
    ok &= np.all(np.isfinite(sol), axis=-1)
    xy = np.where(ok[:, None], center[:, :2] + sol[:, :2], xy)
    r2 = np.sum((q[..., :2] - xy[:, None, :]) ** 2, axis=-1)
    z_ranges = np.mean(q[..., 2] - np.sqrt(np.maximum(d_hat * d_hat - r2, 0.01)), axis=-1)
    z = np.where(ok, center[:, 2] + sol[:, 2], z_ranges)
    z = np.where(z < q[..., 2].min(axis=-1) - 0.1, z, z_ranges)
    return np.column_stack([xy, z])


def estimate_target_3d(
    uav_xyz: ArrayLike,
    measured_ranges: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    init: ArrayLike | None = None,
    *,
    max_iter: int = 100,
    tol: float = 1e-10,
) -> TargetEstimate:
    r"""Maximum-likelihood estimate of the target's 3-D position (height unknown), for a
    batch of trials.

    The two stages of :func:`crlbswarm.estimate_target` in three unknowns: weighted least
    squares with frozen weights :math:`A_m/\hat d_m^4`, then the exact negative
    log-likelihood :math:`\sum_m [2\ln d_m + A_m(\hat d_m - d_m)^2/(2d_m^4)]` with its exact
    :math:`3\times 3` Hessian, each a Levenberg-Marquardt-damped Newton iteration (damping
    scaled by :math:`\operatorname{tr}\mathbf J/3`), compiled, one trial after the other.

    The mirror ambiguity: UAVs all at one height :math:`H` measure the same ranges from a
    target at :math:`z` and from its reflection :math:`2H - z`, so the likelihood has two
    equal maxima. The target is below the UAVs (the model), so a result above the UAVs is
    replaced by its reflection (the same likelihood). With UAVs at several heights there is
    no exact mirror; a stage-1 result above the lowest UAV is reflected about the UAVs'
    mean height before stage 2 (a start in the other basin).

    Parameters
    ----------
    uav_xyz : array_like, shape (..., M, 3)
        UAV positions, m (M >= 3 unless ``init`` is given).
    measured_ranges : array_like, shape (..., M)
        Measured ranges, m (for example from :func:`measure_ranges_3d`).
    radar : Radar, optional
        Link parameters of the likelihood (paper profile by default).
    init : array_like, shape (..., 3), optional
        Starting point; by default a closed-form initialiser: with the UAVs at two or more
        heights the linear least squares of the squared ranges in
        :math:`(\mathbf s, \lVert\mathbf s\rVert^2)`, otherwise the horizontal solve of
        :func:`crlbswarm.linearised_estimate` and the height from the ranges (below the
        UAVs).
    max_iter : int, default 100
        Largest number of iterations of each stage.
    tol : float, default 1e-10
        Convergence when the step is below ``tol`` times (1 m + the distance of the
        estimate from the UAVs' centroid).

    Returns
    -------
    TargetEstimate
        ``position`` of shape (..., 3), convergence flags, iterations and the negative
        log-likelihood.

    Raises
    ------
    FieldError
        On wrong shapes, numbers that are not real and finite, coordinates beyond
        +-1e7 m, fewer than 3 UAVs without ``init``, or ranges so far from the geometry's
        that the likelihood overflows. One line naming the argument.
    """
    q = _points(uav_xyz, "uav_xyz", "(..., M, 3)", 2)
    m_uavs = q.shape[-2]
    a = check_radar(radar, m_uavs)
    d_hat = _ranges(measured_ranges, m_uavs)
    n_iter = _v.count(max_iter, "max_iter", 1, MAX_ITERATIONS)
    tolerance = _v.scalar(tol, "tol")
    if not tolerance > 0:
        raise FieldError("tol", f"must be > 0, got {tolerance!r}")
    if init is None and m_uavs < 3:
        raise FieldError("uav_xyz", f"needs at least 3 UAVs without an init, got {m_uavs}")
    s0 = None if init is None else _points(init, "init", "(..., 3)", 1)
    batch = _v.broadcast("measured_ranges", q.shape[:-2], d_hat.shape[:-1])
    if s0 is not None:
        batch = _v.broadcast("init", batch, s0.shape[:-1])
    n = float(np.prod(batch, dtype=float))
    _v.check_elements(n * m_uavs, "measured_ranges", f"{n:.3g} trials", copies=40)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        est = _estimate(q, d_hat, a, s0, batch, n_iter, tolerance)
    reason = "so far from the ranges the geometry can produce that the likelihood overflows"
    _v.finite_result(est.position, "measured_ranges", reason)
    _v.finite_result(est.nll, "measured_ranges", reason)
    return est


def _estimate(q, d_hat, a, s0, batch, n_iter, tolerance) -> TargetEstimate:
    m_uavs = q.shape[-2]
    q = np.broadcast_to(q, (*batch, m_uavs, 3)).reshape(-1, m_uavs, 3)
    d_hat = np.broadcast_to(d_hat, (*batch, m_uavs)).reshape(-1, m_uavs)
    a_b = np.broadcast_to(a, d_hat.shape)
    if s0 is None:
        s = _initial(q, d_hat)
    else:
        s = np.broadcast_to(s0, (*batch, 3)).reshape(-1, 3).copy()
    z_low, z_mean = q[..., 2].min(axis=-1), q[..., 2].mean(axis=-1)
    one_height = q[..., 2].max(axis=-1) == z_low
    d_floor = np.maximum(np.abs(d_hat), 0.1)  # (a range measured near zero: finite weight)
    w = a_b / d_floor**4
    loose = max(tolerance, 1e-6)
    s, _, _, it1, _ = damped_newton(False, s, q, d_hat, 0.0, a_b, w, n_iter, loose)
    above = s[:, 2] > z_low - 0.1  # the other basin: reflect before the exact stage
    s[above, 2] = np.minimum(2.0 * z_mean[above] - s[above, 2], z_low[above] - 0.1)
    s, nll, converged, it2, minimum = damped_newton(
        True, s, q, d_hat, 0.0, a_b, w, n_iter, tolerance
    )
    mirror = one_height & (s[:, 2] > z_low)  # exact: the same ranges, the same likelihood
    s[mirror, 2] = 2.0 * z_low[mirror] - s[mirror, 2]
    return TargetEstimate(
        position=s.reshape(*batch, 3),
        converged=(converged & minimum).reshape(batch),
        iterations=(it1 + it2).reshape(batch),
        nll=nll.reshape(batch),
    )


def monte_carlo_mse_3d(
    uav_xyz: ArrayLike,
    target_xyz: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    n_trials: int = 20_000,
    rng: np.random.Generator | None = None,
) -> MonteCarloResult:
    """MSE of the 3-D MLE (height unknown) over ``n_trials`` sets of ranges, with its CRLB.

    Ranges from :func:`measure_ranges_3d`, estimates from :func:`estimate_target_3d`
    (closed-form start, no prior), the CRLB from :func:`crlb_3d`; the statistics of
    :func:`crlbswarm.monte_carlo_mse` (normal 95 % intervals).

    Parameters
    ----------
    uav_xyz : array_like, shape (M, 3)
        One formation, m.
    target_xyz : array_like, shape (3,)
        True target, m.
    radar : Radar, optional
        Link parameters (paper profile by default).
    n_trials : int, default 20000
        Number of independent trials (at least 2).
    rng : numpy.random.Generator
        Source of the measurement noise (required).

    Returns
    -------
    MonteCarloResult
        MSE with its 95 % interval, the CRLB (``ratio`` and ``ratio_ci`` compare them),
        the bias (3 components) and failures.

    Raises
    ------
    FieldError
        As :func:`fisher_information_3d`; for one formation and one target only; for
        ``n_trials`` below 2 or too large for the memory; if ``rng`` is not a Generator.
    """
    q = _points(uav_xyz, "uav_xyz", "(M, 3)", 2)
    if q.ndim != 2:
        raise FieldError("uav_xyz", f"expected one formation of shape (M, 3), got {q.shape}")
    s = _points(target_xyz, "target_xyz", "(3,)", 1)
    if s.shape != (3,):
        raise FieldError("target_xyz", f"expected shape (3,), got {s.shape}")
    bound = float(crlb_3d(q, s, radar))
    n = _v.count(n_trials, "n_trials", 2)
    check_trials(n, q.shape[0])
    ranges = measure_ranges_3d(np.broadcast_to(q, (n, *q.shape)), s, radar, rng)
    est = estimate_target_3d(np.broadcast_to(q, (n, *q.shape)), ranges, radar)
    return summarise(est.position - s, est.failed, bound)
