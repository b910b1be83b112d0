"""Communication links in the simulator (issue 14, item 1): crlbswarm.links and a mission
with a ``[links]`` table.

Each property is checked against an independent reference: the laws and the consensus
of eq. (14) re-computed in plain Python from the saved trajectories, the message process
re-run in plain Python from the same counter draws, binomial and geometric statistics of
the draws. The missions are short (the paper's scenario, its layers only, so that one
compiled kernel serves every test).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import crlbswarm as cs
from crlbswarm import control
from crlbswarm.counter_rng import LINKS, philox4x32, stream_key
from crlbswarm.errors import FieldError, ScenarioError
from crlbswarm.graphs import ring_adjacency
from crlbswarm.links import (
    DRAW_BATCH_PAIRS,
    LINK_SERIES,
    MAX_PERIOD_STEPS,
    LinksConfig,
    candidate_links,
    exchange,
    link_model,
    link_state,
    link_state_bytes,
    message_fates,
)

ROOT = Path(__file__).resolve().parents[1]
ARRAYS = ("positions", "velocities", "reference_velocity", "crlb", "eta", "centroid", "cost",
          "clearance", "separation", "distance_to_go")  # fmt: skip
LINK_FIELDS = tuple(f"link_{n}" for n in LINK_SERIES)
LINK_METRICS = ("delivered_fraction", "mean_age_s", "max_age_s", "disconnected_s")


def _paper(links: dict | None, duration: float = 5.0, **tables: dict) -> cs.Scenario:
    """The paper scenario, ``duration`` seconds long, with ``links`` (None: no table)."""
    data = cs.load_scenario("paper").model_dump(exclude_none=True)
    data["time"].update(duration=duration, hold=min(10.0, duration / 2))
    for name, table in tables.items():
        data[name].update(table)
    if links is not None:
        data["links"] = links
    return cs.Scenario.from_dict(data, source="test")


def _same(a: cs.MissionResult, b: cs.MissionResult, names=ARRAYS) -> None:
    for name in names:
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name


def _consensus(v_m, received, gamma):
    """Eq. (14) for one follower, in plain Python, in the kernel's order of the neighbours."""
    sx = sy = 0.0
    for vx, vy in received:
        sx += v_m[0] - vx
        sy += v_m[1] - vy
    return v_m[0] - gamma * sx, v_m[1] - gamma * sy


# -- without links: nothing changes ----------------------------------------------------------
def test_without_links_the_laws_are_the_papers_bit_for_bit():
    """The laws read a neighbour from a table through a lookup; with the table the state
    itself and the lookup the CSR indices, they are the paper's laws, bit for bit (a plain
    Python transcription, the leader's neighbours reading v*)."""
    rng = np.random.default_rng(5)
    adj = ring_adjacency(7)
    q, v, delta = rng.normal(size=(7, 2)) * 10, rng.normal(size=(7, 2)), rng.normal(size=(7, 2))
    v_ref = np.array([0.7, -0.2])
    got = control.formation_input(q, delta, 0.6, adj, cs.ControlGains(epsilon=0.1))
    velocities = control.consensus_step(v, v_ref, adj, 2, cs.ControlGains(gamma=0.3))
    for m in range(7):
        neighbours = adj.indices[adj.indptr[m] : adj.indptr[m + 1]]
        sx = sy = 0.0
        for p in neighbours:
            sx += q[m, 0] - q[p, 0] - 0.6 * (delta[m, 0] - delta[p, 0])
            sy += q[m, 1] - q[p, 1] - 0.6 * (delta[m, 1] - delta[p, 1])
        assert (got[m, 0], got[m, 1]) == (-0.1 * sx, -0.1 * sy)
        received = [v_ref if p == 2 else v[p] for p in neighbours]
        want = tuple(v_ref) if m == 2 else _consensus(v[m], received, 0.3)
        assert (velocities[m, 0], velocities[m, 1]) == want
    assert v[2, 0] != v_ref[0]  # (the input's leader row is ignored, not modified)


def test_without_links_the_kernel_holds_no_link_layer():
    """No [links] table: no link fields, metrics or columns, and the compiled mission's link
    arguments are None (its code is not compiled)."""
    from crlbswarm import mission_kernel as mk

    sc = _paper(None)
    assert sc.links is None
    assert "[links]" not in sc.to_toml()
    result = cs.simulate(sc, seeds=range(2))
    assert all(getattr(result, name) is None for name in LINK_FIELDS)
    assert not set(LINK_METRICS) & set(result.metrics)
    kinds = {tuple(str(t) for t in sig[-3:-1]) for sig in mk.run_mission.signatures}
    assert ("none", "none") in kinds  # (batches of up to 20 runs run one by one)


# -- perfect links ---------------------------------------------------------------------------
def test_perfect_links_are_links_off_bit_for_bit():
    """An empty [links] table (no loss, no delay, every step, no range): every UAV receives
    every neighbour's state of the step and the leader's eta of the step, so the mission is
    the one without links to the bit (the same values in the same order in every law)."""
    off = cs.simulate(_paper(None, 20.0), seeds=[0, 3])
    on = cs.simulate(_paper({}, 20.0), seeds=[0, 3])
    _same(off, on)
    assert np.all(on.link_sent == 15)  # the ring's 12 links and 3 of the leader's eta
    assert np.array_equal(on.link_delivered, on.link_sent)
    assert np.all(on.link_age == 0.0)
    assert np.all(on.link_connected == 1.0)
    assert on.metrics["delivered_fraction"].tolist() == [1.0, 1.0]
    assert on.metrics["mean_age_s"].tolist() == [0.0, 0.0]
    assert on.metrics["max_age_s"].tolist() == [0.0, 0.0]
    assert on.metrics["disconnected_s"].tolist() == [0.0, 0.0]


# -- the message process ---------------------------------------------------------------------
def test_fixed_delay_gives_the_senders_state_of_d_steps_before():
    """No loss, delay d: at step k each follower's consensus (eq. (14)) uses its neighbours'
    velocities of step k - d, and none before step d (nothing received yet), checked in
    plain Python on the saved trajectories, bit for bit."""
    d, gamma = 3, 0.25
    result = cs.simulate(_paper({"delay": d}), seeds=[1])
    v = result.velocities[0]
    adj = result.scenario.adjacency
    for k in range(v.shape[0] - 1):
        for m in range(1, 6):  # the followers (the leader holds v*)
            nbrs = adj.indices[adj.indptr[m] : adj.indptr[m + 1]]
            received = [v[k - d, p] for p in nbrs] if k >= d else []
            assert tuple(v[k + 1, m]) == _consensus(v[k, m], received, gamma), (k, m)
    assert result.link_age[0, d:].tolist() == [d * 0.1] * (v.shape[0] - d)
    assert np.isnan(result.link_age[0, :d]).all()
    assert result.metrics["disconnected_s"][0] == pytest.approx(d * 0.1)


def _reference_messages(model, seed, q, v, eta, leader, k_steps):
    """The message process re-run in plain Python (lists of every message, no ring
    buffers) from the counter draws: per step, each link's last received send step, the
    UAVs' eta, and the counts sent and delivered."""
    k0, k1 = stream_key(seed, LINKS)
    ptr, senders = model.indptr, model.senders
    n_links, m_uavs = senders.size, ptr.size - 1
    receiver = np.repeat(np.arange(m_uavs), np.diff(ptr))
    arrivals = [[] for _ in range(n_links)]  # (arrival step, send step)
    channel = [-1] * n_links
    stamp = [-1] * n_links
    etas, eta_stamp = [1.0] * m_uavs, [-1.0] * m_uavs
    sent_states = {}  # (step, uav) -> (eta, stamp) broadcast
    out = []
    for k in range(k_steps):
        if k % model.period == 0:
            for p in range(m_uavs):
                sent_states[k, p] = (eta[k], float(k)) if p == leader else (etas[p], eta_stamp[p])
        sent = delivered = 0
        for e in range(n_links):
            m, p = receiver[e], senders[e]
            near = np.sum((q[k, m] - q[k, p]) ** 2) <= model.range2
            if k % model.period == 0 and near:
                sent += 1
                lo, hi = min(p, m), max(p, m)

                def u(kind, lo=lo, hi=hi, p=p, k=k):  # the block of two turns, this turn's
                    t = k // model.period  # and this direction's word, as 32-bit uniform
                    words = philox4x32(t // 2, lo, LINKS, 4 * hi + kind, k0, k1)
                    return (int(words[2 * (t % 2) + int(p > lo)]) + 1) / 2.0**32

                loss = model.loss
                if model.gilbert:
                    if channel[e] < 0:
                        channel[e] = int(u(2) <= model.pi_bad)
                    else:
                        flip = model.p_good_bad if channel[e] == 0 else model.p_bad_good
                        channel[e] = 1 - channel[e] if u(2) <= flip else channel[e]
                    loss = model.loss_bad if channel[e] else model.loss_good
                if loss == 0 or u(0) > loss:
                    delivered += 1
                    extra = math.floor((1.0 - u(1)) * model.span) if model.span > 1 else 0
                    arrivals[e].append((k + model.delay + extra, k))
            for a, s in arrivals[e]:
                if a == k and s > stamp[e]:
                    stamp[e] = s
                    if m != leader and sent_states[s, p][1] > eta_stamp[m]:
                        etas[m], eta_stamp[m] = sent_states[s, p]
        etas[leader] = eta[k]
        out.append((list(stamp), list(etas), sent, delivered))
    return out


@pytest.mark.parametrize(
    ("links", "m_uavs"),
    [
        ({"loss": 0.3, "delay": 1, "delay_max": 4, "rate": 5.0}, 6),
        ({"loss_model": "gilbert", "p_good_bad": 0.2, "p_bad_good": 0.3, "loss_good": 0.1,
          "loss_bad": 0.9, "delay_max": 2, "range": 9.0}, 6),
        ({"range": 7.0, "use_graph": False, "delay": 2}, 6),
        # more than DRAW_BATCH_PAIRS pairs: one turn drawn at a time
        ({"range": 7.0, "use_graph": False, "loss": 0.4, "delay": 1, "delay_max": 3}, 13),
        ({"range": 7.0, "use_graph": False, "loss": 0.3, "rate": 3.3, "delay_max": 2}, 13),
        ({"loss_model": "gilbert", "p_good_bad": 0.3, "p_bad_good": 0.4, "loss_good": 0.1,
          "loss_bad": 0.8, "rate": 2.5, "range": 9.0}, 6),
    ],
)  # fmt: skip
def test_message_process_matches_a_plain_python_rerun(links, m_uavs):
    """The kernel's exchange (:func:`crlbswarm.links.exchange`), driven step by step on
    random positions and velocities, against the plain Python re-run of the same messages:
    every link's last received state and stamp, every UAV's eta, the counts, the links in
    use and their ages, and the connectivity (a breadth-first search)."""
    cfg, seed, leader, k_steps, dt = LinksConfig(**links), 4, 2, 60, 0.1
    model = link_model(cfg, ring_adjacency(m_uavs), leader, dt)
    assert (model.batch == 1) == (model.n_pairs > DRAW_BATCH_PAIRS)
    rng = np.random.default_rng(seed)
    q = np.cumsum(rng.normal(size=(k_steps, m_uavs, 2)), axis=0) + rng.uniform(-6, 6, (m_uavs, 2))
    v = rng.normal(size=(k_steps, m_uavs, 2))
    eta = rng.uniform(0.3, 1.0, k_steps)
    want = _reference_messages(model, seed, q, v, eta, leader, k_steps)
    st = link_state(model, m_uavs)
    series = np.zeros((5, k_steps))
    k0, k1 = stream_key(seed, LINKS)
    receiver = np.repeat(np.arange(m_uavs), np.diff(model.indptr))
    for k in range(k_steps):
        exchange(k, np.ascontiguousarray(q[k]), np.ascontiguousarray(v[k]), eta[k], leader,
                 k0, k1, model, st, series)  # fmt: skip
        stamp, etas, sent, delivered = want[k]
        assert st.stamp.tolist() == stamp, k
        assert st.eta.tolist() == etas, k
        assert series[:2, k].tolist() == [sent, delivered], k
        for e in np.flatnonzero((st.stamp >= 0) & model.law):  # (the others: eta only)
            s, p = st.stamp[e], model.senders[e]
            assert st.recv_q[e].tolist() == q[s, p].tolist()
            assert st.recv_v[e].tolist() == v[s, p].tolist()
        near = np.sum((q[k, receiver] - q[k, model.senders]) ** 2, axis=1) <= model.range2
        used = np.flatnonzero(model.law & near & (st.stamp >= 0))
        count = st.act_indptr[-1]
        assert st.act_links[:count].tolist() == used.tolist()
        per_receiver = np.bincount(receiver[used], minlength=m_uavs)
        assert np.diff(st.act_indptr).tolist() == per_receiver.tolist()
        ages = k - st.stamp[used]
        if used.size:
            assert series[2, k] == pytest.approx(ages.mean() * dt, rel=1e-12)
            assert series[3, k] == pytest.approx(ages.max() * dt, rel=1e-12)
        fresh = used[ages <= model.stale]
        assert series[4, k] == _connected(m_uavs, receiver[fresh], model.senders[fresh])


def _connected(n: int, a: np.ndarray, b: np.ndarray) -> float:
    """1.0 if the undirected graph of the edges (a[i], b[i]) on n nodes is connected."""
    seen, todo = {0}, [0]
    while todo:
        x = todo.pop()
        for y in [*b[a == x], *a[b == x]]:
            if y not in seen:
                seen.add(int(y))
                todo.append(int(y))
    return 1.0 if len(seen) == n else 0.0


def test_loss_fraction_is_binomial():
    """Independent losses: the lost fraction of many messages within a 99.9 % binomial
    interval of ``loss``, for several seeds and links, and in a mission."""
    loss = 0.2
    for seed, (p, m) in zip(range(4), [(0, 1), (3, 2), (1, 0), (5, 4)], strict=True):
        ok, _, _ = message_fates(LinksConfig(loss=loss), seed, p, m, 20_000)
        assert abs((1 - ok.mean()) - loss) < 3.29 * math.sqrt(loss * (1 - loss) / ok.size)
    result = cs.simulate(_paper({"loss": loss}), seeds=range(3))
    sent, delivered = result.link_sent.sum(), result.link_delivered.sum()
    assert abs(1 - delivered / sent - loss) < 3.29 * math.sqrt(loss * (1 - loss) / sent)


def test_gilbert_elliott_bursts_last_one_over_p_bad_good():
    """Gilbert-Elliott with loss only in the bad state: the loss bursts are the bad
    sojourns, geometric with mean 1/p_bad_good, and the lost fraction is the stationary
    p_good_bad / (p_good_bad + p_bad_good)."""
    p_gb, p_bg = 0.05, 0.25
    cfg = LinksConfig(loss_model="gilbert", p_good_bad=p_gb, p_bad_good=p_bg)
    for seed in (0, 1):
        ok, _, state = message_fates(cfg, seed, 2, 3, 200_000)
        assert np.array_equal(~ok, state == 1)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], (~ok).astype(int), [0]])))
        bursts = edges[1::2] - edges[::2]
        mean, sd = 1 / p_bg, math.sqrt(1 - p_bg) / p_bg
        assert abs(bursts.mean() - mean) < 4 * sd / math.sqrt(bursts.size)
        assert abs((1 - ok.mean()) - p_gb / (p_gb + p_bg)) < 0.01


def test_random_delays_are_uniform_and_the_rate_sets_the_period():
    cfg = LinksConfig(delay=2, delay_max=5, rate=2.5)
    ok, delay, _ = message_fates(cfg, 7, 0, 1, 40_000)
    assert ok.all()
    assert ok.size == 10_000  # every 4 steps at dT = 0.1 s
    counts = np.bincount(delay, minlength=6)[2:]
    assert counts.sum() == 10_000
    assert np.all(np.abs(counts - 2500) < 4 * math.sqrt(10_000 * 0.25 * 0.75))


def test_range_links_are_exactly_the_uavs_within_range():
    """With a range and no graph, each follower's consensus at step k sums over exactly the
    UAVs within range at step k (from the saved positions), and the messages sent are the
    ordered pairs within range; with the graph, its neighbours within range."""
    for use_graph, radius in ((False, 14.0), (True, 18.0)):
        result = cs.simulate(
            _paper({"range": radius, "use_graph": use_graph}, control={"gamma": 0.15}), seeds=[2]
        )  # fmt: skip
        q, v = result.positions[0], result.velocities[0]
        adj = result.scenario.adjacency
        counts = []
        for k in range(q.shape[0] - 1):
            dist = np.hypot(*(q[k][:, None] - q[k][None]).transpose(2, 0, 1))
            near = (dist <= radius) & ~np.eye(6, dtype=bool)
            counts.append(near.sum())
            for m in range(1, 6):
                nbrs = [p for p in range(6) if near[m, p]]
                if use_graph:
                    nbrs = [
                        p for p in adj.indices[adj.indptr[m] : adj.indptr[m + 1]] if near[m, p]
                    ]
                received = [v[k, p] for p in nbrs]
                assert tuple(v[k + 1, m]) == _consensus(v[k, m], received, 0.15), (k, m)
        if not use_graph:
            assert result.link_sent[0, :-1].tolist() == counts
            assert 0 < min(counts) < max(counts) < 30  # the neighbours did change


# -- runs, batches, outputs ------------------------------------------------------------------
def test_a_run_with_links_is_the_same_bits_in_any_batch():
    links = {"loss_model": "gilbert", "p_good_bad": 0.1, "p_bad_good": 0.4, "delay_max": 3,
             "range": 25.0}  # fmt: skip
    sc = _paper(links)
    batch = cs.simulate(sc, seeds=[3, 5, 8])
    single = cs.simulate(sc, seed=5)
    for name in (*ARRAYS, *LINK_FIELDS):
        assert np.array_equal(getattr(batch, name)[1], getattr(single, name)[0], equal_nan=True)


def test_link_state_does_not_grow_with_the_mission():
    sc = _paper({"delay_max": 4, "range": 20.0, "use_graph": False}, control={"gamma": 0.15})
    model = cs.simulation.link_arguments(sc)
    st = link_state(model, 6)
    assert st.history.shape == (5, 6, 6)
    assert st.pending.shape == (30, 5)
    assert link_state_bytes(model) == sum(a.nbytes for a in st)


def test_metrics_are_saved_and_loaded(tmp_path):
    result = cs.simulate(_paper({"loss": 0.3, "delay": 2}), seeds=range(2))
    result.save(tmp_path / "out")
    header = (tmp_path / "out" / "metrics.csv").read_text().splitlines()[0].split(",")
    assert set(LINK_METRICS) <= set(header)
    back = cs.load_results(tmp_path / "out")
    _same(result, back, (*ARRAYS, *LINK_FIELDS))
    for name in LINK_METRICS:
        assert np.array_equal(result.metrics[name], back.metrics[name], equal_nan=True)
    assert back.scenario.links == LinksConfig(loss=0.3, delay=2)
    assert any(line.startswith("links ") for line in cs.results.outcome_report(result))


def test_campaigns_sweep_links_fields():
    from crlbswarm.campaign import CampaignSpec, plan_tasks

    spec = CampaignSpec.from_toml(
        'base = "paper"\n[seeds]\ncount = 2\n[grid]\n"links.loss" = [0.0, 0.25]\n'
        '"links.delay" = [0, 3]\n'
    )
    scenarios, tasks = plan_tasks(spec)
    assert [s["links"] for s in scenarios] == [
        {"loss": 0.0, "delay": 0}, {"loss": 0.0, "delay": 3}, {"loss": 0.25, "delay": 0},
        {"loss": 0.25, "delay": 3},
    ]  # fmt: skip
    assert len(tasks) == 4


def test_the_paper_mission_converges_with_loss_and_delay():
    """20 % loss and 3 steps of delay: most runs still reach the bound (docs/links.md has
    the measured figures over more seeds)."""
    result = cs.simulate(_paper({"loss": 0.2, "delay": 3}, 150.0), seeds=range(6),
                         keep_trajectories=False)  # fmt: skip
    converged = np.isfinite(result.metrics["convergence_time_s"])
    assert converged.sum() >= 5
    assert np.all(result.metrics["final_crlb_ratio"][converged] < 1.01)
    assert np.all(np.abs(result.metrics["delivered_fraction"] - 0.8) < 0.02)


def test_auto_gains_are_resolved_for_the_links_largest_age():
    """ "auto" epsilon is halved delayed limit for the largest age (delay_max + period - 1);
    without a delay (and without links) the gains of the state of the step."""
    base = cs.load_scenario("paper_safe").model_dump(exclude_none=True)
    adj = cs.load_scenario("paper_safe").adjacency
    for links, age in (
        ({}, 0),
        ({"loss": 0.3}, 0),
        ({"delay": 3}, 3),
        ({"delay": 1, "delay_max": 4}, 4),
        ({"rate": 2.5, "delay": 2}, 5),
    ):
        sc = cs.Scenario.from_dict({**base, "links": links}, source="test")
        assert sc.links is not None
        assert sc.links.largest_age(sc.time.step) == age
        assert sc.gains.epsilon == cs.graphs.auto_formation_step(adj, age)
        assert sc.gains.gamma == cs.load_scenario("paper_safe").gains.gamma
    assert cs.load_scenario("paper_safe").gains.epsilon == cs.graphs.auto_formation_step(adj)
    fixed = _paper({"delay": 3})
    assert fixed.gains.epsilon == 0.01  # (explicit gains kept)
    assert fixed.gains.gamma == 0.25


def test_auto_gains_converge_with_delay():
    """paper_safe ("auto" gains) with 3 steps of delay: every run converges (with the gains
    of the state of the step none did: the formation crawled, docs/control.md sec. 6)."""
    data = cs.load_scenario("paper_safe").model_dump(exclude_none=True)
    data["links"] = {"loss": 0.2, "delay": 3}
    result = cs.simulate(cs.Scenario.from_dict(data, source="test"), seeds=range(3),
                         keep_trajectories=False)  # fmt: skip
    assert np.all(np.isfinite(result.metrics["convergence_time_s"]))
    assert np.all(result.metrics["final_crlb_ratio"] < 1.01)


# -- errors ----------------------------------------------------------------------------------
@pytest.mark.parametrize("links", [{"timeout": 1e300}, {"range": 1e300}, {"range": 1e-300}])
def test_extreme_timeout_and_range_run(links):
    """A timeout longer than any mission never goes stale; a range beyond any distance is
    every link; a range below any distance is none (nothing delivered)."""
    result = cs.simulate(_paper(links, 2.0), seeds=[0], keep_trajectories=False)
    fraction = result.metrics["delivered_fraction"][0]
    if links.get("range") == 1e-300:
        assert np.isnan(fraction)  # (no message in range: none sent)
    else:
        assert fraction == 1.0
        assert result.metrics["disconnected_s"][0] == 0.0


def test_a_rate_of_one_message_per_mission_is_accepted():
    sc = _paper({"rate": 0.2})  # (once every 50 steps: the 5 s mission's K)
    assert sc.links is not None
    assert sc.links.period(sc.time.step) == sc.time.steps


@pytest.mark.parametrize(
    ("links", "tables", "field"),
    [
        ({"loss": 1.5}, {}, "links.loss"),
        ({"loss": "0.2"}, {}, "links.loss"),
        ({"delay": -1}, {}, "links.delay"),
        ({"delay": 2000}, {}, "links.delay"),
        ({"delay": 3, "delay_max": 2}, {}, "links.delay_max"),
        ({"rate": 0}, {}, "links.rate"),
        ({"rate": 1e-300}, {}, "links.rate"),  # (no second message in the 5 s mission)
        ({"rate": 0.1}, {}, "links.rate"),
        ({"rate": 1e-300}, {"control": {"epsilon": "auto", "gamma": "auto"}}, "links.rate"),
        ({"rate": 5e-324}, {}, "links.rate"),  # (rate x time.step underflows to 0)
        ({"delay": 50}, {}, "links.delay"),  # (the 5 s mission's 50 steps: nothing arrives)
        ({"loss_model": "gilbert", "p_good_bad": 0.1, "p_bad_good": 0.5, "loss": 1e-9}, {},
         "links.loss"),
        ({"range": -5.0}, {}, "links.range"),
        ({"loss_model": "burst"}, {}, "links.loss_model"),
        ({"p_good_bad": 0.1}, {}, "links.p_good_bad"),
        ({"loss_model": "gilbert", "p_bad_good": 0.5}, {}, "links.p_good_bad"),
        ({"loss_model": "gilbert", "p_good_bad": 0.1, "p_bad_good": 0.5, "loss": 0.1}, {},
         "links.loss"),
        ({"use_graph": False}, {}, "links.use_graph"),
        ({"timeout": 0.2, "delay": 3}, {}, "links.timeout"),
        ({"range": 30.0, "use_graph": False}, {}, "control.gamma"),
        ({"lose": 0.1}, {}, "links.lose"),
    ],
)  # fmt: skip
def test_bad_links_are_one_line_naming_the_field(links, tables, field):
    with pytest.raises(ScenarioError) as info:
        _paper(links, **tables)
    message = str(info.value)
    assert "\n" not in message
    assert f": {field}: " in message


def test_a_delay_one_step_shorter_than_the_mission_is_accepted():
    assert _paper({"delay": 49}).links is not None


def test_a_gilbert_elliott_table_round_trips_through_toml_and_a_dump():
    """Its ``loss = 0.0`` (the default, written out by a dump) is accepted."""
    sc = _paper({"loss_model": "gilbert", "p_good_bad": 0.1, "p_bad_good": 0.5})
    assert cs.Scenario.from_toml(sc.to_toml()) == sc
    assert cs.Scenario.from_dict(sc.model_dump()) == sc


@pytest.mark.parametrize("dt", [0.0, -0.1, math.nan, math.inf, "0.1"])
def test_the_periods_of_a_bad_time_step_are_one_line(dt):
    links = LinksConfig(rate=5.0, timeout=1.0)
    for method in (links.period, links.largest_age, links.timeout_steps):
        with pytest.raises(FieldError, match=r"^dt: "):
            method(dt)


@pytest.mark.parametrize("rate", [1e-310, 5e-324])
def test_a_rate_whose_period_overflows_never_sends_again(rate):
    links = LinksConfig(rate=rate)
    assert links.period(0.1) == MAX_PERIOD_STEPS
    assert links.largest_age(0.1) == MAX_PERIOD_STEPS - 1
    delivered, delay, _ = message_fates(links, 0, 1, 2, 1000)
    assert delivered.tolist() == [True]  # (step 0 only)
    assert delay.tolist() == [0]


@pytest.mark.parametrize(
    ("args", "field"),
    [
        ((0, 2, 2, 10), "receiver"),  # (no link to itself)
        ((0, 1, 2**30, 10), "receiver"),  # (4 b + kind would wrap the counter's word)
        ((0, 2**31 - 1, 0, 10), "sender"),
        ((0, 1, 2, 2**32), "steps"),  # (72 GB of fates: refused before allocating)
    ],
)
def test_bad_message_fates_are_one_line(args, field, monkeypatch):
    monkeypatch.setattr("crlbswarm._validation.memory_room", lambda: 8 * 2**30)
    with pytest.raises(FieldError, match=rf"^{field}: "):
        message_fates(LinksConfig(loss=0.2), *args)


def test_links_with_several_targets_are_refused():
    data = cs.load_scenario("paper").model_dump(exclude_none=True)
    data.update(extra_targets=[[-40.0, 60.0]], links={"loss": 0.1})
    data["uavs"]["count"] = 6
    with pytest.raises(ScenarioError, match=r": links: is not supported with extra_targets"):
        cs.Scenario.from_dict(data)


# -- docs ------------------------------------------------------------------------------------
def test_the_links_table_is_documented_with_its_defaults():
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    start = text.index("### `[links]`")
    table = text[start : text.find("\n#", start + 1)]
    for name, info in LinksConfig.model_fields.items():
        row = next((x for x in table.splitlines() if x.startswith(f"| `{name}` |")), None)
        assert row is not None, name
        cells = [c.strip().strip("`").strip('"').lower() for c in row.split("|")]
        if info.default is not None:
            assert str(info.default).lower() in cells, name
    assert "links" in (ROOT / "docs" / "contents.rst").read_text(encoding="utf-8")
    assert (ROOT / "docs" / "links.md").is_file()


def test_candidate_links_carry_the_leaders_eta_to_everyone():
    ptr, senders, law = candidate_links(ring_adjacency(6), 0, True)
    rows = [senders[ptr[m] : ptr[m + 1]].tolist() for m in range(6)]
    assert rows == [[1, 5], [0, 2], [1, 3, 0], [2, 4, 0], [3, 5, 0], [0, 4]]
    assert law.sum() == 12
