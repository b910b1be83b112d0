r"""Numerical optimal design under constraints: obstacles, no-fly zones, separation, radius.

Not in the paper (issue 11, item 2). The closed-form optimum :math:`F^*`
(:func:`crlbswarm.design.optimal_formation`) may put a slot inside an obstacle or a no-fly
zone, too close to another UAV, or beyond a largest radius. :func:`constrained_design`
finds the best formation that fits, for one of three criteria of
:math:`\mathbf J_s = \sum_m w_m \mathbf u_m \mathbf u_m^\top` (eq. (9)):

* **A**: :math:`\operatorname{tr}\mathbf J_s^{-1}`, the CRLB of eq. (10), m^2;
* **D**: :math:`\det\mathbf J_s^{-1} = 1/\det\mathbf J_s`, m^4 (the area of the error
  ellipse squared, up to :math:`\pi^2`);
* **E**: :math:`\lambda_{\max}(\mathbf J_s^{-1}) = 1/\lambda_{\min}(\mathbf J_s)`, m^2 (the
  worst direction's variance bound);

the same figures as :func:`crlbswarm.fisher.crlb`, :func:`~crlbswarm.fisher.d_optimality`
and :func:`~crlbswarm.fisher.e_optimality`. With :math:`W = \sum_m w_m` and
:math:`z = \sum_m w_m e^{j2\theta_m}` the eigenvalues of :math:`\mathbf J_s` are
:math:`(W \pm |z|)/2`, so the three are :math:`4W/(W^2 - |z|^2)`,
:math:`4/(W^2 - |z|^2)` and :math:`2/(W - |z|)`: each decreases as any weight grows and as
:math:`|z|` shrinks. Every UAV at its own optimal elevation (largest :math:`w_m^*`) with
the azimuths of :func:`~crlbswarm.design.isotropic_azimuths` (smallest :math:`|z|`,
:math:`\max(0, 2w^*_{\max} - W^*)`) is therefore optimal for all three at once:
:math:`F^*` is A-, D- and E-optimal, for equal and unequal UAVs (:func:`optimal_value`).

**Altitude bands** (issue 11): each UAV at its own altitude :math:`H_m` in a band
:math:`[\underline H_m, \overline H_m]`. The target's height is known and the estimate
stays 2-D, so :math:`H_m` enters eq. (9) only through :math:`d_m^2 = |\mathbf q_m -
\mathbf s|^2 + H_m^2`: :math:`\mathbf J_s = \sum_m c_m \mathbf v_m\mathbf v_m^\top` with
:math:`c_m = (A_m/d_m^2 + 8)/d_m^4` (eq. (6)), strictly decreasing in :math:`H_m` for a
fixed horizontal offset :math:`\mathbf v_m`. Lowering a UAV adds a positive semi-definite
term to :math:`\mathbf J_s`, and A, D and E are non-increasing in the Loewner order: for
every horizontal layout (the constraints are horizontal) each UAV's best altitude is
:math:`\underline H_m`. Hence :math:`w_m^*(H) = \max_\phi w_m` is decreasing in
:math:`H` (:math:`w^*(H_2) = c(r_2, H_2) r_2^2 < c(r_2, H_1) r_2^2 \le w^*(H_1)` for
:math:`H_1 < H_2`, :math:`r_2` the best radius at :math:`H_2`), and the unconstrained
optimum with bands is the closed form with each UAV at :math:`\underline H_m` (its own
optimal radius, the weights :math:`w_m^*(\underline H_m)`, the azimuths of
:func:`~crlbswarm.design.isotropic_azimuths`): :func:`optimal_value` with ``per_uav``.

The search is a multistart of SLSQP over the :math:`2M` horizontal coordinates (and the
:math:`M` altitudes, bounded by the bands, when bands are given) with
analytic gradients (the E criterion in epigraph form, :math:`\max t` subject to
:math:`\mathbf J_s \succeq t\mathbf I`, which is smooth where :math:`\lambda_{\min}` is
not). Start 0 is :math:`F^*`, projected onto the feasible set when it is blocked; the
others are random feasible formations. Each result is checked against every constraint in
metres; the best feasible one is returned with its ratio to the unconstrained optimum (the
certificate of what the constraints cost).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .design import (
    best_eigenvalues,
    information_weight,
    isotropic_azimuths,
    optimal_elevation,
    optimal_formation,
    optimal_radius,
    optimal_weights,
)
from .errors import FieldError
from .fisher import (
    crlb,
    crlb_from_fim,
    d_optimality,
    d_optimality_from_fim,
    e_optimality,
    e_optimality_from_fim,
)
from .obstacles import Obstacles, check_obstacles
from .radar import Radar, check_radar

__all__ = [
    "ACTIVE_TOL",
    "CRITERIA",
    "DEFAULT_STARTS",
    "FEASIBILITY_TOL",
    "MARGIN",
    "UNITS",
    "ConstrainedDesign",
    "constrained_design",
    "constrained_report",
    "criterion_value",
    "default_starts",
    "optimal_value",
]

#: The design criteria: ``"A"`` (trace of the CRLB matrix, m^2), ``"D"`` (its
#: determinant, m^4) and ``"E"`` (its largest eigenvalue, m^2).
CRITERIA = ("A", "D", "E")

#: Number of starts of :func:`constrained_design` by default for small swarms (start 0 is
#: :math:`F^*`); larger swarms get fewer (:func:`default_starts`), each start costing about
#: :math:`M^3`.
DEFAULT_STARTS = 64


def default_starts(n_uavs: int) -> int:
    """Starts of :func:`constrained_design` when none are given: :data:`DEFAULT_STARTS`
    up to 16 UAVs, then fewer, ``1024 // n_uavs``, and at least 4 (M = 100: 10 starts).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs.

    Returns
    -------
    int
        Number of starts.
    """
    return max(4, min(DEFAULT_STARTS, 1024 // max(int(n_uavs), 1)))


#: Largest violation of a constraint, m, that a returned formation may show (the search
#: aims at constraints tightened by :data:`MARGIN` times the formation's scale, so the
#: returned formation normally satisfies them strictly).
FEASIBILITY_TOL = 1e-9

#: The tightening of every constraint during the search, relative to the formation's
#: scale (its mean optimal radius): 1e-8, which costs about 1e-8 of the criterion.
MARGIN = 1e-8

#: Slack, relative to the formation's scale, below which a constraint is reported active.
ACTIVE_TOL = 1e-6

_DEFAULT_RADAR = Radar()


@dataclass(frozen=True, eq=False)
class ConstrainedDesign:
    """The best feasible formation found by :func:`constrained_design`.

    Attributes
    ----------
    positions : ndarray, shape (M, 2)
        Horizontal UAV positions, m.
    criterion : str
        ``"A"``, ``"D"`` or ``"E"`` (:data:`CRITERIA`).
    value : float
        The criterion of ``positions``: m^2 for A and E, m^4 for D.
    unconstrained : float
        The criterion's unconstrained optimum (:func:`optimal_value`), same unit.
    starts : int
        Number of starts run.
    feasible_starts : int
        Number of starts whose local optimum satisfied every constraint.
    active : tuple of str
        The constraints within :data:`ACTIVE_TOL` of their limit at ``positions``, e.g.
        ``"no_fly[0] UAV 3"``, ``"obstacle[1] UAV 2"``, ``"min_separation UAV 1-4"``,
        ``"max_radius UAV 5"``, ``"altitude_band UAV 2 (low)"`` (UAVs numbered from 1).
    unconstrained_positions : ndarray, shape (M, 2)
        :math:`F^*` (:func:`~crlbswarm.design.optimal_formation`), m; with altitude bands,
        the closed form with each UAV at the low end of its band (the reference optimum).
    altitudes : ndarray, shape (M,)
        Each UAV's altitude, m: the common altitude repeated, or with ``altitude_bands``
        the altitudes found in the bands (the low ends: module docstring).
    altitude_bands : ndarray, shape (M, 2), or None
        ``[low, high]`` of each UAV, m, as given (one band broadcast to every UAV); None
        for a common altitude.
    """

    positions: np.ndarray
    criterion: str
    value: float
    unconstrained: float
    starts: int
    feasible_starts: int
    active: tuple[str, ...]
    unconstrained_positions: np.ndarray
    altitudes: np.ndarray
    altitude_bands: np.ndarray | None = None

    @property
    def ratio(self) -> float:
        """``value / unconstrained`` >= 1: what the constraints cost (for D a ratio of
        squared areas; its square root compares with A and E)."""
        return self.value / self.unconstrained


def _check_criterion(criterion: object) -> str:
    if not isinstance(criterion, str) or criterion.upper() not in CRITERIA:
        raise FieldError("criterion", f"expected one of 'A', 'D', 'E', got {_v.short(criterion)}")
    return criterion.upper()


def _flag(value: object, name: str) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise FieldError(name, f"expected True or False, got {_v.short(value)}")
    return bool(value)


def _uav_altitudes(altitude: object, n: int) -> np.ndarray:
    """Per-UAV altitudes ``(..., M)``, m, in the model's range."""
    h = _v.altitude(altitude, "altitude")
    if h.ndim < 1 or h.shape[-1] != n:
        raise FieldError(
            "altitude", f"with per_uav=True expected shape (..., {n}) (one per UAV), got {h.shape}"
        )
    return h


def _fim(offsets: np.ndarray, heights: np.ndarray,
         a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    r"""The FIM :math:`\mathbf J_s` (eqs. (8)-(9)) with each UAV at its own altitude: the
    one place the constrained design writes it.

    :math:`\mathbf J_s = \sum_m c_m \mathbf v_m \mathbf v_m^\top` with :math:`\mathbf v_m`
    the horizontal offset ``(..., M, 2)``, :math:`d_m^2 = |\mathbf v_m|^2 + H_m^2` and
    :math:`c_m = [\mathbf J_d]_{mm}/d_m^2 = (A_m/d_m^2 + 8)/d_m^4` (eq. (6)). Returns
    ``(J (..., 2, 2), c, dc/d(d^2))``; the last two are the search's gradient weights."""
    d2 = np.einsum("...k,...k->...", offsets, offsets) + heights * heights
    c = (a / d2 + 8.0) / (d2 * d2)
    dc = -(3.0 * a / d2 + 16.0) / (d2 * d2 * d2)
    return np.einsum("...m,...mi,...mj->...ij", c, offsets, offsets), c, dc


def criterion_value(
    positions: ArrayLike,
    target_xy: ArrayLike,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    criterion: str = "A",
    *,
    per_uav: bool = False,
) -> np.ndarray:
    """The A-, D- or E-criterion of formations (:func:`~crlbswarm.fisher.crlb`,
    :func:`~crlbswarm.fisher.d_optimality` or :func:`~crlbswarm.fisher.e_optimality`), at
    a common altitude or with each UAV at its own.

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        Horizontal UAV positions, m.
    target_xy : array_like, shape (..., 2)
        Horizontal target position, m.
    altitude : float or array_like, shape (...), or shape (..., M) with ``per_uav``
        Flight altitude H, m (a batch of common altitudes), or each UAV's altitude
        :math:`H_m` with ``per_uav=True``: :math:`d_m^2 = |\\mathbf q_m - \\mathbf s|^2 +
        H_m^2` in eq. (9) (the target's height is known; the estimate stays 2-D).
    radar : Radar, optional
        Link parameters; per-UAV fields must have length M.
    criterion : {"A", "D", "E"}, default "A"
        The criterion (:data:`CRITERIA`).
    per_uav : bool, default False
        Whether the last axis of ``altitude`` runs over the UAVs.

    Returns
    -------
    ndarray, shape (...)
        m^2 for A and E, m^4 for D; ``+inf`` for a singular geometry.

    Examples
    --------
    >>> from crlbswarm import criterion_value, optimal_formation
    >>> f = optimal_formation(4, (0.0, 0.0), 20.0)
    >>> a = float(criterion_value(f, (0.0, 0.0), 20.0))
    >>> b = float(criterion_value(f, (0.0, 0.0), [20.0] * 4, per_uav=True))
    >>> abs(a / b - 1) < 1e-12
    True
    """
    name = _check_criterion(criterion)
    if not _flag(per_uav, "per_uav"):
        figure = {"A": crlb, "D": d_optimality, "E": e_optimality}[name]
        return figure(positions, target_xy, altitude, radar)
    q = _v.coordinates(positions, "positions")
    s = _v.location(target_xy, "target_xy")
    h = _uav_altitudes(altitude, q.shape[-2])
    a = np.asarray(check_radar(radar, q.shape[-2]), dtype=float)
    batch = _v.broadcast("target_xy", q.shape[:-2], s.shape[:-1])
    batch = _v.broadcast("altitude", batch, h.shape[:-1])
    n = float(np.prod(batch, dtype=float)) * q.shape[-2]
    _v.check_elements(n, "positions", f"{n:.3g} UAV-target pairs", copies=8)
    fim, _, _ = _fim(s[..., None, :] - q, h, a)
    return {"A": crlb_from_fim, "D": d_optimality_from_fim, "E": e_optimality_from_fim}[name](fim)


def _best_weights(n_uavs: object, altitude: object, radar: Radar, per_uav: bool) -> np.ndarray:
    """Each UAV's largest weight :math:`w_m^*` at a common altitude or at its own."""
    if not per_uav:
        return optimal_weights(n_uavs, altitude, radar)  # type: ignore[arg-type]
    n = _v.uav_count(n_uavs, "n_uavs")
    check_radar(radar, n)
    h = _uav_altitudes(altitude, n)
    return information_weight(optimal_elevation(h, radar), h, radar)


def optimal_value(
    n_uavs: int,
    altitude: ArrayLike,
    radar: Radar = _DEFAULT_RADAR,
    criterion: str = "A",
    *,
    per_uav: bool = False,
) -> np.ndarray:
    r"""The unconstrained optimum of the A-, D- or E-criterion over all formations.

    With the weights :math:`w_m^*` (:func:`~crlbswarm.design.optimal_weights`),
    :math:`W = \sum_m w_m^*` and :math:`z = \max(0, 2w^*_{\max} - W)`:
    A :math:`= 4W/(W^2 - z^2)` (:func:`~crlbswarm.design.crlb_bound`),
    D :math:`= 4/(W^2 - z^2)`, E :math:`= 2/(W - z)`; attained by
    :func:`~crlbswarm.design.optimal_formation` (derivation in the module docstring). With
    equal UAVs, :math:`z = 0`: :math:`4/W`, :math:`4/W^2`, :math:`2/W`. With ``per_uav``,
    each UAV's :math:`w_m^*` at its own altitude :math:`H_m` (eq. (9) with :math:`H_m`).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs M >= 3.
    altitude : float or array_like, shape (...), or shape (..., M) with ``per_uav``
        Flight altitude H, m, or each UAV's altitude.
    radar : Radar, optional
        Link parameters; per-UAV fields must have length ``n_uavs``.
    criterion : {"A", "D", "E"}, default "A"
        The criterion (:data:`CRITERIA`).
    per_uav : bool, default False
        Whether the last axis of ``altitude`` runs over the UAVs.

    Returns
    -------
    ndarray, shape (...)
        m^2 for A and E, m^4 for D.

    Examples
    --------
    >>> from crlbswarm import crlb_bound, optimal_value
    >>> bool(abs(optimal_value(6, 20.0) - crlb_bound(6, 20.0)) < 1e-18)
    True
    """
    name = _check_criterion(criterion)
    weights = _best_weights(n_uavs, altitude, radar, _flag(per_uav, "per_uav"))
    lam_max, lam_min = best_eigenvalues(weights)
    if name == "A":
        return 1.0 / lam_max + 1.0 / lam_min
    if name == "D":
        return 1.0 / (lam_max * lam_min)
    return 1.0 / lam_min


# -- the feasible set ------------------------------------------------------------------------
@dataclass(frozen=True)
class _Zones:
    """Polygons (edges stacked, ``first`` edge of each) and circles, with labels."""

    a: np.ndarray  # (E, 2) edge starts
    b: np.ndarray  # (E, 2) edge ends
    normal: np.ndarray  # (E, 2) outward unit normals
    first: np.ndarray  # (P + 1,) edge ranges of the polygons
    circles: np.ndarray  # (C, 3)
    labels: tuple[str, ...]  # polygons first, then circles

    @property
    def count(self) -> int:
        return len(self.labels)


def _polygon(vertices: np.ndarray, name: str) -> np.ndarray:
    """A simple polygon's vertices, counter-clockwise; refuse degenerate or crossing ones."""
    k = vertices.shape[0]
    x, y = vertices[:, 0], vertices[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    scale = float(np.ptp(vertices, axis=0).max()) if k else 0.0
    if not abs(area) > 1e-12 * max(scale, _v.MIN_LENGTH) ** 2:
        raise FieldError("no_fly", f"{name} has zero area")
    a, b = vertices, np.roll(vertices, -1, axis=0)
    for i in range(k):  # no two edges that do not share a vertex may meet
        for j in range(i + 2, k):
            if i == 0 and j == k - 1:
                continue
            if _segments_meet(a[i], b[i], a[j], b[j]):
                raise FieldError("no_fly", f"{name} is not a simple polygon (edges cross)")
    return vertices if area > 0 else vertices[::-1].copy()


def _segments_meet(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> bool:
    def cross(o: np.ndarray, u: np.ndarray, v: np.ndarray) -> float:
        return float((u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0]))

    d1, d2 = cross(q1, q2, p1), cross(q1, q2, p2)
    d3, d4 = cross(p1, p2, q1), cross(p1, p2, q2)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 * d2 < 0 and d3 * d4 < 0:
        return True

    def on(o: np.ndarray, u: np.ndarray, v: np.ndarray) -> bool:  # v on segment o-u
        return bool(
            min(o[0], u[0]) <= v[0] <= max(o[0], u[0])
            and min(o[1], u[1]) <= v[1] <= max(o[1], u[1])
        )

    return (
        (d1 == 0 and on(q1, q2, p1))
        or (d2 == 0 and on(q1, q2, p2))
        or (d3 == 0 and on(p1, p2, q1))
        or (d4 == 0 and on(p1, p2, q2))
    )


def _zones(obstacles: Obstacles | None, no_fly: object) -> _Zones:
    """The obstacles' rectangles and the no-fly polygons as polygons, and every circle."""
    polygons: list[np.ndarray] = []
    circles: list[np.ndarray] = []
    labels: list[str] = []
    circle_labels: list[str] = []
    if no_fly is not None:
        if isinstance(no_fly, np.ndarray) or not isinstance(no_fly, Sequence):
            raise FieldError(
                "no_fly", "expected a list of (K, 2) polygons or (x, y, radius) circles"
            )
        for i, item in enumerate(no_fly):
            arr = _v.as_float_array(item, "no_fly")
            _v.bounded(arr, "no_fly", -_v.MAX_COORDINATE, _v.MAX_COORDINATE, " m")
            if arr.shape == (3,):
                if not arr[2] > 0:
                    raise FieldError("no_fly", f"no_fly[{i}] is a circle of radius <= 0")
                circles.append(arr)
                circle_labels.append(f"no_fly[{i}]")
            elif arr.ndim == 2 and arr.shape[1] == 2 and arr.shape[0] >= 3:
                polygons.append(_polygon(arr, f"no_fly[{i}]"))
                labels.append(f"no_fly[{i}]")
            else:
                raise FieldError(
                    "no_fly",
                    f"no_fly[{i}] has shape {arr.shape}: expected (K, 2) with K >= 3 "
                    "(a polygon) or (3,) (a circle x, y, radius)",
                )
    if obstacles is not None:
        obs = check_obstacles(obstacles)
        for k, (x0, x1, y0, y1) in enumerate(obs.rectangles):
            polygons.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
            labels.append(f"obstacle[{k}]")
        for k, row in enumerate(obs.circles):
            circles.append(row)
            circle_labels.append(f"obstacle[{k + obs.rectangles.shape[0]}]")
    a = np.concatenate(polygons) if polygons else np.empty((0, 2))
    b = np.concatenate([np.roll(p, -1, axis=0) for p in polygons]) if polygons else a
    edge = b - a
    normal = (
        np.stack([edge[:, 1], -edge[:, 0]], -1)
        / np.maximum(np.hypot(edge[:, 0], edge[:, 1]), 1e-300)[:, None]
    )
    first = np.cumsum([0] + [p.shape[0] for p in polygons])
    circ = np.array(circles).reshape(-1, 3)
    return _Zones(a, b, normal, first, circ, tuple(labels + circle_labels))


def _signed_distance(zones: _Zones, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of each point to each zone, ``(N, Z)`` (negative inside), and its
    gradient ``(N, Z, 2)`` (the outward direction)."""
    n = points.shape[0]
    dist = np.empty((n, zones.count))
    grad = np.empty((n, zones.count, 2))
    if zones.a.shape[0]:
        ab = zones.b - zones.a  # (E, 2)
        ap = points[:, None, :] - zones.a  # (N, E, 2)
        t = np.clip(np.einsum("nek,ek->ne", ap, ab) / np.einsum("ek,ek->e", ab, ab), 0.0, 1.0)
        diff = ap - t[..., None] * ab  # from the nearest point of each edge
        d = np.hypot(diff[..., 0], diff[..., 1])
        py = points[:, 1:2]
        ay, by = zones.a[:, 1], zones.b[:, 1]
        straddle = (ay > py) != (by > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = zones.a[:, 0] + (py - ay) * ab[:, 0] / (by - ay)
        crossing = straddle & (points[:, 0:1] < x_cross)
        rows = np.arange(n)
        for p in range(zones.first.shape[0] - 1):
            lo, hi = zones.first[p], zones.first[p + 1]
            e = lo + np.argmin(d[:, lo:hi], axis=1)
            inside = np.count_nonzero(crossing[:, lo:hi], axis=1) % 2 == 1
            sign = np.where(inside, -1.0, 1.0)
            de = d[rows, e]
            unit = np.where(
                (de > 0)[:, None], diff[rows, e] / np.maximum(de, 1e-300)[:, None], zones.normal[e]
            )
            dist[:, p] = sign * de
            grad[:, p] = unit * np.where(de > 0, sign, 1.0)[:, None]  # on the edge: outward
    n_poly = zones.first.shape[0] - 1
    if zones.circles.shape[0]:
        rel = points[:, None, :] - zones.circles[:, :2]
        rho = np.hypot(rel[..., 0], rel[..., 1])
        dist[:, n_poly:] = rho - zones.circles[:, 2]
        grad[:, n_poly:] = np.where(
            (rho > 0)[..., None], rel / np.maximum(rho, 1e-300)[..., None], [1.0, 0.0]
        )
    return dist, grad


# -- the problem in scaled coordinates -------------------------------------------------------
@dataclass(frozen=True)
class _Problem:
    """The scene, in coordinates ``x = (q - target) / scale`` and the FIM over ``w_scale``."""

    target: np.ndarray  # (2,), m
    altitude: float  # m: the common altitude (unused with bands)
    heights: np.ndarray  # (M,) m: each UAV's altitude, the band's low end with bands
    bands: np.ndarray | None  # (M, 2) m, or None: no altitude variables
    a: np.ndarray  # (M,) the radar constants A_m
    scale: float  # m: the mean optimal radius
    w_scale: float  # m^-2: the sum of the optimal weights
    criterion: str
    zones: _Zones
    clearance: float  # m
    min_separation: float  # m
    max_radius: float | None  # m

    @property
    def n(self) -> int:
        return int(self.a.shape[0])

    @property
    def n_alt(self) -> int:
        """Number of altitude variables: M with bands, else 0."""
        return 0 if self.bands is None else self.n

    def metres(self, z: np.ndarray) -> np.ndarray:
        """Positions ``(M, 2)``, m, of the search variables ``z``."""
        return self.target + self.scale * z[: 2 * self.n].reshape(self.n, 2)

    def altitudes(self, u: np.ndarray | None) -> np.ndarray:
        """Altitudes ``(M,)``, m, of the scaled altitude variables ``u`` (clipped to the
        bands), or the fixed ones."""
        if u is None or self.bands is None:
            return self.heights
        low, high = self.bands[:, 0], self.bands[:, 1]
        h = self.scale * u  # (at a band's end to rounding: exactly there)
        h = np.where(np.abs(h - low) <= 1e-12 * low, low, h)
        return np.clip(np.where(np.abs(h - high) <= 1e-12 * high, high, h), low, high)


def _split(z: np.ndarray, prob: _Problem) -> tuple[np.ndarray, np.ndarray | None]:
    """The scaled positions ``(M, 2)`` and altitudes ``(M,)`` (None without bands) of the
    search variables ``z = [x_1, y_1, ..., x_M, y_M, u_1, ..., u_M, (t)]``."""
    m = prob.n
    xy = z[: 2 * m].reshape(m, 2)
    return xy, (z[2 * m : 3 * m] if prob.bands is not None else None)


def _fim_terms(
    prob: _Problem, xy: np.ndarray, u: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The scaled FIM :math:`\mathbf J_s / W^*` (eq. (9), :func:`_fim`) of scaled positions
    ``xy`` and altitudes ``u`` (:math:`H_m / L`; None: the fixed ones), and the weights
    ``k`` and ``k'`` of its gradient (:func:`_fim_gradient`)."""
    length = prob.scale
    heights = prob.heights if u is None else length * u
    fim, c, dc = _fim(length * xy, heights, prob.a)
    return fim / prob.w_scale, c * length**2 / prob.w_scale, dc * length**4 / prob.w_scale


def _fim_gradient(g: np.ndarray, xy: np.ndarray, k: np.ndarray, kp: np.ndarray,
                  u: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    r"""``d f / d [xy, u]`` (``2M`` values, ``3M`` with altitudes ``u``) of a function f of
    the scaled FIM with ``G = df/dJ``: :math:`k_m = c_m L^2/W` depends on
    :math:`d_m^2 = L^2(|\mathbf x_m|^2 + u_m^2)`, so :math:`\partial k_m/\partial u_m =
    2u_m k'_m` as :math:`\partial k_m/\partial \mathbf x_m = 2\mathbf x_m k'_m`."""
    gx = xy @ g
    quad = np.einsum("mi,mi->m", gx, xy)
    grad = (2.0 * k[:, None] * gx + 2.0 * (kp * quad)[:, None] * xy).ravel()
    return grad if u is None else np.concatenate([grad, 2.0 * u * kp * quad])


def _objective(z: np.ndarray, prob: _Problem) -> tuple[float, np.ndarray]:
    """The search's objective and gradient: log A, log D, or -t (E in epigraph form)."""
    grad = np.zeros_like(z)
    if prob.criterion == "E":
        grad[-1] = -1.0
        return -float(z[-1]), grad
    xy, u = _split(z, prob)
    jn, k, kp = _fim_terms(prob, xy, u)
    det = jn[0, 0] * jn[1, 1] - jn[0, 1] ** 2
    tr = jn[0, 0] + jn[1, 1]
    if not det > 1e-300:  # a singular geometry: a large value, no direction
        return 1e6, grad
    inv = np.array([[jn[1, 1], -jn[0, 1]], [-jn[0, 1], jn[0, 0]]]) / det
    if prob.criterion == "A":  # log tr(J^-1) = log tr J - log det J
        value, g = np.log(tr) - np.log(det), np.eye(2) / tr - inv
    else:  # log det(J^-1) = -log det J
        value, g = -np.log(det), -inv
    grad[: 2 * prob.n + prob.n_alt] = _fim_gradient(g, xy, k, kp, u)
    return float(value), grad


def _constraints(
    z: np.ndarray, prob: _Problem, pairs: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """Every constraint of the search as ``g(z) >= 0`` (tightened by :data:`MARGIN`), and
    its Jacobian ``(n_constraints, len(z))`` (the bands are bounds of the variables)."""
    m, length, nz = prob.n, prob.scale, z.shape[0]
    xy, u = _split(z, prob)
    rows = np.arange(m)
    vals: list[np.ndarray] = []
    jacs: list[np.ndarray] = []
    if prob.zones.count:
        sd, g = _signed_distance(prob.zones, prob.metres(z))
        vals.append(((sd - prob.clearance) / length - MARGIN).ravel())
        jac = np.zeros((m, prob.zones.count, m, 2))
        jac[rows, :, rows, :] = g
        jacs.append(jac.reshape(-1, 2 * m))
    if prob.max_radius is not None:
        vals.append((prob.max_radius / length - MARGIN) ** 2 - np.einsum("mk,mk->m", xy, xy))
        jac = np.zeros((m, m, 2))
        jac[rows, rows, :] = -2.0 * xy
        jacs.append(jac.reshape(m, 2 * m))
    i, j = pairs
    if i.shape[0]:
        diff = xy[i] - xy[j]
        dist = np.hypot(diff[:, 0], diff[:, 1])
        vals.append(dist - (prob.min_separation / length + MARGIN))
        unit = np.where((dist > 0)[:, None], diff / np.maximum(dist, 1e-300)[:, None], [1.0, 0.0])
        jac = np.zeros((i.shape[0], m, 2))
        cols = np.arange(i.shape[0])
        jac[cols, i, :] = unit
        jac[cols, j, :] = -unit
        jacs.append(jac.reshape(-1, 2 * m))
    jac = np.concatenate(jacs) if jacs else np.empty((0, 2 * m))
    jac = np.concatenate([jac, np.zeros((jac.shape[0], nz - 2 * m))], axis=1)
    if prob.criterion == "E":  # J - t I positive semi-definite: det(J - tI) >= 0, tr >= 2t
        jn, k, kp = _fim_terms(prob, xy, u)
        t = z[-1]
        vals.append(np.array([(jn[0, 0] - t) * (jn[1, 1] - t) - jn[0, 1] ** 2,
                              jn[0, 0] + jn[1, 1] - 2.0 * t]))  # fmt: skip
        g1 = np.array([[jn[1, 1] - t, -jn[0, 1]], [-jn[0, 1], jn[0, 0] - t]])
        e_jac = np.zeros((2, nz))
        e_jac[0, :-1] = _fim_gradient(g1, xy, k, kp, u)
        e_jac[1, :-1] = _fim_gradient(np.eye(2), xy, k, kp, u)
        e_jac[:, -1] = [2.0 * t - jn[0, 0] - jn[1, 1], -2.0]
        jac = np.concatenate([jac, e_jac])
    if not vals:
        return np.empty(0), np.empty((0, nz))
    return np.concatenate(vals), jac


def _close_pairs(prob: _Problem, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of UAVs within two separations (scaled ``xy``): the separation rows (the
    others are added when the search brings them closer, :func:`_local_optimum`)."""
    if prob.min_separation <= 0.0:
        return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.intp)
    i, j = np.triu_indices(prob.n, 1)
    d = np.hypot(*(xy[i] - xy[j]).T) * prob.scale
    near = d < 2.0 * prob.min_separation
    return i[near], j[near]


def _slsqp(z0: np.ndarray, prob: _Problem, pairs: tuple[np.ndarray, np.ndarray],
           objective: object) -> np.ndarray:  # fmt: skip
    from scipy.optimize import minimize

    last: dict[str, tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]] = {}

    def parts(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if "z" not in last or not np.array_equal(last["z"][0], z):
            last["z"] = (z.copy(), _constraints(z, prob, pairs))
        return last["z"][1]

    cons = []
    if parts(z0)[0].shape[0]:
        cons = [{"type": "ineq", "fun": lambda z: parts(z)[0], "jac": lambda z: parts(z)[1]}]
    # A box keeps the steps from flinging UAVs out of the model's range: |x| within
    # max_radius, or within 100 optimal radii (where a UAV adds nothing); the altitudes in
    # their bands; t within [0, 2].
    box = (prob.max_radius / prob.scale) if prob.max_radius is not None else 100.0
    low = np.full(z0.shape[0], -box)
    high = np.full(z0.shape[0], box)
    if prob.bands is not None:
        low[2 * prob.n : 3 * prob.n] = prob.bands[:, 0] / prob.scale
        high[2 * prob.n : 3 * prob.n] = prob.bands[:, 1] / prob.scale
    low[2 * prob.n + prob.n_alt :], high[2 * prob.n + prob.n_alt :] = 0.0, 2.0
    with np.errstate(all="ignore"):
        res = minimize(objective, np.clip(z0, low, high), jac=True, method="SLSQP",
                       constraints=cons, bounds=list(zip(low, high, strict=True)),
                       options={"maxiter": 400, "ftol": 1e-15})  # fmt: skip
    return np.clip(np.asarray(res.x, dtype=float), low, high)


def _project(xy0: np.ndarray, prob: _Problem) -> np.ndarray:
    """The feasible formation nearest ``xy0`` (scaled), found by SLSQP."""
    geometric = _replace_criterion(prob, "A")
    z0 = xy0.ravel()

    def distance(z: np.ndarray) -> tuple[float, np.ndarray]:
        return 0.5 * float(np.sum((z - z0) ** 2)), z - z0

    z = z0
    for _ in range(3):
        z = _slsqp(z, geometric, _close_pairs(prob, z.reshape(-1, 2)), distance)
    return z.reshape(-1, 2)


def _replace_criterion(prob: _Problem, criterion: str) -> _Problem:
    from dataclasses import replace

    return replace(prob, criterion=criterion, bands=None)  # (geometry only: no altitudes)


def _local_optimum(xy0: np.ndarray, u0: np.ndarray | None,
                   prob: _Problem) -> tuple[np.ndarray, np.ndarray | None]:  # fmt: skip
    """The local optimum from ``xy0`` and ``u0`` (scaled; ``u0`` None without bands), the
    separation rows renewed until no pair outside them comes closer than the separation."""
    z = xy0.ravel() if u0 is None else np.concatenate([xy0.ravel(), u0])
    if prob.criterion == "E":
        jn, _, _ = _fim_terms(prob, xy0, u0)
        z = np.append(z, np.linalg.eigvalsh(jn)[0] * (1.0 - 1e-9))
    for _ in range(8):
        pairs = _close_pairs(prob, z[: 2 * prob.n].reshape(-1, 2))
        z = _slsqp(z, prob, pairs, lambda v: _objective(v, prob))
        xy, _u = _split(z, prob)
        if _slack(prob, prob.target + prob.scale * xy)[0].min(initial=np.inf) >= -FEASIBILITY_TOL:
            break
    return _split(z, prob)


# -- feasibility in metres, starts, the search -------------------------------------------
def _slack(prob: _Problem, q: np.ndarray,
           heights: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:  # fmt: skip
    """Every constraint's slack at positions ``q`` ``(M, 2)`` and altitudes ``heights``
    ``(M,)`` (with bands), m (>= 0: satisfied), over all pairs of UAVs, and the
    constraint's name for each."""
    m = prob.n
    uav = [f"UAV {k + 1}" for k in range(m)]
    slacks: list[np.ndarray] = []
    names: list[str] = []
    if prob.zones.count:
        sd, _ = _signed_distance(prob.zones, q)
        slacks.append((sd - prob.clearance).ravel())
        names += [f"{zone} {u}" for u in uav for zone in prob.zones.labels]
    if prob.max_radius is not None:
        slacks.append(prob.max_radius - np.hypot(*(q - prob.target).T))
        names += [f"max_radius {u}" for u in uav]
    if prob.min_separation > 0.0:
        i, j = np.triu_indices(m, 1)
        slacks.append(np.hypot(*(q[i] - q[j]).T) - prob.min_separation)
        names += [f"min_separation UAV {a + 1}-{b + 1}" for a, b in zip(i, j, strict=True)]
    if prob.bands is not None and heights is not None:
        slacks += [heights - prob.bands[:, 0], prob.bands[:, 1] - heights]
        names += [f"altitude_band {u} (low)" for u in uav]
        names += [f"altitude_band {u} (high)" for u in uav]
    return (np.concatenate(slacks) if slacks else np.empty(0)), names


def _free_points(prob: _Problem, rng: np.random.Generator, radius: float, count: int,
                 margin: float) -> np.ndarray:  # fmt: skip
    """``count`` uniform points of the disc of ``radius`` m round the target, scaled, kept
    only where they clear every zone by ``clearance + margin``."""
    rho = radius * np.sqrt(rng.random(count))
    phi = 2.0 * np.pi * rng.random(count)
    q = prob.target + np.stack([rho * np.cos(phi), rho * np.sin(phi)], -1)
    if prob.zones.count:
        sd, _ = _signed_distance(prob.zones, q)
        q = q[sd.min(axis=1) >= prob.clearance + margin]
    return (q - prob.target) / prob.scale


def _spread(points: np.ndarray, n: int, separation: float) -> np.ndarray:
    """The first ``n`` of ``points`` (scaled) picked greedily ``separation`` apart (fewer if
    they do not fit)."""
    if separation <= 0.0:
        return points[:n]
    chosen = np.empty((n, 2))
    k = 0
    for p in points:
        if k == 0 or np.min(np.hypot(*(chosen[:k] - p).T)) >= separation:
            chosen[k] = p
            k += 1
            if k == n:
                break
    return chosen[:k]


def _random_start(prob: _Problem, rng: np.random.Generator, radius: float) -> np.ndarray | None:
    """A random feasible formation (scaled) in the disc of ``radius`` m round the target,
    widened (without a largest radius) until one fits; None if none was found."""
    margin = 4.0 * MARGIN * prob.scale
    if prob.max_radius is not None:
        radius = min(radius, prob.max_radius - margin)
    for _ in range(12):
        points = _free_points(prob, rng, radius, 40 * prob.n + 200, margin)
        xy = _spread(points, prob.n, (prob.min_separation + margin) / prob.scale)
        if xy.shape[0] == prob.n:
            return xy
        if prob.max_radius is None:
            radius *= 1.5
    return None


def _infeasible(prob: _Problem, rng: np.random.Generator, starts: int) -> FieldError:
    """The one-line error when no start reached a feasible formation: why, if it is clear."""
    radius = prob.max_radius if prob.max_radius is not None else 1e3 * prob.scale
    where = (f"within max_radius = {prob.max_radius:g} m of the target"
             if prob.max_radius is not None else "near the target")  # fmt: skip
    points = _free_points(prob, rng, radius, 200_000, 0.0)
    if points.shape[0] == 0:
        field = "max_radius" if prob.max_radius is not None else "no_fly"
        return FieldError(
            field,
            f"no point {where} keeps clearance = {prob.clearance:g} m from the obstacles and "
            "no-fly zones: no feasible formation",
        )
    fit = _spread(points, prob.n, prob.min_separation / prob.scale).shape[0]
    if fit < prob.n:
        return FieldError(
            "min_separation",
            f"only {fit} of the {prob.n} UAVs were fitted min_separation = "
            f"{prob.min_separation:g} m apart in the free area {where}",
        )
    return FieldError("starts", f"none of the {starts} starts reached a feasible formation")


def _altitude_bands(value: object, n: int) -> np.ndarray | None:
    """``altitude_bands`` as an ``(M, 2)`` array of ``[low, high]``, m, or None."""
    if value is None:
        return None
    arr = _v.as_float_array(value, "altitude_bands")
    if arr.shape == (2,):
        arr = np.broadcast_to(arr, (n, 2))
    if arr.shape != (n, 2):
        raise FieldError(
            "altitude_bands",
            f"expected shape (2,) (one [low, high] for every UAV) or ({n}, 2) (one per UAV), "
            f"got {arr.shape}",
        )
    _v.altitude(arr, "altitude_bands")
    wrong = np.flatnonzero(arr[:, 0] > arr[:, 1])
    if wrong.size:
        k = int(wrong[0])
        raise FieldError(
            "altitude_bands",
            f"band of UAV {k + 1} has low {arr[k, 0]:g} m > high {arr[k, 1]:g} m",
        )
    out = np.array(arr, dtype=float)
    out.flags.writeable = False
    return out


def _problem(n_uavs: object, target_xy: object, altitude: object, radar: Radar,
             criterion: object, obstacles: object, no_fly: object, clearance: object,
             min_separation: object, max_radius: object,
             altitude_bands: object = None) -> _Problem:  # fmt: skip
    """Check the arguments of :func:`constrained_design` and build its problem."""
    n = _v.uav_count(n_uavs, "n_uavs")
    if n > _v.MAX_DESIGN_UAVS:
        raise FieldError(
            "n_uavs", f"at most {_v.MAX_DESIGN_UAVS} UAVs for the constrained design, got {n}"
        )
    target = _v.location(target_xy, "target_xy")
    if target.shape != (2,):
        raise FieldError("target_xy", f"expected shape (2,), got {target.shape}")
    h = float(_v.altitude(_v.scalar(altitude, "altitude"), "altitude"))
    a = np.broadcast_to(np.asarray(check_radar(radar, n), dtype=float), (n,)).copy()
    name = _check_criterion(criterion)
    if obstacles is not None:
        check_obstacles(obstacles)
    lengths = {}
    for key, value in (("clearance", clearance), ("min_separation", min_separation)):
        number = _v.scalar(value, key)
        if not 0.0 <= number <= _v.MAX_DISTANCE:
            raise FieldError(key, f"must be between 0 and {_v.MAX_DISTANCE:g} m, got {number:g}")
        lengths[key] = number
    if max_radius is not None:
        max_radius = float(_v.length(_v.scalar(max_radius, "max_radius"), "max_radius"))
    zones = _zones(obstacles, no_fly)  # type: ignore[arg-type]
    bands = _altitude_bands(altitude_bands, n)
    # The reference altitudes: the common one, or each band's low end (the best, module
    # docstring); the scales of the search are those of the closed form there.
    ref: float | np.ndarray = h if bands is None else bands[:, 0]
    return _Problem(
        target=target.copy(),
        altitude=h,
        heights=np.full(n, h) if bands is None else bands[:, 0].copy(),
        bands=bands,
        a=a,
        scale=float(np.mean(optimal_radius(ref, radar))),
        w_scale=float(np.sum(_best_weights(n, ref, radar, bands is not None))),
        criterion=name,
        zones=zones,
        clearance=lengths["clearance"],
        min_separation=lengths["min_separation"],
        max_radius=max_radius,
    )


def constrained_design(
    n_uavs: int,
    target_xy: ArrayLike,
    altitude: float,
    radar: Radar = _DEFAULT_RADAR,
    *,
    criterion: str = "A",
    obstacles: Obstacles | None = None,
    no_fly: Sequence[ArrayLike] | None = None,
    clearance: float = 0.0,
    min_separation: float = 0.0,
    max_radius: float | None = None,
    altitude_bands: ArrayLike | None = None,
    starts: int | None = None,
    seed: int = 0,
    rotation: float = 0.0,
) -> ConstrainedDesign:
    r"""The best formation found that keeps out of obstacles and no-fly zones, apart and
    within a radius: multistart SLSQP from :math:`F^*` and random feasible formations.

    Not in the paper. Minimises the A-, D- or E-criterion (module docstring) over the
    :math:`2M` horizontal coordinates at the common altitude (and, with ``altitude_bands``,
    the :math:`M` altitudes in their bands), subject to: each UAV at least ``clearance``
    from every obstacle and no-fly zone (signed distance, negative inside), every pair at
    least ``min_separation`` apart, each UAV within ``max_radius`` of the target. Start 0
    is :math:`F^*` (:func:`~crlbswarm.design.optimal_formation`; with bands, the closed
    form with each UAV at the low end of its band), projected onto the feasible set when
    blocked; starts 1, 2, ... are random feasible formations in a disc of three optimal
    radii round the target (or ``max_radius``, if smaller), with altitudes uniform in the
    bands. The returned formation satisfies every constraint to :data:`FEASIBILITY_TOL`.

    Parameters
    ----------
    n_uavs : int
        Number of UAVs M, 3 to ``MAX_DESIGN_UAVS`` (500).
    target_xy : array_like, shape (2,)
        Horizontal target position, m.
    altitude : float
        Common flight altitude H, m (checked, but not used, when ``altitude_bands`` is
        given).
    radar : Radar, optional
        Link parameters; per-UAV fields (length ``n_uavs``) give unequal UAVs.
    criterion : {"A", "D", "E"}, default "A"
        ``"A"``: :math:`\operatorname{tr}\mathbf J_s^{-1}` (the CRLB, m^2); ``"D"``:
        :math:`\det\mathbf J_s^{-1}` (m^4); ``"E"``: :math:`\lambda_{\max}(\mathbf J_s^{-1})`
        (m^2).
    obstacles : Obstacles, optional
        Rectangles and circles the UAVs keep ``clearance`` from.
    no_fly : sequence of array_like, optional
        No-fly zones: each a simple polygon, shape (K, 2) with K >= 3 vertices in order
        (convex or not), or a circle, shape (3,): ``(x, y, radius)``, m.
    clearance : float, default 0
        Smallest distance from each UAV's horizontal position to every obstacle and no-fly
        zone, m.
    min_separation : float, default 0
        Smallest horizontal distance between two UAVs, m (0: none).
    max_radius : float, optional
        Largest horizontal distance from the target to a UAV, m (None: none).
    altitude_bands : array_like, shape (2,) or (M, 2), optional
        ``[low, high]`` altitude of every UAV, or of each, m (within 0.1 to 1e5, low <=
        high): each UAV's altitude :math:`H_m` becomes a variable in its band, and eq. (9)
        uses it (:math:`d_m^2 = |\mathbf q_m - \mathbf s|^2 + H_m^2`). The reference
        optimum is the closed form with every UAV at its band's low end (module
        docstring: lower is never worse). None: every UAV at ``altitude``.
    starts : int, optional
        Number of starts, the first :math:`F^*` (default :func:`default_starts`: 64 up to
        16 UAVs, then fewer; each costs about :math:`M^3`, M = 100 some 15-30 s).
    seed : int, default 0
        Seed of the random starts.
    rotation : float, default 0
        Azimuth of UAV 1 of :math:`F^*`, rad (the first start and the reference).

    Returns
    -------
    ConstrainedDesign
        The formation and its altitudes, its criterion value, the unconstrained optimum,
        their ratio, the number of starts and of feasible ones, the active constraints.

    Raises
    ------
    FieldError
        On an invalid argument (one line naming it), or when no start reaches a feasible
        formation: the error then says why (e.g. every point within ``max_radius`` lies in
        a zone) and names the argument to change.

    Examples
    --------
    >>> from crlbswarm import constrained_design
    >>> d = constrained_design(6, (0.0, 0.0), 20.0, max_radius=10.0, starts=4)
    >>> round(d.ratio, 3), d.feasible_starts
    (1.157, 4)
    >>> b = constrained_design(6, (0.0, 0.0), 20.0, altitude_bands=(15.0, 40.0), starts=4)
    >>> b.altitudes.round(6).tolist(), round(b.ratio, 9)
    ([15.0, 15.0, 15.0, 15.0, 15.0, 15.0], 1.0)
    """
    prob = _problem(n_uavs, target_xy, altitude, radar, criterion, obstacles, no_fly,
                    clearance, min_separation, max_radius, altitude_bands)  # fmt: skip
    n_starts = _v.count(
        default_starts(_v.uav_count(n_uavs, "n_uavs")) if starts is None else starts,
        "starts", 1, 100_000,
    )  # fmt: skip
    seed = _v.seed(seed, "seed")
    rng = np.random.default_rng(seed)
    # The starts' altitudes from their own stream: the horizontal starts are those of the
    # same seed without bands.
    rngs = (rng, np.random.default_rng([seed, 1]))
    fstar = _reference_formation(prob, radar, _v.angle(rotation, "rotation"))
    start_radius = 3.0 * float(np.max(optimal_radius(prob.heights, radar)))
    best: tuple[np.ndarray, np.ndarray] | None = None
    best_value, feasible = np.inf, 0
    for k in range(n_starts):
        reached = False
        for q, h in _start_candidates(k, prob, rngs, start_radius, fstar):
            if _slack(prob, q, h)[0].min(initial=np.inf) < -FEASIBILITY_TOL:
                continue
            reached = True
            value = float(_value(prob, radar, q, h))
            if value < best_value:
                best, best_value = (q, h), value
        feasible += reached
    if best is None:
        raise _infeasible(prob, rng, n_starts)
    return _design(prob, radar, best, best_value, n_starts, feasible, fstar)


def _value(prob: _Problem, radar: Radar, q: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """The criterion of positions ``q`` at altitudes ``heights`` (:func:`criterion_value`)."""
    if prob.bands is None:
        return criterion_value(q, prob.target, prob.altitude, radar, prob.criterion)
    return criterion_value(q, prob.target, heights, radar, prob.criterion, per_uav=True)


def _reference_formation(prob: _Problem, radar: Radar, rotation: float) -> np.ndarray:
    """:math:`F^*` at the reference altitudes: :func:`~crlbswarm.design.optimal_formation`
    at a common altitude, else each UAV at its own optimal radius
    :math:`H_m/\\tan\\phi^*(H_m)` and the azimuths of
    :func:`~crlbswarm.design.isotropic_azimuths` for the weights :math:`w_m^*(H_m)`."""
    h = prob.heights
    if prob.bands is None or np.all(h == h[0]):
        altitude = prob.altitude if prob.bands is None else float(h[0])
        return optimal_formation(prob.n, prob.target, altitude, radar, rotation)
    radius = optimal_radius(h, radar)
    theta = isotropic_azimuths(_best_weights(prob.n, h, radar, True), rotation)
    return prob.target + radius[:, None] * np.stack([np.cos(theta), np.sin(theta)], -1)


def _start_candidates(k: int, prob: _Problem, rngs: tuple[np.random.Generator, ...],
                      radius: float,
                      fstar: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:  # fmt: skip
    """Start ``k``'s formations worth checking, in metres with their altitudes: start 0
    (:math:`F^*`, projected when blocked) itself, and the local optimum from the start; with
    bands, also that optimum's layout at the bands' low ends (never worse, module
    docstring)."""
    u0 = None if prob.bands is None else prob.heights / prob.scale
    candidates = []
    if k == 0:
        xy0 = (fstar - prob.target) / prob.scale
        if _slack(prob, fstar)[0].min(initial=np.inf) < 2.0 * MARGIN * prob.scale:
            xy0 = _project(xy0, prob)
        candidates.append((xy0, u0))
    else:
        start = _random_start(prob, rngs[0], radius)
        if start is None:
            return []
        xy0 = start
        if prob.bands is not None:
            u0 = rngs[1].uniform(prob.bands[:, 0], prob.bands[:, 1]) / prob.scale
    xy, u = _local_optimum(xy0, u0, prob)
    candidates.append((xy, u))
    if u is not None:
        candidates.append((xy, prob.heights / prob.scale))
    return [(prob.target + prob.scale * xy, prob.altitudes(u)) for xy, u in candidates]


def _design(prob: _Problem, radar: Radar, best: tuple[np.ndarray, np.ndarray], value: float,
            starts: int, feasible: int, fstar: np.ndarray) -> ConstrainedDesign:  # fmt: skip
    """The result object, with the active constraints named."""
    q, heights = best
    slack, names = _slack(prob, q, heights)
    active = tuple(names[i] for i in np.flatnonzero(slack <= ACTIVE_TOL * prob.scale))
    if prob.bands is None:
        reference = optimal_value(prob.n, prob.altitude, radar, prob.criterion)
    else:
        reference = optimal_value(prob.n, prob.heights, radar, prob.criterion, per_uav=True)
    arrays = [q.copy(), fstar.copy(), np.array(heights, dtype=float)]
    for array in arrays:
        array.flags.writeable = False
    return ConstrainedDesign(
        positions=arrays[0],
        criterion=prob.criterion,
        value=value,
        unconstrained=float(reference),
        starts=starts,
        feasible_starts=int(feasible),
        active=active,
        unconstrained_positions=arrays[1],
        altitudes=arrays[2],
        altitude_bands=prob.bands,
    )


#: Unit of each criterion's value.
UNITS = {"A": "m^2", "D": "m^4", "E": "m^2"}


def constrained_report(
    n_uavs: int,
    target_xy: ArrayLike,
    altitude: float,
    radar: Radar = _DEFAULT_RADAR,
    *,
    criterion: str = "A",
    obstacles: Obstacles | None = None,
    no_fly: Sequence[ArrayLike] | None = None,
    clearance: float = 0.0,
    min_separation: float = 0.0,
    max_radius: float | None = None,
    altitude_bands: ArrayLike | None = None,
    starts: int | None = None,
    seed: int = 0,
    rotation_deg: float = 0.0,
) -> dict[str, Any]:
    """:func:`constrained_design` of a scene and its figures, as a JSON-ready dict.

    What ``crlbswarm design`` prints when a constraint is given (as a table, or as JSON
    with ``--json``).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs M (as :func:`constrained_design`, like the parameters below).
    target_xy : array_like, shape (2,)
        Horizontal target position, m.
    altitude : float
        Common flight altitude H, m.
    radar : Radar, optional
        Link parameters.
    criterion : {"A", "D", "E"}, default "A"
        The criterion.
    obstacles : Obstacles, optional
        Obstacles.
    no_fly : sequence of array_like, optional
        No-fly polygons and circles.
    clearance : float, default 0
        Distance to keep from obstacles and zones, m.
    min_separation : float, default 0
        Smallest horizontal distance between two UAVs, m.
    max_radius : float, optional
        Largest horizontal distance from the target, m.
    altitude_bands : array_like, shape (2,) or (M, 2), optional
        ``[low, high]`` altitudes, m.
    starts : int, optional
        Number of starts.
    seed : int, default 0
        Seed of the random starts.
    rotation_deg : float, default 0
        Azimuth of UAV 1 of :math:`F^*`, degrees (a report for display, in degrees like
        its output).

    Returns
    -------
    dict
        Keys: ``design`` (``"constrained"``), ``n_uavs``, ``altitude_m`` (the common
        altitude; None with bands), ``altitudes_m`` (each UAV's), ``altitude_bands_m``
        (M x [low, high], or None), ``target_m``, ``rotation_deg``, ``criterion``,
        ``unit`` (of the criterion), ``value``, ``unconstrained`` (the reference optimum),
        ``ratio``, ``crlb_m2`` (tr J^-1 of the design, eq. (10)), ``rmse_bound_m``,
        ``positions_m``, ``unconstrained_positions_m``, ``active`` (list of str),
        ``starts``, ``feasible_starts``, ``seed``, ``constraints`` (``obstacles`` with
        ``rectangles`` and ``circles``, ``no_fly``, ``clearance_m``, ``min_separation_m``,
        ``max_radius_m``), ``radar``.
    """
    rotation_deg = _v.angle(rotation_deg, "rotation_deg", " deg")
    d = constrained_design(
        n_uavs, target_xy, altitude, radar, criterion=criterion, obstacles=obstacles,
        no_fly=no_fly, clearance=clearance, min_separation=min_separation,
        max_radius=max_radius, altitude_bands=altitude_bands, starts=starts, seed=seed,
        rotation=np.radians(rotation_deg),
    )  # fmt: skip
    target = np.asarray(target_xy, dtype=float)
    banded = d.altitude_bands is not None
    a_value = float(criterion_value(d.positions, target, d.altitudes, radar, "A", per_uav=True))
    obs = check_obstacles(obstacles) if obstacles is not None else None
    return {
        "design": "constrained",
        "n_uavs": int(d.positions.shape[0]),
        "altitude_m": None if banded else float(d.altitudes[0]),
        "altitudes_m": d.altitudes.tolist(),
        "altitude_bands_m": d.altitude_bands.tolist() if d.altitude_bands is not None else None,
        "target_m": target.tolist(),
        "rotation_deg": float(rotation_deg),
        "criterion": d.criterion,
        "unit": UNITS[d.criterion],
        "value": d.value,
        "unconstrained": d.unconstrained,
        "ratio": d.ratio,
        "crlb_m2": a_value,
        "rmse_bound_m": float(np.sqrt(a_value)),
        "positions_m": d.positions.tolist(),
        "unconstrained_positions_m": d.unconstrained_positions.tolist(),
        "active": list(d.active),
        "starts": d.starts,
        "feasible_starts": d.feasible_starts,
        "seed": int(seed),
        "constraints": {
            "obstacles": {
                "rectangles": obs.rectangles.tolist() if obs is not None else [],
                "circles": obs.circles.tolist() if obs is not None else [],
            },
            "no_fly": [np.asarray(z, dtype=float).tolist() for z in (no_fly or [])],
            "clearance_m": float(clearance),
            "min_separation_m": float(min_separation),
            "max_radius_m": None if max_radius is None else float(max_radius),
        },
        "radar": radar.to_dict(),
    }
