"""Several targets (issue 11, item 4): the allocation of UAVs to targets against an
independent exhaustive search written here (the groups' CRLB from the formula of the
issue: 4/W when no weight exceeds the others' sum, else 1/w_max + 1/(W - w_max)), and the
groups' formations flown at the reported CRLB."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import crlbswarm as cs


def brute_force(weights: np.ndarray, k: int, objective: str) -> float:
    best = np.inf
    for labels in itertools.product(range(k), repeat=weights.shape[0]):
        labels = np.array(labels)
        costs = []
        for j in range(k):
            w = weights[labels == j]
            if w.size < 3:
                break
            big, total = w.max(), w.sum()
            costs.append(4 / total if big <= total - big else 1 / big + 1 / (total - big))
        else:
            best = min(best, sum(costs) if objective == "sum" else max(costs))
    return best


TARGETS = np.array([[0.0, 0.0], [250.0, 0.0], [0.0, 300.0]])


@pytest.mark.parametrize("objective", ["sum", "max"])
@pytest.mark.parametrize(("m", "k", "seed"), [(6, 2, 0), (7, 2, 1), (9, 3, 2), (8, 2, 3),
                                              (9, 2, 4), (9, 3, 5)])  # fmt: skip
def test_equals_exhaustive_search_for_small_problems(m, k, seed, objective):
    rng = np.random.default_rng(seed)
    radar = cs.Radar(tx_power=10 ** rng.uniform(-2.0, 0.0, m))
    result = cs.allocate_targets(TARGETS[:k], m, 20.0, radar, objective=objective)
    assert result.exhaustive
    weights = cs.optimal_weights(m, 20.0, radar)
    assert result.value == pytest.approx(brute_force(weights, k, objective), rel=1e-12)
    assert all(len(g) >= 3 for g in result.groups)
    assert sorted(np.concatenate(result.groups).tolist()) == list(range(m))
    for j, members in enumerate(result.groups):  # each group flies its reported CRLB
        sub = radar.take(members)
        value = float(cs.crlb(result.positions[members], TARGETS[j], 20.0, sub))
        assert value == pytest.approx(result.crlb[j], rel=1e-9)
    heuristic = cs.allocate_targets(TARGETS[:k], m, 20.0, radar, objective=objective,
                                    method="heuristic")  # fmt: skip
    assert not heuristic.exhaustive
    assert heuristic.value >= result.value * (1 - 1e-12)


def test_equal_uavs_split_evenly():
    result = cs.allocate_targets(TARGETS, 10, 20.0)
    assert sorted(len(g) for g in result.groups) == [3, 3, 4]
    big = cs.allocate_targets(np.vstack([TARGETS, [[500.0, 500.0], [900.0, 0.0]]]), 30, 20.0)
    assert not big.exhaustive
    assert [len(g) for g in big.groups] == [6] * 5


def test_errors_name_the_argument():
    with pytest.raises(cs.FieldError) as info:
        cs.allocate_targets(TARGETS, 8, 20.0)
    assert info.value.field == "n_uavs"
    with pytest.raises(cs.FieldError) as info:
        cs.allocate_targets(TARGETS, 30, 20.0, method="exhaustive")
    assert info.value.field == "method"
    with pytest.raises(cs.FieldError) as info:
        cs.allocate_targets(TARGETS, 9, 20.0, objective="mean")
    assert info.value.field == "objective"
    with pytest.raises(cs.FieldError) as info:
        cs.allocate_targets([1.0, 2.0, 3.0], 9, 20.0)
    assert info.value.field == "targets_xy"
