"""The mission kernel's layout (issue 12): draws inside the kernel, trajectories kept with
a stride, blocks of UAVs on all threads, the obstacle grid, the eta rule's path test.

Each is a change of *how* the mission is computed, never of *what*: the tests compare the
new path with an independent or a plain one, bit for bit where the arithmetic is the same.
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import crlbswarm as cs
from crlbswarm import control, simulation
from crlbswarm.counter_rng import DISTURBANCE, standard_normals
from crlbswarm.errors import FieldError
from crlbswarm.obstacles import Obstacles, clearance_at
from crlbswarm.results import kept_rows

ARRAYS = ("positions", "velocities", "crlb", "eta", "centroid", "cost", "clearance",
          "separation", "distance_to_go", "reference_velocity")  # fmt: skip


def _same(a: cs.MissionResult, b: cs.MissionResult, names=ARRAYS) -> None:
    for name in names:
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(x, y, equal_nan=True), name


def _swarm(n: int, steps: int, circles: int = 0, seed: int = 0) -> cs.Scenario:
    """n UAVs on a ring graph (the paper's laws), with ``circles`` small discs spread
    around the target off the formation's ring and the start region."""
    radius = 2.0 * n / (2.0 * math.pi)
    side = 2.0 * math.sqrt(n)
    rng = np.random.default_rng(seed)
    centres = []
    while len(centres) < circles:
        x, y = rng.uniform(-2 * radius, 2 * radius, 2)
        if abs(math.hypot(x, y) - radius) > 12 and (
            abs(x) > side / 2 + 12 or abs(y) > side / 2 + 12
        ):
            centres.append([float(x), float(y)])
    return cs.Scenario.from_dict(
        {
            "altitude": radius * math.tan(float(cs.optimal_elevation(1000.0))),
            "target": [0.0, 0.0],
            "uavs": {"count": n, "start_region": [[-side / 2, side / 2]] * 2},
            "time": {"step": 0.1, "duration": 0.1 * steps, "hold": 0.05 * steps},
            "graph": {"kind": "ring"},
            "safety": {"enabled": False},
            "guidance": {"planner": False},
            "formation": {"assignment": "index", "design": "closed_form"},
            "obstacles": [{"type": "circle", "center": c, "radius": 2.0} for c in centres],
        }
    )


# ---------------------------------------------------------------------------------------
# Draws inside the kernel
# ---------------------------------------------------------------------------------------
def test_disturbance_is_the_counter_based_draw():
    """Without obstacles, repulsion and formation input the motion of eq. (3) is
    q_{k+1} = q_k + v_k dT + sigma n_k: the increments minus the velocities are the
    counter-based draws of (seed, DISTURBANCE) times sigma."""
    data = cs.load_scenario("paper").model_dump()
    data.update(obstacles=[])
    data["control"].update(epsilon=1e-12)  # (a negligible formation input)
    sc = cs.Scenario.from_dict(data)
    r = cs.simulate(sc, seed=11)
    q, v = r.positions[0], r.velocities[0]
    n = standard_normals(11, DISTURBANCE, 5, sc.uavs.count)
    step = (q[1:6] - q[:5] - v[:5] * sc.time.step) / sc.disturbance.sigma
    np.testing.assert_allclose(step, n, atol=1e-6)


@pytest.mark.parametrize("name", ["paper", "sensing", "moving_target", "paper_safe"])
def test_a_run_is_the_same_bits_in_any_batch(name):
    """Chunks of more than one run (more than 20 runs) go through the parallel driver."""
    sc = cs.load_scenario(name)
    one = cs.simulate(sc, seed=7)
    batch = cs.simulate(sc, seeds=range(3, 45))
    for attr in ARRAYS:
        assert np.array_equal(getattr(one, attr)[0], getattr(batch, attr)[4], equal_nan=True)


# ---------------------------------------------------------------------------------------
# Trajectories with a stride
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("stride", [1, 7, 1500, 2000 - 1])
def test_trajectory_stride_keeps_the_rows_of_the_full_trajectory(stride):
    sc = cs.load_scenario("paper")
    full = cs.simulate(sc, seeds=range(2))
    stride = min(stride, sc.time.steps)
    part = cs.simulate(sc, seeds=range(2), trajectory_stride=stride)
    kept = part.trajectory_steps
    assert kept[0] == 0
    assert kept[-1] == sc.time.steps
    assert np.all(np.diff(kept) <= stride)
    assert np.all(kept[:-1] % stride == 0)
    np.testing.assert_array_equal(part.positions, full.positions[:, kept])
    np.testing.assert_array_equal(part.velocities, full.velocities[:, kept])
    _same(part, full, ("crlb", "eta", "cost", "clearance", "separation", "centroid"))


def test_trajectory_stride_round_trips_and_is_checked(tmp_path):
    sc = cs.load_scenario("paper")
    r = cs.simulate(sc, seed=1, trajectory_stride=100)
    r.save(tmp_path / "out")
    back = cs.load_results(tmp_path / "out")
    assert back.trajectory_stride == 100
    np.testing.assert_array_equal(back.positions, r.positions)
    cols = back.trajectory_columns(0)
    assert np.isnan(cols["x_uav1"][1])
    assert cols["x_uav1"][100] == r.positions[0, 1, 0, 0]
    for bad in (0, -3, 1.5, True, sc.time.steps + 1):
        with pytest.raises(FieldError, match="trajectory_stride"):
            cs.simulate(sc, seed=1, trajectory_stride=bad)
    assert kept_rows(10, 0).size == 0
    assert kept_rows(10, 4).tolist() == [0, 4, 8, 10]


def test_without_trajectories_the_time_series_are_the_same():
    sc = cs.load_scenario("sensing")
    full = cs.simulate(sc, seeds=range(2))
    none = cs.simulate(sc, seeds=range(2), keep_trajectories=False)
    assert none.positions is None
    assert none.velocities is None
    _same(none, full, ("crlb", "eta", "cost", "clearance", "separation", "centroid",
                       "estimate", "distance_to_go"))  # fmt: skip
    np.testing.assert_array_equal(none.pcrb, full.pcrb)


def test_crlb_in_the_kernel_is_the_crlb_of_the_positions():
    for name in ("paper", "moving_target"):
        sc = cs.load_scenario(name)
        r = cs.simulate(sc, seeds=range(2))
        ref = cs.crlb(r.positions, r.target, sc.altitude, sc.radar_model)
        np.testing.assert_allclose(r.crlb, ref, rtol=1e-12)
        np.testing.assert_allclose(r.centroid, r.positions.mean(axis=-2), rtol=0, atol=1e-12)
        # The centroid error, also computed in the kernel: against the positions' mean ...
        offset = r.positions.mean(axis=-2) - r.target - sc.formation_design.centre_offset
        np.testing.assert_allclose(r.centroid_error, np.hypot(*np.moveaxis(offset, -1, 0)),
                                   rtol=0, atol=1e-9)  # fmt: skip
        # ... and the same bits as the result's own formula from its centroid (the fallback
        # for results saved without it)
        rebuilt = dataclasses.replace(r, centroid_error=None)
        assert np.array_equal(rebuilt.centroid_error, r.centroid_error)


def test_results_saved_without_the_centroid_error_load(tmp_path):
    """A folder written before the kernel computed the centroid error loads, the error
    computed from the centroid; a wrong shape is refused naming the array."""
    r = cs.simulate(cs.load_scenario("paper"), seeds=[3, 4], keep_trajectories=False)
    r.save(tmp_path / "new")
    npz = tmp_path / "new" / "trajectories.npz"
    with np.load(npz) as data:
        arrays = dict(data)
    old = arrays.pop("centroid_error")
    np.testing.assert_array_equal(old, r.centroid_error)
    np.savez(npz, **arrays)
    back = cs.load_results(tmp_path / "new")
    np.testing.assert_array_equal(back.centroid_error, r.centroid_error)
    assert back.metrics["final_centroid_error_m"].tolist() == r.centroid_error[:, -1].tolist()
    np.savez(npz, **arrays, centroid_error=old[:, :-1])
    with pytest.raises(FieldError, match="'centroid_error' is shape"):
        cs.load_results(tmp_path / "new")


# ---------------------------------------------------------------------------------------
# Blocks of UAVs on all threads (one large swarm)
# ---------------------------------------------------------------------------------------
@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two threads")
def test_wide_mission_is_bit_identical_to_the_serial_one(monkeypatch):
    """A single run of a large swarm does its per-UAV work in blocks on all threads; the
    same run with one thread, and the same run inside a batch, give the same bits."""
    monkeypatch.setattr(simulation, "WIDE_UAVS", 300)  # (a small swarm takes the wide path)
    sc = _swarm(700, 12, circles=30)
    threads = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        wide = cs.simulate(sc, seed=4)
        numba.set_num_threads(1)
        serial = cs.simulate(sc, seed=4)
    finally:
        numba.set_num_threads(threads)
    batch = cs.simulate(sc, seeds=range(42))
    _same(wide, serial)
    for attr in ARRAYS:
        assert np.array_equal(getattr(wide, attr)[0], getattr(batch, attr)[4])


# ---------------------------------------------------------------------------------------
# The obstacle grid in the mission
# ---------------------------------------------------------------------------------------
def test_mission_on_the_grid_equals_the_mission_on_every_obstacle(monkeypatch):
    sc = _swarm(60, 40, circles=80, seed=3)
    assert simulation.obstacle_index(sc.obstacle_set.rectangles, sc.obstacle_set.circles,
                                     5.0) is not None  # fmt: skip
    grid = cs.simulate(sc, seeds=range(2))
    monkeypatch.setattr(simulation, "obstacle_index", lambda *args: None)  # every obstacle
    every = cs.simulate(sc, seeds=range(2))
    _same(grid, every)


# ---------------------------------------------------------------------------------------
# The eta rule's path test (exact shortcut)
# ---------------------------------------------------------------------------------------
def _eta_goal_sampled(cx, cy, sx, sy, radius, obs, margin, lookahead, n, eta_min):
    """The eta rule without the path test: every sample, as the rule is documented."""
    rects, circles = obs.rectangles, obs.circles
    if rects.shape[0] + circles.shape[0] == 0:
        return 1.0
    hx, hy = sx - cx, sy - cy
    dist = math.sqrt(hx * hx + hy * hy)
    hx, hy = (hx / dist, hy / dist) if dist > 0 else (1.0, 0.0)
    ahead = min(lookahead, dist)
    width = math.inf
    enough = radius + margin
    for i in range(n):
        t = -radius + (ahead + radius) * i / (n - 1)
        px, py = cx + t * hx, cy + t * hy
        if clearance_at(px, py, rects, circles) >= enough:
            continue
        best = -math.inf
        for j in range(control.LATERAL_SAMPLES):
            o = radius * (2.0 * j / (control.LATERAL_SAMPLES - 1) - 1.0)
            best = max(best, clearance_at(px - o * hy, py + o * hx, rects, circles))
        width = min(width, best)
        if width <= margin + eta_min * radius:
            break
    return control.eta_from_width(width, margin, radius, eta_min, dist)


@settings(max_examples=150, deadline=None)
@given(
    st.floats(-60, 60), st.floats(-60, 60), st.floats(-60, 60), st.floats(-60, 60),
    st.integers(0, 6), st.integers(0, 2**31 - 1),
)  # fmt: skip
def test_eta_rule_path_test_changes_nothing(cx, cy, sx, sy, n_obs, seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-50, 50, (n_obs, 2))
    rects = np.column_stack([lo[:, 0], lo[:, 0] + rng.uniform(0.5, 20, n_obs),
                             lo[:, 1], lo[:, 1] + rng.uniform(0.5, 20, n_obs)])  # fmt: skip
    circles = np.column_stack([rng.uniform(-50, 50, (n_obs, 2)), rng.uniform(0.5, 8, n_obs)])
    obs = Obstacles(rects, circles)
    rule = control.EtaRule()
    radius = 12.0
    got = control.eta_target((cx, cy), (sx, sy), obs, radius, rule)
    want = _eta_goal_sampled(cx, cy, sx, sy, radius, obs, rule.margin_for(control.ControlGains()),
                             rule.lookahead, rule.samples, rule.minimum)  # fmt: skip
    assert float(got) == want
