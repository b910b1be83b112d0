r"""Several targets: which UAVs sense which target, and in what formation (not in the paper).

M UAVs and K ground targets at known positions. Each UAV serves one target (it ranges that
target only), and each target needs at least :data:`MIN_GROUP` UAVs. Given a group
:math:`G_k`, its best formation around target :math:`k` is the closed-form optimum of
:func:`crlbswarm.optimal_formation` for the group's own radars: each UAV at its own optimal
elevation, with the attainable CRLB

.. math::

    c(G_k) = \begin{cases} 4 / W_k & w_{\max} \le W_k - w_{\max}\\
    1/w_{\max} + 1/(W_k - w_{\max}) & \text{otherwise,}\end{cases}
    \qquad W_k = \sum_{m \in G_k} w_m^\star

(:func:`crlbswarm.attainable_crlb`), which depends on the group's weights only, not on where
the target is. The allocation minimises :math:`\sum_k c(G_k)` (``objective="sum"``) or
:math:`\max_k c(G_k)` (``"max"``) over the partitions of the UAVs into K groups of at least
three:

* **exhaustive** for small problems (at most :data:`EXHAUSTIVE_LIMIT` assignments
  :math:`K^M`): every assignment is evaluated, vectorised, and the best one returned (the
  result says so, ``exhaustive=True``);
* a **heuristic** above: groups seeded round-robin with the UAVs in decreasing weight,
  then local search, moving one UAV or swapping two between groups while the objective
  falls (a local optimum: ``exhaustive=False``).

The formations of the groups do not interact here: groups around targets closer than their
formations' radii share airspace, which the mission's safety filter handles in flight.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validation as _v
from .design import attainable_crlb, optimal_formation, optimal_weights
from .errors import FieldError
from .radar import Radar, check_radar

__all__ = [
    "EXHAUSTIVE_LIMIT",
    "MAX_ALLOCATION_UAVS",
    "MIN_GROUP",
    "OBJECTIVES",
    "TargetAllocation",
    "allocate_targets",
    "allocation_report",
]

#: Fewest UAVs serving one target (the design's smallest formation).
MIN_GROUP = 3

#: Largest number of assignments K^M evaluated exhaustively.
EXHAUSTIVE_LIMIT = 3**12

#: Most UAVs allocated (the local search scores every move and swap at each pass, about
#: M^3 work: 100 UAVs to 20 targets take a few seconds).
MAX_ALLOCATION_UAVS = 100

#: The objectives over the targets' CRLBs.
OBJECTIVES = ("sum", "max")

_DEFAULT_RADAR = Radar()


@dataclass(frozen=True, eq=False)
class TargetAllocation:
    """Which UAVs serve which target, their formations and CRLBs.

    Attributes
    ----------
    assignment : ndarray of int, shape (M,)
        The target each UAV serves (index into ``targets``).
    groups : tuple of ndarray of int
        The UAVs of each target, in increasing order.
    positions : ndarray, shape (M, 2)
        Each UAV's slot: its group's optimal formation around its target, m.
    crlb : ndarray, shape (K,)
        Attainable CRLB of each target, m^2.
    objective : str
        ``"sum"`` or ``"max"``.
    exhaustive : bool
        Whether every assignment was evaluated (the optimum), or the heuristic was used.
    evaluated : int
        Assignments evaluated.
    """

    assignment: np.ndarray
    groups: tuple[np.ndarray, ...]
    positions: np.ndarray
    crlb: np.ndarray
    objective: str
    exhaustive: bool
    evaluated: int

    @property
    def value(self) -> float:
        """The objective: the sum or the largest of ``crlb``, m^2."""
        return float(_objective(self.crlb, self.objective))


def allocate_targets(
    targets_xy: ArrayLike,
    n_uavs: int,
    altitude: float,
    radar: Radar = _DEFAULT_RADAR,
    *,
    objective: str = "sum",
    method: str = "auto",
) -> TargetAllocation:
    """Allocate M UAVs to K targets and design each group's formation (module docstring).

    Parameters
    ----------
    targets_xy : array_like, shape (K, 2)
        Target positions, m, K >= 1.
    n_uavs : int
        Number of UAVs M, at least ``MIN_GROUP * K``, at most :data:`MAX_ALLOCATION_UAVS`.
    altitude : float
        Flight altitude H, m.
    radar : Radar, optional
        Link parameters; per-UAV fields (length M) make the UAVs unequal.
    objective : {"sum", "max"}, default "sum"
        Minimise the sum or the largest of the targets' CRLBs.
    method : {"auto", "exhaustive", "heuristic"}, default "auto"
        ``auto``: exhaustive when K^M <= :data:`EXHAUSTIVE_LIMIT`, else the heuristic.

    Returns
    -------
    TargetAllocation
        The groups, their formations and CRLBs.

    Raises
    ------
    FieldError
        On an invalid argument, too few UAVs for the targets, or an exhaustive search asked
        for beyond :data:`EXHAUSTIVE_LIMIT` assignments.

    Examples
    --------
    >>> from crlbswarm import allocate_targets
    >>> a = allocate_targets([[0.0, 0.0], [200.0, 0.0]], 7, 20.0)
    >>> sorted(len(g) for g in a.groups), a.exhaustive
    ([3, 4], True)
    """
    targets = _v.location(targets_xy, "targets_xy")
    if targets.ndim != 2 or targets.shape[0] < 1:
        raise FieldError("targets_xy", f"expected shape (K, 2), got {targets.shape}")
    k = targets.shape[0]
    n = _v.count(n_uavs, "n_uavs", MIN_GROUP, MAX_ALLOCATION_UAVS)
    if n < MIN_GROUP * k:
        raise FieldError(
            "n_uavs", f"{n} UAVs cannot give {k} targets {MIN_GROUP} UAVs each ({MIN_GROUP * k})"
        )
    h = _v.scalar(altitude, "altitude")
    if objective not in OBJECTIVES:
        raise FieldError(
            "objective", f"expected one of {', '.join(OBJECTIVES)}, got {objective!r}"
        )
    if method not in ("auto", "exhaustive", "heuristic"):
        raise FieldError("method", f"expected auto, exhaustive or heuristic, got {method!r}")
    check_radar(radar, n)
    weights = np.asarray(optimal_weights(n, h, radar), dtype=float)
    size = float(k) ** n
    if method == "exhaustive" and size > EXHAUSTIVE_LIMIT:
        raise FieldError(
            "method",
            f"an exhaustive search over {k}^{n} = {size:.3g} assignments is beyond the limit of "
            f"{EXHAUSTIVE_LIMIT}; use the heuristic",
        )
    exhaustive = method == "exhaustive" or (method == "auto" and size <= EXHAUSTIVE_LIMIT)
    if exhaustive:
        assignment, evaluated = _exhaustive(weights, k, objective)
    else:
        assignment, evaluated = _heuristic(weights, k, objective)
    return _allocation(assignment, targets, h, radar, weights, objective, exhaustive, evaluated)


def _objective(costs: np.ndarray, objective: str) -> np.ndarray:
    return np.sum(costs, axis=-1) if objective == "sum" else np.max(costs, axis=-1)


def _group_costs(labels: np.ndarray, weights: np.ndarray, k: int) -> np.ndarray:
    """Attainable CRLB of each group, shape (..., K); inf where a group is too small."""
    onehot = labels[..., None] == np.arange(k)  # (..., M, K)
    total = np.einsum("...mk,m->...k", onehot, weights)
    largest = np.max(np.where(onehot, weights[:, None], 0.0), axis=-2)
    count = np.sum(onehot, axis=-2)
    rest = total - largest
    with np.errstate(divide="ignore", invalid="ignore"):
        cost = np.where(largest <= rest, 4.0 / total, 1.0 / largest + 1.0 / rest)
    return np.where(count >= MIN_GROUP, cost, np.inf)


def _exhaustive(weights: np.ndarray, k: int, objective: str) -> tuple[np.ndarray, int]:
    """Every assignment with UAV 0 to target 0 .. K-1 (all K^M), in chunks; the best."""
    n = weights.shape[0]
    best, best_value, evaluated = None, np.inf, 0
    chunk_len = min(n, 8)
    tail = np.array(list(itertools.product(range(k), repeat=chunk_len)), dtype=np.int64)
    for head in itertools.product(range(k), repeat=n - chunk_len):
        labels = np.concatenate([np.broadcast_to(head, (tail.shape[0], len(head))), tail], 1)
        values = _objective(_group_costs(labels, weights, k), objective)
        evaluated += labels.shape[0]
        i = int(np.argmin(values))  # first of the best: deterministic
        if values[i] < best_value:
            best, best_value = labels[i].copy(), float(values[i])
    assert best is not None  # (n >= MIN_GROUP * k: some assignment is feasible)
    return best, evaluated


def _heuristic(weights: np.ndarray, k: int, objective: str) -> tuple[np.ndarray, int]:
    """Round-robin seeding by decreasing weight, then single moves and pairwise swaps while
    the objective falls."""
    n = weights.shape[0]
    labels = np.empty(n, dtype=np.int64)
    labels[np.argsort(-weights, kind="stable")] = np.arange(n) % k
    value = float(_objective(_group_costs(labels, weights, k), objective))
    evaluated = 1
    improved = True
    while improved:
        improved = False
        candidates = [labels]
        for m in range(n):  # every move of one UAV, and every swap of two
            for target in range(k):
                if target != labels[m]:
                    moved = labels.copy()
                    moved[m] = target
                    candidates.append(moved)
            for p in range(m + 1, n):
                if labels[p] != labels[m]:
                    swapped = labels.copy()
                    swapped[[m, p]] = labels[[p, m]]
                    candidates.append(swapped)
        batch = np.stack(candidates)
        values = _objective(_group_costs(batch, weights, k), objective)
        evaluated += batch.shape[0]
        i = int(np.argmin(values))
        if values[i] < value * (1.0 - 1e-12):
            labels, value, improved = batch[i].copy(), float(values[i]), True
    return labels, evaluated


def _allocation(assignment: np.ndarray, targets: np.ndarray, altitude: float, radar: Radar,
                weights: np.ndarray, objective: str, exhaustive: bool,
                evaluated: int) -> TargetAllocation:  # fmt: skip
    k = targets.shape[0]
    groups = tuple(np.flatnonzero(assignment == j) for j in range(k))
    positions = np.empty((assignment.shape[0], 2))
    costs = np.empty(k)
    for j, members in enumerate(groups):
        sub = radar.take(members) if radar.per_uav else radar
        positions[members] = optimal_formation(len(members), targets[j], altitude, sub)
        costs[j] = float(attainable_crlb(weights[members]))
    for array in (assignment, positions, costs, *groups):
        array.flags.writeable = False
    return TargetAllocation(
        assignment=assignment,
        groups=groups,
        positions=positions,
        crlb=costs,
        objective=objective,
        exhaustive=exhaustive,
        evaluated=evaluated,
    )


def allocation_report(
    targets_xy: ArrayLike,
    n_uavs: int,
    altitude: float,
    radar: Radar = _DEFAULT_RADAR,
    *,
    objective: str = "sum",
    method: str = "auto",
) -> dict[str, Any]:
    """:func:`allocate_targets` of a scene and its figures, as a JSON-ready dict.

    What ``crlbswarm design`` prints for two or more targets (a table, or JSON with
    ``--json``). UAVs and targets are numbered from 1.

    Parameters
    ----------
    targets_xy : array_like, shape (K, 2)
        Target positions, m (as :func:`allocate_targets`, like the parameters below).
    n_uavs : int
        Number of UAVs M.
    altitude : float
        Flight altitude H, m.
    radar : Radar, optional
        Link parameters.
    objective : {"sum", "max"}, default "sum"
        Minimise the sum or the largest of the targets' CRLBs.
    method : {"auto", "exhaustive", "heuristic"}, default "auto"
        The search.

    Returns
    -------
    dict
        Keys: ``design`` (``"allocation"``), ``n_uavs``, ``altitude_m``, ``targets_m``
        (K x [x, y]), ``objective``, ``value_m2`` (the sum or the largest of the CRLBs),
        ``exhaustive`` (every assignment evaluated: the optimum; else the heuristic, a
        local optimum), ``evaluated``, ``assignment`` (each UAV's target number),
        ``groups`` (one per target: ``target``, ``target_m``, ``uavs``, ``positions_m``,
        ``crlb_m2``, ``rmse_bound_m``), ``positions_m`` (every UAV's slot), ``radar``.
    """
    alloc = allocate_targets(targets_xy, n_uavs, altitude, radar, objective=objective,
                             method=method)  # fmt: skip
    targets = np.asarray(targets_xy, dtype=float)
    groups = [
        {
            "target": k + 1,
            "target_m": targets[k].tolist(),
            "uavs": (members + 1).tolist(),
            "positions_m": alloc.positions[members].tolist(),
            "crlb_m2": float(alloc.crlb[k]),
            "rmse_bound_m": float(np.sqrt(alloc.crlb[k])),
        }
        for k, members in enumerate(alloc.groups)
    ]
    return {
        "design": "allocation",
        "n_uavs": int(alloc.assignment.shape[0]),
        "altitude_m": float(altitude),
        "targets_m": targets.tolist(),
        "objective": alloc.objective,
        "value_m2": alloc.value,
        "exhaustive": alloc.exhaustive,
        "evaluated": alloc.evaluated,
        "assignment": (alloc.assignment.astype(np.int64) + 1).tolist(),
        "groups": groups,
        "positions_m": alloc.positions.tolist(),
        "radar": radar.to_dict(),
    }
