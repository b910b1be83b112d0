r"""Distributed formation control laws of the paper, Sec. IV, as pure functions.

Each law is written once, as a Numba-compiled kernel on one formation (arrays ``(M, 2)``),
and called both by the mission kernel (:mod:`crlbswarm.mission_kernel`) and by the public
functions below, which accept any batch ``(..., M, 2)`` and never modify their inputs. The
gains of every law are declared once, in :class:`ControlGains` and :class:`EtaRule` (name,
type, default, unit and meaning); the scenario file's ``[control]`` and ``[eta]`` tables are
these types, the public laws take them, and the mission kernel receives them as typed
tuples (:meth:`ControlGains.kernel_tuple`).

Laws and the choices the paper leaves open (each documented in ``docs/control.md``):

* **Velocity consensus**, eq. (14). The printed update has no :math:`\mathbf v_{m,k}` on the
  right and the wrong sign on the leader term, so it does not converge. crlbswarm uses the
  standard convergent form (Ren & Beard 2008)

  .. math::
      \mathbf v_{m,k+1} = \mathbf v_{m,k} - \gamma\Bigl[\sum_{p\in\mathcal N_m\setminus\{1\}}
      a_{mp}(\mathbf v_{m,k} - \mathbf v_{p,k}) + a_{m1}(\mathbf v_{m,k} - \mathbf v^*_k)\Bigr].

* **Leader guidance** (not in the paper; :func:`leader_guidance`): proportional guidance
  with gain :math:`k_g` toward the leader's slot of :math:`F^*` over the target (scaled by
  :math:`\eta_k`), plus the repulsion felt by the formation's disc of radius
  :math:`\eta_k r^*` (so the leader steers the formation to the middle of a passage),
  saturated at the cruise speed :math:`v_c`; it decays to zero as the formation settles.
* **Formation input**, eqs. (16) and (19):
  :math:`\mathbf u_{m,k} = -\varepsilon\sum_p a_{mp}(\mathbf q_{m,k} - \mathbf q_{p,k} -
  \eta_k\boldsymbol\delta_{pm}) + \mathbf u^r_{m,k}`, a position increment per step (m).
* **Repulsion**, eq. (18): :func:`crlbswarm.obstacles.repulsion_at`, with the gains of
  :class:`ControlGains` in :func:`repulsion`.
* **Motion model**, eq. (3): :func:`motion_model`.
* **Scaling factor** :math:`\eta_k` (rule not in the paper): see :func:`eta_target` and
  :func:`eta_update`.
* **Cost** :math:`\mathcal L_\text{tot}`, eq. (15) summed over UAVs: see
  :func:`formation_cost`.

Adding a control law: write it as an ``@njit`` function on one formation below, wrap it in a
public function that validates and batches, declare its gains in :class:`ControlGains`, and
call it from the mission kernel's block where its inputs are ready
(:func:`crlbswarm.mission_kernel.input_block` or :func:`crlbswarm.mission_kernel.update_block`).
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Annotated, Any, Literal

import numpy as np
from numba import njit, types
from numba.extending import overload
from numpy.typing import ArrayLike
from pydantic import Field, PlainValidator, ValidationError

from . import _validation as _v
from ._config import ConfigModel, PositiveFloat, describe
from ._numba import leaf
from .errors import FieldError
from .geometry import clip_norm
from .graphs import Adjacency, auto_consensus_step, auto_formation_step
from .obstacles import Obstacles, check_obstacles, clearance_of, obstacle_index, repulsion_at
from .planning import segment_clear

__all__ = [
    "ControlGains",
    "EtaRule",
    "consensus_rows",
    "consensus_step",
    "consensus_update",
    "control_cost",
    "corridor_width",
    "cost_rows",
    "eta_from_width",
    "eta_goal",
    "eta_rate_limit",
    "eta_target",
    "eta_update",
    "formation_cost",
    "formation_input",
    "formation_rows",
    "formation_update",
    "leader_guidance",
    "motion_model",
    "reference_velocity",
    "repulsion",
    "route_clear",
    "route_eta_goal",
    "route_point",
    "row_scale",
    "smoothstep",
    "travel_weight",
]


def _positive_or_auto(value: object) -> float | str:
    if value == "auto":
        return "auto"
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError('must be a number > 0 or "auto"')
    try:
        value = float(value)
    except OverflowError:
        raise ValueError('must be a finite number > 0 or "auto"') from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError('must be a finite number > 0 or "auto"')
    return float(value)


#: A gain that may be ``"auto"`` (resolved from the graph's spectrum by
#: :meth:`ControlGains.resolve`).
AutoGain = Annotated[float | Literal["auto"], PlainValidator(_positive_or_auto)]


class _OneLineErrors(type(ConfigModel)):  # type: ignore[misc]
    """Metaclass of the gains: built directly (``ControlGains(epsilon=-1)``), an invalid
    value raises one :class:`FieldError` line naming the first offending field (every
    problem after it, ``"; "``-joined). Validation inside a scenario does not call the
    class, so the scenario's own error (``control.epsilon``) is unchanged."""

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        try:
            return super().__call__(*args, **kwargs)
        except ValidationError as exc:
            problems = describe(exc)
            field, first = problems[0]
            rest = [f"{f}: {r}" if f else r for f, r in problems[1:]]
            raise FieldError(field, "; ".join([first, *rest])) from None


# ---------------------------------------------------------------------------------------
# Gains: each declared once, with its unit and meaning
# ---------------------------------------------------------------------------------------
class ControlGains(ConfigModel, metaclass=_OneLineErrors):
    """Gains of the control laws (Sec. IV; choices documented in ``docs/control.md``).

    The scenario's ``[control]`` table; the public laws take it, and the mission kernel
    receives it as :meth:`kernel_tuple`. Frozen; an invalid value raises
    :class:`~crlbswarm.errors.FieldError` (a :class:`ValueError`) naming the field, in one
    line (inside a scenario, the scenario's error names ``control.<field>``). Each field is
    declared once below, with its unit; this docstring's Parameters section and the comments
    of the scenario file are generated from those declarations.
    """

    epsilon: AutoGain = Field(
        "auto",
        description="formation gain epsilon per step, eqs. (16), (19) (paper: 0.01); "
        '"auto": 1/lambda_max(L), the fastest step without oscillation; with links d steps '
        "old min(1/lambda_max(L), 0.15/(max degree d))",
    )
    gamma: AutoGain = Field(
        "auto",
        description="consensus step gamma, eq. (14), < 1/max degree (paper scenario: 0.25); "
        '"auto": min(1/lambda_max(L_ff), 0.99/max degree)',
    )
    guidance_gain: PositiveFloat = Field(0.5, description="leader guidance gain k_g, 1/s")
    cruise_speed: PositiveFloat = Field(2.0, description="leader cruise speed v_c, m/s")
    safety_radius: PositiveFloat = Field(5.0, description="l_safe of eq. (18), m (paper: 5)")
    repulsion_gain: PositiveFloat = Field(
        2.0, description="E_r of eq. (18), m^4 per step (u^r is in metres)"
    )
    repulsion_max_step: PositiveFloat = Field(1.0, description="cap on |u^r| per step, m")
    formation_steering: bool = Field(
        True, description="leader also steers the formation (disc of radius eta r*) off obstacles"
    )

    def resolve(self, adjacency: Adjacency, leader: int, delay: int = 0) -> ControlGains:
        """The gains with ``"auto"`` replaced by the values the graph's spectrum gives.

        Parameters
        ----------
        adjacency : Adjacency
            The communication graph.
        leader : int
            Index of the leader.
        delay : int, optional
            The largest age of a neighbour's state the laws act on, steps (0: the state of
            the step; a scenario's links: :meth:`crlbswarm.links.LinksConfig.largest_age`).

        Returns
        -------
        ControlGains
            The same gains, ``epsilon`` from :func:`crlbswarm.graphs.auto_formation_step`
            (for ``delay``) and ``gamma`` from :func:`crlbswarm.graphs.auto_consensus_step`
            where ``"auto"`` (a convex combination: stable whatever the delay).
        """
        update: dict[str, float] = {}
        if self.epsilon == "auto":
            update["epsilon"] = auto_formation_step(adjacency, delay)
        if self.gamma == "auto":
            update["gamma"] = auto_consensus_step(adjacency, leader)
        return self.model_copy(update=update) if update else self

    def kernel_tuple(self) -> Any:
        """The gains as a typed named tuple for the compiled kernels (same field names).

        Returns
        -------
        ControlGainsTuple
            A :func:`collections.namedtuple` of the fields, in declaration order.

        Raises
        ------
        FieldError
            If a gain is still ``"auto"`` (call :meth:`resolve` first).
        """
        for name in ("epsilon", "gamma"):
            if getattr(self, name) == "auto":
                raise FieldError(
                    f"gains.{name}", '"auto" must be resolved on a graph first (gains.resolve)'
                )
        return ControlGainsTuple(**self.model_dump())


#: Most points the eta rule samples along the path (each is checked against every obstacle
#: at every step of every run; thousands already resolve any passage to a millimetre).
MAX_ETA_SAMPLES = 10_000


class EtaRule(ConfigModel, metaclass=_OneLineErrors):
    """Rule for the scaling factor :math:`\\eta` (not in the paper; :func:`eta_target`).

    The scenario's ``[eta]`` table; :func:`eta_target` and :func:`eta_update` take it, and
    the mission kernel receives it as :meth:`kernel_tuple`. Each field is declared once
    below, with its unit; this docstring's Parameters section is generated from them. An
    invalid value raises :class:`~crlbswarm.errors.FieldError` naming the field.
    """

    enabled: bool = Field(True, description="false keeps eta = 1")
    minimum: Annotated[float, Field(gt=0, le=1)] = Field(0.3, description="smallest eta")
    rate: PositiveFloat = Field(0.1, description="largest change of eta per second, 1/s")
    lookahead: PositiveFloat = Field(40.0, description="distance looked ahead, m")
    margin: PositiveFloat | None = Field(
        None, description="clearance to keep, m (default: control.safety_radius)"
    )
    samples: Annotated[int, Field(ge=2, le=MAX_ETA_SAMPLES)] = Field(
        32, description=f"points sampled on the path (2 to {MAX_ETA_SAMPLES})"
    )

    def margin_for(self, gains: ControlGains) -> float:
        """The clearance the rule keeps: ``margin``, or the gains' safety radius.

        Parameters
        ----------
        gains : ControlGains
            The gains (their ``safety_radius`` is the default margin).

        Returns
        -------
        float
            Margin, m.
        """
        return gains.safety_radius if self.margin is None else self.margin

    def kernel_tuple(self, gains: ControlGains) -> Any:
        """The rule as a typed named tuple for the compiled kernels, margin resolved.

        Parameters
        ----------
        gains : ControlGains
            The gains (their ``safety_radius`` is the default margin).

        Returns
        -------
        EtaRuleTuple
            A :func:`collections.namedtuple` of the fields, in declaration order.
        """
        return EtaRuleTuple(**{**self.model_dump(), "margin": self.margin_for(gains)})


#: The typed tuples the compiled kernels receive (derived from the declarations above).
# (Built from the declarations, so type checkers cannot see their fields.)
ControlGainsTuple = namedtuple("ControlGainsTuple", list(ControlGains.model_fields))  # type: ignore[misc]
EtaRuleTuple = namedtuple("EtaRuleTuple", list(EtaRule.model_fields))  # type: ignore[misc]

_DEFAULT_GAINS = ControlGains()


def _check_gains(gains: object) -> ControlGains:
    if not isinstance(gains, ControlGains):
        raise FieldError("gains", f"expected a crlbswarm.ControlGains, got {type(gains).__name__}")
    return gains


def _check_rule(rule: object) -> EtaRule:
    if not isinstance(rule, EtaRule):
        raise FieldError("rule", f"expected a crlbswarm.EtaRule, got {type(rule).__name__}")
    return rule


#: Points sampled across the path (odd, so the path itself is one) by the eta rule.
LATERAL_SAMPLES = 9

#: Margin, m, by which the eta rule's path must clear the obstacles for its samples to be
#: skipped in one pass (far above the rounding of a sample's position and clearance, so
#: the shortcut never changes the rule's result).
PATH_PAD = 1e-6

#: The eta rule near the target, in units of the formation radius R: within HOVER_INNER R
#: of the target the goal is 1 (the validated slots of F* are clear), beyond HOVER_OUTER R
#: it is the free-width rule, and in between a smooth blend, so the rule is continuous.
HOVER_INNER = 0.25
HOVER_OUTER = 1.0

#: With the planner, the eta rule along the route blends to 1 only on arrival, from this
#: many formation radii to HOVER_INNER (:func:`route_eta_goal`).
ARRIVAL_OUTER = 0.5


# ---------------------------------------------------------------------------------------
# Compiled laws on one formation (called by the public functions and the mission kernel)
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def consensus_update(v, v_ref, leader, indptr, indices, gamma, out):
    """Corrected eq. (14) on one formation: followers step toward their neighbours; the
    leader holds ``v_ref``. Writes ``out`` (M, 2). The leader's row of ``v`` is what its
    neighbours read as its velocity: the caller puts :math:`\\mathbf v^*_k` there (as the
    mission kernel does, and :func:`consensus_step` on its copy). Compiled kernel, no
    checks."""
    consensus_rows(v, v_ref, leader, v, indices, indptr, gamma, out, 0, v.shape[0])


@leaf
def consensus_rows(v, v_ref, leader, tab, lookup, indptr, gamma, out, lo, hi):
    """:func:`consensus_update` for the UAVs ``lo .. hi - 1`` only (a block of a large
    swarm; the law's one writing). UAV m's neighbours are the entries ``j`` of
    ``indptr[m] .. indptr[m+1] - 1``; neighbour j's velocity is ``tab[lookup[j]]``: with
    perfect links ``tab`` is ``v`` itself and ``lookup`` the CSR neighbour indices (the
    leader's row holding :math:`\\mathbf v^*_k`); with the links of :mod:`crlbswarm.links`
    it is the copy each UAV last received from that neighbour (the leader's reference
    travels in the leader's messages) and ``lookup`` the link's number."""
    for m in range(lo, hi):
        if m == leader:
            out[m, 0] = v_ref[0]
            out[m, 1] = v_ref[1]
            continue
        sx = 0.0
        sy = 0.0
        for j in range(indptr[m], indptr[m + 1]):
            n = lookup[j]
            sx += v[m, 0] - tab[n, 0]
            sy += v[m, 1] - tab[n, 1]
        out[m, 0] = v[m, 0] - gamma * sx
        out[m, 1] = v[m, 1] - gamma * sy


def row_scale(eta: Any, m: int) -> float:
    r"""The scaling factor of UAV ``m``: ``eta`` itself (one for the whole formation, the
    paper's :math:`\eta_k`) or ``eta[m]`` (one per UAV: the :math:`\eta` each UAV knows,
    with the links of :mod:`crlbswarm.links`). Compiled kernels get the one of the type
    they are compiled for (a Numba ``overload``, inlined: nothing is looked up at run
    time).

    Parameters
    ----------
    eta : float or ndarray, shape (M,)
        One scaling factor, or one per UAV.
    m : int
        The UAV.

    Returns
    -------
    float
        Its scaling factor.

    Examples
    --------
    >>> row_scale(0.5, 3), row_scale(np.array([1.0, 0.7]), 1)
    (0.5, 0.7)
    """
    return float(eta) if np.ndim(eta) == 0 else float(eta[m])


@overload(row_scale, inline="always")
def _row_scale_kernel(eta, m):
    if isinstance(eta, types.Array):
        return lambda eta, m: eta[m]
    return lambda eta, m: eta


@njit(cache=True)
def formation_update(q, delta, eta, eps, indptr, indices, out):
    """Eq. (19) without repulsion on one formation:
    ``-eps sum_p a_mp (q_m - q_p - eta (delta_m - delta_p))``. Writes ``out`` (M, 2)."""
    formation_rows(q, delta, eta, eps, q, indices, indptr, indices, out, 0, q.shape[0])


@leaf
def formation_rows(q, delta, eta, eps, tab, lookup, indptr, indices, out, lo, hi):
    """:func:`formation_update` for the UAVs ``lo .. hi - 1`` only (a block of a large
    swarm; the law's one writing). UAV m's neighbours are the entries ``j`` of
    ``indptr[m] .. indptr[m+1] - 1``: neighbour ``indices[j]`` (its slot offset) at
    position ``tab[lookup[j]]``. With perfect links ``tab`` is ``q`` itself, ``lookup`` is
    ``indices`` and ``eta`` one number; with the links of :mod:`crlbswarm.links` ``tab``
    holds the position each UAV last received from that neighbour, ``lookup`` the link's
    number, and ``eta`` the scaling factor each UAV knows (:func:`row_scale`)."""
    for m in range(lo, hi):
        e = row_scale(eta, m)
        sx = 0.0
        sy = 0.0
        for j in range(indptr[m], indptr[m + 1]):
            p = indices[j]
            n = lookup[j]
            sx += q[m, 0] - tab[n, 0] - e * (delta[m, 0] - delta[p, 0])
            sy += q[m, 1] - tab[n, 1] - e * (delta[m, 1] - delta[p, 1])
        out[m, 0] = -eps * sx
        out[m, 1] = -eps * sy


@njit(cache=True, inline="always")
def motion_model(q, u, u_r, v, dt, n):
    """Eq. (3) for one coordinate: ``q_{k+1} = q_k + u_k + u^r_k + v_k dT + n_k``, with the
    formation input ``u``, the repulsion ``u_r`` (together the paper's u), the consensus
    velocity ``v`` (the paper's g) and the disturbance ``n``."""
    return q + u + u_r + v * dt + n


@leaf
def reference_velocity(
    qx, qy, gx, gy, cx, cy, gain, cruise, tvx, tvy, rects, circles, e_r, l_safe, footprint, dt
):
    """Leader reference velocity (not in the paper; :func:`leader_guidance`): the goal's
    velocity plus proportional guidance to the goal plus, if ``footprint > 0``, the
    repulsion felt by the formation's disc, saturated at ``cruise``. Compiled kernel."""
    wx = tvx + gain * (gx - qx)
    wy = tvy + gain * (gy - qy)
    if footprint > 0.0:
        rx, ry = repulsion_at(cx, cy, rects, circles, e_r, l_safe, math.inf, footprint)
        wx += rx / dt
        wy += ry / dt
    return clip_norm(wx, wy, cruise)


@njit(cache=True, inline="always")
def corridor_width(px, py, hx, hy, radius, rects, circles, index):
    """Half-width of the corridor's cross-section at (px, py), travelling along (hx, hy):
    the best clearance the formation's centre could have within +-radius across the path
    (the repulsion and the steering centre the formation), on ``LATERAL_SAMPLES`` points."""
    best = -math.inf
    for j in range(LATERAL_SAMPLES):
        o = radius * (2.0 * j / (LATERAL_SAMPLES - 1) - 1.0)
        best = max(best, clearance_of(px - o * hy, py + o * hx, rects, circles, index))
    return best


@njit(cache=True, inline="always")
def smoothstep(t):
    """0 for t <= 0, 1 for t >= 1, and :math:`3t^2 - 2t^3` in between."""
    if t >= 1.0:
        return 1.0
    return 0.0 if t <= 0.0 else t * t * (3.0 - 2.0 * t)


@njit(cache=True, inline="always")
def travel_weight(dist, radius):
    """1 while the formation travels, 0 while it hovers over the target (``dist`` away): a
    smoothstep from ``HOVER_INNER`` to ``HOVER_OUTER`` formation radii. The travelling
    layers (the eta rule, the leader's steering) fade out with it over the target."""
    return smoothstep((dist - HOVER_INNER * radius) / ((HOVER_OUTER - HOVER_INNER) * radius))


@njit(cache=True, inline="always")
def eta_from_width(width, margin, radius, eta_min, dist):
    """The scale at which a formation of radius ``radius`` keeps ``margin`` in a corridor of
    half-width ``width``, in [eta_min, 1]; blended to 1 near the target (``dist`` away) by
    :func:`travel_weight`, so exactly 1 while hovering."""
    goal = min(1.0, max(eta_min, (width - margin) / radius))
    w = travel_weight(dist, radius)
    if w == 1.0:
        return goal
    return goal + (1.0 - goal) * (1.0 - w)


@leaf
def eta_goal(cx, cy, sx, sy, radius, rects, circles, index, margin, lookahead, n_samples,
             eta_min):  # fmt: skip
    """Free half-width of the corridor ahead of the formation on the straight line to the
    target -> scale in [eta_min, 1], blended to 1 near the target (:func:`eta_target`).
    ``index``: the obstacles' index, or None (:func:`crlbswarm.obstacles.obstacle_index`;
    the clearance of a sample is exact either way). Compiled kernel, no checks."""
    if rects.shape[0] + circles.shape[0] == 0:
        return 1.0
    hx = sx - cx
    hy = sy - cy
    dist = math.sqrt(hx * hx + hy * hy)
    if dist > 0.0:
        hx /= dist
        hy /= dist
    else:
        hx, hy = 1.0, 0.0
    ahead = min(lookahead, dist)
    width = math.inf
    enough = radius + margin  # a half-width this large allows eta = 1
    floor = margin + eta_min * radius  # a half-width this small forces eta = eta_min
    if segment_clear(cx - radius * hx, cy - radius * hy, cx + ahead * hx, cy + ahead * hy,
                     rects, circles, enough + PATH_PAD):  # fmt: skip
        # Every sample is at least ``enough`` from every obstacle: each would be skipped
        # below, so one pass over the obstacles gives the same result (the usual case).
        return eta_from_width(width, margin, radius, eta_min, dist)
    for i in range(n_samples):
        t = -radius + (ahead + radius) * i / (n_samples - 1)
        px = cx + t * hx
        py = cy + t * hy
        if clearance_of(px, py, rects, circles, index) >= enough:
            continue  # the lateral best is at least as large: no effect on the result
        width = min(width, corridor_width(px, py, hx, hy, radius, rects, circles, index))
        if width <= floor:
            break  # clipped at eta_min whatever the remaining samples say
    return eta_from_width(width, margin, radius, eta_min, dist)


@leaf
def route_eta_goal(cx, cy, sx, sy, k, nodes, next_node, radius, rects, circles, index, margin,
                   lookahead, n_samples, eta_min, planned=False):  # fmt: skip
    r"""The eta goal as flown: :func:`eta_goal` (the straight line to the target, the best
    point across it) without the planner (``planned`` False); with it, the scale at which
    the formation's disc fits at the points of its route itself: from the centre through
    ``nodes[k]``, ``nodes[next_node[k]]``, ... (or, with ``k < 0``, the target in sight,
    the straight line to it), from ``radius`` behind to ``lookahead`` ahead. The leader
    holds the centre on the route, so the half-width at a sample is that point's own
    clearance. The goal is blended to 1 only on arrival, from ``ARRIVAL_OUTER`` radii to
    ``HOVER_INNER`` radii of the target and exactly 1 within (where the formation opens up
    along the segments from the target to its slots, which the scenario checks are clear):
    a wide formation may still have to round an obstacle within :math:`r^\star` of the
    target. Compiled kernel."""
    if not planned or rects.shape[0] + circles.shape[0] == 0:
        return eta_goal(cx, cy, sx, sy, radius, rects, circles, index, margin, lookahead,
                        n_samples, eta_min)  # fmt: skip
    dist = math.hypot(sx - cx, sy - cy)
    if k >= 0:
        length = math.hypot(nodes[k, 0] - cx, nodes[k, 1] - cy)  # the route's length ahead
        j = k
        while next_node[j] >= 0 and length < lookahead:
            i = next_node[j]
            length += math.hypot(nodes[i, 0] - nodes[j, 0], nodes[i, 1] - nodes[j, 1])
            j = i
    else:
        length = dist
    hx, hy = ((sx - cx) / dist, (sy - cy) / dist) if dist > 0.0 else (1.0, 0.0)
    ahead = min(lookahead, length)
    width = math.inf
    floor = margin + eta_min * radius
    if route_clear(cx, cy, hx, hy, k, nodes, next_node, radius, ahead, rects, circles,
                   radius + margin + PATH_PAD):  # fmt: skip
        return 1.0  # every sample's clearance allows eta = 1 (and the blend keeps 1)
    for s in range(n_samples):
        t = -radius + (ahead + radius) * s / (n_samples - 1)
        if k >= 0:
            px, py, _, _ = route_point(cx, cy, k, nodes, next_node, t)
        else:
            px, py = cx + t * hx, cy + t * hy
        width = min(width, clearance_of(px, py, rects, circles, index))
        if width <= floor:
            break
    goal = min(1.0, max(eta_min, (width - margin) / radius))
    if k < 0:  # arrival: 1 within HOVER_INNER radii, the route's rule from ARRIVAL_OUTER out
        w = smoothstep((dist - HOVER_INNER * radius) / ((ARRIVAL_OUTER - HOVER_INNER) * radius))
        goal += (1.0 - goal) * (1.0 - w)
    return goal


@leaf
def route_clear(cx, cy, hx, hy, k, nodes, next_node, behind, ahead, rects, circles, keep):
    """Whether the route from ``behind`` m behind the centre (cx, cy) to ``ahead`` m along it
    (through ``nodes[k]`` and its successors; ``k < 0``: the straight line along (hx, hy))
    keeps ``keep`` m (less :data:`crlbswarm.planning.CLEAR_TOL`) from every obstacle: the
    samples of :func:`route_eta_goal` all lie on it. Compiled kernel."""
    if k < 0:
        return segment_clear(cx - behind * hx, cy - behind * hy, cx + ahead * hx,
                             cy + ahead * hy, rects, circles, keep)  # fmt: skip
    bx, by, _, _ = route_point(cx, cy, k, nodes, next_node, -behind)
    if not segment_clear(bx, by, cx, cy, rects, circles, keep):
        return False
    ax, ay = cx, cy
    length = 0.0
    j = k
    while True:  # whole legs: a longer path is only more demanding
        if not segment_clear(ax, ay, nodes[j, 0], nodes[j, 1], rects, circles, keep):
            return False
        length += math.hypot(nodes[j, 0] - ax, nodes[j, 1] - ay)
        if length >= ahead or next_node[j] < 0:
            return True
        ax, ay = nodes[j, 0], nodes[j, 1]
        j = next_node[j]


@leaf
def route_point(cx, cy, k, nodes, next_node, t):
    """The point at arc length ``t`` along the route from (cx, cy) through ``nodes[k]`` and
    its successors (``t < 0``: behind, on the first leg's line), and the unit direction of
    the leg there."""
    ax, ay, j = cx, cy, k
    while True:
        bx, by = nodes[j, 0], nodes[j, 1]
        leg = math.hypot(bx - ax, by - ay)
        if leg > 0.0:
            hx, hy = (bx - ax) / leg, (by - ay) / leg
            if t <= leg or next_node[j] < 0:
                return ax + t * hx, ay + t * hy, hx, hy
            t -= leg
        if next_node[j] < 0:
            return bx, by, 1.0, 0.0
        ax, ay, j = bx, by, next_node[j]


@njit(cache=True, inline="always")
def eta_rate_limit(eta, goal, max_step):
    """One rate-limited step of eta toward its goal (:func:`eta_update`): eta plus the change,
    clipped to +-``max_step``."""
    return eta + min(max_step, max(-max_step, goal - eta))


@njit(cache=True)
def control_cost(q, q_next, delta, v_ref, dt, indptr, indices):
    """Eq. (15) summed over UAVs on one formation, with the nominal displacements
    ``delta_pm = delta_m - delta_p`` (:func:`formation_cost`). Compiled kernel."""
    return cost_rows(q, q_next, delta, v_ref, dt, indptr, indices, 0, q.shape[0])


@leaf
def cost_rows(q, q_next, delta, v_ref, dt, indptr, indices, lo, hi):
    """The terms of :func:`control_cost` of the UAVs ``lo .. hi - 1``, summed in order (a
    block of a large swarm; the law's one writing)."""
    total = 0.0
    for m in range(lo, hi):
        for j in range(indptr[m], indptr[m + 1]):
            p = indices[j]
            ex = q[m, 0] - q[p, 0] - (delta[m, 0] - delta[p, 0])
            ey = q[m, 1] - q[p, 1] - (delta[m, 1] - delta[p, 1])
            total += ex * ex + ey * ey
        wx = (q_next[m, 0] - q[m, 0]) / dt - v_ref[0]
        wy = (q_next[m, 1] - q[m, 1]) / dt - v_ref[1]
        total += wx * wx + wy * wy
    return total


# Batched drivers: loop over the flattened batch, one formation at a time.
@njit(cache=True)
def _consensus_batch(v, v_ref, leader, indptr, indices, gamma, out):
    for b in range(v.shape[0]):
        consensus_update(v[b], v_ref[b], leader, indptr, indices, gamma, out[b])


@njit(cache=True)
def _formation_batch(q, delta, eta, eps, indptr, indices, out):
    for b in range(q.shape[0]):
        formation_update(q[b], delta, eta[b], eps, indptr, indices, out[b])


@njit(cache=True)
def _repulsion_batch(q, rects, circles, gain, l_safe, max_step, out):
    for b in range(q.shape[0]):
        fx, fy = repulsion_at(q[b, 0], q[b, 1], rects, circles, gain, l_safe, max_step)
        out[b, 0] = fx
        out[b, 1] = fy


@njit(cache=True)
def _reference_batch(
    q, goal, c, tv, gain, cruise, rects, circles, e_r, l_safe, footprint, dt, out
):
    for b in range(q.shape[0]):
        vx, vy = reference_velocity(
            q[b, 0], q[b, 1], goal[b, 0], goal[b, 1], c[b, 0], c[b, 1], gain, cruise,
            tv[b, 0], tv[b, 1], rects, circles, e_r, l_safe, footprint, dt,
        )  # fmt: skip
        out[b, 0] = vx
        out[b, 1] = vy


@njit(cache=True)
def _eta_goal_batch(c, s, radius, rects, circles, index, margin, lookahead, n_samples, eta_min,
                    out):  # fmt: skip
    for b in range(c.shape[0]):
        out[b] = eta_goal(c[b, 0], c[b, 1], s[b, 0], s[b, 1], radius, rects, circles, index,
                          margin, lookahead, n_samples, eta_min)  # fmt: skip


@njit(cache=True)
def _eta_rate_limit_batch(eta, goal, max_step, out):
    for b in range(eta.shape[0]):
        out[b] = eta_rate_limit(eta[b], goal[b], max_step)


@njit(cache=True)
def _cost_batch(q, q_next, delta, v_ref, dt, indptr, indices, out):
    for b in range(q.shape[0]):
        out[b] = control_cost(q[b], q_next[b], delta, v_ref[b], dt, indptr, indices)


# ---------------------------------------------------------------------------------------
# Public pure functions (any batch shape, inputs never modified)
# ---------------------------------------------------------------------------------------
def _flat(arr: np.ndarray, batch: tuple[int, ...], tail: tuple[int, ...]) -> np.ndarray:
    """Broadcast ``arr`` to ``batch + tail`` and flatten the batch: a C-contiguous copy."""
    return np.ascontiguousarray(np.broadcast_to(arr, (*batch, *tail))).reshape(-1, *tail)


#: The reason of the error when a gain makes a law's output overflow.
_TOO_LARGE = "{} so large that the output overflows"


def _check_size(batch: tuple[int, ...], n: int, name: str) -> None:
    """Refuse, before allocating, a batch whose arrays would not fit in memory."""
    size = float(np.prod(batch, dtype=float)) * n
    _v.check_elements(2.0 * size, name, f"{size:.3g} UAV rows", copies=4)


def _overflow(out: np.ndarray, gain: str, *inputs: tuple[str, np.ndarray]) -> None:
    """Refuse a law's output that overflowed, naming the input beyond the model's range
    that caused it, or else the gain."""
    if np.all(np.isfinite(out)):
        return
    for name, arr in inputs:
        if arr.size and np.max(np.abs(arr)) > _v.MAX_COORDINATE:
            _v.finite_result(out, name, "so large that the output overflows")
    _v.finite_result(out, "gains", _TOO_LARGE.format(gain))


def _formation_arrays(q: ArrayLike, name: str, adjacency: Adjacency) -> np.ndarray:
    if not isinstance(adjacency, Adjacency):
        raise FieldError(
            "adjacency", f"expected a crlbswarm.Adjacency, got {type(adjacency).__name__}"
        )
    arr = _v.positions(q, name)
    if arr.shape[-2] != adjacency.n_nodes:
        raise FieldError(
            f"{name}", f"has {arr.shape[-2]} UAVs but the graph has {adjacency.n_nodes} nodes"
        )
    return arr


def _slot_offsets(delta: ArrayLike, adjacency: Adjacency) -> np.ndarray:
    d = _formation_arrays(delta, "delta", adjacency)
    if d.ndim != 2:
        raise FieldError("delta", f"expected shape (M, 2), got {d.shape}")
    return np.ascontiguousarray(d)


def _scale(eta: ArrayLike, name: str) -> np.ndarray:
    e = _v.finite(eta, name)
    if np.any((e <= 0) | (e > 1)):
        raise FieldError(name, f"must lie in (0, 1], got {_v.short(eta)}")
    return e


def _check_leader(leader: int, n: int) -> int:
    lead = _v.count(leader, "leader", 0)
    if lead >= n:
        raise FieldError("leader", f"must be a UAV index below {n}, got {lead}")
    return lead


def consensus_step(
    velocities: ArrayLike,
    v_ref: ArrayLike,
    adjacency: Adjacency,
    leader: int,
    gains: ControlGains = _DEFAULT_GAINS,
) -> np.ndarray:
    r"""One step of the corrected leader-follower velocity consensus, eq. (14).

    .. math::
        \mathbf v_{m,k+1} = \mathbf v_{m,k} - \gamma\Bigl[\sum_{p\in\mathcal N_m\setminus\{1\}}
        a_{mp}(\mathbf v_{m,k} - \mathbf v_{p,k}) + a_{m1}(\mathbf v_{m,k} - \mathbf v^*_k)\Bigr]

    The paper's printed update lacks :math:`\mathbf v_{m,k}` on the right and flips the sign
    of the leader term; this is the standard convergent form.

    Parameters
    ----------
    velocities : array_like, shape (..., M, 2)
        Velocity estimates :math:`\mathbf v_{m,k}`, m/s. The leader's row is ignored.
    v_ref : array_like, shape (..., 2)
        Leader's reference velocity :math:`\mathbf v^*_k`, m/s.
    adjacency : Adjacency
        Communication graph.
    leader : int
        Index of the leader.
    gains : ControlGains, optional
        Its ``gamma`` is the consensus step (stable iff below
        :func:`crlbswarm.consensus_step_limit`; ``"auto"`` is resolved on ``adjacency``).

    Returns
    -------
    ndarray, shape (..., M, 2)
        :math:`\mathbf v_{m,k+1}`; the leader's row is :math:`\mathbf v^*_k`.
    """
    v = _formation_arrays(velocities, "velocities", adjacency)
    ref = _v.point(v_ref, "v_ref")
    lead = _check_leader(leader, adjacency.n_nodes)
    gamma = float(_check_gains(gains).resolve(adjacency, lead).gamma)
    shape = _v.broadcast("v_ref", v.shape[:-2], ref.shape[:-1])
    _check_size(shape, v.shape[-2], "velocities")
    vb = _flat(v, shape, v.shape[-2:]).copy()
    rb = _flat(ref, shape, (2,))
    vb[:, lead] = rb  # the leader's velocity as its neighbours read it: v*
    out = np.empty_like(vb)
    _consensus_batch(vb, rb, lead, adjacency.indptr, adjacency.indices, gamma, out)
    _overflow(out, "gamma", ("velocities", v), ("v_ref", ref))
    return out.reshape(*shape, *v.shape[-2:])


def leader_guidance(
    leader_xy: ArrayLike,
    goal_xy: ArrayLike,
    gains: ControlGains = _DEFAULT_GAINS,
    *,
    center_xy: ArrayLike | None = None,
    goal_velocity: ArrayLike = (0.0, 0.0),
    footprint: float = 0.0,
    obstacles: Obstacles | None = None,
    dt: float = 0.1,
) -> np.ndarray:
    r"""Leader's reference velocity :math:`\mathbf v^*_k` (not in the paper).

    .. math::
        \mathbf v^* = \operatorname{sat}_{v_c}\bigl(\dot{\mathbf g} + k_g(\mathbf g -
        \mathbf q_1) + \mathbf u^r(\mathbf c;\, \rho)/\Delta T\bigr),
        \qquad \operatorname{sat}_{v_c}(\mathbf w) = \mathbf w\,\min(1, v_c/\lVert\mathbf w
        \rVert)

    Proportional guidance toward the goal :math:`\mathbf g` (the leader's slot over the
    target) with the goal's own velocity :math:`\dot{\mathbf g}` as feedforward (zero for a
    static target), saturated at the cruise speed, so that it decays to zero as the
    formation settles over a static target. With ``footprint`` :math:`\rho > 0` the leader
    also steers the whole formation: :math:`\mathbf u^r(\mathbf c; \rho)` is the repulsion
    of eq. (18) felt by a disc of radius :math:`\rho` (the formation, :math:`\eta_k r^*`)
    centred at the formation centre :math:`\mathbf c`, i.e. eq. (18) with every distance
    reduced by :math:`\rho`. This keeps the formation centred in a passage instead of
    letting the walls squeeze it.

    Parameters
    ----------
    leader_xy : array_like, shape (..., 2)
        Leader position :math:`\mathbf q_1`, m.
    goal_xy : array_like, shape (..., 2)
        Goal :math:`\mathbf g`, m.
    gains : ControlGains, optional
        Its ``guidance_gain`` :math:`k_g` (1/s), ``cruise_speed`` :math:`v_c` (m/s), and
        for the steering term ``repulsion_gain`` :math:`E_r` and ``safety_radius``
        :math:`l_\text{safe}`.
    center_xy : array_like, shape (..., 2), optional
        Formation centre :math:`\mathbf c` (needed when ``footprint > 0``), m.
    goal_velocity : array_like, shape (..., 2), default (0, 0)
        Velocity of the goal :math:`\dot{\mathbf g}` (the target's), m/s.
    footprint : float, default 0
        Radius :math:`\rho` of the formation's disc, m; 0 turns steering off, and so does
        ``gains.formation_steering = False`` (as in a mission).
    obstacles : Obstacles, optional
        Obstacles for the steering term.
    dt : float, default 0.1
        Time step :math:`\Delta T`, s (turns the repulsive step into a velocity).

    Returns
    -------
    ndarray, shape (..., 2)
        :math:`\mathbf v^*`, m/s.

    Raises
    ------
    FieldError
        On positions beyond +-1e7 m, velocities beyond +-1e6 m/s, a footprint outside
        [0, 3e7] m, or gains so large that the velocity overflows before the saturation
        (field ``gains``).
    """
    q = _v.location(leader_xy, "leader_xy")
    goal = _v.location(goal_xy, "goal_xy")
    gains = _check_gains(gains)
    rho = _v.scalar(footprint, "footprint")
    if not 0 <= rho <= _v.MAX_DISTANCE:
        raise FieldError(
            "footprint", f"must be between 0 and {_v.MAX_DISTANCE:g} m (the model's range), "
            f"got {rho:g}"
        )  # fmt: skip
    obs = check_obstacles(obstacles) if obstacles is not None else Obstacles()
    c = q if center_xy is None else _v.location(center_xy, "center_xy")
    if rho > 0 and gains.formation_steering and (center_xy is None or obstacles is None):
        raise FieldError("footprint", "steering needs center_xy and obstacles")
    step = _v.positive_scalar(dt, "dt")
    tv = _v.velocity(goal_velocity, "goal_velocity")
    shape = _v.broadcast("goal_xy", q.shape, goal.shape)
    shape = _v.broadcast("center_xy", shape, c.shape)
    shape = _v.broadcast("goal_velocity", shape, tv.shape)
    _check_size(shape[:-1], 1, "leader_xy")
    out = np.empty((int(np.prod(shape[:-1], dtype=int)), 2))
    _reference_batch(
        _flat(q, shape[:-1], (2,)), _flat(goal, shape[:-1], (2,)), _flat(c, shape[:-1], (2,)),
        _flat(tv, shape[:-1], (2,)), gains.guidance_gain, gains.cruise_speed, obs.rectangles,
        obs.circles, gains.repulsion_gain, gains.safety_radius,
        rho if gains.formation_steering else 0.0,
        step, out,
    )  # fmt: skip
    _v.finite_result(
        out, "gains", "guidance_gain (or repulsion_gain / dt) so large that the velocity overflows"
    )
    return out.reshape(shape)


def formation_input(
    positions: ArrayLike,
    delta: ArrayLike,
    eta: ArrayLike,
    adjacency: Adjacency,
    gains: ControlGains = _DEFAULT_GAINS,
) -> np.ndarray:
    r"""Displacement-based formation input without repulsion, eqs. (16) and (19).

    .. math::
        \mathbf u_{m,k} = -\varepsilon \sum_p a_{mp}
        (\mathbf q_{m,k} - \mathbf q_{p,k} - \eta_k \boldsymbol\delta_{pm}),
        \qquad \boldsymbol\delta_{pm} = \boldsymbol\delta_m - \boldsymbol\delta_p

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        UAV positions :math:`\mathbf q_{m,k}`, m.
    delta : array_like, shape (M, 2)
        Slot offsets :math:`\boldsymbol\delta_m` of the desired formation (for example
        :math:`F^*` minus its centre), m.
    eta : float or array_like, shape (...)
        Scaling factor :math:`\eta_k \in (0, 1]`.
    adjacency : Adjacency
        Communication graph.
    gains : ControlGains, optional
        Its ``epsilon`` is the per-step gain :math:`\varepsilon` (stable iff below
        :func:`crlbswarm.formation_step_limit`; ``"auto"`` is resolved on ``adjacency``).

    Returns
    -------
    ndarray, shape (..., M, 2)
        Position increment per step, m.
    """
    q = _formation_arrays(positions, "positions", adjacency)
    d = _slot_offsets(delta, adjacency)
    e = _scale(eta, "eta")
    eps = float(_check_gains(gains).resolve(adjacency, 0).epsilon)
    shape = _v.broadcast("eta", q.shape[:-2], e.shape)
    _check_size(shape, q.shape[-2], "positions")
    qb = _flat(q, shape, q.shape[-2:])
    eb = _flat(e, shape, ())
    out = np.empty_like(qb)
    _formation_batch(
        qb, np.ascontiguousarray(d), eb, eps, adjacency.indptr, adjacency.indices, out
    )
    _overflow(out, "epsilon", ("positions", q), ("delta", d))
    return out.reshape(*shape, *q.shape[-2:])


def repulsion(
    positions: ArrayLike, obstacles: Obstacles, gains: ControlGains = _DEFAULT_GAINS
) -> np.ndarray:
    r"""Repulsive input :math:`\mathbf u^r`, eq. (18), summed over nearby obstacles.

    .. math::
        \mathbf u^r = \sum_{o:\, l_o < l_\text{safe}} E_r \Bigl(\frac{1}{l_o} -
        \frac{1}{l_\text{safe}}\Bigr) \frac{1}{l_o^2}\, \frac{\vec{\mathbf l}_o}{l_o}

    with :math:`\vec{\mathbf l}_o` from the nearest point of obstacle :math:`o` to the UAV.
    Not in the paper: the sum is capped at ``repulsion_max_step`` metres.

    Parameters
    ----------
    positions : array_like, shape (..., 2)
        UAV positions, m.
    obstacles : Obstacles
        Rectangles and circles.
    gains : ControlGains, optional
        Its ``repulsion_gain`` :math:`E_r` (m^4 per step, so that :math:`\mathbf u^r` is
        in metres), ``safety_radius`` :math:`l_\text{safe}` (m) and
        ``repulsion_max_step``, the cap on the length of :math:`\mathbf u^r` (m).

    Returns
    -------
    ndarray, shape (..., 2)
        Position increment per step, m.
    """
    q = _v.location(positions, "positions")
    gains = _check_gains(gains)
    qb = np.ascontiguousarray(q).reshape(-1, 2)
    out = np.empty_like(qb)
    obs = check_obstacles(obstacles)
    _repulsion_batch(
        qb, obs.rectangles, obs.circles, gains.repulsion_gain, gains.safety_radius,
        gains.repulsion_max_step, out,
    )  # fmt: skip
    _v.finite_result(out, "gains", _TOO_LARGE.format("repulsion_gain"))
    return out.reshape(q.shape)


def eta_target(
    center_xy: ArrayLike,
    target_xy: ArrayLike,
    obstacles: Obstacles,
    radius: float,
    rule: EtaRule,
    gains: ControlGains = _DEFAULT_GAINS,
) -> np.ndarray:
    r"""Desired scaling factor from the free width ahead of the formation (not in the paper).

    The paper says only that :math:`\eta_k` "is adaptively reduced when the formation centre
    approaches spatial bottlenecks". crlbswarm samples ``rule.samples`` points on the segment
    from ``radius`` behind the formation centre :math:`\mathbf c` to ``rule.lookahead``
    ahead of it, toward the target. At each point it takes the largest obstacle clearance
    across the path within :math:`\pm R` (``LATERAL_SAMPLES`` = 9 points, spacing
    :math:`R/4`): the half-width of the corridor's cross-section there, since the repulsion
    and the leader's steering centre the formation in a passage (the sampling errs on the
    safe side: it can miss the widest point by up to :math:`R/8`, so the formation shrinks
    slightly more than needed). The smallest of these along the path is the free half-width
    :math:`w` of the corridor the formation is about to use, and the rule asks for the scale
    at which a formation of nominal radius :math:`R` keeps the margin (``rule.margin``, or
    the safety radius) from every obstacle:

    .. math:: \eta^\text{goal} = \operatorname{clip}\bigl((w - \text{margin})/R,\;
              \eta_\min,\; 1\bigr).

    Looking behind keeps :math:`\eta` low until the rear of the formation has cleared the
    bottleneck; looking ahead lets the shape (time constant :math:`1/(\varepsilon\lambda_2)`)
    shrink before the centre arrives. At the target the direction of travel is undefined, so
    the goal is blended to 1 there:

    .. math:: \eta^\text{goal} \leftarrow \eta^\text{goal} + (1 - \eta^\text{goal})\,
              \bigl(1 - \beta(\lVert\mathbf c - \mathbf s\rVert)\bigr),

    with :math:`\beta` the smoothstep from 0 at ``HOVER_INNER`` :math:`R` to 1 at ``HOVER_OUTER``
    :math:`R`. The result is continuous in :math:`\mathbf c` everywhere, and exactly 1 while
    the formation hovers over the target (whose slots the scenario checks are clear);
    :func:`eta_update` rate-limits it.

    Parameters
    ----------
    center_xy : array_like, shape (..., 2)
        Formation centre, m.
    target_xy : array_like, shape (..., 2)
        Target (the direction of travel), m.
    obstacles : Obstacles
        Rectangles and circles.
    radius : float
        Nominal formation radius :math:`R` (at :math:`\eta = 1`), m.
    rule : EtaRule
        Its ``margin`` (clearance to keep, m), ``lookahead`` (m), ``minimum``
        (:math:`\eta_\min`) and ``samples`` (points along the segment); with
        ``enabled = False`` the goal is 1 everywhere, as in a mission.
    gains : ControlGains, optional
        Its ``safety_radius`` is the margin when ``rule.margin`` is not set.

    Returns
    -------
    ndarray, shape (...)
        :math:`\eta^\text{goal} \in [\eta_\min, 1]`.
    """
    c = _v.location(center_xy, "center_xy")
    s = _v.location(target_xy, "target_xy")
    shape = _v.broadcast("target_xy", c.shape, s.shape)
    r = float(_v.length(_v.scalar(radius, "radius"), "radius"))
    rl = _check_rule(rule)
    mrg = rl.margin_for(_check_gains(gains))
    obs = check_obstacles(obstacles)
    if not rl.enabled:
        return np.ones(shape[:-1])
    _check_size(shape[:-1], 1, "center_xy")
    cb = _flat(c, shape[:-1], (2,))
    sb = _flat(s, shape[:-1], (2,))
    out = np.empty(cb.shape[0])
    index = obstacle_index(obs.rectangles, obs.circles, 0.0)
    _eta_goal_batch(cb, sb, r, obs.rectangles, obs.circles, index, mrg, rl.lookahead,
                    rl.samples, rl.minimum, out)  # fmt: skip
    return out.reshape(shape[:-1])


def eta_update(eta: ArrayLike, goal: ArrayLike, rule: EtaRule, dt: float) -> np.ndarray:
    r"""Rate-limited step of :math:`\eta` toward its goal (not in the paper).

    :math:`\eta_{k+1} = \eta_k + \operatorname{clip}(\eta^\text{goal}_k - \eta_k,
    -\rho\,\Delta T, \rho\,\Delta T)`: smooth, and back to 1 after the bottleneck.

    Parameters
    ----------
    eta : float or array_like
        Current scale :math:`\eta_k`.
    goal : float or array_like
        Desired scale from :func:`eta_target`.
    rule : EtaRule
        Its ``rate`` is the largest change per second :math:`\rho`, 1/s; with
        ``enabled = False`` the result is 1, as in a mission.
    dt : float
        Time step :math:`\Delta T`, s.

    Returns
    -------
    ndarray
        :math:`\eta_{k+1}`.
    """
    e = _scale(eta, "eta")
    goal_eta = _scale(goal, "goal")
    rl = _check_rule(rule)
    step = rl.rate * _v.positive_scalar(dt, "dt")
    shape = _v.broadcast("goal", e.shape, goal_eta.shape)
    _check_size(shape, 1, "eta")
    if not rl.enabled:
        return np.ones(shape)
    out = np.empty(int(np.prod(shape, dtype=int)))
    _eta_rate_limit_batch(_flat(e, shape, ()), _flat(goal_eta, shape, ()), step, out)
    return out.reshape(shape)


def formation_cost(
    positions: ArrayLike,
    next_positions: ArrayLike,
    delta: ArrayLike,
    v_ref: ArrayLike,
    adjacency: Adjacency,
    dt: float,
) -> np.ndarray:
    r"""Total control cost :math:`\mathcal L_\text{tot} = \sum_m \mathcal L_m`, eq. (15).

    .. math::
        \mathcal L_\text{tot} = \sum_m \Bigl[\sum_p a_{mp}\lVert \mathbf q_{m,k} -
        \mathbf q_{p,k} - \boldsymbol\delta_{pm}\rVert^2 + \Bigl\lVert
        \frac{\mathbf q_{m,k+1} - \mathbf q_{m,k}}{\Delta T} - \mathbf v^*_k\Bigr\rVert^2\Bigr]

    The displacements are the nominal ones (:math:`\eta = 1`), as printed: shrinking the
    formation in a passage is a deviation from :math:`\mathbb F` and raises the cost.

    Parameters
    ----------
    positions : array_like, shape (..., M, 2)
        :math:`\mathbf q_{m,k}`, m.
    next_positions : array_like, shape (..., M, 2)
        :math:`\mathbf q_{m,k+1}`, m.
    delta : array_like, shape (M, 2)
        Slot offsets :math:`\boldsymbol\delta_m`, m.
    v_ref : array_like, shape (..., 2)
        Leader's reference velocity :math:`\mathbf v^*_k`, m/s.
    adjacency : Adjacency
        Communication graph.
    dt : float
        Time step, s.

    Returns
    -------
    ndarray, shape (...)
        :math:`\mathcal L_\text{tot}` (m^2 + m^2/s^2, summed as printed).
    """
    q = _formation_arrays(positions, "positions", adjacency)
    qn = _formation_arrays(next_positions, "next_positions", adjacency)
    d = _slot_offsets(delta, adjacency)
    ref = _v.velocity(v_ref, "v_ref")
    step = _v.positive_scalar(dt, "dt")
    shape = _v.broadcast("next_positions", q.shape[:-2], qn.shape[:-2], ref.shape[:-1])
    _check_size(shape, q.shape[-2], "positions")
    mshape = q.shape[-2:]
    qb = _flat(q, shape, mshape)
    qnb = _flat(qn, shape, mshape)
    rb = _flat(ref, shape, (2,))
    out = np.empty(qb.shape[0])
    with np.errstate(over="ignore"):
        _cost_batch(
            qb, qnb, np.ascontiguousarray(d), rb, step, adjacency.indptr, adjacency.indices, out
        )
    _v.finite_result(out, "dt", f"{step:g} s is so short that the cost overflows")
    return out.reshape(shape)
