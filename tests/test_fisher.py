"""Fisher information and CRLB (crlbswarm.fisher) against an independent reference.

The reference (``ref`` fixture, tests/conftest.py) builds the FIM from the Gaussian
log-likelihood of the range model itself, never from the library's closed form
``[J_d]_mm = A/d^4 + 8/d^2`` and ``J_s = Q^T J_d Q``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st
from numpy.polynomial.hermite_e import hermegauss

from crlbswarm import (
    FieldError,
    Radar,
    crlb,
    crlb_from_fim,
    d_optimality,
    d_optimality_from_fim,
    e_optimality,
    e_optimality_from_fim,
    elevation_angles,
    fisher_information,
    range_information,
    slant_ranges,
)

SEEDS = [0, 1, 2]
CRITERIA = [crlb, d_optimality, e_optimality]

#: Draws whose reference FIM has a condition number above this are left out of the
#: 1e-9 comparisons: there, the CRLB amplifies the ~1e-16 rounding of the FIM entries by
#: up to cond(J), so a 1e-9 agreement is not expected of any correct implementation.
MAX_COND = 1e6


def random_scenes(seed: int, n_uavs: int, count: int, rng_ref):
    """``count`` random scenes (uav_xy, target_xy, H): H log-uniform in [5 m, 5 km], the
    UAVs uniform in a disc around the target of radius log-uniform in [0.1 H, 10 H]."""
    rng = np.random.default_rng([seed, n_uavs])
    scenes = []
    for _ in range(count):
        altitude = float(np.exp(rng.uniform(np.log(5.0), np.log(5000.0))))
        target = rng.uniform(-1000.0, 1000.0, size=2)
        radius = altitude * float(np.exp(rng.uniform(np.log(0.1), np.log(10.0))))
        scenes.append((rng_ref.random_formation(rng, n_uavs, radius, target), target, altitude))
    return scenes


def assert_matches_reference(uav_xy, target, altitude, radar, fim_ref, ref) -> None:
    """FIM entries relative to ||J|| and the three criteria relative to themselves, 1e-9."""
    fim = fisher_information(uav_xy, target, altitude, radar)
    scale = np.linalg.norm(fim_ref)
    assert np.max(np.abs(fim - fim_ref)) <= 1e-9 * scale
    np.testing.assert_allclose(
        crlb(uav_xy, target, altitude, radar), ref.crlb_of_fim(fim_ref), 1e-9
    )
    np.testing.assert_allclose(
        d_optimality(uav_xy, target, altitude, radar), ref.d_optimality_of_fim(fim_ref), 1e-9
    )
    np.testing.assert_allclose(
        e_optimality(uav_xy, target, altitude, radar), ref.e_optimality_of_fim(fim_ref), 1e-9
    )


# -- agreement with the reference FIM -------------------------------------------------------


@pytest.mark.parametrize("n_uavs", range(3, 13))
@pytest.mark.parametrize("seed", SEEDS)
def test_fim_matches_slepian_bangs(seed, n_uavs, ref):
    """10 random scenes per (seed, M): 300 in all, FIM and criteria vs Slepian-Bangs."""
    prm = ref.radar_params()
    kept = 0
    for uav_xy, target, altitude in random_scenes(seed, n_uavs, 10, ref):
        fim_ref = ref.fim_slepian_bangs(uav_xy, target, altitude, prm)
        if np.linalg.cond(fim_ref) > MAX_COND:
            continue
        kept += 1
        assert_matches_reference(uav_xy, target, altitude, Radar(), fim_ref, ref)
    assert kept >= 8  # the filter must not empty the test


@pytest.mark.parametrize("n_uavs", range(3, 13))
@pytest.mark.parametrize("seed", SEEDS)
def test_fim_matches_expected_score_outer_product(seed, n_uavs, ref):
    """The same 300 scenes against J = E[score score^T] (Gauss-Hermite, complex step)."""
    prm = ref.radar_params()
    kept = 0
    for uav_xy, target, altitude in random_scenes(seed, n_uavs, 10, ref):
        fim_ref, mean_score = ref.fim_expected_score(uav_xy, target, altitude, prm)
        # Sanity of the reference itself: every UAV's score has zero mean.
        assert np.max(np.abs(mean_score)) <= 1e-9 * np.sqrt(np.linalg.norm(fim_ref))
        if np.linalg.cond(fim_ref) > MAX_COND:
            continue
        kept += 1
        assert_matches_reference(uav_xy, target, altitude, Radar(), fim_ref, ref)
    assert kept >= 8


@pytest.mark.parametrize("n_uavs", [3, 4])
@pytest.mark.parametrize("seed", SEEDS)
def test_fim_matches_joint_likelihood_on_full_grid(seed, n_uavs, ref):
    """No per-UAV split at all: E[score score^T] of the *joint* log-likelihood over a full
    tensor-product Gauss-Hermite grid (5^M nodes) of all the ranges."""
    prm = ref.radar_params()
    uav_xy, target, altitude = random_scenes(seed, n_uavs, 1, ref)[0]
    mu = ref.range_mean(uav_xy, target, altitude)
    sd = np.sqrt(ref.range_var(mu, prm))
    nodes, weights = hermegauss(5)
    grid = np.stack(np.meshgrid(*[nodes] * n_uavs, indexing="ij"), axis=-1).reshape(-1, n_uavs)
    grid_w = np.prod(np.meshgrid(*[weights] * n_uavs, indexing="ij"), axis=0).ravel()
    grid_w /= (2.0 * np.pi) ** (n_uavs / 2)
    dhat = mu + sd * grid  # (K, M)

    def joint_log_likelihood(s):
        return ref.log_likelihood_terms(dhat, uav_xy, s, altitude, prm).sum(axis=-1)

    score = ref.complex_step_grad(joint_log_likelihood, target)  # (2, K)
    fim_ref = (score * grid_w) @ score.T
    assert_matches_reference(uav_xy, target, altitude, Radar(), fim_ref, ref)


PER_UAV_FIELDS = [
    "tx_power",
    "noise_power",
    "processing_gain",
    "tx_gain",
    "rx_gain",
    "rcs",
    "carrier_frequency",
    "kappa",
]


@pytest.mark.parametrize("field", PER_UAV_FIELDS)
@pytest.mark.parametrize("seed", SEEDS)
def test_per_uav_radar_field_matches_reference(seed, field, ref):
    """One field per UAV (scaled by factors in [0.1, 10]) against the reference."""
    rng = np.random.default_rng([seed, 17])
    n_uavs = 7
    values = ref.PAPER_PROFILE[field] * np.exp(rng.uniform(np.log(0.1), np.log(10.0), n_uavs))
    radar = Radar(**{field: values})
    prm = ref.radar_params(**{field: values})
    for uav_xy, target, altitude in random_scenes(seed, n_uavs, 5, ref):
        fim_ref = ref.fim_slepian_bangs(uav_xy, target, altitude, prm)
        if np.linalg.cond(fim_ref) > MAX_COND:
            continue
        assert_matches_reference(uav_xy, target, altitude, radar, fim_ref, ref)


@pytest.mark.parametrize("seed", SEEDS)
def test_all_fields_per_uav_and_scalar_non_default(seed, ref):
    """Every field per UAV at once, and a non-default scalar radar."""
    rng = np.random.default_rng([seed, 23])
    n_uavs = 5
    per_uav = {k: v * np.exp(rng.uniform(-1.0, 1.0, n_uavs)) for k, v in ref.PAPER_PROFILE.items()}
    scalar = {k: v * float(np.exp(rng.uniform(-1.0, 1.0))) for k, v in ref.PAPER_PROFILE.items()}
    for fields in (per_uav, scalar):
        radar = Radar(**fields)
        prm = ref.radar_params(**fields)
        for uav_xy, target, altitude in random_scenes(seed, n_uavs, 5, ref):
            fim_ref = ref.fim_slepian_bangs(uav_xy, target, altitude, prm)
            if np.linalg.cond(fim_ref) > MAX_COND:
                continue
            assert_matches_reference(uav_xy, target, altitude, radar, fim_ref, ref)


@pytest.mark.parametrize("seed", SEEDS)
def test_range_information_matches_reference(seed, ref):
    """[J_d]_mm = 1/var + 0.5 (dvar/dd)^2 / var^2 of a range about itself (complex step)."""
    rng = np.random.default_rng(seed)
    distance = np.exp(rng.uniform(np.log(1.0), np.log(1e4), size=(4, 6)))
    prm = ref.radar_params()
    var = ref.range_var(distance, prm)
    dvar = np.imag(ref.range_var(distance + 1j * 1e-30, prm)) / 1e-30
    np.testing.assert_allclose(
        range_information(distance), 1 / var + 0.5 * dvar**2 / var**2, 1e-12
    )


# -- invariances -------------------------------------------------------------------------------


def well_conditioned_scene(seed: int, n_uavs: int, ref):
    """A random scene around a target in [-1 km, 1 km]^2 (offsets 0.3 H to 3 H)."""
    rng = np.random.default_rng(seed)
    altitude = float(np.exp(rng.uniform(np.log(5.0), np.log(5000.0))))
    target = rng.uniform(-1000.0, 1000.0, size=2)
    uav_xy = ref.random_formation(rng, n_uavs, altitude * rng.uniform(0.3, 3.0), target)
    return uav_xy, target, altitude


def rotation(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


scene_args = {
    "seed": st.integers(0, 2**32 - 1),
    "n_uavs": st.integers(3, 12),
}


@given(**scene_args)
def test_crlb_invariant_to_uav_order(seed, n_uavs, ref):
    """Permuting the UAVs (rows) changes no criterion."""
    uav_xy, target, altitude = well_conditioned_scene(seed, n_uavs, ref)
    perm = np.random.default_rng(seed + 1).permutation(n_uavs)
    for criterion in CRITERIA:
        np.testing.assert_allclose(
            criterion(uav_xy[perm], target, altitude),
            criterion(uav_xy, target, altitude),
            rtol=1e-10,
        )


@given(**scene_args, angle=st.floats(-10.0, 10.0))
def test_criteria_invariant_to_rotating_the_scene(seed, n_uavs, angle, ref):
    """Rotating UAVs and target together about the origin changes no criterion."""
    uav_xy, target, altitude = well_conditioned_scene(seed, n_uavs, ref)
    rot = rotation(angle)
    for criterion in CRITERIA:
        np.testing.assert_allclose(
            criterion(uav_xy @ rot.T, rot @ target, altitude),
            criterion(uav_xy, target, altitude),
            rtol=1e-10,
        )


@given(**scene_args, shift=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)))
def test_criteria_invariant_to_translating_the_scene(seed, n_uavs, shift, ref):
    """Translating UAVs and target together changes no criterion."""
    uav_xy, target, altitude = well_conditioned_scene(seed, n_uavs, ref)
    shift = np.array(shift)
    for criterion in CRITERIA:
        np.testing.assert_allclose(
            criterion(uav_xy + shift, target + shift, altitude),
            criterion(uav_xy, target, altitude),
            rtol=1e-10,
        )


@pytest.mark.parametrize("seed", [10, 11, 12, 13, 14])
def test_criteria_invariant_to_rigid_motion_and_relabelling(seed, ref):
    """Seeded: permute the UAVs (with their per-UAV radar entries), rotate by any angle and
    translate; crlb, d_optimality and e_optimality stay the same to 1e-10."""
    rng = np.random.default_rng(seed)
    n_uavs = int(rng.integers(3, 13))
    uav_xy, target, altitude = well_conditioned_scene(seed, n_uavs, ref)
    powers = rng.uniform(0.01, 1.0, n_uavs)
    perm = rng.permutation(n_uavs)
    rot = rotation(rng.uniform(-np.pi, np.pi))
    shift = rng.uniform(-1e3, 1e3, size=2)
    moved_xy = uav_xy[perm] @ rot.T + shift
    moved_target = rot @ target + shift
    for criterion in CRITERIA:
        np.testing.assert_allclose(
            criterion(moved_xy, moved_target, altitude, Radar(tx_power=powers[perm])),
            criterion(uav_xy, target, altitude, Radar(tx_power=powers)),
            rtol=1e-10,
        )


@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_fim_rotates_covariantly(seed, ref):
    """J(R q, R s) = R J(q, s) R^T, also for a per-UAV radar; traces are equal."""
    uav_xy, target, altitude = well_conditioned_scene(seed, 6, ref)
    radar = Radar(tx_power=np.linspace(0.05, 0.3, 6))
    rot = rotation(np.random.default_rng(seed).uniform(-np.pi, np.pi))
    fim = fisher_information(uav_xy, target, altitude, radar)
    fim_rot = fisher_information(uav_xy @ rot.T, rot @ target, altitude, radar)
    np.testing.assert_allclose(fim_rot, rot @ fim @ rot.T, atol=1e-10 * np.linalg.norm(fim))


@pytest.mark.parametrize("seed", SEEDS)
def test_crlb_invariant_to_reflection(seed, ref):
    """Mirroring the scene (x -> -x) changes no criterion: the FIM depends on 2 theta."""
    uav_xy, target, altitude = well_conditioned_scene(seed, 8, ref)
    flip = np.array([-1.0, 1.0])
    for criterion in CRITERIA:
        np.testing.assert_allclose(
            criterion(uav_xy * flip, target * flip, altitude),
            criterion(uav_xy, target, altitude),
            rtol=1e-10,
        )


# -- singular geometry -------------------------------------------------------------------------


def assert_all_infinite(uav_xy, target, altitude) -> None:
    fim = fisher_information(uav_xy, target, altitude)
    assert np.all(np.isfinite(fim))
    for criterion in CRITERIA:
        value = criterion(uav_xy, target, altitude)
        assert not np.any(np.isnan(value))
        assert np.all(np.isposinf(value))


@given(
    n_uavs=st.integers(1, 12),
    direction=st.floats(-np.pi, np.pi),
    offsets=st.lists(st.floats(-3.0, 3.0), min_size=12, max_size=12),
    target=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    altitude=st.floats(1.0, 5e3),
)
def test_uavs_on_a_line_through_the_target_give_inf(n_uavs, direction, offsets, target, altitude):
    """UAVs on a line through the target's projection: J_s has rank <= 1, so +inf.

    pytest turns warnings into errors, so a divide-by-zero warning would fail the test.
    """
    target = np.array(target)
    t = altitude * np.array(offsets[:n_uavs])
    uav_xy = target + t[:, None] * np.array([np.cos(direction), np.sin(direction)])
    assert_all_infinite(uav_xy, target, altitude)


@given(
    uav=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    target=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    altitude=st.floats(0.1, 5e3),
)
def test_single_uav_gives_inf(uav, target, altitude):
    """One range cannot fix two coordinates."""
    assert_all_infinite(np.array([uav]), np.array(target), altitude)


@pytest.mark.parametrize("n_uavs", [1, 3, 6])
@pytest.mark.parametrize("altitude", [0.1, 20.0, 5e3])
def test_uavs_straight_above_the_target_give_inf(n_uavs, altitude):
    """Every UAV at the target's projection: no horizontal information, J_s = 0."""
    target = np.array([80.0, 90.0])
    uav_xy = np.tile(target, (n_uavs, 1))
    np.testing.assert_array_equal(fisher_information(uav_xy, target, altitude), np.zeros((2, 2)))
    assert_all_infinite(uav_xy, target, altitude)


def test_singular_and_regular_scenes_in_one_batch(ref):
    """Only the singular entries of a batch are inf; the others are finite and exact."""
    regular = ref.random_formation(np.random.default_rng(0), 4, 30.0)
    line = np.array([[0.0, 0.0], [5.0, 5.0], [-3.0, -3.0], [10.0, 10.0]])
    above = np.zeros((4, 2))
    batch = np.stack([regular, line, above, regular])
    for criterion in CRITERIA:
        values = criterion(batch, np.zeros(2), 20.0)
        np.testing.assert_array_equal(np.isinf(values), [False, True, True, False])
        np.testing.assert_allclose(values[[0, 3]], criterion(regular, np.zeros(2), 20.0), 1e-15)


@pytest.mark.parametrize("from_fim", [crlb_from_fim, d_optimality_from_fim, e_optimality_from_fim])
def test_from_fim_singular_matrices_give_inf(from_fim):
    """Zero and rank-one matrices give +inf, no warning, no NaN."""
    u = np.array([0.6, 0.8])
    fims = np.stack([np.zeros((2, 2)), 3.0 * np.outer(u, u), np.diag([1.0, 0.0])])
    np.testing.assert_array_equal(from_fim(fims), np.full(3, np.inf))


@pytest.mark.parametrize("seed", SEEDS)
def test_from_fim_matches_numpy_linalg(seed, ref):
    """The *_from_fim figures of random SPD matrices against numpy.linalg."""
    rng = np.random.default_rng(seed)
    factors = rng.normal(size=(20, 2, 2))
    fims = factors @ np.swapaxes(factors, -1, -2) + 1e-3 * np.eye(2)
    for from_fim, reference in [
        (crlb_from_fim, ref.crlb_of_fim),
        (d_optimality_from_fim, ref.d_optimality_of_fim),
        (e_optimality_from_fim, ref.e_optimality_of_fim),
    ]:
        expected = [reference(j) for j in fims if np.linalg.cond(j) < MAX_COND]
        got = from_fim(fims)[np.linalg.cond(fims) < MAX_COND]
        np.testing.assert_allclose(got, expected, rtol=1e-9)


# -- batch shapes -------------------------------------------------------------------------------


def loop_reference(function, uav_xy, target, altitude):
    """``function`` applied to each element of the broadcast batch, one call each."""
    batch = np.broadcast_shapes(uav_xy.shape[:-2], target.shape[:-1], np.shape(altitude))
    q = np.broadcast_to(uav_xy, (*batch, *uav_xy.shape[-2:]))
    s = np.broadcast_to(target, (*batch, 2))
    h = np.broadcast_to(altitude, batch)
    out = [function(q[i], s[i], h[i]) for i in np.ndindex(batch)]
    return np.array(out).reshape(*batch, *np.shape(out[0]))


BATCH_CASES = [
    # (uav_xy batch shape, target batch shape, altitude shape)
    ((2, 3), (3,), (2, 1)),
    ((4,), (), (4,)),
    ((), (5,), ()),
    ((), (), (6,)),
    ((2, 1, 3), (4, 1), ()),
]


@pytest.mark.parametrize(("q_batch", "s_batch", "h_shape"), BATCH_CASES)
@pytest.mark.parametrize(
    "function",
    [fisher_information, crlb, d_optimality, e_optimality, slant_ranges, elevation_angles],
)
def test_batch_equals_loop(function, q_batch, s_batch, h_shape):
    """(..., M, 2) positions, (..., 2) targets and (...) altitudes broadcast like NumPy."""
    rng = np.random.default_rng(7)
    n_uavs = 5
    uav_xy = rng.uniform(-40.0, 40.0, size=(*q_batch, n_uavs, 2))
    target = rng.uniform(-5.0, 5.0, size=(*s_batch, 2))
    altitude = rng.uniform(5.0, 60.0, size=h_shape)
    got = function(uav_xy, target, altitude)
    expected = loop_reference(function, uav_xy, target, altitude)
    batch = np.broadcast_shapes(q_batch, s_batch, h_shape)
    assert got.shape == expected.shape
    assert got.shape[: len(batch)] == batch
    np.testing.assert_allclose(got, expected, rtol=1e-13)


def test_batch_with_per_uav_radar_equals_loop():
    """Per-UAV radar fields broadcast over the UAV axis of a batch."""
    rng = np.random.default_rng(8)
    radar = Radar(tx_power=[0.1, 0.2, 0.05, 0.1], kappa=[1.0, 2.0, 1.0, 0.5])
    uav_xy = rng.uniform(-40.0, 40.0, size=(3, 2, 4, 2))
    for criterion in [*CRITERIA, fisher_information]:

        def one(q, s, h, criterion=criterion):
            return criterion(q, s, h, radar)

        np.testing.assert_allclose(
            one(uav_xy, np.zeros(2), 20.0),
            loop_reference(one, uav_xy, np.zeros(2), 20.0),
            rtol=1e-13,
        )


# -- bad input ------------------------------------------------------------------------------------

GOOD_Q = np.array([[10.0, 0.0], [0.0, 10.0], [-10.0, -5.0]])
GOOD_S = np.array([1.0, 2.0])

BAD_INPUTS = [
    # (uav_xy, target_xy, altitude, radar, message start)
    (np.zeros((6, 3)), GOOD_S, 20.0, Radar(), r"^uav_xy"),
    (np.zeros(6), GOOD_S, 20.0, Radar(), r"^uav_xy"),
    (np.zeros((0, 2)), GOOD_S, 20.0, Radar(), r"^uav_xy"),
    (np.where(np.eye(3, 2) > 0, np.nan, GOOD_Q), GOOD_S, 20.0, Radar(), r"^uav_xy"),
    (np.where(np.eye(3, 2) > 0, np.inf, GOOD_Q), GOOD_S, 20.0, Radar(), r"^uav_xy"),
    (GOOD_Q, np.zeros(3), 20.0, Radar(), r"^target_xy"),
    (GOOD_Q, np.array([np.nan, 0.0]), 20.0, Radar(), r"^target_xy"),
    (GOOD_Q, np.array([0.0, -np.inf]), 20.0, Radar(), r"^target_xy"),
    (np.zeros((4, 3, 2)), np.zeros((5, 2)), 20.0, Radar(), r"^target_xy"),
    (GOOD_Q, GOOD_S, 0.0, Radar(), r"^altitude"),
    (GOOD_Q, GOOD_S, -20.0, Radar(), r"^altitude"),
    (GOOD_Q, GOOD_S, np.nan, Radar(), r"^altitude"),
    (GOOD_Q, GOOD_S, np.array([20.0, 0.0]), Radar(), r"^altitude"),
    (np.zeros((4, 3, 2)), GOOD_S, np.ones(5), Radar(), r"^altitude"),
    (GOOD_Q, GOOD_S, 20.0, Radar(tx_power=[0.1, 0.1]), r"^radar"),
    (GOOD_Q, GOOD_S, 20.0, Radar(kappa=[1.0, 1.0, 1.0, 1.0]), r"^radar"),
]


@pytest.mark.parametrize("function", [fisher_information, *CRITERIA])
@pytest.mark.parametrize(("uav_xy", "target", "altitude", "radar", "match"), BAD_INPUTS)
def test_bad_input_raises_value_error_naming_the_argument(
    function, uav_xy, target, altitude, radar, match
):
    """Wrong shapes, NaN/inf, bad altitude, per-UAV length mismatch."""
    with pytest.raises(ValueError, match=match):
        function(uav_xy, target, altitude, radar)


@pytest.mark.parametrize("from_fim", [crlb_from_fim, d_optimality_from_fim, e_optimality_from_fim])
@pytest.mark.parametrize("fim", [np.eye(3), np.ones(2), np.array([[1.0, np.nan], [0.0, 1.0]])])
def test_from_fim_bad_input(from_fim, fim):
    """A FIM must have shape (..., 2, 2) and be finite."""
    with pytest.raises(ValueError, match=r"^fim"):
        from_fim(fim)


def test_range_information_bad_distance():
    """Ranges must be positive and finite."""
    for bad in (0.0, -1.0, np.nan, [1.0, np.inf]):
        with pytest.raises(ValueError, match=r"^distance"):
            range_information(bad)


# -- inputs are never modified ------------------------------------------------------------------


@pytest.mark.parametrize(
    "function",
    [fisher_information, crlb, d_optimality, e_optimality, slant_ranges, elevation_angles],
)
def test_read_only_inputs_are_accepted_and_unchanged(function, make_readonly):
    """Read-only inputs are accepted, unchanged, and not aliased by the output."""
    uav_xy = make_readonly(np.random.default_rng(0).uniform(-30.0, 30.0, size=(2, 5, 2)))
    target = make_readonly([[1.0, 2.0], [3.0, -4.0]])
    altitude = make_readonly([20.0, 35.0])
    copies = [a.copy() for a in (uav_xy, target, altitude)]
    out = function(uav_xy, target, altitude)
    for arr, copy in zip((uav_xy, target, altitude), copies, strict=True):
        np.testing.assert_array_equal(arr, copy)
        assert not np.shares_memory(out, arr)


def test_from_fim_and_range_information_leave_inputs_unchanged(make_readonly):
    """Read-only inputs are accepted and left unchanged."""
    fim = make_readonly([[[2.0, 0.5], [0.5, 1.0]], [[1.0, 0.0], [0.0, 1.0]]])
    distance = make_readonly([[20.0, 30.0, 40.0]])
    for function, arg in [
        (crlb_from_fim, fim),
        (d_optimality_from_fim, fim),
        (e_optimality_from_fim, fim),
        (range_information, distance),
    ]:
        copy = arg.copy()
        function(arg)
        np.testing.assert_array_equal(arg, copy)


@given(seed=st.integers(0, 2**32 - 1), n_uavs=st.integers(3, 12))
def test_fim_is_symmetric_positive_semidefinite(seed, n_uavs, ref):
    """J_s is symmetric PSD with trace sum_m [J_d]_mm cos^2(phi_m) (reference weights)."""
    uav_xy, target, altitude = well_conditioned_scene(seed, n_uavs, ref)
    fim = fisher_information(uav_xy, target, altitude)
    assert fim[0, 1] == fim[1, 0]
    assert np.all(np.linalg.eigvalsh(fim) >= -1e-12 * np.trace(fim))
    rho = np.hypot(*(uav_xy - target).T)
    phi = np.arctan2(altitude, rho)
    a = ref.snr_constant(ref.radar_params())
    np.testing.assert_allclose(
        np.trace(fim), ref.information_weight(phi, altitude, a).sum(), rtol=1e-12
    )


@pytest.mark.parametrize("fim", [-np.eye(2), [[1.0, 2.0], [2.0, 1.0]], [[1.0, 0.5], [0.0, 1.0]]])
def test_from_fim_rejects_matrices_that_are_not_fims(fim):
    """A FIM is symmetric positive semi-definite; anything else is an input error."""
    for fn in (crlb_from_fim, d_optimality_from_fim, e_optimality_from_fim):
        with pytest.raises(ValueError, match=r"^fim"):
            fn(fim)


def test_extreme_fims_are_refused_and_singular_ones_give_inf():
    """FIMs whose inverse would over- or underflow are refused (one line naming fim); the
    zero matrix is singular: +inf, silently."""
    with pytest.raises(FieldError, match=r"^fim: .*model's range"):
        crlb_from_fim(np.eye(2) * 1e-300)
    with pytest.raises(FieldError, match=r"^fim: "):
        crlb_from_fim(np.eye(2) * 1e200)
    assert crlb_from_fim(np.zeros((2, 2))) == np.inf
    assert np.isfinite(crlb_from_fim(np.eye(2) * 1e-150))
