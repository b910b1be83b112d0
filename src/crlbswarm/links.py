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
    by the run's seed: the messages between UAVs ``a < b`` sent at the sending turns
    ``2 j`` and ``2 j + 1`` (turn ``t``: step ``t * period``) take the block of the counter
    (j, a, LINKS, 4 b + kind), kind 0 for the loss, 1 for the delay and 2 for the
    Gilbert-Elliott transition, as four 32-bit uniforms: turn ``2 j``'s for the message
    from ``a`` to ``b`` and for the one from ``b`` to ``a``, then turn ``2 j + 1``'s
    (:func:`pair_block`, :func:`pair_draws`); only the kinds the model needs are drawn.
    A run's messages do not depend on its batch, and a link (p, m) has the same messages
    whether it is a graph link or a pair within range.
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
from .counter_rng import LINKS, stream_key, uniform_quad
from .errors import FieldError
from .graphs import Adjacency

__all__ = [
    "CHANNEL_DRAW",
    "DELAY_DRAW",
    "DRAW_BATCH",
    "DRAW_BATCH_PAIRS",
    "LINK_SERIES",
    "LOSS_DRAW",
    "LOSS_MODELS",
    "MAX_ALL_PAIRS_UAVS",
    "MAX_DELAY",
    "MAX_LINK_UAV",
    "MAX_PERIOD_STEPS",
    "STATE_HEADER",
    "LinkModel",
    "LinkState",
    "LinksConfig",
    "all_pairs_adjacency",
    "arrivals",
    "broadcast",
    "candidate_links",
    "check_link_timing",
    "check_links",
    "connected_fresh",
    "draw_kind",
    "draw_messages",
    "exchange",
    "in_range",
    "layouts",
    "link_ages",
    "link_model",
    "link_pairs",
    "link_series",
    "link_state",
    "link_state_bytes",
    "link_uniform",
    "links_in_use",
    "message_fate",
    "message_fates",
    "model_layout",
    "neighbour_tables",
    "pair_block",
    "pair_draws",
    "pending_slot",
    "send_gilbert",
    "send_messages",
    "state_layout",
    "turn_draws",
]

#: Largest delay of a message, steps (each run keeps this many past states per UAV).
MAX_DELAY = 1000

#: Longest send period or timeout, steps (:meth:`LinksConfig.period`,
#: :meth:`LinksConfig.timeout_steps`): beyond any mission, and two periods plus the largest
#: delay within an int64.
MAX_PERIOD_STEPS = 2**60

#: Largest index of a UAV whose messages the counter tells apart (:func:`pair_block`: the
#: counter's 32-bit word ``4 b + kind``).
MAX_LINK_UAV = 2**30 - 1

#: Most UAVs of a mission whose range links every pair (``use_graph = false``): every
#: ordered pair is a candidate link, M (M - 1) of them.
MAX_ALL_PAIRS_UAVS = 1000

#: Sending turns whose message uniforms a run draws at once (:func:`draw_messages`), when
#: the candidate links join at most :data:`DRAW_BATCH_PAIRS` pairs of UAVs (with more
#: pairs, one turn at a time). Even: one Philox block serves two turns (:func:`pair_block`).
DRAW_BATCH = 8

#: Most pairs of UAVs for which a run draws :data:`DRAW_BATCH` sending turns at once.
DRAW_BATCH_PAIRS = 64

#: Words at the start of ``LinkState.ints``: M, E, ``delay_max + 1`` and the uniforms
#: per kind (its parts' sizes, for the properties).
STATE_HEADER = 4


#: The kernels index the flat buffers of a :class:`LinkState` and a ``LinkModel.table``
#: with unsigned integers (``buffer[_U(i)]``): the offsets are never negative, and Numba
#: then emits no wraparound of negative indices (a third of the instructions of a loop
#: over the links).
_U = np.uint64

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
        "at most every step, at least once in the mission (none: every step)",
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
            if self.loss != 0.0:  # (0, the default, as a dump of the table writes it)
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
            The send period, steps (1 without ``rate``; at most
            :data:`~crlbswarm.links.MAX_PERIOD_STEPS`: a rate so low never sends again in
            any mission).

        Raises
        ------
        FieldError
            ``dt``, unless a finite number > 0.
        """
        dt = _v.positive_scalar(dt, "dt")
        if self.rate is None:
            return 1
        return max(1, round(_send_interval(self.rate, dt)))

    @property
    def largest_delay(self) -> int:
        """The largest delay of a message, steps (``delay_max``, or the fixed ``delay``)."""
        return self.delay if self.delay_max is None else self.delay_max

    def silence_steps(self, dt: float) -> int:
        """The longest a live link can go without a message when none is lost, steps: a
        send period plus the largest delay (the shortest timeout that a perfect link never
        reaches: ``links.timeout``, ``faults.timeout``).

        Parameters
        ----------
        dt : float
            The time step, s.

        Returns
        -------
        int
            ``period(dt) + largest_delay``.
        """
        return self.period(dt) + self.largest_delay

    def largest_age(self, dt: float) -> int:
        """The largest age of a neighbour's state when no message is lost, steps: the
        largest delay plus a send period less one (``"auto"`` gains are resolved for it,
        :func:`crlbswarm.graphs.auto_formation_step`).

        Parameters
        ----------
        dt : float
            The time step, s.

        Returns
        -------
        int
            ``silence_steps(dt) - 1``.
        """
        return self.silence_steps(dt) - 1

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
            Steps (at most :data:`~crlbswarm.links.MAX_PERIOD_STEPS`: a longer timeout
            never goes stale in any mission).

        Raises
        ------
        FieldError
            ``dt``, unless a finite number > 0.
        """
        dt = _v.positive_scalar(dt, "dt")
        if self.timeout is None:
            return self.period(dt) + self.silence_steps(dt)
        return math.floor(min(self.timeout / dt, float(MAX_PERIOD_STEPS)) + 1e-9)


def _send_interval(rate: float, dt: float) -> float:
    """``1 / (rate dT)``, steps between two messages, at most :data:`MAX_PERIOD_STEPS` (a
    product that underflows to 0 too: such a rate never sends again)."""
    product = rate * dt
    if product > 0.0:
        return min(1.0 / product, float(MAX_PERIOD_STEPS))
    return float(MAX_PERIOD_STEPS)


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


def check_link_timing(links: LinksConfig, dt: float, steps: int) -> None:
    """The checks of a ``[links]`` table's timing against its mission (called by the
    scenario's validation first: the ``"auto"`` gains are resolved for the links' largest
    age).

    Parameters
    ----------
    links : LinksConfig
        The table.
    dt : float
        The time step, s.
    steps : int
        The mission's steps, K.

    Raises
    ------
    FieldError
        Naming the field: a rate so low that a UAV sends once every more steps than the
        mission has, a delay as long as the mission (no message would arrive in it), or a
        timeout shorter than a send period plus the largest delay (even a perfect link
        would go stale).
    """
    if links.delay >= steps:
        raise FieldError(
            "links.delay", f"{links.delay} steps is not shorter than the mission's {steps} "
            f"steps of time.duration: no message would arrive in it",
        )  # fmt: skip
    if links.rate is not None and _send_interval(links.rate, dt) > steps + 0.5:
        raise FieldError(
            "links.rate", f"{links.rate:g} per second sends no second message within the "
            f"{steps * dt:g} s mission: at least about 1/time.duration = "
            f"{1.0 / (steps * dt):.4g}",
        )  # fmt: skip
    silence = links.silence_steps(dt)
    if links.timeout is not None and links.timeout_steps(dt) < silence:
        raise FieldError(
            "links.timeout", f"{links.timeout:g} s is shorter than a send period plus the "
            f"largest delay, {silence * dt:g} s: even a perfect link would go stale",
        )  # fmt: skip


def check_links(links: LinksConfig, n_uavs: int, gains: Any) -> None:
    """The checks of a ``[links]`` table against its scenario's swarm and gains (called by
    its validation, after :func:`check_link_timing`).

    Parameters
    ----------
    links : LinksConfig
        The table.
    n_uavs : int
        Number of UAVs.
    gains : ControlGains
        The resolved gains (numbers, not ``"auto"``).

    Raises
    ------
    FieldError
        Naming the field: too many UAVs for links between every pair, or gains unstable
        when every pair may be linked.
    """
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
    """The link model as the compiled mission receives it (:func:`link_model`): scalars and
    one flat integer table (a compiled function receives each array as several words, so
    few arrays make its calls cheap). The table's parts are the properties below.

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
    n_uavs : int
        Number of UAVs, M.
    n_links : int
        Number of candidate links, E.
    n_pairs : int
        Number of pairs of UAVs linked in at least one direction, P.
    batch : int
        Sending turns whose uniforms are drawn at once (:data:`DRAW_BATCH` for at most
        :data:`DRAW_BATCH_PAIRS` pairs, else 1).
    table : ndarray of int64
        :attr:`indptr`, :attr:`senders`, :attr:`receivers`, :attr:`law`,
        :attr:`pair_slot`, :attr:`pair_lo`, :attr:`pair_hi`, :attr:`pair_fwd` and
        :attr:`pair_back`, one after the other (:func:`model_layout`).
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
    n_uavs: int
    n_links: int
    n_pairs: int
    batch: int
    table: np.ndarray

    def _part(self, i: int) -> np.ndarray:
        at = model_layout(self.n_uavs, self.n_links, self.n_pairs, self.batch)
        return self.table[at[i] : at[i + 1]]

    @property
    def indptr(self) -> np.ndarray:
        """The candidate links by receiver (:func:`candidate_links`), shape (M+1,)."""
        return self._part(0)

    @property
    def senders(self) -> np.ndarray:
        """The sender of each candidate link, shape (E,)."""
        return self._part(1)

    @property
    def receivers(self) -> np.ndarray:
        """The receiver of each candidate link, shape (E,)."""
        return self._part(2)

    @property
    def law(self) -> np.ndarray:
        """Whether the laws use each link (bool, shape (E,); False: the leader's eta only)."""
        return self._part(3).astype(bool)

    @property
    def pair_slot(self) -> np.ndarray:
        """Where each link's uniform is among a sending step's ``2 P`` of a kind
        (:attr:`LinkState.draws`): ``2 i`` for the link from ``pair_lo[i]`` to
        ``pair_hi[i]``, ``2 i + 1`` for the other direction; shape (E,)."""
        return self._part(4)

    @property
    def pair_lo(self) -> np.ndarray:
        """The pairs of UAVs linked in at least one direction: the lower UAV
        (:func:`pair_draws`), shape (P,)."""
        return self._part(5)

    @property
    def pair_hi(self) -> np.ndarray:
        """The higher UAV of each pair, shape (P,)."""
        return self._part(6)

    @property
    def pair_fwd(self) -> np.ndarray:
        """The link from the lower UAV of each pair to the higher, -1 if it is not a
        candidate; shape (P,)."""
        return self._part(7)

    @property
    def pair_back(self) -> np.ndarray:
        """The link from the higher UAV to the lower, or -1; shape (P,)."""
        return self._part(8)


@njit(cache=True, inline="always")
def model_layout(m, e, p, b):
    """Where the parts of ``LinkModel.table`` start (and the last ends), for M UAVs,
    E links, P pairs and batches of ``b`` sending steps (the layout's one writing)."""
    senders = m + 1
    receivers = senders + e
    law = receivers + e
    slot = law + e
    lo = slot + e
    hi = lo + p
    fwd = hi + p
    back = fwd + p
    return 0, senders, receivers, law, slot, lo, hi, fwd, back, back + p


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
    receivers = np.repeat(np.arange(indptr.size - 1, dtype=np.int64), np.diff(indptr))
    pair_slot = np.empty(senders.size, dtype=np.int64)
    pair_slot[pair_fwd[pair_fwd >= 0]] = 2 * np.flatnonzero(pair_fwd >= 0)
    pair_slot[pair_back[pair_back >= 0]] = 2 * np.flatnonzero(pair_back >= 0) + 1
    period = links.period(dt)
    batch = DRAW_BATCH if pair_lo.size <= DRAW_BATCH_PAIRS else 1
    table = np.concatenate([
        indptr, senders, receivers, law.astype(np.int64), pair_slot, pair_lo, pair_hi,
        pair_fwd, pair_back,
    ]).astype(np.int64)  # fmt: skip
    gilbert = links.loss_model == "gilbert"
    p_gb = float(links.p_good_bad or 0.0)
    p_bg = float(links.p_bad_good or 0.0)
    return LinkModel(
        period=period, depth=links.largest_delay + 1, delay=links.delay,
        span=links.largest_delay - links.delay + 1,
        range2=math.inf if links.range is None else float(links.range) * float(links.range),
        loss=float(links.loss), gilbert=gilbert, p_good_bad=p_gb, p_bad_good=p_bg,
        pi_bad=p_gb / (p_gb + p_bg) if gilbert else 0.0,
        loss_good=float(0.0 if links.loss_good is None else links.loss_good),
        loss_bad=float(1.0 if links.loss_bad is None else links.loss_bad),
        stale=links.timeout_steps(dt), law_links=int(law.sum()), dt=float(dt),
        n_uavs=int(indptr.size - 1), n_links=int(senders.size), n_pairs=int(pair_lo.size),
        batch=batch, table=table,
    )  # fmt: skip


@njit(cache=True, inline="always")
def state_layout(m, e, d, w):
    """Where the parts of a :class:`LinkState` start (and the last of each buffer ends),
    for M UAVs, E links, ``d`` (``delay_max + 1``) past states and ``w`` uniforms per kind
    (the layout's one writing): in ``floats`` the history, ``recv_q``, ``recv_v``, ``eta``,
    ``eta_stamp``, ``draws``; in ``ints`` (after :data:`STATE_HEADER` words: M, E, d, w)
    ``pending``, ``stamp``, ``tally``, ``act_indptr``, ``act_senders``, ``act_links``,
    ``parent``; in ``flags`` ``channel``, ``near``."""
    recv_q = d * m * 6
    recv_v = recv_q + 2 * e
    eta = recv_v + 2 * e
    eta_stamp = eta + m
    draws = eta_stamp + m
    floats = draws + 3 * w
    pending = STATE_HEADER
    stamp = pending + e * d
    tally = stamp + e
    act_indptr = tally + 3
    act_senders = act_indptr + m + 1
    act_links = act_senders + e
    parent = act_links + e
    ints = parent + m
    return (0, recv_q, recv_v, eta, eta_stamp, draws, floats, pending, stamp, tally, act_indptr,
            act_senders, act_links, parent, ints, 0, e, 2 * e)  # fmt: skip


@njit(cache=True, inline="always")
def layouts(model):
    """The layouts of the model's table (:func:`model_layout`) and of a run's state
    (:func:`state_layout`), and the uniforms per kind of a batch of draws, ``2 batch P``:
    ``(part, at, w)``."""
    m, e, p, b = model.n_uavs, model.n_links, model.n_pairs, model.batch
    w = 2 * b * p
    return model_layout(m, e, p, b), state_layout(m, e, model.depth, w), w


@njit(cache=True, inline="always")
def pending_slot(e, now, delay, model, at):
    """Where in ``ints`` link ``e``'s message sent at the step of slot ``now`` with
    ``delay`` steps waits (slot ``(now + delay) % depth``, without a division: the delay
    is below the depth)."""
    depth = model.depth
    slot = now + delay - depth if now + delay >= depth else now + delay
    return at[7] + e * depth + slot


@njit(cache=True, inline="always")
def turn_draws(k, model, st, at):
    """Where in ``floats`` the loss uniforms of the sending step ``k`` start (its turn's
    within the batch of :attr:`LinkState.draws`; a link's is ``model.pair_slot`` further,
    its delay and channel ones ``w`` and ``2 w`` further)."""
    return at[5] + 2 * model.n_pairs * (k // model.period - st.ints[_U(at[9] + 2)])


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
    at = state_layout(model.n_uavs, model.n_links, model.depth,
                      2 * model.batch * model.n_pairs)  # fmt: skip
    return 8 * (at[6] + at[14]) + at[17]


class LinkState(NamedTuple):
    """One run's link state, allocated once (:func:`link_state`) as three buffers (a
    compiled function receives each array as several words: few make its calls cheap);
    M UAVs, E links, D the largest delay, P pairs. The parts are the properties below
    (views; :func:`state_layout`).

    Parameters
    ----------
    floats : ndarray of float64
        :attr:`history`, :attr:`recv_q`, :attr:`recv_v`, :attr:`eta`, :attr:`eta_stamp`,
        :attr:`draws`.
    ints : ndarray of int64
        M, E, D + 1, the uniforms per kind, then :attr:`pending`, :attr:`stamp`,
        :attr:`tally`, :attr:`act_indptr`, :attr:`act_senders`, :attr:`act_links`,
        :attr:`parent`.
    flags : ndarray of int8
        :attr:`channel`, :attr:`near`.
    """

    floats: np.ndarray
    ints: np.ndarray
    flags: np.ndarray

    def _part(self, buf: np.ndarray, i: int) -> np.ndarray:
        at = state_layout(*(int(x) for x in self.ints[:STATE_HEADER]))
        return buf[at[i] : at[i + 1]]

    @property
    def history(self) -> np.ndarray:
        """Each UAV's broadcast state at the last D+1 sending steps, in slot
        ``step % (D+1)``: x, y, vx, vy, its :math:`\\eta` and that value's stamp; shape
        (D+1, M, 6)."""
        return self._part(self.floats, 0).reshape(-1, int(self.ints[0]), 6)

    @property
    def recv_q(self) -> np.ndarray:
        """Per link, the last received position, m; shape (E, 2)."""
        return self._part(self.floats, 1).reshape(-1, 2)

    @property
    def recv_v(self) -> np.ndarray:
        """Per link, the last received velocity, m/s; shape (E, 2)."""
        return self._part(self.floats, 2).reshape(-1, 2)

    @property
    def eta(self) -> np.ndarray:
        """The :math:`\\eta` each UAV flies (the leader's its own), shape (M,)."""
        return self._part(self.floats, 3)

    @property
    def eta_stamp(self) -> np.ndarray:
        """Its stamp: the step the leader computed it (-1: the start value 1), shape (M,)."""
        return self._part(self.floats, 4)

    @property
    def draws(self) -> np.ndarray:
        """The uniforms of the messages of ``batch`` sending turns, one row per kind (loss,
        delay, channel), two columns per pair of UAVs and sending turn
        (:func:`draw_messages`; link ``e``'s of the ``b``-th turn of the batch in column
        ``2 b P + model.pair_slot[e]``); shape (3, 2 batch P)."""
        return self._part(self.floats, 5).reshape(3, -1)

    @property
    def pending(self) -> np.ndarray:
        """Per link, the send step of the newest message arriving at each step (slot
        ``arrival % (D+1)``), -1 for none; shape (E, D+1)."""
        return self._part(self.ints, 7).reshape(-1, int(self.ints[2]))

    @property
    def stamp(self) -> np.ndarray:
        """The send step of each link's last received message, -1 before any; shape (E,)."""
        return self._part(self.ints, 8)

    @property
    def tally(self) -> np.ndarray:
        """How many links the laws may use have received something; 1 once the links in
        use are all of them for good (no range: ``act_*`` is then not rebuilt); the batch
        in :attr:`draws` (its first sending turn, a multiple of ``batch``; -1: none
        yet). Shape (3,)."""
        return self._part(self.ints, 9)

    @property
    def act_indptr(self) -> np.ndarray:
        """The links the laws use at the step, CSR by receiver; shape (M+1,)."""
        return self._part(self.ints, 10)

    @property
    def act_senders(self) -> np.ndarray:
        """Their senders, shape (E,) (the first ``act_indptr[M]``)."""
        return self._part(self.ints, 11)

    @property
    def act_links(self) -> np.ndarray:
        """Their link numbers (the rows of ``recv_q`` and ``recv_v``), shape (E,)."""
        return self._part(self.ints, 12)

    @property
    def parent(self) -> np.ndarray:
        """Union-find work of :func:`connected_fresh`, shape (M,)."""
        return self._part(self.ints, 13)

    @property
    def channel(self) -> np.ndarray:
        """The Gilbert-Elliott state of each link: -1 before the first message, 0 good,
        1 bad; int8, shape (E,)."""
        return self._part(self.flags, 15)

    @property
    def near(self) -> np.ndarray:
        """Whether each link is within range at the step (with a range only); int8,
        shape (E,)."""
        return self._part(self.flags, 16)


@njit(cache=True)
def link_state(model, m_uavs):
    """A run's link state at the start (:class:`LinkState`): nothing received, every
    UAV at :math:`\\eta = 1`."""
    e, d = model.n_links, model.depth
    at, w = layouts(model)[1:]
    floats = np.zeros(at[6])
    floats[at[3] : at[4]] = 1.0  # eta
    floats[at[4] : at[5]] = -1.0  # eta_stamp
    floats[at[5] : at[6]] = 1.0  # draws
    ints = np.zeros(at[14], np.int64)
    ints[0], ints[1], ints[2], ints[3] = m_uavs, e, d, w
    ints[at[7] : at[9]] = -1  # pending, stamp
    ints[at[9] + 2] = -1  # no batch of draws yet
    flags = np.ones(at[17], np.int8)
    flags[at[15] : at[16]] = -1  # channel
    return LinkState(floats, ints, flags)


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
        The run's link key, shape (2,), and series, shape (5, K+1) (None with ``links``).
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
        ``recv_v`` and ``eta`` (views), and the key's words and the series of ``lio``.
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
        e = links.n_links
        at = layouts(links)[1]
        fl, it = st.floats, st.ints
        return (st, it[at[10] : at[11]], it[at[11] : at[12]], it[at[12] : at[13]],
                fl[at[1] : at[2]].reshape(e, 2), fl[at[2] : at[3]].reshape(e, 2),
                fl[at[3] : at[4]], key[0], key[1], series)  # fmt: skip

    return tables


#: The kinds of a link's uniforms (the last term of the counter's block word).
LOSS_DRAW, DELAY_DRAW, CHANNEL_DRAW = 0, 1, 2


@njit(cache=True, inline="always")
def pair_block(k0, k1, j, lo, hi, kind):
    """The uniforms of kind ``kind`` (:data:`LOSS_DRAW`, :data:`DELAY_DRAW`,
    :data:`CHANNEL_DRAW`) of the messages between UAVs ``lo < hi`` sent at the sending
    turns ``2 j`` and ``2 j + 1`` (the layout's one writing): the block of the counter
    ``(j, lo, LINKS, 4 hi + kind)`` (:func:`crlbswarm.counter_rng.uniform_quad`), its
    words for turn ``2 j`` from ``lo`` to ``hi`` and from ``hi`` to ``lo``, then those of
    turn ``2 j + 1`` (the two directions of a link and two turns share a block)."""
    return uniform_quad(k0, k1, j, lo, LINKS, 4 * hi + kind)


@njit(cache=True, inline="always")
def pair_draws(k0, k1, turn, lo, hi, kind):
    """The two uniforms of kind ``kind`` of the messages between UAVs ``lo < hi`` sent at
    the sending turn ``turn`` (the step ``turn * period``): from ``lo`` to ``hi``, then
    from ``hi`` to ``lo`` (:func:`pair_block`)."""
    a, b, c, d = pair_block(k0, k1, turn >> 1, lo, hi, kind)
    if turn & 1:
        return c, d
    return a, b


@njit(cache=True, inline="always")
def link_uniform(k0, k1, turn, sender, receiver, kind):
    """The uniform of kind ``kind`` of the message of ``sender`` to ``receiver`` sent at the
    sending turn ``turn`` (:func:`pair_draws`)."""
    if sender < receiver:
        return pair_draws(k0, k1, turn, sender, receiver, kind)[0]
    return pair_draws(k0, k1, turn, receiver, sender, kind)[1]


@leaf
def draw_kind(first, k0, k1, lo, hi, kind, batch, row):
    """The uniforms of kind ``kind`` of the ``batch`` sending turns from ``first`` (even
    when ``batch`` is) for the pairs ``lo[i] < hi[i]``: turn ``first + b``'s two of pair
    ``i`` into ``row[2 (b P + i)]`` and the next (:func:`pair_block`, one block for two
    turns; :func:`pair_draws` for a batch of one turn).

    One block at a time, in scalar code: the compiler would otherwise compute several at
    once with wide vector multiplies (AVX-512), whose use lowers the core's clock for
    a while after (the whole mission then runs slower, measured: about 4 % of a batch of
    paper missions). The loop's step depends on a uniform (always in (0, 1], so it is
    always 1): the compiler cannot count the iterations, and keeps the loop scalar."""
    p = lo.shape[0]
    if batch == 1:
        i = 0
        while i < p:
            a, b = pair_draws(k0, k1, first, lo[i], hi[i], kind)
            row[2 * i] = a
            row[2 * i + 1] = b
            i += 1 if a > 0.0 else p
        return
    for t in range(batch >> 1):
        j, base = (first >> 1) + t, 4 * t * p
        q = 0
        while q < p:
            a, b, c, d = pair_block(k0, k1, j, lo[q], hi[q], kind)
            at = base + 2 * q
            row[at] = a
            row[at + 1] = b
            row[at + 2 * p] = c
            row[at + 2 * p + 1] = d
            q += 1 if a > 0.0 else p


@leaf
def draw_messages(first, k0, k1, model, st):
    """The uniforms of the messages of the ``model.batch`` sending turns from ``first`` into
    :attr:`LinkState.draws`: for each kind the model needs (loss, delay, channel; none
    for perfect links), each turn ``b`` of the batch and each pair of UAVs ``i``, its two
    uniforms (:func:`draw_kind`) in columns ``2 (b P + i)`` and the next
    (:data:`DRAW_BATCH`; the draws are functions of the counter, so drawing ahead
    changes none)."""
    part, at, w = layouts(model)
    b = model.batch
    lo = model.table[part[5] : part[6]]
    hi = model.table[part[6] : part[7]]
    if model.loss > 0.0 or model.gilbert:
        draw_kind(first, k0, k1, lo, hi, LOSS_DRAW, b, st.floats[at[5] : at[5] + w])
    if model.span > 1:
        draw_kind(first, k0, k1, lo, hi, DELAY_DRAW, b, st.floats[at[5] + w : at[5] + 2 * w])
    if model.gilbert:
        draw_kind(first, k0, k1, lo, hi, CHANNEL_DRAW, b, st.floats[at[5] + 2 * w : at[6]])


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
def broadcast(k, q, v, eta, leader, model, st):
    """Step ``k`` is a sending step: every UAV's broadcast state into the history (its
    position, velocity, the :math:`\\eta` it knows and its stamp; the leader's :math:`\\eta`
    is ``eta``, stamped ``k``)."""
    m_uavs = q.shape[0]
    at = layouts(model)[1]
    fl = st.floats
    base = (k % model.depth) * m_uavs * 6
    for p in range(m_uavs):
        h = base + 6 * p
        fl[_U(h)] = q[p, 0]
        fl[_U(h + 1)] = q[p, 1]
        fl[_U(h + 2)] = v[p, 0]
        fl[_U(h + 3)] = v[p, 1]
        fl[_U(h + 4)] = fl[_U(at[3] + p)]
        fl[_U(h + 5)] = fl[_U(at[4] + p)]
    fl[_U(base + 6 * leader + 4)] = eta
    fl[_U(base + 6 * leader + 5)] = k


@leaf
def in_range(q, model, st):
    """``near[e]`` (:attr:`LinkState.near`): whether the receiver and the sender of link
    ``e`` are within range at the positions ``q`` (the distance squared at most
    ``model.range2``)."""
    n = model.n_links
    part = layouts(model)[0]
    tab, flags, range2 = model.table, st.flags, model.range2
    for e in range(n):
        r, p = tab[_U(part[2] + e)], tab[_U(part[1] + e)]
        dx, dy = q[r, 0] - q[p, 0], q[r, 1] - q[p, 1]
        flags[_U(n + e)] = dx * dx + dy * dy <= range2


@leaf
def send_gilbert(k, model, st):
    """:func:`send_messages` with the Gilbert-Elliott model (:func:`message_fate` moves
    each link's channel state). Returns ``(sent, delivered)``."""
    n = model.n_links
    part, at, w = layouts(model)
    tab, fl, it, flags = model.table, st.floats, st.ints, st.flags
    now = k % model.depth
    ranged = model.range2 < math.inf
    draws = turn_draws(k, model, st, at)
    sent = delivered = 0
    for e in range(n):
        if ranged and not flags[_U(n + e)]:
            continue
        sent += 1
        j = draws + tab[_U(part[4] + e)]
        ok, delay = message_fate(fl[_U(j)], fl[_U(j + w)], fl[_U(j + 2 * w)], e, model, flags)
        if ok:
            delivered += 1
            i = pending_slot(e, now, delay, model, at)
            it[_U(i)] = max(it[_U(i)], k)
    return sent, delivered


@njit(cache=True, inline="always")
def send_messages(k, model, st):
    """The fates of the messages of the sending step ``k`` (:func:`message_fate`; with
    Gilbert-Elliott :func:`send_gilbert`): each delivered one goes to its link's pending
    slot of its arrival step (the newest send step wins). Returns ``(sent, delivered)``.
    Independent losses take the law of :func:`message_fate` without a branch on the
    draws (the messages are lost at random: a branch would be mispredicted)."""
    if model.gilbert:
        return send_gilbert(k, model, st)
    n = model.n_links
    part, at, w = layouts(model)
    tab, fl, it, flags = model.table, st.floats, st.ints, st.flags
    now = k % model.depth
    ranged = model.range2 < math.inf
    draws = turn_draws(k, model, st, at)
    loss, span, shortest = model.loss, model.span, model.delay
    sent = delivered = 0
    for e in range(n):
        j = draws + tab[_U(part[4] + e)]
        on = not ranged or flags[_U(n + e)] != 0
        ok = on and fl[_U(j)] > loss
        delay = shortest + int((1.0 - fl[_U(j + w)]) * span) if span > 1 else shortest
        i = pending_slot(e, now, delay, model, at)
        it[_U(i)] = max(it[_U(i)], k if ok else -1)
        sent += on
        delivered += ok
    return sent, delivered


@njit(cache=True, inline="always")
def arrivals(k, leader, model, st):
    """The messages arriving at step ``k`` (the pending slot of ``k``): each one newer than
    its link's last is received: its copy of the sender's state (if the laws use the link)
    and its stamp, and, if the message's :math:`\\eta` is fresher than the receiver's (and
    the receiver is not the leader), that :math:`\\eta`. Counts in the tally the links the
    laws use that receive their first message. Returns the sum and the smallest of the
    stamps of the links the laws may use (``k`` for none; the ages of the links in use
    once they are all of them, :func:`link_ages`)."""
    m, n, depth = model.n_uavs, model.n_links, model.depth
    part, at, _ = layouts(model)
    tab, fl, it = model.table, st.floats, st.ints
    now = k % depth
    first = total = 0
    newest_of_oldest = k
    for e in range(n):
        i = at[7] + e * depth + now
        s = it[_U(i)]
        it[_U(i)] = -1
        old = it[_U(at[8] + e)]
        law = tab[_U(part[3] + e)]
        if s > old:  # (none pending: -1)
            it[_U(at[8] + e)] = s
            h = now - (k - s) + depth if now < k - s else now - (k - s)
            row = (h * m + tab[_U(part[1] + e)]) * 6
            if law:
                first += old < 0
                fl[_U(at[1] + 2 * e)] = fl[_U(row)]
                fl[_U(at[1] + 2 * e + 1)] = fl[_U(row + 1)]
                fl[_U(at[2] + 2 * e)] = fl[_U(row + 2)]
                fl[_U(at[2] + 2 * e + 1)] = fl[_U(row + 3)]
            r = tab[_U(part[2] + e)]
            if r != leader and fl[_U(row + 5)] > fl[_U(at[4] + r)]:
                fl[_U(at[3] + r)] = fl[_U(row + 4)]
                fl[_U(at[4] + r)] = fl[_U(row + 5)]
            old = s
        total += old if law else 0
        newest_of_oldest = min(newest_of_oldest, old if law else k)
    it[_U(at[9])] += first
    return total, newest_of_oldest


@leaf
def links_in_use(model, st):
    """The links the laws use at the step (``act_*``, CSR by receiver, in the order of the
    candidates): the graph's, within range, that have received something."""
    m, n = model.n_uavs, model.n_links
    part, at, _ = layouts(model)
    tab, it, flags = model.table, st.ints, st.flags
    ranged = model.range2 < math.inf
    count = 0
    for r in range(m):
        it[_U(at[10] + r)] = count
        for e in range(tab[_U(r)], tab[_U(r + 1)]):
            if (tab[_U(part[3] + e)] and it[_U(at[8] + e)] >= 0
                    and (not ranged or flags[_U(n + e)])):  # fmt: skip
                it[_U(at[11] + count)] = tab[_U(part[1] + e)]
                it[_U(at[12] + count)] = e
                count += 1
    it[_U(at[10] + m)] = count


@leaf
def exchange(k, q, v, eta, leader, k0, k1, model, st, series):
    """The messages of step ``k`` (:class:`LinkState` ``st``, in place): the broadcast (if
    ``k`` is a sending step), the range test (:func:`in_range`), each sent message's fate
    (:func:`send_messages`), the arrivals of the step (:func:`arrivals`) and the links the
    laws use (:func:`links_in_use`; without a range they are all of them once each has
    received a message, and are then kept, not rebuilt); then the step's column ``k`` of
    ``series`` (:data:`LINK_SERIES`, :func:`link_series`). ``eta`` is the leader's.

    A leaf kernel (no reference counts: inlined into the mission, each of its arrays
    would be counted at every step); the work of the rare cases (a range,
    Gilbert-Elliott, the links in use changing, a stale link) is in functions of their
    own."""
    at = layouts(model)[1]
    it = st.ints
    ranged = model.range2 < math.inf
    if ranged:
        in_range(q, model, st)
    sent = delivered = 0
    if k % model.period == 0:
        broadcast(k, q, v, eta, leader, model, st)
        turn = k // model.period
        first = turn - turn % model.batch  # the batch of this sending step
        if first != it[_U(at[9] + 2)]:
            it[_U(at[9] + 2)] = first
            draw_messages(first, k0, k1, model, st)
        sent, delivered = send_messages(k, model, st)
    st.floats[_U(at[3] + leader)] = eta
    kept = not ranged and it[_U(at[9] + 1)] == 1  # the links in use: every one, for good
    total, newest_of_oldest = arrivals(k, leader, model, st)
    series[0, k] = sent
    series[1, k] = delivered
    if kept:
        link_ages(k, model.law_links, total, k - newest_of_oldest, model, st, series)
        return
    links_in_use(model, st)
    if not ranged and it[_U(at[9])] == model.law_links:
        it[_U(at[9] + 1)] = 1
    link_series(k, model, st, series)


@njit(cache=True, inline="always")
def link_ages(k, count, total, oldest, model, st, series):
    """Column ``k`` of ``series``, rows 2 to 4, from the links in use at the step: their
    number, the sum of their stamps and the largest age, steps: the mean and largest age
    (s; NaN without any), and 1.0 if the communication graph (those links at most
    ``model.stale`` steps old) is connected, else 0.0 (every link fresh: the whole graph,
    connected by the scenario checks; else :func:`connected_fresh`)."""
    series[2, k] = (count * k - total) / count * model.dt if count else math.nan
    series[3, k] = oldest * model.dt if count else math.nan
    whole = count == model.law_links and oldest <= model.stale
    series[4, k] = 1.0 if whole or connected_fresh(k, model, st) else 0.0


@leaf
def link_series(k, model, st, series):
    """Column ``k`` of ``series`` after the messages of step ``k``, rows 2 to 4
    (:func:`link_ages`), from the links in use (``act_*``)."""
    m = model.n_uavs
    at = layouts(model)[1]
    it = st.ints
    count = it[_U(at[10] + m)]
    total = 0
    newest_of_oldest = k
    for j in range(count):
        s = it[_U(at[8] + it[_U(at[12] + j)])]
        total += s
        newest_of_oldest = min(newest_of_oldest, s)
    link_ages(k, count, total, k - newest_of_oldest, model, st, series)


@leaf
def connected_fresh(k, model, st):
    """Whether the communication graph of step ``k`` is connected: the undirected graph on
    the UAVs whose edges are the links in use (``act_*``) whose last message is at most
    ``model.stale`` steps old (union-find in :attr:`LinkState.parent`)."""
    n = model.n_uavs
    at = layouts(model)[1]
    it, stale, parent = st.ints, model.stale, at[13]
    for i in range(n):
        it[_U(parent + i)] = i
    parts = n
    for m in range(n):
        for j in range(it[_U(at[10] + m)], it[_U(at[10] + m + 1)]):
            if k - it[_U(at[8] + it[_U(at[12] + j)])] > stale:
                continue
            a, b = m, it[_U(at[11] + j)]
            while it[_U(parent + a)] != a:
                it[_U(parent + a)] = it[_U(parent + it[_U(parent + a)])]
                a = it[_U(parent + a)]
            while it[_U(parent + b)] != b:
                it[_U(parent + b)] = it[_U(parent + it[_U(parent + b)])]
                b = it[_U(parent + b)]
            if a != b:
                it[_U(parent + a)] = b
                parts -= 1
    return parts == 1


@njit(cache=True)
def _fates(k0, k1, model, steps, sender, receiver, delivered, delay, state):
    channel = np.full(1, -1, np.int8)
    for i in range(steps.shape[0]):
        turn = steps[i] // model.period
        u_loss = link_uniform(k0, k1, turn, sender, receiver, LOSS_DRAW)
        u_delay = link_uniform(k0, k1, turn, sender, receiver, DELAY_DRAW)
        u_channel = link_uniform(k0, k1, turn, sender, receiver, CHANNEL_DRAW)
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
        The sending UAV, ``0 .. 2**30 - 1`` (the counter's word ``4 b + kind`` holds it).
    receiver : int
        The receiving UAV, another one.
    steps : int
        The messages sent at the sending steps below ``steps`` (every
        :meth:`LinksConfig.period` steps from 0), ``1 .. 2**32``.
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
    sender = _v.count(sender, "sender", 0, MAX_LINK_UAV)
    receiver = _v.count(receiver, "receiver", 0, MAX_LINK_UAV)
    if receiver == sender:
        raise FieldError("receiver", f"must differ from the sender, {sender}")
    messages = -(-count // period)
    _v.check_memory(18.0 * messages, "steps", f"{messages:,} messages", "ask for fewer steps")
    at = np.arange(0, count, period, dtype=np.int64)
    one = Adjacency(np.array([0, 1, 2], np.int64), np.array([1, 0], np.int64))
    model = link_model(links.model_copy(update={"range": None, "use_graph": True}), one, 0, dt)
    delivered = np.empty(at.size, dtype=bool)
    delay = np.empty(at.size, dtype=np.int64)
    state = np.empty(at.size, dtype=np.int8)
    _fates(k0, k1, model, at, sender, receiver, delivered, delay, state)
    return delivered, delay, state
