r"""The network side of ``crlbswarm fly``: Zenoh sessions, key expressions, messages, the
loss and delay injected at the sender, and the inbox the stepped mode waits on.

Every process of a flight (one per UAV, and the recorder) opens one Zenoh session in peer
mode with explicit endpoints (:func:`session_config`: it listens on its own endpoint,
127.0.0.1 unless told otherwise, connects to the endpoints it is given, and never scouts by
multicast). Under a key prefix (:data:`DEFAULT_KEY`, or one per flight chosen by the
launcher), the traffic is:

==============================  =========================================================
key expression                  what
==============================  =========================================================
``<prefix>/state/<m>``          UAV m's state of step k for the swarm (:data:`STATE`):
                                the only messages loss and delay are injected into
``<prefix>/log/<m>``            UAV m's true state and step metrics for the recorder
                                (:data:`LOG`), never dropped
``<prefix>/done``               the recorder's end of the flight (:data:`DONE`)
``<prefix>/alive/uav/<m>``,     the liveliness tokens of the members: a process that exits
``<prefix>/alive/recorder``     (or whose link stays down for Zenoh's lease) is seen at once
==============================  =========================================================

A message is a :class:`Packet`: a 16-byte header (magic ``b"CS"``, version, kind, sender,
step, stamp) and little-endian float64 values (:data:`STATE_FIELDS`, :data:`LOG_FIELDS`).
``step`` is the sender's step when it sent the message, ``stamp`` the step the values
describe: equal without delay, ``step - delay`` with it, and :data:`NO_STAMP` for a packet
that carries nothing (the stepped mode's tick of a lost or not yet delivered message).

Loss and delay are injected at the sender (:class:`Injection`): the message of step k is
lost with probability ``loss``, independently, its uniform the first of the pair of
counter ``(k, sender, LOSS_STREAM, 0)`` of :mod:`crlbswarm.counter_rng` keyed by (seed,
:data:`LOSS_STREAM`), so a flight's losses are reproducible; a message not lost is
delivered ``delay`` steps later. Zenoh is imported only when a session opens
(:func:`import_zenoh`), never by ``import crlbswarm``.
"""

from __future__ import annotations

import json
import os
import struct
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from . import _validation as _v
from .counter_rng import stream_key, uniform_pair
from .errors import FieldError

__all__ = [
    "CLOSE_WAIT",
    "DEFAULT_KEY",
    "DEFAULT_TIMEOUT",
    "DONE",
    "FLY_EXTRA",
    "LOG",
    "LOG_FIELDS",
    "LOSS_STREAM",
    "MAX_DELAY",
    "MODES",
    "NO_STAMP",
    "RECORDER",
    "START_TIMEOUT",
    "STATE",
    "STATE_FIELDS",
    "SWARM_FIELDS",
    "FlightError",
    "FlightOptions",
    "Inbox",
    "Injection",
    "Member",
    "Packet",
    "ParentGone",
    "SwarmBlock",
    "alive_key",
    "decode",
    "done_key",
    "encode",
    "import_zenoh",
    "log_key",
    "member_name",
    "session_config",
    "state_key",
]

#: The optional extra that installs Zenoh (``pip install 'crlbswarm[fly]'``).
FLY_EXTRA = "fly"

#: Key prefix of a flight started by hand (the launcher picks one per flight).
DEFAULT_KEY = "crlbswarm/fly"

#: How long a process waits for every member of the flight to appear at the start, s (a
#: process started by hand may compile the laws first).
START_TIMEOUT = 120.0

#: Stream word of the injected loss's draws (:mod:`crlbswarm.counter_rng`; the kernel's
#: streams are 0 and 1).
LOSS_STREAM = 8

#: The modes of a flight: ``stepped`` (a UAV takes step k + 1 when it has the states of
#: step k it needs, or the timeout expires: reproducible) and ``realtime`` (steps on the
#: wall clock every ``time.step`` seconds, on the newest states received).
MODES = ("stepped", "realtime")

#: Default of the stepped mode's timeout, s.
DEFAULT_TIMEOUT = 5.0

#: Largest injected delay, steps.
MAX_DELAY = 100_000

#: Longest wait for a Zenoh session to close, s (:meth:`Member.close`).
CLOSE_WAIT = 2.0

#: The stamp of a packet that carries no state.
NO_STAMP = -1

#: Kinds of message.
STATE, LOG, DONE = 0, 1, 2

#: The values of a :data:`STATE` message: position, velocity (the leader's is its
#: reference v*), the scaling factor eta (the leader's; NaN from a follower), the range
#: measured at the step (NaN when none is).
STATE_FIELDS = ("qx", "qy", "vx", "vy", "eta", "range")

#: The values of a :data:`LOG` message: the true position and velocity, the UAV's obstacle
#: clearance, and (from the leader; NaN from a follower) eta, the distance to go and the
#: filter's estimate and the trace of its position covariance; ``late``, the steps at
#: which the UAV went on without a message it waited for (the stepped mode's timeouts).
LOG_FIELDS = (
    "qx", "qy", "vx", "vy", "clearance", "eta", "distance_to_go", "estimate_x", "estimate_y",
    "estimate_variance", "late",
)  # fmt: skip

_RETRY = {"period_init_ms": 100, "period_max_ms": 500, "period_increase_factor": 2}
#: What every :data:`STATE` and :data:`LOG` message carries after its fields: the swarm as
#: its sender knows it (:class:`SwarmBlock`): the re-planning it follows (``phase``, 0 for
#: the mission's start, and the ``step`` it was decided at), whether the UAVs hover, the
#: leader, the members, their slots and the leader's estimate of the target.
SWARM_FIELDS = ("phase", "step", "hover", "leader", "n", "members...", "delta...", "nx",
                "estimate...")  # fmt: skip

_MAGIC = b"CS"
_VERSION = 1
_HEADER = struct.Struct("<2sBBIIi")  # magic, version, kind, sender, step, stamp
#: The sender number of the recorder.
RECORDER = 0xFFFFFFFF


class FlightError(RuntimeError):
    """A flight could not go on: a member never appeared, or a position ran away."""


class ParentGone(RuntimeError):
    """The launcher that started this process has exited."""


def import_zenoh() -> ModuleType:
    """Zenoh's Python module (the optional package ``eclipse-zenoh``).

    Returns
    -------
    module
        ``zenoh``.

    Raises
    ------
    FieldError
        (field ``zenoh``) If it is not installed, naming the extra that installs it.
    """
    try:
        import zenoh
    except ImportError:
        raise FieldError(
            "zenoh",
            "crlbswarm fly needs the optional package eclipse-zenoh: pip install "
            f"'crlbswarm[{FLY_EXTRA}]'",
        ) from None
    return zenoh


def _endpoints(values: Sequence[str], field: str) -> list[str]:
    """Zenoh endpoints ``proto/address``, checked for their form."""
    out = []
    for value in values:
        if not isinstance(value, str) or "/" not in value.strip("/") or " " in value:
            raise FieldError(
                field, f"{value!r} is not a Zenoh endpoint such as tcp/127.0.0.1:7447"
            )
        out.append(value)
    return out


def session_config(listen: Sequence[str], connect: Sequence[str]) -> Any:
    """The Zenoh configuration of a member: peer mode, explicit endpoints, no multicast
    scouting.

    Parameters
    ----------
    listen : sequence of str
        Endpoints to listen on, e.g. ``["tcp/127.0.0.1:7447"]``.
    connect : sequence of str
        Endpoints of other members to connect to (retried every 0.1 s until they answer).

    Returns
    -------
    zenoh.Config
        The configuration.

    Raises
    ------
    FieldError
        (field ``listen`` or ``connect``) For a string that is not an endpoint; (field
        ``zenoh``) without Zenoh.
    """
    zenoh = import_zenoh()
    config = zenoh.Config()
    listen, connect = _endpoints(listen, "listen"), _endpoints(connect, "connect")
    try:
        config.insert_json5("mode", '"peer"')
        config.insert_json5("listen/endpoints", json.dumps(listen))
        config.insert_json5("connect/endpoints", json.dumps(connect))
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("connect/retry", json.dumps(_RETRY))
    except zenoh.ZError as exc:  # (an endpoint Zenoh does not take)
        raise FieldError("listen", f"Zenoh refused the endpoints: {exc}") from None
    return config


def state_key(prefix: str, m: int) -> str:
    """Key expression of UAV ``m``'s swarm state (:data:`STATE`).

    Parameters
    ----------
    prefix : str
        The flight's key prefix.
    m : int
        The UAV.

    Returns
    -------
    str
        ``<prefix>/state/<m>``.
    """
    return f"{prefix}/state/{m}"


def log_key(prefix: str, m: int) -> str:
    """Key expression of UAV ``m``'s log for the recorder (:data:`LOG`).

    Parameters
    ----------
    prefix : str
        The flight's key prefix.
    m : int
        The UAV.

    Returns
    -------
    str
        ``<prefix>/log/<m>``.
    """
    return f"{prefix}/log/{m}"


def done_key(prefix: str) -> str:
    """Key expression of the recorder's end of the flight (:data:`DONE`).

    Parameters
    ----------
    prefix : str
        The flight's key prefix.

    Returns
    -------
    str
        ``<prefix>/done``.
    """
    return f"{prefix}/done"


def member_name(m: int | None) -> str:
    """The name of a member of a flight: ``uav/<m>``, or ``recorder`` for None.

    Parameters
    ----------
    m : int or None
        The UAV, or None for the recorder.

    Returns
    -------
    str
        The name (its liveliness token is ``<prefix>/alive/<name>``).
    """
    return "recorder" if m is None else f"uav/{m}"


def alive_key(prefix: str, name: str) -> str:
    """Key expression of a member's liveliness token.

    Parameters
    ----------
    prefix : str
        The flight's key prefix.
    name : str
        The member (:func:`member_name`).

    Returns
    -------
    str
        ``<prefix>/alive/<name>``.
    """
    return f"{prefix}/alive/{name}"


@dataclass(frozen=True)
class FlightOptions:
    """How a member of a flight talks to the others.

    Parameters
    ----------
    key : str, default DEFAULT_KEY
        The flight's key prefix (every member of a flight uses the same).
    listen : tuple of str, default ("tcp/127.0.0.1:0",)
        Endpoints this member listens on (port 0: any free port).
    connect : tuple of str, default ()
        Endpoints of other members to connect to.
    mode : str, default "stepped"
        ``stepped`` or ``realtime`` (:data:`MODES`).
    timeout : float, default DEFAULT_TIMEOUT
        Stepped mode: how long a UAV waits for a state of the step before it goes on
        with the last it holds, s (a follower waits twice as long for the leader's, which
        may itself wait a timeout for a follower); the recorder waits three times as long
        for a UAV's log before it ends the recording.
    loss : float, default 0
        Probability that a swarm message is lost (injected at the sender).
    delay : int, default 0
        Steps a swarm message is held back at the sender.
    parent : int or None, default None
        The launcher's process id (the member exits when it is gone).
    kill : tuple of (int, float) or None, default None
        ``(uav, time)``: that UAV's process kills itself (SIGKILL) when its mission
        reaches ``time`` (s): a UAV lost, for tests and demonstrations.

    Raises
    ------
    FieldError
        Naming the option that is out of range.
    """

    key: str = DEFAULT_KEY
    listen: tuple[str, ...] = ("tcp/127.0.0.1:0",)
    connect: tuple[str, ...] = ()
    mode: str = "stepped"
    timeout: float = DEFAULT_TIMEOUT
    loss: float = 0.0
    delay: int = 0
    parent: int | None = None
    kill: tuple[int, float] | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise FieldError("mode", f"must be one of {', '.join(MODES)}, got {self.mode!r}")
        _v.positive_scalar(self.timeout, "timeout")
        loss = _v.scalar(self.loss, "loss")
        if not 0.0 <= loss <= 1.0:
            raise FieldError("loss", f"must be a probability in [0, 1], got {loss:g}")
        _v.count(self.delay, "delay", 0, MAX_DELAY)
        if not self.key or any(c in self.key for c in "*$?# ") or self.key.strip("/") != self.key:
            raise FieldError(
                "key", f"{self.key!r} is not a plain key prefix such as {DEFAULT_KEY!r}"
            )
        _endpoints(self.listen, "listen")
        _endpoints(self.connect, "connect")


@dataclass(frozen=True)
class Packet:
    """One message of a flight.

    Parameters
    ----------
    kind : int
        :data:`STATE`, :data:`LOG` or :data:`DONE`.
    sender : int
        The UAV that sent it (the recorder: ``0xFFFFFFFF``).
    step : int
        The sender's step when it sent it.
    stamp : int
        The step its values describe, or :data:`NO_STAMP` if it carries none.
    values : ndarray
        The values (:data:`STATE_FIELDS` or :data:`LOG_FIELDS`; empty without a stamp).
    """

    kind: int
    sender: int
    step: int
    stamp: int
    values: np.ndarray


def encode(packet: Packet) -> bytes:
    """The bytes of a packet: the header, then the values as little-endian float64.

    Parameters
    ----------
    packet : Packet
        The packet.

    Returns
    -------
    bytes
        Its encoding.
    """
    head = _HEADER.pack(_MAGIC, _VERSION, packet.kind, packet.sender, packet.step, packet.stamp)
    return head + np.ascontiguousarray(packet.values, dtype="<f8").tobytes()


def decode(data: bytes) -> Packet | None:
    """A packet from its bytes (:func:`encode`), or None for bytes that are not one (a
    foreign message, another version).

    Parameters
    ----------
    data : bytes
        The payload of a Zenoh sample.

    Returns
    -------
    Packet or None
        The packet.
    """
    if len(data) < _HEADER.size or (len(data) - _HEADER.size) % 8:
        return None
    magic, version, kind, sender, step, stamp = _HEADER.unpack_from(data)
    if magic != _MAGIC or version != _VERSION:
        return None
    values = np.frombuffer(data, dtype="<f8", offset=_HEADER.size).astype(float)
    return Packet(kind, sender, step, stamp, values)


@dataclass(frozen=True, eq=False)
class SwarmBlock:
    """The swarm as a UAV of a flight knows it: the formation flown since the last
    re-planning (:mod:`crlbswarm.faults`), told in every message (:data:`SWARM_FIELDS`).

    Parameters
    ----------
    phase : int
        Re-plannings so far (0: the mission's own formation).
    step : int
        The step the last one was decided at (-1: none).
    hover : bool
        Whether the UAVs hover (too few to fly a formation).
    leader : int
        The leader.
    members : ndarray of int64, shape (M',)
        The UAVs flying the formation (swarm indices, increasing).
    delta : ndarray, shape (M', 2)
        Their slot offsets from the formation's centre, m.
    estimate : ndarray, shape (n,)
        The leader's filter state (sensing in the loop; empty without).
    """

    phase: int
    step: int
    hover: bool
    leader: int
    members: np.ndarray
    delta: np.ndarray
    estimate: np.ndarray

    def newer_than(self, other: SwarmBlock) -> bool:
        """Whether this re-planning comes after ``other``'s.

        Parameters
        ----------
        other : SwarmBlock
            Another block.

        Returns
        -------
        bool
            Later phase, or the same phase decided at a later step.
        """
        return (self.phase, self.step) > (other.phase, other.step)

    def values(self, estimate: np.ndarray | None = None) -> np.ndarray:
        """The block as message values (:data:`SWARM_FIELDS`).

        Parameters
        ----------
        estimate : ndarray, optional
            The estimate to tell instead of the block's own (the leader's current one).

        Returns
        -------
        ndarray
            The values.
        """
        n = self.members.shape[0]
        x = self.estimate if estimate is None else estimate
        head = [self.phase, self.step, float(self.hover), self.leader, n]
        return np.concatenate([head, self.members, self.delta.ravel(), [x.shape[0]], x])

    @classmethod
    def read(cls, values: np.ndarray, start: int) -> SwarmBlock | None:
        """The block in ``values`` from ``start`` (None if there is none, or it is cut).

        Parameters
        ----------
        values : ndarray
            A message's values.
        start : int
            Where the block starts (after the message's own fields).

        Returns
        -------
        SwarmBlock or None
            The block.
        """
        v = values[start:]
        if v.shape[0] < 5:
            return None
        n = int(v[4])
        if n < 0 or v.shape[0] < 6 + 3 * n:
            return None
        nx = int(v[5 + 3 * n])
        if v.shape[0] != 6 + 3 * n + nx:
            return None
        return cls(int(v[0]), int(v[1]), bool(v[2]), int(v[3]),
                   v[5 : 5 + n].astype(np.int64), v[5 + n : 5 + 3 * n].reshape(n, 2).copy(),
                   v[6 + 3 * n :].copy())  # fmt: skip


class Injection:
    """Loss and delay injected at a sender: what its swarm message of each step carries.

    Parameters
    ----------
    seed : int
        The flight's seed (the key of the loss's draws).
    sender : int
        The sending UAV.
    loss : float
        Probability that a message is lost, independently per message.
    delay : int
        Steps a message is held back before it is sent.
    """

    def __init__(self, seed: int, sender: int, loss: float, delay: int) -> None:
        self.keys = stream_key(seed, LOSS_STREAM)
        self.sender = sender
        self.loss = loss
        self.delay = delay
        self.line: dict[int, np.ndarray] = {}  # step -> values held back

    def outgoing(self, step: int, values: np.ndarray) -> tuple[int, np.ndarray] | None:
        """The message of step ``step`` (``values``) enters the sender's line unless it is
        lost; the one of step ``step - delay`` leaves it.

        Parameters
        ----------
        step : int
            The sender's step.
        values : ndarray
            Its state at this step.

        Returns
        -------
        tuple or None
            ``(stamp, values)`` of the message delivered at this step, or None when none
            is (lost, or the first ``delay`` steps).
        """
        if (
            self.loss <= 0.0
            or uniform_pair(*self.keys, step, self.sender, LOSS_STREAM, 0)[0] >= self.loss
        ):
            self.line[step] = values.copy()
        stamp = step - self.delay
        held = self.line.pop(stamp, None)
        return None if held is None else (stamp, held)


class Member:
    """A member's Zenoh session: its publishers, subscribers and liveliness token.

    Parameters
    ----------
    key : str
        The flight's key prefix.
    name : str
        The member (:func:`member_name`).
    listen : sequence of str
        Endpoints it listens on.
    connect : sequence of str
        Endpoints it connects to.
    inbox : Inbox
        Where what it receives goes.

    Raises
    ------
    FieldError
        (field ``listen``) If Zenoh cannot open the session (an endpoint in use or
        unreachable form), or ``zenoh`` without the package.
    """

    def __init__(self, key: str, name: str, listen: Sequence[str], connect: Sequence[str],
                 inbox: Inbox) -> None:  # fmt: skip
        zenoh = import_zenoh()
        self.key = key
        self.name = name
        self.inbox = inbox
        config = session_config(listen, connect)
        try:
            self.session = zenoh.open(config)
        except zenoh.ZError as exc:
            raise FieldError("listen", f"cannot open the Zenoh session: {exc}") from None
        self._zenoh = zenoh
        self._held: list[Any] = []  # subscribers, publishers, token: kept alive
        self._publishers: dict[str, Any] = {}
        alive = self.session.liveliness().declare_subscriber(
            f"{key}/alive/**", inbox.on_alive, history=True
        )
        self._held.append(alive)

    def subscribe(self, keys: Iterable[str]) -> None:
        """Receive the messages of ``keys`` into the inbox.

        Parameters
        ----------
        keys : iterable of str
            Key expressions.
        """
        for k in keys:
            self._held.append(self.session.declare_subscriber(k, self.inbox.on_sample))

    def announce(self) -> None:
        """Declare the member's liveliness token (after its subscribers: a member that sees
        it also has its subscriptions)."""
        token = self.session.liveliness().declare_token(alive_key(self.key, self.name))
        self._held.append(token)

    def publish(self, key: str, packet: Packet) -> None:
        """Send a packet on ``key`` (reliable, never dropped by congestion, not batched).

        Parameters
        ----------
        key : str
            Key expression.
        packet : Packet
            The message.
        """
        pub = self._publishers.get(key)
        if pub is None:
            z = self._zenoh
            pub = self.session.declare_publisher(
                key, congestion_control=z.CongestionControl.BLOCK, express=True,
                reliability=z.Reliability.RELIABLE,
            )  # fmt: skip
            self._publishers[key] = pub
        pub.put(encode(packet))

    def close(self) -> None:
        """Close the session (its token disappears for the others), waiting at most
        :data:`CLOSE_WAIT` seconds: Zenoh's close can hang on a link to a peer that stopped
        without closing it (a frozen process), and the member then exits without it."""
        if self.session.is_closed():
            return
        closing = threading.Thread(target=self.session.close, daemon=True)
        closing.start()
        closing.join(CLOSE_WAIT)


class Inbox:
    """What a member has received, by kind, step and sender, and which members are alive;
    the stepped mode waits on it.

    Parameters
    ----------
    parent : int or None
        The launcher's process id: a wait ends (``ParentGone``) when the process's parent
        is no longer it, so no child outlives a launcher killed outright.
    stepped : bool, default True
        Keep the swarm states by step (the stepped mode); without, only the newest of each
        sender is kept.
    """

    def __init__(self, parent: int | None = None, stepped: bool = True) -> None:
        self.parent = parent
        self.stepped = stepped
        self.changed = threading.Condition()
        self.by_step: dict[tuple[int, int], dict[int, Packet]] = {}
        self.latest: dict[tuple[int, int], Packet] = {}  # (kind, sender) -> newest stamp
        self.alive: set[str] = set()
        self.gone: set[str] = set()  # members seen alive, then not

    def on_sample(self, sample: Any) -> None:
        """Zenoh's callback of a data sample: store the packet.

        Parameters
        ----------
        sample : zenoh.Sample
            The sample.
        """
        packet = decode(bytes(sample.payload.to_bytes()))
        if packet is None:
            return
        with self.changed:
            if self.stepped or packet.kind != STATE:
                self.by_step.setdefault((packet.kind, packet.step), {})[packet.sender] = packet
            if packet.stamp != NO_STAMP:
                old = self.latest.get((packet.kind, packet.sender))
                if old is None or old.stamp <= packet.stamp:
                    self.latest[(packet.kind, packet.sender)] = packet
            self.changed.notify_all()

    def on_alive(self, sample: Any) -> None:
        """Zenoh's callback of a liveliness change: a member appears or disappears.

        Parameters
        ----------
        sample : zenoh.Sample
            The liveliness sample (its key ``<prefix>/alive/<name>``).
        """
        name = str(sample.key_expr).split("/alive/", 1)[-1]
        with self.changed:
            if str(sample.kind).endswith("DELETE"):
                self.alive.discard(name)
                self.gone.add(name)
            else:
                self.alive.add(name)
            self.changed.notify_all()

    def check_parent(self) -> None:
        """Raise ``ParentGone`` if the launcher that started this process has exited.

        Raises
        ------
        ParentGone
            If the process's parent is no longer ``parent``.
        """
        if self.parent is not None and os.getppid() != self.parent:
            raise ParentGone(f"the launcher (process {self.parent}) is gone")

    def wait(self, ready: Any, timeout: float) -> bool:
        """Wait until ``ready()`` (called under the inbox's lock) is true, at most
        ``timeout`` seconds.

        Parameters
        ----------
        ready : callable
            The condition.
        timeout : float
            Longest wait, s.

        Returns
        -------
        bool
            Whether it became true.

        Raises
        ------
        ParentGone
            If the launcher exits meanwhile.
        """
        deadline = time.monotonic() + timeout
        with self.changed:
            while not ready():
                left = deadline - time.monotonic()
                if left <= 0.0:
                    return False
                self.changed.wait(min(left, 0.25))
                self.check_parent()
        return True

    def wait_step(self, kind: int, step: int, senders: Iterable[int], timeout: float,
                  members: dict[int, str]) -> set[int]:  # fmt: skip
        """Wait for the messages of ``kind`` and ``step`` from ``senders``, at most
        ``timeout`` seconds; a sender whose member is gone is not waited for.

        Parameters
        ----------
        kind : int
            The kind of message.
        step : int
            The step.
        senders : iterable of int
            The senders.
        timeout : float
            Longest wait, s.
        members : dict
            Each sender's member name (:func:`member_name`).

        Returns
        -------
        set of int
            The senders whose message did not come (gone, or late).
        """
        wanted = set(senders)

        def missing() -> set[int]:
            got = self.by_step.get((kind, step), {})
            return {s for s in wanted if s not in got and members[s] not in self.gone}

        self.wait(lambda: not missing(), timeout)
        with self.changed:
            got = self.by_step.get((kind, step), {})
            return {s for s in wanted if s not in got}

    def take(self, kind: int, step: int) -> list[Packet]:
        """The packets of ``kind`` of steps up to ``step`` received so far (a late one
        too: its state is still the newest its sender sent), removed from the inbox.

        Parameters
        ----------
        kind : int
            The kind of message.
        step : int
            The step.

        Returns
        -------
        list of Packet
            In the order of their steps.
        """
        with self.changed:
            keys = sorted(key for key in self.by_step if key[0] == kind and key[1] <= step)
            return [p for key in keys for p in self.by_step.pop(key).values()]
