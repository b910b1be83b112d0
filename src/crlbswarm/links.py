r"""Communication links: what each UAV knows of its neighbours (not in the paper).

The paper's controller is distributed: every law needs only the states of a UAV's
neighbours. Without a ``[links]`` table a mission assumes perfect links (every neighbour's
state of the step, instantly); with one, each UAV acts on the **last state it received**
from each neighbour, through a link model declared once, in :class:`LinksConfig`, and
run by the compiled kernels below. The choices (documented in ``docs/links.md``):

Messages
    Every ``period`` steps (:meth:`LinksConfig.period`, from ``rate``; at most every step,
    all UAVs at the steps ``k`` with ``k % period == 0``) each UAV broadcasts its state:
    position, consensus velocity (the leader's is its reference :math:`\mathbf v^*_k`),
    the scaling factor :math:`\eta` it knows and that value's stamp, and the step it was
    sent at. A message from ``p`` to ``m`` is *sent* when ``m`` is a candidate receiver of
    ``p`` (below) within ``range`` at the sending step; it is then lost with the loss
    probability, or received ``delay`` steps later (``delay`` .. ``delay_max``, uniform).
    A receiver keeps, per link, the newest message (the largest send step): a message
    overtaken by a newer one is dropped. So the age of what it uses is always known.
Neighbours
    Without ``range`` the candidates of ``m`` are its neighbours in the configured graph
    (``[graph]``), at any distance. With ``range`` they are those neighbours within
    ``range`` at the step (``use_graph = true``) or every UAV within ``range``
    (``use_graph = false``). At step ``k`` the laws of eqs. (14) and (19) of UAV ``m``
    sum over its candidates within range now from which it has received something, each
    at its last received state (:func:`crlbswarm.control.formation_rows`,
    :func:`crlbswarm.control.consensus_rows` with the received copies as their table).
    A UAV knows its own state exactly.
The leader's reference
    Its velocity :math:`\mathbf v^*_k` reaches its neighbours in its messages (the
    consensus carries it on). Its scaling factor :math:`\eta_k` is *broadcast*: every
    UAV is a candidate receiver of the leader's messages (a link of the same model, which
    carries only :math:`\eta` to a UAV that is not the leader's neighbour), and every
    message also carries the newest :math:`\eta` its sender knows, with its stamp (the
    step the leader computed it), so :math:`\eta` floods; each UAV flies the freshest
    :math:`\eta` it has received (1, the start, before any). The formation input of UAV
    ``m`` scales the slots by its own :math:`\eta`.
What is not communicated (stated assumptions)
    The leader's steering and the :math:`\eta` rule use the formation's true centroid
    (formation-wide quantities, as in the paper: the leader observes the swarm); the
    safety filter acts on sensed positions (the true positions of the UAVs within its
    sensing radius); the target filter in the loop stays formation-wide; the cost of
    eq. (15) is an observer's figure (true positions, the configured graph).
Draws
    From :mod:`crlbswarm.counter_rng`, stream :data:`~crlbswarm.counter_rng.LINKS`, keyed
    by the run's seed: the messages between UAVs ``a < b`` sent at step ``k`` take the
    block of the counter (k, a, LINKS, 4 b + kind), kind 0 for the loss, 1 for the delay
    and 2 for the Gilbert-Elliott transition, its first uniform for the message from ``a``
    to ``b`` and its second for the one from ``b`` to ``a`` (:func:`pair_draws`); only the
    kinds the model needs are drawn. A run's messages do not depend on its batch, and a
    link (p, m) has the same messages whether it is a graph link or a pair within range.
Loss models
    ``bernoulli``: each message lost independently with probability ``loss``.
    ``gilbert`` (Gilbert-Elliott): each link has a channel state, good or bad, that
    changes once per message (to bad with probability ``p_good_bad``, back with
    ``p_bad_good``; the first message draws it from the stationary distribution), and
    a message is lost with probability ``loss_good`` or ``loss_bad`` of its state: the
    bad state lasts ``1 / p_bad_good`` messages on average.
Memory
    Per run: the last ``delay_max + 1`` broadcast states of each UAV, and per link its
    received copy, its pending arrivals (``delay_max + 1`` stamps) and its channel state,
    allocated once (:func:`link_state`): memory does not grow with the mission's length.

Metrics (:class:`crlbswarm.MissionResult`): per step the messages sent and delivered, the
mean and largest age of the states the laws use, and whether the *communication graph* is
connected: the undirected graph of the links in use whose last message is at most
``timeout`` old. Failures (a UAV that stops sending, detected by that silence) are not
modelled yet; the timeout is already the silence after which a link is stale.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
from numba import njit, types
from numba.extending import overload
from pydantic import Field, model_validator

from . import _validation as _v
from ._config import ConfigModel, PositiveFloat
from ._numba import leaf
from .counter_rng import LINKS, stream_key, uniform_pair
from .errors import FieldError
from .graphs import Adjacency

__all__ = [
    "CHANNEL_DRAW",
    "DELAY_DRAW",
    "LINK_SERIES",
    "LOSS_DRAW",
    "LOSS_MODELS",
    "MAX_ALL_PAIRS_UAVS",
    "MAX_DELAY",
    "LinkModel",
    "LinkState",
    "LinksConfig",
    "all_pairs_adjacency",
    "broadcast",
    "candidate_links",
    "check_links",
    "connected_fresh",
    "draw_messages",
    "exchange",
    "link_model",
    "link_pairs",
    "link_series",
    "link_state",
    "link_state_bytes",
    "link_uniform",
    "message_fate",
    "message_fates",
    "neighbour_tables",
    "pair_draws",
    "receive",
]

#: Largest delay of a message, steps (each run keeps this many past states per UAV).
MAX_DELAY = 1000

#: Most UAVs of a mission whose range links every pair (``use_graph = false``): every
#: ordered pair is a candidate link, M (M - 1) of them.
MAX_ALL_PAIRS_UAVS = 1000

#: The loss models.
LOSS_MODELS = ("bernoulli", "gilbert")

#: The per-step series of a mission with links (``MissionResult.link_<name>``).
LINK_SERIES = ("sent", "delivered", "age", "age_max", "connected")

Probability = Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)]
Steps = Annotated[int, Field(ge=0, le=MAX_DELAY)]

#: The fields of the Gilbert-Elliott model (refused with ``loss_model = "bernoulli"``).
_GILBERT = ("p_good_bad", "p_bad_good", "loss_good", "loss_bad")


class LinksConfig(ConfigModel):
    """The communication links of a mission: the scenario's ``[links]`` table (none: perfect
    links). Each field is declared once below, with its unit; the model is described in the
    module docstring and ``docs/links.md``.
    """

    range: PositiveFloat | None = Field(
        None, description="radio range, m: the neighbours are the UAVs within it, recomputed "
        "each step (none: every link of the graph, at any distance)",
    )  # fmt: skip
    use_graph: bool = Field(
        True, description="with range: true keeps the graph's links within range, false links "
        "every pair of UAVs within range",
    )  # fmt: skip
    loss: Probability = Field(0.0, description="bernoulli: probability that a message is lost")
    loss_model: Literal[LOSS_MODELS] = Field(  # type: ignore[valid-type]
        "bernoulli", description="bernoulli (independent losses) or gilbert (Gilbert-Elliott "
        "bursts)",
    )  # fmt: skip
    p_good_bad: Probability | None = Field(
        None, description="gilbert: probability per message that the channel turns bad"
    )
    p_bad_good: Probability | None = Field(
        None, description="gilbert: probability per message that it turns good again (the mean "
        "bad burst is 1/p_bad_good messages)",
    )  # fmt: skip
    loss_good: Probability | None = Field(
        None, description="gilbert: loss probability in the good state (default 0)"
    )
    loss_bad: Probability | None = Field(
        None, description="gilbert: loss probability in the bad state (default 1)"
    )
    delay: Steps = Field(
        0, description=f"steps from sending to receiving (with delay_max: the smallest; at most "
        f"{MAX_DELAY})",
    )  # fmt: skip
    delay_max: Steps | None = Field(
        None, description="largest delay, steps: each message's delay uniform in delay .. "
        "delay_max (none: fixed delay)",
    )  # fmt: skip
    rate: PositiveFloat | None = Field(
        None, description="messages per second of each UAV: one every round(1/(rate dT)) steps, "
        "at most every step (none: every step)",
    )  # fmt: skip
    timeout: PositiveFloat | None = Field(
        None, description="a link whose last message is older than this is stale, s (not in "
        "the communication graph); default (2 send periods + delay_max) dT",
    )  # fmt: skip

    @model_validator(mode="after")
    def _consistent(self) -> LinksConfig:
        if not self.use_graph and self.range is None:
            raise FieldError("links.use_graph", "false needs links.range (the pairs within it)")
        if self.delay_max is not None and self.delay_max < self.delay:
            raise FieldError(
                "links.delay_max", f"{self.delay_max} is below links.delay = {self.delay}"
            )
        if self.loss_model == "bernoulli":
            for name in _GILBERT:
                if getattr(self, name) is not None:
                    raise FieldError(f"links.{name}", "applies to loss_model 'gilbert' only")
        else:
            if "loss" in self.model_fields_set:
                raise FieldError(
                    "links.loss", "does not apply to loss_model 'gilbert' (loss_good, loss_bad)"
                )
            for name in ("p_good_bad", "p_bad_good"):
                value = getattr(self, name)
                if value is None or value == 0.0:
                    raise FieldError(f"links.{name}", "loss_model 'gilbert' needs a value > 0")
        return self

    def period(self, dt: float) -> int:
        """Steps between two messages of a UAV: ``round(1 / (rate dT))``, at least 1.

        Parameters
        ----------
        dt : float
            The time step, s.

        Returns
        -------
        int
            The send period, steps (1 without ``rate``).
        """
        if self.rate is None:
            return 1
        return max(1, round(1.0 / (self.rate * dt)))

    @property
    def largest_delay(self) -> int:
        """The largest delay of a message, steps (``delay_max``, or the fixed ``delay``)."""
        return self.delay if self.delay_max is None else self.delay_max

    def timeout_steps(self, dt: float) -> int:
        """Age in steps beyond which a link is stale: ``timeout`` (rounded down), or two
        send periods plus the largest delay.

        Parameters
        ----------
        dt : float
            The time step, s.

        Returns
        -------
        int
            Steps.
        """
        if self.timeout is None:
            return 2 * self.period(dt) + self.largest_delay
        return math.floor(self.timeout / dt + 1e-9)


def all_pairs_adjacency(n_uavs: int) -> Adjacency:
    """The complete graph on ``n_uavs`` UAVs as CSR (the candidate links of a range without
    the graph, on which its ``"auto"`` gains are resolved and its gains checked).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs M >= 2.

    Returns
    -------
    Adjacency
        Row ``m`` lists every other UAV in increasing order.

    Examples
    --------
    >>> all_pairs_adjacency(3).indices.tolist()
    [1, 2, 0, 2, 0, 1]
    """
    n = _v.count(n_uavs, "n_uavs", 2, MAX_ALL_PAIRS_UAVS)
    grid = np.broadcast_to(np.arange(n, dtype=np.int64), (n, n))
    indices = grid[~np.eye(n, dtype=bool)]
    return Adjacency(np.arange(n + 1, dtype=np.int64) * (n - 1), np.ascontiguousarray(indices))


def check_links(links: LinksConfig, n_uavs: int, dt: float, gains: Any) -> None:
    """The checks of a ``[links]`` table against its scenario (called by its validation).

    Parameters
    ----------
    links : LinksConfig
        The table.
    n_uavs : int
        Number of UAVs.
    dt : float
        The time step, s.
    gains : ControlGains
        The resolved gains (numbers, not ``"auto"``).

    Raises
    ------
    FieldError
        Naming the field: a timeout shorter than a send period plus the largest delay
        (even a perfect link would go stale), too many UAVs for links between every pair,
        or gains unstable when every pair may be linked.
    """
    period, largest = links.period(dt), links.largest_delay
    if links.timeout is not None and links.timeout_steps(dt) < period + largest:
        raise FieldError(
            "links.timeout", f"{links.timeout:g} s is shorter than a send period plus the "
            f"largest delay, {(period + largest) * dt:g} s: even a perfect link would go stale",
        )  # fmt: skip
    if links.use_graph:
        return
    if n_uavs > MAX_ALL_PAIRS_UAVS:
        raise FieldError(
            "links.use_graph", f"false links every pair: at most {MAX_ALL_PAIRS_UAVS} UAVs "
            f"(uavs.count is {n_uavs}); keep the graph (true)",
        )  # fmt: skip
    eps, gamma = float(gains.epsilon), float(gains.gamma)
    if eps * n_uavs >= 2.0 * (1.0 - 1e-12):  # lambda_max of the complete graph's Laplacian: M
        raise FieldError(
            "control.epsilon", f"{eps:g} is unstable when every pair is linked "
            f"(links.use_graph = false): it must be < 2/M = {2.0 / n_uavs:.4g}",
        )  # fmt: skip
    if gamma * (n_uavs - 1) >= 1.0:
        raise FieldError(
            "control.gamma", f"{gamma:g} is too large when every pair is linked "
            f"(links.use_graph = false): it must be < 1/(M - 1) = {1.0 / (n_uavs - 1):.4g}",
        )  # fmt: skip


def candidate_links(
    adjacency: Adjacency, leader: int, use_graph: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The candidate links, as CSR by receiver: who may hear whom.

    Parameters
    ----------
    adjacency : Adjacency
        The configured graph.
    leader : int
        The leader (every UAV hears its broadcast).
    use_graph : bool
        True: the graph's links (each row in the graph's order), and the leader for a UAV
        that is not its neighbour (its :math:`\\eta` only); False: every other UAV.

    Returns
    -------
    indptr : ndarray of int64, shape (M+1,)
        Row pointers: the links of receiver ``m`` are ``indptr[m] .. indptr[m+1] - 1``.
    senders : ndarray of int64, shape (E,)
        The sender of each link.
    law : ndarray of bool, shape (E,)
        Whether the laws use the link (False: the leader's :math:`\\eta` only).

    Examples
    --------
    >>> from crlbswarm.graphs import ring_adjacency
    >>> ptr, senders, law = candidate_links(ring_adjacency(5), 0, True)
    >>> senders[ptr[2] : ptr[3]].tolist(), law[ptr[2] : ptr[3]].tolist()
    ([1, 3, 0], [True, True, False])
    """
    graph = adjacency if use_graph else all_pairs_adjacency(adjacency.n_nodes)
    n, ptr, idx = graph.n_nodes, graph.indptr, graph.indices
    degree = np.diff(ptr)
    hears = np.zeros(n, dtype=bool)  # the leader's neighbours (the graph is undirected)
    hears[idx[ptr[leader] : ptr[leader + 1]]] = True
    extra = (np.arange(n) != leader) & ~hears  # one more link: the leader's eta
    indptr = np.concatenate([[0], np.cumsum(degree + extra)]).astype(np.int64)
    senders = np.empty(indptr[-1], dtype=np.int64)
    law = np.ones(indptr[-1], dtype=bool)
    before = np.concatenate([[0], np.cumsum(extra)[:-1]])  # extra links of the rows before
    senders[np.arange(idx.size) + np.repeat(before, degree)] = idx
    last = indptr[1:][extra] - 1
    senders[last] = leader
    law[last] = False
    return indptr, senders, law


class LinkModel(NamedTuple):
    """The link model as the compiled mission receives it (:func:`link_model`).

    Parameters
    ----------
    period : int
        Steps between two messages of a UAV.
    depth : int
        ``delay_max + 1``: the past states kept per UAV, the pending slots per link.
    delay : int
        Smallest delay, steps.
    span : int
        Number of possible delays, ``delay_max - delay + 1``.
    range2 : float
        The range squared, m^2 (inf without range).
    loss : float
        Loss probability (``bernoulli``).
    gilbert : bool
        Whether the Gilbert-Elliott model is on.
    p_good_bad : float
        Its probability of turning bad, per message.
    p_bad_good : float
        Its probability of turning good.
    pi_bad : float
        Its stationary probability of the bad state, ``p_good_bad / (p_good_bad +
        p_bad_good)`` (the first message's state).
    loss_good : float
        Loss probability in the good state.
    loss_bad : float
        Loss probability in the bad state.
    stale : int
        Age, steps, beyond which a link is stale (:meth:`LinksConfig.timeout_steps`).
    law_links : int
        How many candidate links the laws may use (the communication graph is then whole).
    dt : float
        The time step, s (ages in seconds).
    indptr : ndarray of int64, shape (M+1,)
        The candidate links by receiver (:func:`candidate_links`).
    senders : ndarray of int64, shape (E,)
        Their senders.
    law : ndarray of bool, shape (E,)
        Whether the laws use them.
    pair_lo : ndarray of int64, shape (P,)
        The pairs of UAVs linked in at least one direction: the lower UAV
        (:func:`pair_draws`).
    pair_hi : ndarray of int64, shape (P,)
        The higher UAV.
    pair_fwd : ndarray of int64, shape (P,)
        The link from the lower to the higher, -1 if it is not a candidate.
    pair_back : ndarray of int64, shape (P,)
        The link from the higher to the lower, or -1.
    """

    period: int
    depth: int
    delay: int
    span: int
    range2: float
    loss: float
    gilbert: bool
    p_good_bad: float
    p_bad_good: float
    pi_bad: float
    loss_good: float
    loss_bad: float
    stale: int
    law_links: int
    dt: float
    indptr: np.ndarray
    senders: np.ndarray
    law: np.ndarray
    pair_lo: np.ndarray
    pair_hi: np.ndarray
    pair_fwd: np.ndarray
    pair_back: np.ndarray


def link_pairs(
    indptr: np.ndarray, senders: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of UAVs of the candidate links, each with its links in both directions.

    Parameters
    ----------
    indptr : ndarray of int64, shape (M+1,)
        The candidate links by receiver (:func:`candidate_links`).
    senders : ndarray of int64, shape (E,)
        Their senders.

    Returns
    -------
    lo, hi, fwd, back : ndarray of int64, shape (P,)
        For each pair ``lo < hi`` (in increasing order): the link from ``lo`` to ``hi``
        and the link from ``hi`` to ``lo`` (-1 when not a candidate).

    Examples
    --------
    >>> lo, hi, fwd, back = link_pairs(np.array([0, 2, 3, 4]), np.array([1, 2, 0, 0]))
    >>> lo.tolist(), hi.tolist(), fwd.tolist(), back.tolist()
    ([0, 0], [1, 2], [2, 3], [0, 1])
    """
    receivers = np.repeat(np.arange(indptr.size - 1, dtype=np.int64), np.diff(indptr))
    lo, hi = np.minimum(senders, receivers), np.maximum(senders, receivers)
    key = lo * (indptr.size - 1) + hi
    pairs, first = np.unique(key, return_inverse=True)
    fwd = np.full(pairs.size, -1, np.int64)
    back = np.full(pairs.size, -1, np.int64)
    links = np.arange(senders.size, dtype=np.int64)
    forward = senders < receivers
    fwd[first[forward]] = links[forward]
    back[first[~forward]] = links[~forward]
    n = indptr.size - 1
    return pairs // n, pairs % n, fwd, back


def link_model(links: LinksConfig, adjacency: Adjacency, leader: int, dt: float) -> LinkModel:
    """The compiled mission's link model of a ``[links]`` table.

    Parameters
    ----------
    links : LinksConfig
        The table.
    adjacency : Adjacency
        The configured graph.
    leader : int
        The leader.
    dt : float
        The time step, s.

    Returns
    -------
    LinkModel
        Scalars and candidate links.
    """
    indptr, senders, law = candidate_links(adjacency, leader, links.use_graph)
    pair_lo, pair_hi, pair_fwd, pair_back = link_pairs(indptr, senders)
    gilbert = links.loss_model == "gilbert"
    p_gb = float(links.p_good_bad or 0.0)
    p_bg = float(links.p_bad_good or 0.0)
    return LinkModel(
        period=links.period(dt), depth=links.largest_delay + 1, delay=links.delay,
        span=links.largest_delay - links.delay + 1,
        range2=math.inf if links.range is None else float(links.range) ** 2,
        loss=float(links.loss), gilbert=gilbert, p_good_bad=p_gb, p_bad_good=p_bg,
        pi_bad=p_gb / (p_gb + p_bg) if gilbert else 0.0,
        loss_good=float(0.0 if links.loss_good is None else links.loss_good),
        loss_bad=float(1.0 if links.loss_bad is None else links.loss_bad),
        stale=links.timeout_steps(dt), law_links=int(law.sum()), dt=float(dt), indptr=indptr,
        senders=senders, law=law, pair_lo=pair_lo, pair_hi=pair_hi, pair_fwd=pair_fwd,
        pair_back=pair_back,
    )  # fmt: skip


def link_state_bytes(model: LinkModel) -> int:
    """Bytes of one run's link state (:func:`link_state`).

    Parameters
    ----------
    model : LinkModel
        The model.

    Returns
    -------
    int
        Bytes.
    """
    m_uavs, n_links = model.indptr.shape[0] - 1, model.senders.shape[0]
    return 8 * (model.depth * m_uavs * 6 + 4 * m_uavs + 3) + n_links * (8 * model.depth + 81)


class LinkState(NamedTuple):
    """One run's link state, allocated once (:func:`link_state`); M UAVs, E links, D the
    largest delay.

    Parameters
    ----------
    history : ndarray, shape (D+1, M, 6)
        Each UAV's broadcast state at the last D+1 sending steps, in slot ``step % (D+1)``:
        x, y, vx, vy, its :math:`\\eta` and that value's stamp.
    pending : ndarray of int64, shape (E, D+1)
        Per link, the send step of the newest message arriving at each step (slot
        ``arrival % (D+1)``), -1 for none.
    recv_q : ndarray, shape (E, 2)
        Per link, the last received position, m.
    recv_v : ndarray, shape (E, 2)
        The last received velocity, m/s.
    stamp : ndarray of int64, shape (E,)
        The send step of the last received message, -1 before any.
    channel : ndarray of int8, shape (E,)
        The Gilbert-Elliott state: -1 before the first message, 0 good, 1 bad.
    tally : ndarray of int64, shape (2,)
        How many links the laws may use have received something; 1 once the links in use
        are all of them for good (no range): ``act_*`` is then not rebuilt.
    eta : ndarray, shape (M,)
        The :math:`\\eta` each UAV flies (the leader's its own).
    eta_stamp : ndarray, shape (M,)
        Its stamp: the step the leader computed it (-1: the start value 1).
    act_indptr : ndarray of int64, shape (M+1,)
        The links the laws use at the step, CSR by receiver.
    act_senders : ndarray of int64, shape (E,)
        Their senders.
    act_links : ndarray of int64, shape (E,)
        Their link numbers (the rows of ``recv_q`` and ``recv_v``).
    parent : ndarray of int64, shape (M,)
        Union-find work of :func:`connected_fresh`.
    draws : ndarray, shape (E, 3)
        The uniforms of each link's message of the sending step (:func:`draw_messages`).
    """

    history: np.ndarray
    pending: np.ndarray
    recv_q: np.ndarray
    recv_v: np.ndarray
    stamp: np.ndarray
    channel: np.ndarray
    tally: np.ndarray
    eta: np.ndarray
    eta_stamp: np.ndarray
    act_indptr: np.ndarray
    act_senders: np.ndarray
    act_links: np.ndarray
    parent: np.ndarray
    draws: np.ndarray


@njit(cache=True)
def link_state(model, m_uavs):
    """A run's link state at the start (:class:`LinkState`): nothing received, every
    UAV at :math:`\\eta = 1`."""
    n_links = model.senders.shape[0]
    return LinkState(
        np.zeros((model.depth, m_uavs, 6)), np.full((n_links, model.depth), -1, np.int64),
        np.zeros((n_links, 2)), np.zeros((n_links, 2)), np.full(n_links, -1, np.int64),
        np.full(n_links, -1, np.int8), np.zeros(2, np.int64), np.ones(m_uavs),
        np.full(m_uavs, -1.0), np.zeros(m_uavs + 1, np.int64), np.zeros(n_links, np.int64),
        np.zeros(n_links, np.int64), np.zeros(m_uavs, np.int64), np.ones((n_links, 3)),
    )  # fmt: skip


def neighbour_tables(
    links: LinkModel | None,
    lio: tuple[np.ndarray, np.ndarray] | None,
    m_uavs: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
) -> tuple[Any, ...]:
    """A run's link state and the tables its laws read the neighbours from.

    Parameters
    ----------
    links : LinkModel or None
        The link model, or None for perfect links.
    lio : tuple or None
        The run's link key, shape (2,), and series, shape (K+1, 5) (None with ``links``).
    m_uavs : int
        Number of UAVs.
    indptr : ndarray of int64
        The graph's CSR row pointers.
    indices : ndarray of int64
        Its neighbour indices.
    q : ndarray, shape (M, 2)
        The positions of the step (the mission's work array).
    v : ndarray, shape (M, 2)
        The velocities of the step.

    Returns
    -------
    tuple
        ``(state, indptr, senders, lookup, q_table, v_table, etas, k0, k1, series)``:
        without links ``(None, indptr, indices, indices, q, v, None, 0, 0, None)`` (each
        UAV reads its neighbours' state of the step, all at one eta); with links a new
        :class:`LinkState`, its ``act_indptr``, ``act_senders``, ``act_links``, ``recv_q``,
        ``recv_v`` and ``eta``, and the key's words and the series of ``lio``.
        Compiled kernels get the arrays of the exact types of either case (a Numba
        ``overload``): a mission without links compiles none of the link layer.
    """
    if links is None or lio is None:
        return None, indptr, indices, indices, q, v, None, 0, 0, None
    st = link_state(links, m_uavs)
    key, series = lio
    return (st, st.act_indptr, st.act_senders, st.act_links, st.recv_q, st.recv_v, st.eta,
            key[0], key[1], series)  # fmt: skip


@overload(neighbour_tables)
def _neighbour_tables_kernel(links, lio, m_uavs, indptr, indices, q, v):
    if isinstance(links, types.NoneType):
        return lambda links, lio, m_uavs, indptr, indices, q, v: (
            None, indptr, indices, indices, q, v, None, 0, 0, None
        )  # fmt: skip

    def tables(links, lio, m_uavs, indptr, indices, q, v):
        st = link_state(links, m_uavs)
        key, series = lio
        return (st, st.act_indptr, st.act_senders, st.act_links, st.recv_q, st.recv_v, st.eta,
                key[0], key[1], series)  # fmt: skip

    return tables


#: The kinds of a link's uniforms (the last term of the counter's block word).
LOSS_DRAW, DELAY_DRAW, CHANNEL_DRAW = 0, 1, 2


@njit(cache=True, inline="always")
def pair_draws(k0, k1, step, lo, hi, kind):
    """The uniforms of kind ``kind`` (:data:`LOSS_DRAW`, :data:`DELAY_DRAW`,
    :data:`CHANNEL_DRAW`) of the two messages between UAVs ``lo < hi`` sent at ``step``
    (the layout's one writing): the pair of the counter ``(step, lo, LINKS, 4 hi + kind)``,
    the first for ``lo`` to ``hi``, the second for ``hi`` to ``lo`` (the two directions of
    a link share a Philox block)."""
    return uniform_pair(k0, k1, step, lo, LINKS, 4 * hi + kind)


@njit(cache=True, inline="always")
def link_uniform(k0, k1, step, sender, receiver, kind):
    """The uniform of kind ``kind`` of the message of ``sender`` to ``receiver`` sent at
    ``step`` (:func:`pair_draws`)."""
    if sender < receiver:
        return pair_draws(k0, k1, step, sender, receiver, kind)[0]
    return pair_draws(k0, k1, step, receiver, sender, kind)[1]


@leaf
def draw_messages(k, k0, k1, model, draws):
    """The uniforms of every candidate link's message of step ``k`` into ``draws`` (E, 3):
    its loss, delay and channel uniforms (:func:`pair_draws`, one block per pair of UAVs
    and kind, only the kinds the model needs: none for perfect links). One pass, apart
    from the messages' fates: the Philox blocks of a step are then computed back to back."""
    kinds = (model.loss > 0.0 or model.gilbert, model.span > 1, model.gilbert)
    for kind in range(3):
        if not kinds[kind]:
            continue
        for i in range(model.pair_lo.shape[0]):
            a, b = pair_draws(k0, k1, k, model.pair_lo[i], model.pair_hi[i], kind)
            if model.pair_fwd[i] >= 0:
                draws[model.pair_fwd[i], kind] = a
            if model.pair_back[i] >= 0:
                draws[model.pair_back[i], kind] = b


@njit(cache=True, inline="always")
def message_fate(u_loss, u_delay, u_channel, link, model, channel):
    """The fate of a message from its uniforms (the law's one writing): ``(delivered,
    delay)``. With Gilbert-Elliott, ``u_channel`` first moves the link's channel state
    ``channel[link]`` (to bad if at most ``p_good_bad``, back if at most ``p_bad_good``;
    the stationary draw at its first message), whose loss probability then applies. Lost
    if ``u_loss`` is at most the loss probability; else the delay is ``delay + floor((1 -
    u_delay) span)``. Perfect links use no uniform."""
    loss = model.loss
    if model.gilbert:
        state = channel[link]
        if state < 0:
            state = 1 if u_channel <= model.pi_bad else 0
        elif state == 0:
            state = 1 if u_channel <= model.p_good_bad else 0
        else:
            state = 0 if u_channel <= model.p_bad_good else 1
        channel[link] = state
        loss = model.loss_bad if state == 1 else model.loss_good
    if u_loss <= loss:
        return False, 0
    if model.span == 1:
        return True, model.delay
    return True, model.delay + int((1.0 - u_delay) * model.span)


@njit(cache=True, inline="always")
def receive(link, sender, receiver, leader, step, h, law, history, recv_q, recv_v, stamp, eta,
            eta_stamp):  # fmt: skip
    """Link ``link`` (``sender`` to ``receiver``) receives the message sent at ``step``
    (slot ``h`` of the history; the arrays of :class:`LinkState`): its copy of the sender's
    state (if the laws use the link, ``law``), and, if the message's :math:`\\eta` is
    fresher than the receiver's (and the receiver is not the leader), that
    :math:`\\eta`."""
    if law:
        recv_q[link, 0] = history[h, sender, 0]
        recv_q[link, 1] = history[h, sender, 1]
        recv_v[link, 0] = history[h, sender, 2]
        recv_v[link, 1] = history[h, sender, 3]
    stamp[link] = step
    if receiver != leader and history[h, sender, 5] > eta_stamp[receiver]:
        eta[receiver] = history[h, sender, 4]
        eta_stamp[receiver] = history[h, sender, 5]


@leaf
def broadcast(k, q, v, eta, leader, st):
    """Step ``k`` is a sending step: every UAV's broadcast state into the history (its
    position, velocity, the :math:`\\eta` it knows and its stamp; the leader's :math:`\\eta`
    is ``eta``, stamped ``k``)."""
    slot = k % st.history.shape[0]
    history, etas, stamps = st.history, st.eta, st.eta_stamp
    for p in range(q.shape[0]):
        history[slot, p, 0] = q[p, 0]
        history[slot, p, 1] = q[p, 1]
        history[slot, p, 2] = v[p, 0]
        history[slot, p, 3] = v[p, 1]
        history[slot, p, 4] = eta if p == leader else etas[p]
        history[slot, p, 5] = k if p == leader else stamps[p]


@leaf
def exchange(k, q, v, eta, leader, k0, k1, model, st, series):
    """The messages of step ``k`` (:class:`LinkState` ``st``, in place): the broadcast (if
    ``k`` is a sending step) and, link by link, the range test, each sent message's fate
    (:func:`message_fate`) and the arrivals of the step (:func:`receive`), and the links
    the laws use (the graph's, in range, something received: ``st.act_*``, in the order
    of the candidates; without a range they are all of them once each has received a
    message, and are then kept); then the step's row ``k`` of ``series``
    (:data:`LINK_SERIES`, :func:`link_series`). ``eta`` is the leader's."""
    depth = model.depth
    sending = k % model.period == 0
    if sending:
        broadcast(k, q, v, eta, leader, st)
        draw_messages(k, k0, k1, model, st.draws)
    st.eta[leader] = eta
    now = k % depth
    indptr, senders, law, range2 = model.indptr, model.senders, model.law, model.range2
    pending, channel, stamp, tally, draws = st.pending, st.channel, st.stamp, st.tally, st.draws
    history, recv_q, recv_v = st.history, st.recv_q, st.recv_v
    etas, eta_stamp = st.eta, st.eta_stamp
    act_indptr, act_senders, act_links = st.act_indptr, st.act_senders, st.act_links
    ranged = range2 < math.inf
    rebuild = ranged or tally[1] == 0
    sent = delivered = count = 0
    for m in range(q.shape[0]):
        if rebuild:
            act_indptr[m] = count
        for e in range(indptr[m], indptr[m + 1]):
            p = senders[e]
            near = True
            if ranged:
                dx, dy = q[m, 0] - q[p, 0], q[m, 1] - q[p, 1]
                near = dx * dx + dy * dy <= range2
            if sending and near:
                sent += 1
                ok, delay = message_fate(draws[e, 0], draws[e, 1], draws[e, 2], e, model,
                                         channel)  # fmt: skip
                if ok:  # (slots modulo depth without a division: delay < depth)
                    delivered += 1
                    slot = now + delay - depth if now + delay >= depth else now + delay
                    pending[e, slot] = max(pending[e, slot], k)
            s = pending[e, now]
            if s >= 0:
                pending[e, now] = -1
                if s > stamp[e]:
                    tally[0] += stamp[e] < 0 and law[e]
                    h = now - (k - s) + depth if now < k - s else now - (k - s)
                    receive(e, p, m, leader, s, h, law[e], history, recv_q, recv_v, stamp,
                            etas, eta_stamp)  # fmt: skip
            if rebuild and law[e] and near and stamp[e] >= 0:  # a link the laws use
                act_senders[count] = p
                act_links[count] = e
                count += 1
    if rebuild:
        act_indptr[q.shape[0]] = count
        if not ranged and tally[0] == model.law_links:  # every link in use, for good
            tally[1] = 1
    series[k, 0] = sent
    series[k, 1] = delivered
    link_series(k, model, st, series)


@leaf
def link_series(k, model, st, series):
    """Row ``k`` of ``series`` after the messages of step ``k``: (its columns 2 to 4) the
    mean and largest age of the links in use (s; NaN without any), and 1.0 if the
    communication graph (those links at most ``model.stale`` steps old) is connected, else
    0.0 (every link fresh: the whole graph, connected by the scenario checks; else
    :func:`connected_fresh`)."""
    count = st.act_indptr[st.act_indptr.shape[0] - 1]
    total = fresh = 0
    oldest = -1
    for j in range(count):
        age = k - st.stamp[st.act_links[j]]
        total += age
        oldest = max(oldest, age)
        fresh += age <= model.stale
    series[k, 2] = total / count * model.dt if count else math.nan
    series[k, 3] = oldest * model.dt if count else math.nan
    whole = fresh == model.law_links or connected_fresh(k, model.stale, st)
    series[k, 4] = 1.0 if whole else 0.0


@leaf
def connected_fresh(k, stale, st):
    """Whether the communication graph of step ``k`` is connected: the undirected graph on
    the UAVs whose edges are the links in use (``st.act_*``) whose last message is at most
    ``stale`` steps old (union-find in ``st.parent``)."""
    parent = st.parent
    n = parent.shape[0]
    for i in range(n):
        parent[i] = i
    parts = n
    for m in range(n):
        for j in range(st.act_indptr[m], st.act_indptr[m + 1]):
            if k - st.stamp[st.act_links[j]] > stale:
                continue
            a, b = m, st.act_senders[j]
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            while parent[b] != b:
                parent[b] = parent[parent[b]]
                b = parent[b]
            if a != b:
                parent[a] = b
                parts -= 1
    return parts == 1


@njit(cache=True)
def _fates(k0, k1, model, steps, sender, receiver, delivered, delay, state):
    channel = np.full(1, -1, np.int8)
    for i in range(steps.shape[0]):
        k = steps[i]
        u_loss = link_uniform(k0, k1, k, sender, receiver, LOSS_DRAW)
        u_delay = link_uniform(k0, k1, k, sender, receiver, DELAY_DRAW)
        u_channel = link_uniform(k0, k1, k, sender, receiver, CHANNEL_DRAW)
        ok, d = message_fate(u_loss, u_delay, u_channel, 0, model, channel)
        delivered[i] = ok
        delay[i] = d
        state[i] = channel[0]


def message_fates(
    links: LinksConfig, seed: int, sender: int, receiver: int, steps: int, dt: float = 0.1
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fates of the messages of one link, as the mission draws them.

    Parameters
    ----------
    links : LinksConfig
        The link model (its range is not applied: every message is in range).
    seed : int
        The run's seed.
    sender : int
        The sending UAV.
    receiver : int
        The receiving UAV.
    steps : int
        The messages sent at the sending steps below ``steps`` (every
        :meth:`LinksConfig.period` steps from 0).
    dt : float, default 0.1
        The time step, s (for the period).

    Returns
    -------
    delivered : ndarray of bool
        Whether each message is received.
    delay : ndarray of int64
        Its delay, steps (0 for a lost message).
    channel : ndarray of int8
        The Gilbert-Elliott state after each message (1 bad), -1 without that model.

    Examples
    --------
    >>> ok, delay, _ = message_fates(LinksConfig(loss=0.2, delay=3), 0, 1, 2, 1000)
    >>> bool(0.15 < 1 - ok.mean() < 0.25), set(delay[ok].tolist())
    (True, {3})
    """
    if not isinstance(links, LinksConfig):
        raise FieldError("links", f"expected a crlbswarm.LinksConfig, got {type(links).__name__}")
    k0, k1 = stream_key(seed, LINKS)
    dt = _v.positive_scalar(dt, "dt")
    period = links.period(dt)
    count = _v.count(steps, "steps", 1, 2**32)
    at = np.arange(0, count, period, dtype=np.int64)
    sender = _v.count(sender, "sender", 0, 2**31 - 1)
    receiver = _v.count(receiver, "receiver", 0, 2**31 - 1)
    one = Adjacency(np.array([0, 1, 2], np.int64), np.array([1, 0], np.int64))
    model = link_model(links.model_copy(update={"range": None, "use_graph": True}), one, 0, dt)
    delivered = np.empty(at.size, dtype=bool)
    delay = np.empty(at.size, dtype=np.int64)
    state = np.empty(at.size, dtype=np.int8)
    _fates(k0, k1, model, at, sender, receiver, delivered, delay, state)
    return delivered, delay, state
