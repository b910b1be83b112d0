r"""Communication graphs of the formation (paper Sec. IV) and their stability bounds.

The formation exchanges information over an undirected graph
:math:`\mathcal G_f = (\mathcal M, \mathcal E, \mathcal A)` with binary adjacency
:math:`a_{mp}`. Graphs are built with networkx and handed to the simulator as CSR adjacency
arrays (:class:`Adjacency`), so that memory and work grow with the number of edges, not
with :math:`M^2`.

Stability of the two discrete-time linear laws (not in the paper; standard results):

* Displacement-based formation control, eq. (16)/(19): the shape error obeys
  :math:`e_{k+1} = (I - \varepsilon L)\, e_k`, which converges iff
  :math:`\varepsilon\,\lambda_{\max}(L) < 2` (and without oscillation iff
  :math:`\varepsilon\,\lambda_{\max}(L) \le 1`).
* Leader-follower velocity consensus, eq. (14) corrected: the followers' error obeys
  :math:`e_{k+1} = (I - \gamma L_{ff})\, e_k` with :math:`L_{ff}` the follower block of the
  Laplacian (positive definite for a connected graph), which converges iff
  :math:`\gamma\,\lambda_{\max}(L_{ff}) < 2`. The sufficient condition crlbswarm's
  scenarios require, :math:`\gamma < 1/\Delta` (:math:`\Delta` the largest degree), also makes
  each update a convex combination, so no velocity ever exceeds the leader's.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from . import _validation as _v
from .errors import FieldError

if TYPE_CHECKING:  # networkx and scipy.sparse are imported when a graph is built
    import networkx as nx
    import scipy.sparse as sp

__all__ = [
    "DELAY_DRAG",
    "GRAPH_KINDS",
    "Adjacency",
    "auto_consensus_step",
    "auto_formation_step",
    "communication_graph",
    "consensus_step_limit",
    "delayed_speed_factor",
    "formation_step_limit",
    "ring_adjacency",
    "settling_steps",
]

#: Graph kinds understood by :func:`communication_graph`, each with the options it takes:
#: the scenario's ``[graph]`` table takes its ``kind`` from here and refuses an option that
#: does not belong to the kind (the options themselves are the keyword arguments of
#: :func:`communication_graph` and fields of the scenario's table).
GRAPH_KINDS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "ring": (),
        "complete": (),
        "path": (),
        "star": ("center",),
        "random_geometric": ("radius", "seed"),
        "edges": ("edges",),
    }
)


@dataclass(frozen=True, eq=False)
class Adjacency:
    """Undirected binary adjacency in CSR form (row ``m`` lists the neighbours of UAV ``m``).

    Parameters
    ----------
    indptr : ndarray of int64, shape (M + 1,)
        CSR row pointers.
    indices : ndarray of int64, shape (2 \\|E\\|,)
        Neighbour indices, sorted within each row.

    Raises
    ------
    FieldError
        If the arrays are not integer CSR arrays of an undirected graph on at least 2 UAVs
        without self-loops in which every UAV has a neighbour (field ``indptr`` or
        ``indices``).
    """

    indptr: np.ndarray
    indices: np.ndarray

    def __post_init__(self) -> None:
        ptr = _index_array(self.indptr, "indptr")
        idx = _index_array(self.indices, "indices")
        n = ptr.shape[0] - 1
        if n < 1 or ptr[0] != 0 or ptr[-1] != idx.shape[0] or np.any(np.diff(ptr) < 0):
            raise FieldError(
                "indptr", "expected CSR row pointers: 0 first, non-decreasing, len(indices) last"
            )
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise FieldError("indices", f"UAV index out of range 0..{n - 1}")
        if n < 2 or np.any(np.diff(ptr) == 0):
            raise FieldError("indices", "every UAV needs a neighbour (and there are at least 2)")
        rows = np.repeat(np.arange(n), np.diff(ptr))
        if np.any(rows == idx):
            raise FieldError("indices", "self-loop")
        forward = np.sort(rows * n + idx)
        if not np.array_equal(forward, np.sort(idx * n + rows)):
            raise FieldError("indices", "the graph must be undirected (symmetric)")
        object.__setattr__(self, "indptr", ptr)
        object.__setattr__(self, "indices", idx)

    @classmethod
    def of_phase(cls, indptr: np.ndarray, indices: np.ndarray) -> Adjacency:
        """CSR arrays taken as they are, unchecked: the graph of a phase of a mission with
        faults (:mod:`crlbswarm.faults`), where a UAV lost and not yet declared lost has no
        neighbour left.

        Parameters
        ----------
        indptr : ndarray of int64, shape (M + 1,)
            CSR row pointers.
        indices : ndarray of int64
            Neighbour indices, sorted within each row, symmetric.

        Returns
        -------
        Adjacency
            The adjacency.
        """
        adjacency = object.__new__(cls)
        object.__setattr__(adjacency, "indptr", np.asarray(indptr, dtype=np.int64))
        object.__setattr__(adjacency, "indices", np.asarray(indices, dtype=np.int64))
        return adjacency

    @classmethod
    def from_graph(cls, graph: nx.Graph) -> Adjacency:
        """Build from a networkx graph on the nodes ``0 .. M-1``.

        Parameters
        ----------
        graph : networkx.Graph
            Undirected graph whose nodes are exactly ``range(M)``.

        Returns
        -------
        Adjacency
            The CSR adjacency.
        """
        import networkx as nx

        n = graph.number_of_nodes()
        if set(graph.nodes) != set(range(n)):
            raise FieldError("graph", "nodes must be the UAV indices 0 .. M-1")
        matrix = nx.to_scipy_sparse_array(graph, nodelist=range(n), format="csr", dtype=float)
        matrix.sort_indices()
        indptr = matrix.indptr.astype(np.int64)
        indices = matrix.indices.astype(np.int64)
        indptr.flags.writeable = False
        indices.flags.writeable = False
        return cls(indptr, indices)

    @property
    def n_nodes(self) -> int:
        """Number of UAVs M."""
        return int(self.indptr.shape[0] - 1)

    @property
    def degrees(self) -> np.ndarray:
        """Degree of each UAV, shape (M,)."""
        return np.diff(self.indptr)

    @property
    def edges(self) -> np.ndarray:
        """Undirected edges ``(m, p)`` with ``m < p``, shape (\\|E\\|, 2)."""
        rows = np.repeat(np.arange(self.n_nodes), self.degrees)
        keep = rows < self.indices
        return np.stack([rows[keep], self.indices[keep]], axis=-1)

    def laplacian(self) -> sp.csr_array:
        """Graph Laplacian :math:`L = D - A`.

        Returns
        -------
        scipy.sparse.csr_array, shape (M, M)
            The Laplacian, sparse.
        """
        import scipy.sparse as sp

        n = self.n_nodes
        adj = sp.csr_array(
            (np.ones(self.indices.shape[0]), self.indices, self.indptr), shape=(n, n)
        )
        return sp.diags_array(self.degrees.astype(float)) - adj


#: Bytes networkx takes per edge and per node, roughly (for the memory check).
_EDGE_BYTES = 300
_NODE_BYTES = 600


def _check_graph_size(kind: str, n: int, radius: object) -> None:
    """Refuse, before building it, a graph whose networkx form would not fit in memory."""
    edges = float(n)
    if kind == "complete":
        edges = n * (n - 1) / 2.0
    elif kind == "random_geometric" and isinstance(radius, numbers.Real):
        try:
            r = min(abs(float(radius)), 2.0)
        except OverflowError:  # an int beyond the floats
            r = 2.0
        share = min(1.0, math.pi * r * r) if math.isfinite(r) else 1.0
        edges = max(float(n), share * n * (n - 1) / 2.0)
    what = f"a {kind} graph on {n} UAVs ({edges:.3g} edges)"
    _v.check_memory(_EDGE_BYTES * edges + _NODE_BYTES * n, "n_uavs", what)


def _index_array(value: object, name: str) -> np.ndarray:
    """A read-only 1-D int64 array of ``value`` (integers only)."""
    try:
        raw = np.asarray(value)
    except Exception as exc:
        raise FieldError(name, "expected a 1-D array of integers") from exc
    if raw.ndim != 1 or raw.dtype.kind not in "iu":
        raise FieldError(name, f"expected a 1-D array of integers, got {raw.dtype} {raw.shape}")
    if raw.dtype == np.int64 and not raw.flags.writeable:
        return raw
    arr = raw.astype(np.int64)
    arr.flags.writeable = False
    return arr


def communication_graph(
    kind: str,
    n_uavs: int,
    *,
    radius: float | None = None,
    seed: int | None = None,
    edges: list[list[int]] | None = None,
    center: int | None = None,
) -> nx.Graph:
    """Build the communication graph of a formation.

    Parameters
    ----------
    kind : str
        One of :data:`GRAPH_KINDS`: ``ring`` (cycle over the UAV indices, the paper's
        default), ``complete``, ``path``, ``star`` (hub ``center``), ``random_geometric``
        (nodes dropped uniformly in the unit square with ``seed``, linked when closer than
        ``radius``; networkx's model) or ``edges`` (the explicit list ``edges``).
    n_uavs : int
        Number of UAVs M >= 2.
    radius : float, optional
        Connection radius of ``random_geometric`` (unit-square units, in (0, sqrt(2)]).
    seed : int, optional
        Seed of ``random_geometric``.
    edges : list of [int, int], optional
        Undirected edges for ``edges``.
    center : int, optional
        Hub of ``star`` (UAV 0 if not given).

    Returns
    -------
    networkx.Graph
        Undirected graph on the nodes ``0 .. M-1``.

    Raises
    ------
    ValueError
        For an unknown kind, missing or bad parameters, self-loops, nodes out of range, or a
        disconnected graph (the formation laws need a connected graph).
    """
    import networkx as nx

    n = _v.count(n_uavs, "n_uavs", 2, _v.MAX_UAVS)
    if not isinstance(kind, str):
        raise FieldError("graph.kind", f"expected one of {', '.join(GRAPH_KINDS)}, got {kind!r}")
    _check_graph_size(kind, n, radius)
    if kind == "ring":
        graph = nx.cycle_graph(n)
    elif kind == "complete":
        graph = nx.complete_graph(n)
    elif kind == "path":
        graph = nx.path_graph(n)
    elif kind == "star":
        c = 0 if center is None else _v.count(center, "graph.center", 0)
        if c >= n:
            raise FieldError("graph.center", f"must be a UAV index below {n}, got {c}")
        graph = nx.relabel_nodes(nx.star_graph(n - 1), lambda i: (i + c) % n)
    elif kind == "random_geometric":
        if radius is None or seed is None:
            raise FieldError("graph", "random_geometric needs 'radius' and 'seed'")
        r = _v.scalar(radius, "graph.radius")
        if not r > 0.0:
            raise FieldError("graph.radius", f"must be > 0, got {radius!r}")
        graph = nx.random_geometric_graph(n, r, seed=_v.count(seed, "graph.seed", 0))
        graph = nx.Graph(graph.edges)
        graph.add_nodes_from(range(n))
    elif kind == "edges":
        if edges is None:
            raise FieldError("graph.edges", "kind 'edges' needs an explicit edge list")
        if isinstance(edges, str | bytes) or not isinstance(edges, Iterable):
            raise FieldError("graph.edges", f"expected a list of pairs [m, p], got {edges!r}")
        graph = nx.Graph()
        graph.add_nodes_from(range(n))
        for i, edge in enumerate(edges):
            if not isinstance(edge, Sequence | np.ndarray) or len(edge) != 2:
                raise FieldError(f"graph.edges[{i}]", f"expected a pair [m, p], got {edge!r}")
            if not all(isinstance(x, numbers.Integral) and not isinstance(x, bool) for x in edge):
                raise FieldError(
                    f"graph.edges[{i}]", f"UAV indices must be integers, got {edge!r}"
                )
            m, p = (int(x) for x in edge)
            if not (0 <= m < n and 0 <= p < n):
                raise FieldError(f"graph.edges[{i}]", f"UAV index out of range 0..{n - 1}")
            if m == p:
                raise FieldError(f"graph.edges[{i}]", f"self-loop on UAV {m}")
            graph.add_edge(m, p)
    else:
        raise FieldError("graph.kind", f"expected one of {', '.join(GRAPH_KINDS)}, got {kind!r}")
    if not nx.is_connected(graph):
        parts = nx.number_connected_components(graph)
        raise FieldError(
            "graph",
            f"the {kind} graph on {n} UAVs is disconnected ({parts} components); "
            "the consensus and formation laws need a connected graph",
        )
    return graph


#: Up to this many UAVs the stability limits use the exact largest eigenvalue.
EXACT_EIGEN_MAX_NODES = 400


def _largest_eigenvalue(matrix: sp.csr_array) -> float:
    """Exact for small graphs; Gershgorin's bound (twice the largest diagonal) above
    :data:`EXACT_EIGEN_MAX_NODES`, which costs O(M) and is tight for regular graphs."""
    if matrix.shape[0] <= EXACT_EIGEN_MAX_NODES:
        return float(np.linalg.eigvalsh(matrix.toarray())[-1])
    return 2.0 * float(matrix.diagonal().max())


def settling_steps(adjacency: Adjacency, leader: int, epsilon: float, gamma: float) -> float:
    r"""Steps for the slower of the two linear laws to shrink its error a hundredfold.

    The shape error decays as :math:`\max_{i \ge 2}|1 - \varepsilon\lambda_i(L)|` per step
    and the followers' velocity error as :math:`\max_i|1 - \gamma\lambda_i(L_{ff})|`; the
    slower rate :math:`\rho` takes :math:`\ln 100 / (-\ln\rho)` steps. Exact eigenvalues up
    to ``EXACT_EIGEN_MAX_NODES`` UAVs; above, ``nan`` (not estimated).

    Parameters
    ----------
    adjacency : Adjacency
        The communication graph.
    leader : int
        Index of the leader.
    epsilon : float
        Formation gain per step.
    gamma : float
        Consensus step.

    Returns
    -------
    float
        Steps (``inf`` if a law does not converge).
    """
    if adjacency.n_nodes > EXACT_EIGEN_MAX_NODES:
        return math.nan
    lap = adjacency.laplacian().toarray()
    keep = np.setdiff1d(np.arange(adjacency.n_nodes), [leader])
    shape = np.linalg.eigvalsh(lap)[1:]
    follow = np.linalg.eigvalsh(lap[np.ix_(keep, keep)])
    rho = max(np.max(np.abs(1.0 - epsilon * shape)), np.max(np.abs(1.0 - gamma * follow)))
    return math.inf if rho >= 1.0 else math.log(100.0) / -math.log(rho)


def formation_step_limit(adjacency: Adjacency) -> float:
    r"""Largest stable formation gain, :math:`2/\lambda_{\max}(L)`.

    For more than ``EXACT_EIGEN_MAX_NODES`` UAVs :math:`\lambda_{\max}(L)` is replaced
    by its Gershgorin bound :math:`2\Delta` (exact for a ring or any bipartite regular
    graph), so the limit :math:`1/\Delta` is sufficient, computed in O(M).

    Parameters
    ----------
    adjacency : Adjacency
        The communication graph.

    Returns
    -------
    float
        The formation law converges if :math:`\varepsilon` is below this value (iff, for
        graphs of up to ``EXACT_EIGEN_MAX_NODES`` UAVs).
    """
    return 2.0 / _largest_eigenvalue(_check_adjacency(adjacency).laplacian())


def auto_formation_step(adjacency: Adjacency, delay: int = 0) -> float:
    r"""The formation gain of ``epsilon = "auto"``: :math:`1/\lambda_{\max}(L)`, or, when
    the neighbours' positions are up to ``delay`` steps old,
    :math:`\min(1/\lambda_{\max}(L),\ 0.15/(\Delta d))`.

    Without delay, half the stability limit: the fastest step at which every mode of the
    shape error, :math:`1 - \varepsilon\lambda_i`, decays without changing sign (the step
    that minimises the spectral radius, :math:`2/(\lambda_2 + \lambda_{\max})`, would make
    the stiffest mode alternate sign every step: the UAVs would zig-zag). With a delay of
    :math:`d` steps eq. (19) steers each UAV toward where its neighbours were :math:`d`
    steps before: a formation that moves is held back, and travels at
    :func:`delayed_speed_factor` :math:`= 1/(1 + \varepsilon\Delta d)` of its speed
    (:math:`\Delta` the largest degree). The gain keeps :math:`\varepsilon\Delta d \le`
    :data:`DELAY_DRAG` (87 % of the speed). It stays stable for any delay: below
    :math:`1/\Delta` each UAV's update is a convex combination of its own position and its
    neighbours' received ones. Not in the paper (``docs/control.md`` sec. 6).

    Parameters
    ----------
    adjacency : Adjacency
        The communication graph.
    delay : int, optional
        The largest age of a neighbour's position the law acts on, steps (0: the state of
        the step; with links, :meth:`crlbswarm.links.LinksConfig.largest_age`).

    Returns
    -------
    float
        :math:`\varepsilon`, per step.
    """
    d = _v.count(delay, "delay", 0)
    step = 0.5 * formation_step_limit(adjacency)
    if d == 0:
        return step
    degree = float(_check_adjacency(adjacency).degrees.max())
    return min(step, DELAY_DRAG / (degree * d))


#: The largest :math:`\varepsilon\Delta d` of ``epsilon = "auto"`` with delayed links
#: (:func:`auto_formation_step`): the formation keeps ``1 / 1.15``, 87 %, of its speed.
#: Chosen from measured missions (``docs/control.md`` sec. 6): a smaller value corrects the
#: shape too slowly, a larger one slows the travel.
DELAY_DRAG = 0.15


def delayed_speed_factor(epsilon: float, degree: float, delay: int) -> float:
    r"""The speed of a formation whose law acts on neighbours' positions ``delay`` steps
    old, as a fraction of its speed without delay: :math:`1/(1 + \varepsilon\Delta d)`.

    A formation translating by :math:`s` per step, each UAV of degree :math:`\Delta`
    steering with eq. (19) toward its neighbours' positions of :math:`d` steps before
    (:math:`\varepsilon\Delta d s` behind where they are) while the consensus velocity
    carries it by :math:`v\Delta T`: :math:`s = v\Delta T - \varepsilon\Delta d\,s`.
    Exact for a regular graph in steady translation.

    Parameters
    ----------
    epsilon : float
        The formation gain, per step.
    degree : float
        :math:`\Delta`, neighbours per UAV.
    delay : int
        :math:`d`, steps.

    Returns
    -------
    float
        :math:`1/(1 + \varepsilon\Delta d)`, in (0, 1].

    Examples
    --------
    >>> delayed_speed_factor(0.25, 2, 3)  # paper_safe's gain without the rule: 40 %
    0.4
    """
    eps = _v.positive_scalar(epsilon, "epsilon")
    deg = _v.scalar(degree, "degree")
    if deg < 0:
        raise FieldError("degree", f"must be >= 0, got {deg:g}")
    return 1.0 / (1.0 + eps * deg * _v.count(delay, "delay", 0))


def auto_consensus_step(adjacency: Adjacency, leader: int) -> float:
    r"""The consensus step of ``gamma = "auto"``: :math:`\min(1/\lambda_{\max}(L_{ff}),
    0.99/\Delta)`.

    The fastest step without sign changes of the followers' velocity error, kept below
    :math:`1/\Delta` so that each update is a convex combination (no velocity exceeds the
    leader's; ``docs/control.md``). Not in the paper.

    Parameters
    ----------
    adjacency : Adjacency
        The communication graph.
    leader : int
        Index of the leader UAV.

    Returns
    -------
    float
        :math:`\gamma`, per step.
    """
    limit = consensus_step_limit(adjacency, leader)
    return min(0.5 * limit, 0.99 / float(adjacency.degrees.max()))


def consensus_step_limit(adjacency: Adjacency, leader: int) -> float:
    r"""Largest stable consensus step, :math:`2/\lambda_{\max}(L_{ff})`.

    Parameters
    ----------
    adjacency : Adjacency
        The communication graph.
    leader : int
        Index of the leader UAV.

    Returns
    -------
    float
        The leader-follower consensus converges if :math:`\gamma` is below this value (iff,
        for graphs of up to ``EXACT_EIGEN_MAX_NODES`` UAVs; above, the Gershgorin bound
        is used as in :func:`formation_step_limit`). Scenarios require the stricter
        :math:`\gamma < 1/\Delta` (``docs/control.md``), under which no velocity overshoots.
    """
    lap = _check_adjacency(adjacency).laplacian()
    lead = _v.count(leader, "leader", 0)
    if lead >= adjacency.n_nodes:
        raise FieldError("leader", f"must be a UAV index below {adjacency.n_nodes}, got {lead}")
    keep = np.setdiff1d(np.arange(adjacency.n_nodes), [lead])
    return 2.0 / _largest_eigenvalue(lap[keep][:, keep])


def _check_adjacency(adjacency: object) -> Adjacency:
    if not isinstance(adjacency, Adjacency):
        raise FieldError(
            "adjacency", f"expected a crlbswarm.Adjacency, got {type(adjacency).__name__}"
        )
    return adjacency


def ring_adjacency(n_uavs: int) -> Adjacency:
    """The ring on ``n_uavs`` UAVs as CSR adjacency, built directly (UAV m's neighbours
    m - 1 and m + 1 modulo M, in increasing order): the same arrays as
    ``Adjacency.from_graph(communication_graph("ring", n_uavs))`` without importing
    networkx and SciPy's sparse matrices (the scenario of the paper flies a ring).

    Parameters
    ----------
    n_uavs : int
        Number of UAVs M >= 2.

    Returns
    -------
    Adjacency
        The CSR adjacency.
    """
    n = _v.count(n_uavs, "n_uavs", 2, _v.MAX_UAVS)
    m = np.arange(n, dtype=np.int64)
    if n == 2:
        indices = np.array([1, 0], dtype=np.int64)
        indptr = np.array([0, 1, 2], dtype=np.int64)
    else:
        pair = np.stack([(m - 1) % n, (m + 1) % n], axis=1)
        indices = np.sort(pair, axis=1).reshape(-1)
        indptr = 2 * np.arange(n + 1, dtype=np.int64)
    indptr.flags.writeable = False
    indices.flags.writeable = False
    return Adjacency(indptr, indices)
