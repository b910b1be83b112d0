"""Unequal UAVs (issue 11, item 1): the closed-form optimum against a multistart numerical
optimisation of the CRLB over all horizontal positions.

The numerical search is written here from the model (not from crlbswarm's design code):
:math:`\\mathbf J = \\sum_m k_m(d_m)\\,\\rho_m\\rho_m^\\top` with :math:`\\rho_m = q_m - s`,
:math:`d_m^2 = |\\rho_m|^2 + H^2` and :math:`k_m(d) = A_m/d^6 + 8/d^4` (the range information
:math:`A/d^4 + 8/d^2` times the squared cosine of the elevation, :math:`|\\rho|^2/d^2`), and
the exact gradient of :math:`\\log\\operatorname{tr}\\mathbf J^{-1}` goes to L-BFGS-B from 200
random starts per case.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

import crlbswarm as cs

STARTS = 200


def log_trace_and_gradient(x: np.ndarray, a: np.ndarray, h: float) -> tuple[float, np.ndarray]:
    rho = x.reshape(-1, 2)
    d2 = np.sum(rho**2, axis=1) + h * h
    d = np.sqrt(d2)
    k = a / d2**3 + 8.0 / d2**2
    dk = -6.0 * a / d**7 - 32.0 / d**5  # dk/dd
    j = np.einsum("m,mi,mj->ij", k, rho, rho)
    inv = np.linalg.inv(j)
    trace = np.trace(inv)
    b = inv @ inv
    quad = np.einsum("mi,ij,mj->m", rho, b, rho)
    grad = -((dk / d * quad)[:, None] * rho + 2.0 * k[:, None] * (rho @ b))
    return float(np.log(trace)), (grad / trace).ravel()


def numerical_best(a: np.ndarray, h: float, seed: int) -> float:
    """The smallest CRLB found from STARTS random starts (target at the origin)."""
    rng = np.random.default_rng(seed)
    scale = float(np.max(cs.optimal_radius(h, cs.Radar())))
    best = np.inf
    for _ in range(STARTS):
        x0 = rng.uniform(-3 * scale, 3 * scale, (a.shape[0], 2)).ravel()
        res = minimize(log_trace_and_gradient, x0, args=(a, h), jac=True, method="L-BFGS-B",
                       options={"maxiter": 2000, "ftol": 1e-15, "gtol": 1e-12})  # fmt: skip
        best = min(best, float(np.exp(res.fun)))
    return best


CASES = [  # (M, seed, dominant)
    (3, 1, False), (3, 2, True), (5, 3, False), (5, 4, True), (8, 5, False), (8, 6, True),
    (12, 7, False), (12, 8, True),
]  # fmt: skip


@pytest.mark.parametrize(("m", "seed", "dominant"), CASES)
def test_closed_form_equals_the_best_of_a_multistart_search(m, seed, dominant):
    rng = np.random.default_rng(seed)
    # Within a factor 2 no UAV outweighs the others (M >= 3); one made 10 M times stronger
    # outweighs them all (and not so much that J is ill-conditioned in double precision).
    power = rng.uniform(0.05, 0.1, m)
    if dominant:
        power[rng.integers(m)] *= 10.0 * m
    radar = cs.Radar(tx_power=power)
    h = 20.0
    w = cs.optimal_weights(m, h, radar)
    assert (w.max() > w.sum() - w.max()) == dominant  # the case is what it says
    target = np.array([3.0, -4.0])
    formation = cs.optimal_formation(m, target, h, radar)
    closed = float(cs.crlb(formation, target, h, radar))
    bound = float(cs.crlb_bound(m, h, radar))
    assert closed == pytest.approx(bound, rel=1e-9)
    best = numerical_best(np.asarray(radar.snr_constant), h, seed)
    assert closed <= best * (1 + 1e-9)  # nothing found is better
    assert closed == pytest.approx(best, rel=1e-6)  # and the search reaches it


def test_the_issue_example_and_the_dominant_formula():
    radar = cs.Radar(tx_power=[10.0, 0.1, 0.1])
    w = cs.optimal_weights(3, 20.0, radar)
    expected = 1 / w.max() + 1 / (w.sum() - w.max())
    assert float(cs.crlb_bound(3, 20.0, radar)) == pytest.approx(expected, rel=1e-14)
    assert float(cs.crlb_bound(3, 20.0, radar)) == pytest.approx(4.0909e-3, rel=1e-4)
    f = cs.optimal_formation(3, (0.0, 0.0), 20.0, radar)
    assert float(cs.crlb(f, (0.0, 0.0), 20.0, radar)) == pytest.approx(expected, rel=1e-12)


def test_equal_uavs_keep_the_regular_polygon_bit_for_bit():
    for m in (3, 6, 11):
        plain = cs.optimal_formation(m, (80.0, 90.0), 20.0)
        per_uav = cs.optimal_formation(m, (80.0, 90.0), 20.0, cs.Radar(tx_power=[0.1] * m))
        np.testing.assert_array_equal(plain, per_uav)
        w = cs.optimal_weights(m, 20.0)
        assert float(cs.crlb_bound(m, 20.0)) == 4.0 / np.sum(w)


@pytest.mark.parametrize("seed", range(5))
def test_isotropic_azimuths_close_the_weighted_polygon(seed):
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.1, 1.0, int(rng.integers(2, 40)))
    theta = cs.isotropic_azimuths(w, rotation=0.7)
    z = np.sum(w * np.exp(2j * theta))
    assert abs(z) <= max(0.0, 2 * w.max() - w.sum()) + 1e-12 * w.sum()
    assert theta[0] == pytest.approx(0.7)
    assert float(cs.attainable_crlb(w)) == pytest.approx(
        4 * w.sum() / (w.sum() ** 2 - abs(z) ** 2), rel=1e-10
    )


def test_heterogeneous_batches_and_errors():
    radar = cs.Radar(tx_power=[1.0, 0.2, 0.3, 0.1])
    targets = np.array([[0.0, 0.0], [100.0, 50.0]])
    batch = cs.optimal_formation(4, targets, [20.0, 40.0], radar)
    assert batch.shape == (2, 4, 2)
    np.testing.assert_allclose(batch[1], cs.optimal_formation(4, targets[1], 40.0, radar))
    with pytest.raises(cs.FieldError, match="length 4"):
        cs.optimal_formation(5, (0.0, 0.0), 20.0, radar)
    with pytest.raises(cs.FieldError) as info:
        cs.attainable_crlb([1.0])
    assert info.value.field == "weights"


@pytest.mark.parametrize("seed", range(10, 16))
def test_random_wide_power_sets(seed):
    """Powers spread over two decades, M from 3 to 12: either case, as it falls."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(3, 13))
    radar = cs.Radar(tx_power=10 ** rng.uniform(-2.0, 0.0, m))
    formation = cs.optimal_formation(m, (0.0, 0.0), 30.0, radar)
    closed = float(cs.crlb(formation, (0.0, 0.0), 30.0, radar))
    assert closed == pytest.approx(float(cs.crlb_bound(m, 30.0, radar)), rel=1e-9)
    best = numerical_best(np.asarray(radar.snr_constant), 30.0, seed)
    assert closed <= best * (1 + 1e-9)
    assert closed == pytest.approx(best, rel=1e-6)
