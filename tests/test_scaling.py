"""Large swarms: the per-step work of the simulator grows linearly with the number of UAVs.

The smallest separation between UAVs is the one quantity that naively costs O(M^2) per
step; above SEPARATION_BRUTE_FORCE_MAX UAVs the kernel uses a cell list. These tests check it
against all pairs, on spread-out, collinear, clustered and duplicated positions.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from crlbswarm import Scenario, simulate
from crlbswarm.spatial import SEPARATION_BRUTE_FORCE_MAX, min_separation


def brute_force(q: np.ndarray) -> float:
    d = np.sqrt(((q[:, None, :] - q[None, :, :]) ** 2).sum(-1))
    np.fill_diagonal(d, np.inf)
    return float(d.min())


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(
    "n", [2, 3, SEPARATION_BRUTE_FORCE_MAX, SEPARATION_BRUTE_FORCE_MAX + 1, 300]
)
@pytest.mark.parametrize("layout", ["uniform", "collinear", "clustered", "duplicates"])
def test_min_separation_equals_all_pairs(seed, n, layout):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-100.0, 100.0, (n, 2))
    if layout == "collinear":
        q[:, 1] = 3.0
    elif layout == "clustered":
        q[: n // 2] = rng.normal(0.0, 1e-3, (n // 2, 2))
    elif layout == "duplicates":
        q = np.round(q / 10.0) * 10.0
    assert min_separation(q) == pytest.approx(brute_force(q), rel=1e-12, abs=1e-15)


@settings(max_examples=40)
@given(
    n=st.integers(SEPARATION_BRUTE_FORCE_MAX + 1, 200),
    scale=st.floats(1e-3, 1e5),
    aspect=st.floats(1e-6, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_min_separation_any_scale_and_aspect(n, scale, aspect, seed):
    """Very elongated or very small or large swarms: the grid adapts, the answer is exact."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(0.0, scale, (n, 2)) * np.array([1.0, aspect])
    assert min_separation(q) == pytest.approx(brute_force(q), rel=1e-12, abs=1e-300)


def test_large_swarm_mission_runs_with_exact_separation():
    """A 200-UAV ring mission (no obstacles): the separation metric of every 100th step
    equals the all-pairs value on the recorded positions."""
    n = 200
    sc = Scenario.from_dict(
        {
            "altitude": 50.0,
            "target": [0.0, 0.0],
            "uavs": {"count": n, "start_region": [[-300.0, 300.0], [-300.0, 300.0]]},
            "time": {"step": 0.1, "duration": 20.0},
            # F*'s side is 1.11 m: a UAV passes between two neighbours at 0.5 m (with margin)
            "safety": {"min_separation": 0.4},
        }
    )
    res = simulate(sc, seed=3)
    for k in range(0, res.time.shape[0], 100):
        assert res.separation[0, k] == pytest.approx(brute_force(res.positions[0, k]), rel=1e-12)
