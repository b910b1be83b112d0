"""Mission simulator (crlbswarm.simulation): acceptance on the paper scenario, exact checks.

* The paper scenario, seeds 0-49 in one batch: the acceptance criteria of issue 3 (clearance,
  CRLB at the bound of eq. (11) computed from conftest's reference model, centroid over the
  target, eta back at 1 and below 1 in the passage, the cost bump and its decay), with the
  clearance, the cost and the CRLB recomputed here, not taken from the simulator.
* Each step of the simulator is the composition of the public laws of crlbswarm.control
  (those are checked against hand-written references in tests/test_control.py).
* Without obstacles, noise or guidance the positions follow (I - eps L)^k exactly.
* Relabellings that are symmetries of the problem give the same trajectories, relabelled.
* Batches equal single runs bit for bit; a diverging run is reported with its run, seed and
  step.
"""

from __future__ import annotations

import copy
import json
import math

import networkx as nx
import numpy as np
import pytest

import crlbswarm.simulation as simulation_module
from conftest import PAPER_LAWS
from crlbswarm import (
    BUILTIN_SCENARIOS,
    MissionResult,
    Scenario,
    SimulationDivergedError,
    consensus_step,
    eta_target,
    eta_update,
    formation_cost,
    formation_input,
    leader_guidance,
    load_scenario,
    obstacle_clearance,
    repulsion,
    simulate,
    start_positions,
)

PAPER_SEEDS = range(50)
ARRAYS = (
    "positions",
    "velocities",
    "reference_velocity",
    "eta",
    "crlb",
    "cost",
    "clearance",
    "separation",
    "centroid",
)


def paper_dict(**changes) -> dict:
    d = copy.deepcopy(BUILTIN_SCENARIOS["paper"])
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(d.get(key), dict):
            d[key].update(value)
        else:
            d[key] = value
    return d


# -- independent references -------------------------------------------------------------------
def rect_clearance(points: np.ndarray, rects) -> np.ndarray:
    """Signed distance from points (..., 2) to the nearest axis-aligned rectangle."""
    x, y = points[..., 0], points[..., 1]
    best = np.full(x.shape, np.inf)
    for xmin, xmax, ymin, ymax in rects:
        dx = np.maximum(np.maximum(xmin - x, x - xmax), 0.0)
        dy = np.maximum(np.maximum(ymin - y, y - ymax), 0.0)
        inside = (dx == 0.0) & (dy == 0.0)
        depth = np.minimum(np.minimum(x - xmin, xmax - x), np.minimum(y - ymin, ymax - y))
        best = np.minimum(best, np.where(inside, -depth, np.hypot(dx, dy)))
    return best


def cost_reference(positions, vref, delta, edges, dt) -> np.ndarray:
    """Eq. (15) summed over UAVs: each undirected edge appears twice in sum_m sum_p."""
    q, qn = positions[..., :-1, :, :], positions[..., 1:, :, :]
    e = q - delta
    shape = sum(np.sum((e[..., m, :] - e[..., p, :]) ** 2, axis=-1) for m, p in edges)
    speed = np.sum(((qn - q) / dt - vref[..., :-1, None, :]) ** 2, axis=(-2, -1))
    return 2.0 * shape + speed


def bound_reference(ref, n_uavs: int, altitude: float) -> float:
    """4 / sum_m w(phi*), phi* by brentq on conftest's dw/dphi."""
    a = float(ref.snr_constant(ref.radar_params()))
    phi = ref.optimal_elevation_numeric(altitude, a)
    return 4.0 / (n_uavs * float(ref.information_weight(phi, altitude, a)))


def paper_rects(sc: Scenario) -> list[list[float]]:
    return [[*o.x, *o.y] for o in sc.obstacles]


# =============================================================================================
# Paper scenario acceptance (issue 3)
# =============================================================================================
@pytest.fixture(scope="module")
def paper():
    sc = load_scenario("paper")
    return sc, simulate(sc, seeds=PAPER_SEEDS)


@pytest.fixture(scope="module")
def passage(paper):
    """Per run: the steps where some UAV is within l_safe of an obstacle (clearance
    recomputed here), and the first and last of them."""
    sc, res = paper
    clearance = rect_clearance(res.positions, paper_rects(sc)).min(axis=-1)  # (B, K+1)
    near = clearance < sc.control.safety_radius
    assert near.any(axis=1).all(), "every run must pass near an obstacle"
    first = np.argmax(near, axis=1)
    last = near.shape[1] - 1 - np.argmax(near[:, ::-1], axis=1)
    return clearance, near, first, last


def test_paper_min_clearance_positive(paper, passage, record_property):
    """No UAV ever enters an obstacle, in any of the 50 runs."""
    _, res = paper
    clearance = passage[0]
    smallest = float(clearance.min())
    record_property("smallest_min_clearance_m", smallest)
    print(f"smallest min clearance over seeds 0-49: {smallest:.4f} m")
    assert np.all(clearance.min(axis=1) > 0.0)
    np.testing.assert_allclose(res.clearance, clearance, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.metrics["min_clearance_m"], clearance.min(axis=1), atol=1e-12)


def test_paper_final_crlb_at_the_bound(paper, ref, record_property):
    """At t = 150 s the CRLB (recomputed by conftest's Slepian-Bangs FIM) is within 1% of
    4/sum(w*) (conftest's brentq elevation)."""
    sc, res = paper
    bound = bound_reference(ref, 6, 20.0)
    assert res.bound == pytest.approx(bound, rel=1e-9)
    prm = ref.radar_params()
    final = np.array(
        [
            ref.crlb_of_fim(ref.fim_slepian_bangs(q, np.array(sc.target), 20.0, prm))
            for q in res.positions[:, -1]
        ]
    )
    np.testing.assert_allclose(res.crlb[:, -1], final, rtol=1e-9)
    ratio = final / bound
    record_property("worst_final_crlb_ratio", float(ratio.max()))
    print(f"worst final CRLB / bound: {ratio.max():.6f}")
    assert np.all(ratio >= 1.0 - 1e-9)  # nothing beats the bound
    assert np.all(ratio <= 1.01)
    assert res.time[-1] == pytest.approx(150.0)


def test_paper_centroid_over_target_and_eta_back_to_one(paper, record_property):
    sc, res = paper
    centroid = res.positions[:, -1].mean(axis=-2)
    err = np.hypot(*(centroid - np.array(sc.target)).T)
    record_property("worst_final_centroid_error_m", float(err.max()))
    print(f"worst final centroid error: {err.max():.4f} m; final eta: {np.unique(res.eta[:, -1])}")
    assert np.all(err < 0.5)
    np.testing.assert_allclose(res.metrics["final_centroid_error_m"], err, atol=1e-12)
    assert np.all(res.eta[:, -1] == 1.0)
    assert np.all((res.eta > 0.0) & (res.eta <= 1.0))
    assert np.all(res.eta >= sc.eta.minimum)


def test_paper_eta_below_one_in_the_passage(paper, passage, record_property):
    """Whenever some UAV is within l_safe of an obstacle the formation is shrunk."""
    sc, res = paper
    near = passage[1]
    worst = float(res.eta[near].max())
    record_property("max_eta_in_passage", worst)
    print(f"largest eta while some UAV is within l_safe: {worst:.4f}")
    assert worst < 1.0
    # And eta changes by at most rate * dT per step.
    assert np.max(np.abs(np.diff(res.eta, axis=1))) <= sc.eta.rate * sc.time.step * (1 + 1e-12)


def test_paper_cost_rises_in_the_passage_and_decays(paper, passage, record_property):
    """The cost (recomputed from the trajectories) peaks inside the passage above its value
    when the passage starts, and ends below 1% of that peak."""
    sc, res = paper
    _, _, first, last = passage
    delta = sc.slots - np.array(sc.target)
    edges = [(i, (i + 1) % 6) for i in range(6)]
    cost = cost_reference(res.positions, res.reference_velocity, delta, edges, sc.time.step)
    np.testing.assert_allclose(res.cost, cost, rtol=1e-10, atol=1e-10)
    at_start = cost[np.arange(50), first]
    peak = np.array([cost[b, first[b] : last[b] + 1].max() for b in range(50)])
    final = cost[:, -1]
    record_property("passage_cost_at_start_min", float(at_start.min()))
    record_property("passage_cost_peak_min", float(peak.min()))
    record_property("final_over_peak_max", float((final / peak).max()))
    print(
        f"passage: cost at start {at_start.min():.1f}-{at_start.max():.1f}, peak "
        f"{peak.min():.1f}-{peak.max():.1f}, peak/start >= {(peak / at_start).min():.3f}, "
        f"final {final.max():.3f} (final/peak <= {(final / peak).max():.2e}); passage from "
        f"{res.time[first].min():.1f}-{res.time[first].max():.1f} s to "
        f"{res.time[last].min():.1f}-{res.time[last].max():.1f} s"
    )
    assert np.all(peak > at_start)
    assert np.all(final < 0.01 * peak)


def test_paper_metrics_and_summary(paper):
    _, res = paper
    assert isinstance(res, MissionResult)
    assert res.n_runs == 50
    np.testing.assert_array_equal(res.seeds, np.arange(50))
    assert res.positions.shape == (50, 1501, 6, 2)
    assert res.cost.shape == (50, 1500)
    np.testing.assert_allclose(res.time, np.arange(1501) * 0.1, rtol=0, atol=1e-12)
    assert np.all(np.isfinite(res.metrics["convergence_time_s"]))
    summary = res.summary()
    json.dumps(summary)
    assert summary["runs"] == 50
    assert summary["steps"] == 1500
    # (runs whose outcome is converged: a run may settle, and so have a convergence time, yet
    # collide)
    assert summary["converged_runs"] == list(res.metrics["outcome"]).count("converged")
    assert summary["min_clearance_m"]["min"] == pytest.approx(res.clearance.min())


def test_paper_toml_round_trip_is_bit_identical(paper):
    """The file printed by to_toml(), read back, gives bit-identical missions."""
    sc, res = paper
    back = Scenario.from_toml(sc.to_toml(), source="paper.toml")
    again = simulate(back, seeds=PAPER_SEEDS)
    for name in ARRAYS:
        assert np.array_equal(getattr(again, name), getattr(res, name)), name
    assert again.bound == res.bound


# =============================================================================================
# Determinism, batches and seeds
# =============================================================================================
@pytest.fixture(scope="module")
def batch6(paper):
    sc, _ = paper
    return simulate(sc, seeds=range(6))


@pytest.mark.parametrize("b", range(6))
def test_batch_run_equals_single_run(paper, batch6, b):
    sc, _ = paper
    single = simulate(sc, seed=b)
    for name in ARRAYS:
        assert np.array_equal(getattr(batch6, name)[b], getattr(single, name)[0]), name
    for key, values in batch6.metrics.items():
        assert np.array_equal(
            values[b], single.metrics[key][0], equal_nan=values.dtype.kind == "f"
        ), key


def test_same_seed_twice_identical_and_seeds_differ(paper, batch6):
    sc, res50 = paper
    again = simulate(sc, seeds=range(6))
    for name in ARRAYS:
        assert np.array_equal(getattr(again, name), getattr(batch6, name)), name
        # The first 6 runs of the 50-run batch are the same runs.
        assert np.array_equal(getattr(res50, name)[:6], getattr(batch6, name)), name
    for a in range(6):
        for b in range(a + 1, 6):
            assert not np.array_equal(batch6.positions[a, 0], batch6.positions[b, 0])
            assert not np.array_equal(batch6.positions[a, 1:], batch6.positions[b, 1:])


def test_batch_order_and_chunking_do_not_matter(paper, batch6, monkeypatch):
    """Seeds in another order give the same runs reordered; chunks of at most 4 runs
    (instead of 256) give the same bits, and progress is reported after each chunk."""
    sc, _ = paper
    order = [4, 1, 5, 0, 3, 2]
    shuffled = simulate(sc, seeds=order)
    np.testing.assert_array_equal(shuffled.seeds, order)
    for name in ARRAYS:
        assert np.array_equal(getattr(shuffled, name), getattr(batch6, name)[order]), name
    monkeypatch.setattr(simulation_module, "CHUNK_RUNS", 4)
    calls = []
    chunked = simulate(sc, seeds=range(6), progress=calls.append)
    assert calls[-1] == 6
    assert np.all(np.diff([0, *calls]) >= 1)
    assert np.all(np.diff([0, *calls]) <= 4)
    for name in ARRAYS:
        assert np.array_equal(getattr(chunked, name), getattr(batch6, name)), name
    numpy_seeds = simulate(sc, seeds=np.arange(6))
    for name in ARRAYS:
        assert np.array_equal(getattr(numpy_seeds, name), getattr(batch6, name)), name


def test_dropping_trajectories_keeps_every_other_array(paper, batch6, monkeypatch):
    """keep_trajectories=False (also across several chunks) changes nothing but the two
    dropped arrays; the centroid is the mean of the positions."""
    sc, _ = paper
    monkeypatch.setattr(simulation_module, "CHUNK_RUNS", 4)
    light = simulate(sc, seeds=range(6), keep_trajectories=False)
    assert light.positions is None
    assert light.velocities is None
    for name in ARRAYS:
        if name not in ("positions", "velocities"):
            assert np.array_equal(getattr(light, name), getattr(batch6, name)), name
    np.testing.assert_allclose(batch6.centroid, batch6.positions.mean(axis=-2), atol=1e-12)


def test_start_positions_and_noise(paper, batch6):
    """Starts are start_positions(seed), inside the start region; the motion residual
    (recorded step minus the noiseless laws) has the scenario's sigma per axis."""
    sc, _ = paper
    for b in range(6):
        np.testing.assert_array_equal(batch6.positions[b, 0], start_positions(sc, b))
    starts = batch6.positions[:, 0]
    assert np.all((starts >= -10.0) & (starts <= 10.0))
    q, qn = batch6.positions[:, :-1], batch6.positions[:, 1:]
    delta = sc.slots - np.array(sc.target)
    ctl = sc.control
    pred = (
        q
        + formation_input(q, delta, batch6.eta[:, :-1], sc.adjacency, ctl)
        + repulsion(q, sc.obstacle_set, ctl)
        + batch6.velocities[:, :-1] * sc.time.step
    )
    noise = (qn - pred).reshape(-1)
    n = noise.size  # 6 runs x 1500 steps x 6 UAVs x 2 axes
    assert abs(noise.mean()) < 5 * 0.01 / math.sqrt(n)
    assert noise.std() == pytest.approx(0.01, rel=5.0 / math.sqrt(2.0 * n))  # 5 sigma


def test_explicit_start_is_used_for_every_seed():
    start = [[float(i), -float(i)] for i in range(6)]
    sc = Scenario.from_dict(paper_dict(uavs={"count": 6, "start": start, "start_region": None}))
    res = simulate(sc, seeds=[0, 7])
    np.testing.assert_array_equal(res.positions[:, 0], [start, start])
    np.testing.assert_array_equal(start_positions(sc, 123), start)
    assert not np.array_equal(res.positions[0, 1:], res.positions[1, 1:])  # noise differs


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"seed": 1, "seeds": [1, 2]}, "seeds"),
        ({"seeds": []}, "seeds"),
        ({"seeds": [0, -1]}, "seeds"),
        ({"seed": -3}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"seed": True}, "seed"),
    ],
)
def test_bad_seeds(paper, kwargs, field):
    sc, _ = paper
    with pytest.raises(ValueError, match=rf"^{field}:"):
        simulate(sc, **kwargs)


def test_simulate_needs_a_scenario():
    with pytest.raises(ValueError, match=r"^scenario:"):
        simulate(BUILTIN_SCENARIOS["paper"])


# =============================================================================================
# The simulator is the composition of the public laws
# =============================================================================================
@pytest.fixture(scope="module")
def noiseless_paper():
    sc = Scenario.from_dict(paper_dict(disturbance={"sigma": 0.0}))
    return sc, simulate(sc, seeds=[0, 1])


def test_each_step_is_the_composition_of_the_laws(noiseless_paper, ref):
    """With sigma = 0: v*_k = leader_guidance(...), the motion of eq. (3) with the formation
    input and repulsion, the consensus of eq. (14), eta_update(eta_target(...)), the cost,
    the clearance, the separation and the CRLB, at every step of two runs."""
    sc, res = noiseless_paper
    ctl, eta_rule, dt = sc.control, sc.eta, sc.time.step
    target = np.array(sc.target)
    delta = sc.slots - target
    radius = float(np.max(np.hypot(*delta.T)))
    obstacles, adj, leader = sc.obstacle_set, sc.adjacency, sc.uavs.leader
    q, qn = res.positions[:, :-1], res.positions[:, 1:]
    eta = res.eta
    centre = res.positions.mean(axis=-2)
    # Leader guidance, footprint eta_k r* (formation_steering is on in the paper scenario).
    vref = np.empty_like(res.reference_velocity)
    for b in range(res.n_runs):
        for k in range(res.time.size):
            vref[b, k] = leader_guidance(
                res.positions[b, k, leader],
                target + eta[b, k] * delta[leader],
                ctl,
                center_xy=centre[b, k],
                footprint=eta[b, k] * radius,
                obstacles=obstacles,
                dt=dt,
            )
    np.testing.assert_allclose(res.reference_velocity, vref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(res.velocities[:, :, leader], res.reference_velocity)
    # Motion, eq. (3) with eq. (19) and (18).
    pred = (
        q
        + formation_input(q, delta, eta[:, :-1], adj, ctl)
        + repulsion(q, obstacles, ctl)
        + res.velocities[:, :-1] * dt
    )
    np.testing.assert_allclose(qn, pred, rtol=0, atol=1e-12)
    # Consensus, eq. (14) corrected; the followers start at rest.
    np.testing.assert_array_equal(res.velocities[:, 0, 1:], 0.0)
    cons = consensus_step(res.velocities[:, :-1], res.reference_velocity[:, :-1], adj, leader, ctl)
    np.testing.assert_allclose(res.velocities[:, 1:, 1:], cons[:, :, 1:], rtol=0, atol=1e-14)
    # Scale factor: rate-limited step toward the free-width rule; starts at 1.
    assert np.all(eta[:, 0] == 1.0)
    goal = eta_target(centre[:, :-1], target, obstacles, radius, eta_rule, ctl)
    np.testing.assert_allclose(
        eta[:, 1:], eta_update(eta[:, :-1], goal, eta_rule, dt), rtol=0, atol=1e-12
    )
    # Cost, clearance, separation, CRLB.
    cost = formation_cost(q, qn, delta, res.reference_velocity[:, :-1], adj, dt)
    np.testing.assert_allclose(res.cost, cost, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        res.clearance, obstacle_clearance(res.positions, obstacles).min(axis=-1), atol=1e-12
    )
    diff = res.positions[..., :, None, :] - res.positions[..., None, :, :]
    dist = np.hypot(diff[..., 0], diff[..., 1]) + np.where(np.eye(6, dtype=bool), np.inf, 0.0)
    np.testing.assert_allclose(res.separation, dist.min(axis=(-2, -1)), rtol=1e-12)
    prm = ref.radar_params()
    for k in (0, 100, 400, 1500):
        crlb_k = ref.crlb_of_fim(ref.fim_slepian_bangs(res.positions[0, k], target, 20.0, prm))
        assert res.crlb[0, k] == pytest.approx(crlb_k, rel=1e-9)


def test_eta_disabled_stays_one():
    sc = Scenario.from_dict(paper_dict(eta={"enabled": False}, disturbance={"sigma": 0.0}))
    res = simulate(sc, seed=0)
    assert np.all(res.eta == 1.0)


# =============================================================================================
# Linear dynamics: closed form (I - eps L)^k
# =============================================================================================
LINEAR_GRAPHS = {
    "ring": {"kind": "ring"},
    "path": {"kind": "path"},
    "star": {"kind": "star", "center": 2},
    "complete": {"kind": "complete"},
    "edges": {"kind": "edges", "edges": [[0, 3], [3, 1], [1, 4], [4, 2], [2, 5], [5, 0], [1, 2]]},
}


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", list(LINEAR_GRAPHS))
def test_simulated_shape_follows_the_laplacian_closed_form(name, seed):
    """No obstacles, sigma = 0, eta disabled, explicit starts, and a cruise speed of 1e-15
    m/s: then q_k - delta = (I - eps L)^k (q_0 - delta) per coordinate, with L from
    networkx. The leader guidance is kept (a scenario cannot switch it off) but saturated
    at 1e-15 m/s, and with gamma < 1/max degree every consensus velocity is a convex
    combination of past references, so the velocities shift the positions by at most
    K dT 1e-15 sqrt(M) in total (|I - eps L| <= 1 below the limit): far below the 1e-10
    tolerance. The velocities are checked to be that small."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-40.0, 40.0, size=(6, 2))
    eps = 0.05
    d = {
        "altitude": 20.0,
        "target": [3.0, -2.0],
        "uavs": {"count": 6, "leader": seed, "start": start.tolist()},
        "time": {"step": 0.1, "duration": 60.0},
        "control": {"epsilon": eps, "gamma": 0.15, "cruise_speed": 1e-15},
        "disturbance": {"sigma": 0.0},
        "eta": {"enabled": False},
        "graph": LINEAR_GRAPHS[name],
        **PAPER_LAWS,
    }
    sc = Scenario.from_dict(d)
    res = simulate(sc)
    graph = nx.Graph([tuple(e) for e in sc.adjacency.edges.tolist()])
    lap = nx.laplacian_matrix(graph, nodelist=range(6)).toarray().astype(float)
    delta = sc.slots - np.array(sc.target)
    steps = sc.time.steps
    assert np.max(np.abs(res.velocities)) <= 1e-15 * (1 + 1e-12)
    slack = steps * sc.time.step * 1e-15 * math.sqrt(6)
    for k in (1, 10, 100, 250, steps):
        power = np.linalg.matrix_power(np.eye(6) - eps * lap, k)
        expected = power @ (start - delta) + delta
        np.testing.assert_allclose(res.positions[0, k], expected, rtol=0, atol=1e-10 + slack)
    # The shape error (centroid removed) decays like rho^k, rho = max |1 - eps lambda|.
    lam = np.linalg.eigvalsh(lap)
    rho = max(abs(1 - eps * lam[1]), abs(1 - eps * lam[-1]))
    err = res.positions[0] - delta
    shape = err - err.mean(axis=-2, keepdims=True)
    norms = np.linalg.norm(shape, axis=(-2, -1))
    k = np.arange(steps + 1)
    assert np.all(norms <= rho**k * norms[0] * (1 + 1e-9) + 1e-10)


def test_formation_at_rest_on_f_star_stays_there(ref):
    """Starting exactly on F* with sigma = 0: nothing moves, cost 0, CRLB = the bound."""
    sc0 = load_scenario("paper")
    start = sc0.slots
    sc = Scenario.from_dict(
        paper_dict(
            uavs={"count": 6, "start": start.tolist(), "start_region": None},
            disturbance={"sigma": 0.0},
            time={"step": 0.1, "duration": 20.0},
        )
    )
    res = simulate(sc)
    np.testing.assert_allclose(res.positions[0], np.broadcast_to(start, (201, 6, 2)), atol=1e-12)
    assert np.all(res.eta == 1.0)
    assert np.max(res.cost) < 1e-20
    np.testing.assert_allclose(res.crlb[0], bound_reference(ref, 6, 20.0), rtol=1e-9)


# =============================================================================================
# Relabelling symmetries
# =============================================================================================
def mission_dict(start, leader=0, rotation=0.0, graph=None, obstacles=None):
    d = paper_dict(disturbance={"sigma": 0.0})
    d["uavs"] = {
        "count": 6,
        "leader": leader,
        "start": np.asarray(start).tolist(),
        "rotation_deg": rotation,
    }
    if graph is not None:
        d["graph"] = graph
    if obstacles is not None:
        d["obstacles"] = obstacles
    return d


def assert_same_missions(a, b, perm, transform=lambda xy: xy):
    """Run a relabelled (UAV i of b is UAV perm[i] of a) and transformed = run b."""
    np.testing.assert_allclose(b.positions, transform(a.positions[:, :, perm]), atol=1e-9)
    np.testing.assert_allclose(b.eta, a.eta, atol=1e-12)
    np.testing.assert_allclose(b.cost, a.cost, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.crlb, a.crlb, rtol=1e-8)
    np.testing.assert_allclose(b.clearance, a.clearance, atol=1e-9)
    np.testing.assert_allclose(b.separation, a.separation, atol=1e-9)


@pytest.mark.parametrize("kind", ["ring", "complete"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mirror_relabelling_with_leader_fixed(kind, seed):
    """Followers relabelled m -> -m mod 6 (the leader 0 keeps its index).

    The simulator gives UAV m the slot at azimuth theta0 + 2 pi m / M of F*, so an arbitrary
    permutation of the followers changes which UAV flies to which slot: it is not a
    symmetry of the mission, not even on a complete graph. The relabelling m -> -m is: it
    maps slot m to the mirror image of slot -m in the line through the target at azimuth
    theta0 = 0, and it is an automorphism of the ring (and of the complete graph). So the
    mission mirrored in y = 90 (obstacles, starts) with the followers relabelled must give
    the mirrored trajectories relabelled (sigma = 0: the noise is drawn per UAV index)."""
    start = start_positions(load_scenario("paper"), seed)
    perm = (-np.arange(6)) % 6
    graph = {"kind": kind}
    gains = {"gamma": 0.1, "epsilon": 0.01}
    a_dict = mission_dict(start, graph=graph)
    a_dict["control"].update(gains)
    mirrored_start = start[perm].copy()
    mirrored_start[:, 1] = 180.0 - mirrored_start[:, 1]
    obstacles = [
        {"type": "rectangle", "x": [30.0, 45.0], "y": [146.0, 180.0]},
        {"type": "rectangle", "x": [30.0, 45.0], "y": [100.0, 126.0]},
    ]
    b_dict = mission_dict(mirrored_start, graph=graph, obstacles=obstacles)
    b_dict["control"].update(gains)
    a = simulate(Scenario.from_dict(a_dict))
    b = simulate(Scenario.from_dict(b_dict))

    def mirror(xy):
        out = xy.copy()
        out[..., 1] = 180.0 - out[..., 1]
        return out

    assert_same_missions(a, b, perm, mirror)


@pytest.mark.parametrize("shift", [1, 2, 5])
def test_cyclic_relabelling_of_the_ring(shift):
    """Relabel every UAV m -> m + c (mod 6): the ring is invariant, the leader becomes
    UAV c, and turning F* by -360 c / 6 degrees gives every UAV the slot it had. The mission
    is the same, relabelled."""
    start = start_positions(load_scenario("paper"), 11)
    a = simulate(Scenario.from_dict(mission_dict(start)))
    b_sc = Scenario.from_dict(
        mission_dict(np.roll(start, shift, axis=0), leader=shift, rotation=-60.0 * shift)
    )
    b = simulate(b_sc)
    perm = (np.arange(6) - shift) % 6  # UAV i of b is UAV i - c of a
    assert_same_missions(a, b, perm)


# =============================================================================================
# Divergence
# =============================================================================================
def divergence_dict(sigma: float, duration: float = 0.1, **uavs) -> dict:
    """A valid scenario that blows up through its disturbance: with sigma of order 1e7 m per
    step (no gain check can forbid a large noise) positions leave the 1e7 m range
    (DIVERGENCE_LIMIT)."""
    return {
        "altitude": 20.0,
        "target": [-100.0, 15.0],
        "uavs": {"count": 6, **uavs},
        "time": {"step": 0.1, "duration": duration, "hold": duration / 2},
        "disturbance": {"sigma": sigma},
        "obstacles": [{"type": "rectangle", "x": [30.0, 45.0], "y": [0.0, 34.0]}],
        **PAPER_LAWS,
    }


def test_divergence_explicit_start_names_run_seed_and_step():
    """sigma = 1e9 m: every run leaves the range at its first step (|N(0, 1e9)| < 1e7 for
    all 12 coordinates has probability ~1e-24)."""
    start = [[29.0, 5.0], [20.0, 5.0], [15.0, 10.0], [10.0, 15.0], [15.0, 20.0], [20.0, 25.0]]
    sc = Scenario.from_dict(divergence_dict(1e9, start=start))
    with pytest.raises(SimulationDivergedError) as info:
        simulate(sc, seeds=[3, 8])
    message = str(info.value)
    assert "run 0 (seed 3)" in message
    assert "step 1 " in message
    assert "\n" not in message
    assert isinstance(info.value, RuntimeError)


def test_divergence_reports_the_first_diverging_run():
    """sigma = 2e6 m over 10 steps: the random walk leaves the 1e7 m range for some seeds
    and not for others. A batch [safe, safe, diverging] names run 2, its seed, and the same
    step as the diverging seed run alone."""
    sc = Scenario.from_dict(divergence_dict(2e6, duration=1.0, start_region=[[-10, 10]] * 2))
    safe, bad = [], {}
    for s in range(40):
        try:
            simulate(sc, seed=s)
            safe.append(s)
        except SimulationDivergedError as exc:
            bad[s] = str(exc)
    assert len(safe) >= 2
    assert bad
    first_bad = min(bad)
    step = bad[first_bad].split(" diverged at step ")[1].split(" ")[0]
    with pytest.raises(SimulationDivergedError) as info:
        simulate(sc, seeds=[safe[0], safe[1], first_bad])
    message = str(info.value)
    assert f"run 2 (seed {first_bad}) diverged at step {step} " in message
    assert 1 <= int(step) <= 10


def test_the_kernel_holds_only_the_layers_a_scenario_uses():
    """The paper's mission passes None for the safety filter, the route and the filter in the
    loop, so its compiled kernel holds none of them (a shorter first compile); paper_safe
    passes arrays for the first two (issue 12)."""
    from crlbswarm import mission_kernel as mk
    from crlbswarm.simulation import layer_markers

    assert layer_markers(load_scenario("paper")) == (None, None, None)
    safe, route, track = layer_markers(load_scenario("paper_safe"))
    assert safe is not None
    assert route is not None
    assert track is None
    assert layer_markers(load_scenario("sensing"))[2] is not None
    simulate(load_scenario("paper"), seed=0)
    kinds = {tuple(str(t) for t in sig[8:11]) for sig in mk.run_batch.signatures}
    assert ("none", "none", "none") in kinds
