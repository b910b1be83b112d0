"""Communication graphs and their stability bounds (crlbswarm.graphs).

Every graph kind is checked against its edge set written out by hand, the CSR adjacency and
the Laplacian against networkx and against a Laplacian built in the test from the edge
list, and the two stability limits against eigenvalues computed here with numpy (and, for
the ring, path, star and complete graphs, against the closed-form Laplacian spectra).
"""

from __future__ import annotations

import itertools
import math
import re

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, strategies as st

from crlbswarm import (
    GRAPH_KINDS,
    Adjacency,
    communication_graph,
    consensus_step_limit,
    formation_step_limit,
)
from crlbswarm.graphs import DELAY_DRAG, auto_formation_step, delayed_speed_factor

SIZES = [2, 3, 4, 5, 6, 7, 10]


def edge_set(graph: nx.Graph) -> set[tuple[int, int]]:
    """Undirected edges as sorted pairs."""
    return {(min(m, p), max(m, p)) for m, p in graph.edges}


def laplacian_by_hand(n: int, edges) -> np.ndarray:
    """L = D - A from an edge list with plain loops (no networkx, no crlbswarm)."""
    lap = [[0.0] * n for _ in range(n)]
    for m, p in edges:
        lap[m][p] -= 1.0
        lap[p][m] -= 1.0
        lap[m][m] += 1.0
        lap[p][p] += 1.0
    return np.array(lap)


def expected_edges(kind: str, n: int, center: int = 0) -> set[tuple[int, int]]:
    """The edge set of each deterministic kind, written out from its definition."""
    if kind == "ring":
        pairs = [(i, (i + 1) % n) for i in range(n)]
    elif kind == "path":
        pairs = [(i, i + 1) for i in range(n - 1)]
    elif kind == "star":
        pairs = [(center, i) for i in range(n) if i != center]
    elif kind == "complete":
        pairs = list(itertools.combinations(range(n), 2))
    else:  # pragma: no cover
        raise AssertionError(kind)
    return {(min(m, p), max(m, p)) for m, p in pairs if m != p}


# -- builders ---------------------------------------------------------------------------------


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("kind", ["ring", "path", "star", "complete"])
def test_deterministic_kinds_have_the_defined_edges(kind, n):
    """ring = cycle over the indices, path, star around UAV 0, complete: exact edge sets."""
    graph = communication_graph(kind, n)
    assert sorted(graph.nodes) == list(range(n))
    assert nx.is_connected(graph)
    assert edge_set(graph) == expected_edges(kind, n)
    counts = {"ring": n if n > 2 else 1, "path": n - 1, "star": n - 1}
    assert graph.number_of_edges() == counts.get(kind, n * (n - 1) // 2)


@pytest.mark.parametrize("center", [0, 2, 5])
def test_star_hub(center):
    """The hub is the given UAV and is linked to every other UAV, and only to them."""
    graph = communication_graph("star", 6, center=center)
    assert edge_set(graph) == expected_edges("star", 6, center)
    assert graph.degree[center] == 5
    assert all(graph.degree[i] == 1 for i in range(6) if i != center)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_random_geometric_links_points_closer_than_radius(seed):
    """Connected, M nodes, and the edges are exactly the pairs of networkx's sample points
    closer than the radius (distances recomputed here)."""
    n, radius = 8, 0.7
    graph = communication_graph("random_geometric", n, radius=radius, seed=seed)
    pos = nx.random_geometric_graph(n, radius, seed=seed).nodes(data="pos")
    near = {
        (m, p)
        for m, p in itertools.combinations(range(n), 2)
        if math.dist(pos[m], pos[p]) <= radius
    }
    assert sorted(graph.nodes) == list(range(n))
    assert nx.is_connected(graph)
    assert edge_set(graph) == near


def test_random_geometric_is_seeded():
    """Same seed, same graph; the graph is a function of the seed only."""
    a = communication_graph("random_geometric", 12, radius=0.5, seed=7)
    b = communication_graph("random_geometric", 12, radius=0.5, seed=7)
    assert edge_set(a) == edge_set(b)


def test_explicit_edges():
    """kind 'edges' builds exactly the listed edges (duplicates and order do not matter)."""
    edges = [[0, 3], [3, 1], [1, 2], [2, 0], [3, 0]]
    graph = communication_graph("edges", 4, edges=edges)
    assert edge_set(graph) == {(0, 3), (1, 3), (1, 2), (0, 2)}
    assert sorted(graph.nodes) == [0, 1, 2, 3]


@pytest.mark.parametrize(
    ("kind", "kwargs"),
    [
        ("edges", {"edges": [[0, 1], [2, 3]]}),
        ("edges", {"edges": [[0, 1], [1, 2]]}),  # UAV 3 isolated
        ("random_geometric", {"radius": 0.01, "seed": 0}),
    ],
)
def test_disconnected_graph_is_rejected(kind, kwargs):
    """A disconnected graph raises ValueError naming 'graph'."""
    with pytest.raises(ValueError, match=r"^graph") as info:
        communication_graph(kind, 4, **kwargs)
    assert "disconnected" in str(info.value)


@pytest.mark.parametrize(
    ("kind", "n", "kwargs", "field"),
    [
        ("hexagon", 4, {}, "graph.kind"),
        ("ring", 1, {}, "n_uavs"),
        ("ring", 4.0, {}, "n_uavs"),
        ("star", 4, {"center": 4}, "graph.center"),
        ("random_geometric", 4, {"radius": 0.5}, "graph"),
        ("random_geometric", 4, {"radius": -0.5, "seed": 0}, "graph.radius"),
        ("edges", 4, {}, "graph.edges"),
        ("edges", 4, {"edges": [[0, 1, 2]]}, "graph.edges[0]"),
        ("edges", 4, {"edges": [[0, 1], [1, 4]]}, "graph.edges[1]"),
        ("edges", 4, {"edges": [[0, 1], [2, 2]]}, "graph.edges[1]"),
    ],
)
def test_bad_parameters_name_the_field(kind, n, kwargs, field):
    """Each invalid input raises ValueError whose message starts with the field's name."""
    with pytest.raises(ValueError, match=r"^" + re.escape(field) + ":"):
        communication_graph(kind, n, **kwargs)


def test_graph_kinds_listed():
    assert set(GRAPH_KINDS) == {"ring", "complete", "path", "star", "random_geometric", "edges"}


# -- adjacency --------------------------------------------------------------------------------


def sample_graphs():
    """A spread of connected graphs with their names."""
    yield "ring6", communication_graph("ring", 6)
    yield "path5", communication_graph("path", 5)
    yield "star7", communication_graph("star", 7, center=3)
    yield "complete5", communication_graph("complete", 5)
    yield "rgg", communication_graph("random_geometric", 15, radius=0.5, seed=3)
    yield "edges", communication_graph("edges", 5, edges=[[4, 0], [0, 2], [2, 1], [1, 3], [3, 4]])


@pytest.mark.parametrize(("name", "graph"), list(sample_graphs()))
def test_adjacency_csr_matches_networkx(name, graph):
    """Row m of the CSR lists the neighbours of m, sorted, as networkx says; degrees and
    the edge list agree too."""
    adj = Adjacency.from_graph(graph)
    n = graph.number_of_nodes()
    assert adj.n_nodes == n
    assert adj.indptr.dtype == np.int64
    assert adj.indices.dtype == np.int64
    dense = np.zeros((n, n))
    for m in range(n):
        row = adj.indices[adj.indptr[m] : adj.indptr[m + 1]]
        assert list(row) == sorted(graph.neighbors(m))
        dense[m, row] = 1.0
    np.testing.assert_array_equal(dense, nx.to_numpy_array(graph, nodelist=range(n)))
    np.testing.assert_array_equal(adj.degrees, [graph.degree[m] for m in range(n)])
    assert {tuple(e) for e in adj.edges.tolist()} == edge_set(graph)
    assert all(m < p for m, p in adj.edges.tolist())


@pytest.mark.parametrize(("name", "graph"), list(sample_graphs()))
def test_laplacian_matches_networkx_and_hand_built(name, graph):
    n = graph.number_of_nodes()
    lap = Adjacency.from_graph(graph).laplacian().toarray()
    np.testing.assert_array_equal(lap, nx.laplacian_matrix(graph, nodelist=range(n)).toarray())
    np.testing.assert_array_equal(lap, laplacian_by_hand(n, graph.edges))


def test_from_graph_needs_nodes_0_to_m_minus_1():
    graph = nx.Graph([(1, 2), (2, 3)])
    with pytest.raises(ValueError, match=r"^graph"):
        Adjacency.from_graph(graph)


def test_from_graph_uses_node_labels_not_insertion_order():
    """Nodes inserted out of order: row m is still UAV m."""
    graph = nx.Graph()
    graph.add_edges_from([(3, 0), (0, 2), (2, 1)])
    adj = Adjacency.from_graph(graph)
    assert [list(adj.indices[adj.indptr[m] : adj.indptr[m + 1]]) for m in range(4)] == [
        [2, 3],
        [2],
        [0, 1],
        [0],
    ]


# -- stability limits -------------------------------------------------------------------------


def closed_form_lambda_max(kind: str, n: int) -> float:
    """Largest Laplacian eigenvalue from the textbook spectra."""
    if kind == "ring":  # 2 - 2 cos(2 pi j / n), j = 0..n-1
        return max(2.0 - 2.0 * math.cos(2.0 * math.pi * j / n) for j in range(n))
    if kind == "path":  # 2 - 2 cos(pi j / n), j = 0..n-1
        return 2.0 - 2.0 * math.cos(math.pi * (n - 1) / n)
    if kind in ("star", "complete"):  # both have n as their largest eigenvalue
        return float(n)
    raise AssertionError(kind)  # pragma: no cover


@pytest.mark.parametrize("n", [3, 4, 5, 6, 9, 12])
@pytest.mark.parametrize("kind", ["ring", "path", "star", "complete"])
def test_formation_step_limit_closed_form(kind, n):
    """2 / lambda_max(L) with lambda_max from the known spectra of these graphs."""
    limit = formation_step_limit(Adjacency.from_graph(communication_graph(kind, n)))
    assert limit == pytest.approx(2.0 / closed_form_lambda_max(kind, n), rel=1e-12)


@pytest.mark.parametrize(("name", "graph"), list(sample_graphs()))
def test_formation_step_limit_eigenvalue(name, graph):
    n = graph.number_of_nodes()
    lam = np.linalg.eigvalsh(laplacian_by_hand(n, graph.edges))[-1]
    limit = formation_step_limit(Adjacency.from_graph(graph))
    assert limit == pytest.approx(2.0 / lam, rel=1e-12)


@pytest.mark.parametrize(("name", "graph"), list(sample_graphs()))
def test_consensus_step_limit_eigenvalue(name, graph):
    """2 / lambda_max of the follower block of L (leader's row and column removed)."""
    n = graph.number_of_nodes()
    lap = laplacian_by_hand(n, graph.edges)
    adj = Adjacency.from_graph(graph)
    for leader in range(n):
        followers = [i for i in range(n) if i != leader]
        block = lap[np.ix_(followers, followers)]
        lam = np.linalg.eigvalsh(block)[-1]
        assert consensus_step_limit(adj, leader) == pytest.approx(2.0 / lam, rel=1e-12)


def test_star_consensus_limit_by_hand():
    """Star, hub = leader: the followers only see the leader, L_ff = I, limit = 2.
    Star, leader = a leaf: L_ff has the hub (degree n-1) and n-2 leaves; its largest
    eigenvalue solves l^2 - n l + 1 = 0 on the symmetric subspace."""
    n = 6
    adj = Adjacency.from_graph(communication_graph("star", n, center=0))
    assert consensus_step_limit(adj, 0) == pytest.approx(2.0, rel=1e-12)
    lam = (n + math.sqrt(n * n - 4.0)) / 2.0
    assert consensus_step_limit(adj, 1) == pytest.approx(2.0 / lam, rel=1e-12)


def test_large_graph_limits_use_the_gershgorin_bound():
    """Beyond EXACT_EIGEN_MAX_NODES the limits use lambda_max <= 2 * max degree: a
    sufficient bound (never above the exact limit), exact for an even ring's Laplacian."""
    from crlbswarm.graphs import EXACT_EIGEN_MAX_NODES

    n = EXACT_EIGEN_MAX_NODES + 50
    adj = Adjacency.from_graph(communication_graph("ring", n))
    assert formation_step_limit(adj) == pytest.approx(2.0 / 4.0, rel=1e-12)  # n even: 4
    lap = laplacian_by_hand(n, communication_graph("ring", n).edges)[1:, 1:]
    lam = np.linalg.eigvalsh(lap)[-1]
    assert consensus_step_limit(adj, 0) <= 2.0 / lam
    assert consensus_step_limit(adj, 0) == pytest.approx(2.0 / lam, rel=1e-4)


@st.composite
def connected_edge_lists(draw):
    """A random connected graph: a random spanning tree plus random extra edges."""
    n = draw(st.integers(2, 12))
    order = draw(st.permutations(range(n)))
    edges = []
    for i in range(1, n):
        parent = order[draw(st.integers(0, i - 1))]
        edges.append((order[i], parent))
    pairs = list(itertools.combinations(range(n), 2))
    extra = draw(st.lists(st.sampled_from(pairs), max_size=2 * n)) if pairs else []
    return n, edges + extra


@given(connected_edge_lists(), st.data())
def test_random_connected_graphs(graph_spec, data):
    """For any connected graph: Laplacian = hand-built, both limits = 2/lambda_max."""
    n, edges = graph_spec
    graph = communication_graph("edges", n, edges=[list(e) for e in edges])
    adj = Adjacency.from_graph(graph)
    lap = laplacian_by_hand(n, edge_set(graph))
    np.testing.assert_array_equal(adj.laplacian().toarray(), lap)
    assert formation_step_limit(adj) == pytest.approx(2.0 / np.linalg.eigvalsh(lap)[-1], 1e-12)
    leader = data.draw(st.integers(0, n - 1))
    keep = [i for i in range(n) if i != leader]
    lam_ff = np.linalg.eigvalsh(lap[np.ix_(keep, keep)])[-1]
    assert consensus_step_limit(adj, leader) == pytest.approx(2.0 / lam_ff, rel=1e-12)


def test_explicit_edges_must_be_integers():
    with pytest.raises(ValueError, match=r"^graph\.edges\[0\]"):
        communication_graph("edges", 3, edges=[[0, 1.7], [1, 2]])


@pytest.mark.parametrize("n", [2, 3, 4, 7, 100, 1001])
def test_ring_adjacency_is_the_ring_graph(n):
    """The ring built directly (the scenario's path for the paper's graph) has the arrays
    of the networkx ring."""
    from crlbswarm.graphs import Adjacency, communication_graph, ring_adjacency

    direct = ring_adjacency(n)
    ref = Adjacency.from_graph(communication_graph("ring", n))
    np.testing.assert_array_equal(direct.indptr, ref.indptr)
    np.testing.assert_array_equal(direct.indices, ref.indices)
    assert direct.indptr.dtype == ref.indptr.dtype
    assert direct.indices.dtype == ref.indices.dtype


def _delayed_formation(adj_matrix: np.ndarray, eps: float, d: int, steps: int = 3000):
    """Eq. (19) in plain NumPy on a formation that translates at one velocity (each UAV's
    own position current, its neighbours' ``d`` steps old; slots at 0): the positions
    (1-D) of every step, from rest at 0, carried by 1 m per step."""
    m = adj_matrix.shape[0]
    q = np.zeros((steps + 1, m))
    for k in range(steps):
        old = q[max(k - d, 0)]
        pull = eps * (adj_matrix @ old - adj_matrix.sum(axis=1) * q[k])
        q[k + 1] = q[k] + 1.0 + pull
    return q


def _lifted_radius(adj_matrix: np.ndarray, eps: float, d: int) -> float:
    """Largest modulus, but the consensus mode's 1, of e_{k+1} = (I - eps D) e_k +
    eps A e_{k-d} (eq. (19), own position current, neighbours' d steps old)."""
    m = adj_matrix.shape[0]
    big = np.zeros((m * (d + 1), m * (d + 1)))
    big[:m, :m] = np.eye(m) - eps * np.diag(adj_matrix.sum(axis=1))
    big[:m, m * d :] += eps * adj_matrix
    big[m:, :-m] += np.eye(m * d)
    moduli = np.sort(np.abs(np.linalg.eigvals(big)))
    return float(moduli[-2])  # (the largest is the consensus mode, 1)


@pytest.mark.parametrize("d", [1, 3, 10])
@pytest.mark.parametrize("eps", [0.02, 0.1, 0.25])
def test_delayed_formation_moves_at_the_speed_factor(d, eps):
    """A ring (regular) translating: steady speed 1/(1 + eps Delta d) of the carried one."""
    graph = communication_graph("ring", 6)
    a = np.zeros((6, 6))
    for m, p in edge_set(graph):
        a[m, p] = a[p, m] = 1.0
    q = _delayed_formation(a, eps, d)
    assert q[-1, 0] - q[-2, 0] == pytest.approx(delayed_speed_factor(eps, 2, d), rel=1e-9)
    assert np.ptp(q[-1]) < 1e-9  # (the shape holds)


@pytest.mark.parametrize("kind", ["ring", "complete", "star", "path"])
@pytest.mark.parametrize("n", [3, 6, 10])
def test_auto_formation_step_with_delay_keeps_speed_and_stability(kind, n):
    """Without delay the "auto" gain is 1/lambda_max(L), the same bits as before delays;
    with d steps eps Delta d <= DELAY_DRAG (13 % of the speed lost at most) and the delayed
    law is stable (lifted system, computed here)."""
    graph = communication_graph(kind, n)
    adj = Adjacency.from_graph(graph)
    a = np.zeros((n, n))
    for m, p in edge_set(graph):
        a[m, p] = a[p, m] = 1.0
    lam = np.linalg.eigvalsh(np.array(laplacian_by_hand(n, edge_set(graph))))
    degree = a.sum(axis=1).max()
    assert auto_formation_step(adj) == 0.5 * formation_step_limit(adj)
    assert auto_formation_step(adj, 0) == auto_formation_step(adj)
    for d in (1, 3, 10):
        eps = auto_formation_step(adj, d)
        assert eps <= 1.0 / lam[-1] * (1 + 1e-12)
        assert eps * degree * d <= DELAY_DRAG * (1 + 1e-12)
        assert eps == pytest.approx(min(1.0 / lam[-1], 0.15 / (degree * d)), rel=1e-9)
        assert _lifted_radius(a, eps, d) < 1.0


@pytest.mark.parametrize("delay", [-1, 1.5, "3", True])
def test_auto_formation_step_refuses_a_bad_delay(delay):
    with pytest.raises(ValueError, match="delay"):
        auto_formation_step(Adjacency.from_graph(communication_graph("ring", 6)), delay)
