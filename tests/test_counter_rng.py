"""The counter-based generator (crlbswarm.counter_rng): Philox4x32-10 against the published
known answers and an independent Python transcription, the uniforms, the normals'
distribution and independence, the keys, and the draws' independence of their order.

The statistical thresholds are five standard errors of each statistic for the sample size
(loose enough never to fail by chance for the fixed seeds, tight enough to catch a biased
or correlated transform); the samples are deterministic, so the tests are too.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st
from numba import njit
from scipy import stats

from crlbswarm.counter_rng import (
    DISTURBANCE,
    KEY_DOMAIN,
    RANGE_NOISE,
    normal_pair,
    philox4x32,
    standard_normals,
    stream_key,
    uniform53,
    uniform_pair,
)
from crlbswarm.errors import FieldError

WORD = st.integers(0, 2**32 - 1)

# Philox4x32-10 known-answer vectors: counter (4 words), key (2 words), expected output.
# Source: D. E. Shaw Research, Random123-Boost, libs/random/test/test_philox.cpp
# (github.com/DEShawResearch/Random123-Boost, commit 916db91a), test_kat_philox4x32, whose
# vectors are "cut-and-pasted from the kat_vectors file in the original Random123
# distribution" (tests/kat_vectors of Random123): the three 10-round lines,
#   philox4x32 10 00000000 00000000 00000000 00000000 00000000 00000000
#       6627e8d5 e169c58d bc57ac4c 9b00dbd8
#   philox4x32 10 ffffffff ffffffff ffffffff ffffffff ffffffff ffffffff
#       408f276d 41c83b0e a20bc7c6 6d5451fd
#   philox4x32 10 243f6a88 85a308d3 13198a2e 03707344 a4093822 299f31d0
#       d16cfe09 94fdcceb 5001e420 24126ea1
KAT_RANDOM123 = [
    ((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
    ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
    (
        (0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344),
        (0xA4093822, 0x299F31D0),
        (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1),
    ),
]

# More 10-round vectors, each flipping single counter or key bits: Random123's generated
# known answers, examples/kat_vectors of github.com/girving/random123-manual (commit
# 61e84792), lines "philox4x32 10 ...".
KAT_SINGLE_BITS = [
    ((1, 0, 0, 0), (1, 0), (0xAC08141B, 0xDFC5CCBE, 0x79C07A47, 0xA7F66093)),
    ((0, 0, 0, 0x80000000), (1, 0), (0xDDE26E4E, 0x17666F3B, 0xFC1F5B3A, 0x83AC805D)),
    ((0, 0, 1, 0), (0, 1), (0x7F6C13FF, 0x114B2447, 0x0550ECED, 0xEA1FC805)),
    (
        (0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344),
        (0, 0xFFFFFFFF),
        (0x08F7720C, 0x845EE9E0, 0x502CCD3D, 0xA9A00E27),
    ),
    ((0, 0xFFFFFFFF, 0, 0), (0, 0x80000000), (0x905EE550, 0xC7520E9A, 0x9AF9D0AD, 0x69B97E98)),
]


def philox_reference(counter, key, rounds=10):
    """Philox4x32 transcribed from Salmon et al. (SC'11), Python integers throughout."""
    m0, m1, w0, w1, mask = 0xD2511F53, 0xCD9E8D57, 0x9E3779B9, 0xBB67AE85, 0xFFFFFFFF
    x0, x1, x2, x3 = counter
    k0, k1 = key
    for r in range(rounds):
        if r:
            k0, k1 = (k0 + w0) & mask, (k1 + w1) & mask
        hi0, lo0 = divmod(m0 * x0, 2**32)
        hi1, lo1 = divmod(m1 * x2, 2**32)
        x0, x1, x2, x3 = hi1 ^ x1 ^ k0, lo1, hi0 ^ x3 ^ k1, lo0
    return x0, x1, x2, x3


# -- Philox4x32-10 -------------------------------------------------------------------------
@pytest.mark.parametrize(("counter", "key", "expected"), KAT_RANDOM123 + KAT_SINGLE_BITS)
def test_philox_reproduces_the_known_answers(counter, key, expected):
    assert tuple(int(x) for x in philox4x32(*counter, *key)) == expected
    assert philox_reference(counter, key) == expected


@given(st.tuples(WORD, WORD, WORD, WORD), st.tuples(WORD, WORD))
def test_philox_is_the_reference_transcription(counter, key):
    assert tuple(int(x) for x in philox4x32(*counter, *key)) == philox_reference(counter, key)


def test_philox_takes_the_low_32_bits_of_any_integer_type():
    want = philox4x32(5, 7, 1, 0, 0x12345678, 0x9ABCDEF0)
    assert philox4x32(5 + 2**32, 7, 1, 0, 0x12345678, 0x9ABCDEF0) == want
    typed = (np.int64(5), np.uint32(7), np.int32(1), np.uint64(0))
    assert philox4x32(*typed, np.uint32(0x12345678), np.uint64(0x9ABCDEF0)) == want


# -- uniforms ------------------------------------------------------------------------------
def test_uniform53_extremes_are_the_open_and_closed_ends():
    assert uniform53(0, 0) == 2.0**-53
    assert uniform53(0, 2**11 - 1) == 2.0**-53  # the low 11 bits of lo are dropped
    assert uniform53(0, 2**11) == 2.0**-52
    assert uniform53(2**32 - 1, 2**32 - 1) == 1.0
    assert uniform53(2**31, 0) == 0.5 + 2.0**-53


@given(WORD, WORD)
def test_uniform53_is_a_multiple_of_2_to_the_minus_53_in_0_1(hi, lo):
    u = uniform53(hi, lo)
    assert 0.0 < u <= 1.0
    assert u * 2.0**53 == (hi << 21) + (lo >> 11) + 1


@given(WORD, WORD, WORD, WORD)
def test_uniform_pair_converts_the_two_halves_of_the_block(k0, k1, step, uav):
    x = philox4x32(step, uav, DISTURBANCE, 0, k0, k1)
    assert uniform_pair(k0, k1, step, uav, DISTURBANCE, 0) == (
        uniform53(x[0], x[1]),
        uniform53(x[2], x[3]),
    )


@njit(cache=True)
def _uniform_extremes(k0, k1, n):
    low, high, total = 1.0, 0.0, 0.0
    for i in range(n):
        u1, u2 = uniform_pair(k0, k1, i, 0, 0, 0)
        low = min(low, u1, u2)
        high = max(high, u1, u2)
        total += u1 + u2
    return low, high, total / (2 * n)


def test_uniforms_never_reach_zero_and_average_one_half():
    n = 1_000_000
    low, high, mean = _uniform_extremes(*stream_key(11, DISTURBANCE), n)
    assert 0.0 < low < 1e-5
    assert 1 - 1e-5 < high <= 1.0
    assert abs(mean - 0.5) < 5 * math.sqrt(1 / 12 / (2 * n))


# -- normals: the transform ----------------------------------------------------------------
@given(WORD, WORD, WORD, WORD, st.sampled_from([DISTURBANCE, RANGE_NOISE]))
def test_normal_pair_is_box_muller_of_the_uniform_pair(k0, k1, step, uav, stream):
    """Against Box-Muller in extended precision (the long double of the platform, at
    least double): the sine and cosine are accurate to a few 1e-16."""
    u1, u2 = uniform_pair(k0, k1, step, uav, stream, 0)
    r = math.sqrt(-2.0 * math.log(u1))
    turn = 2 * np.longdouble("3.14159265358979323846264338327950288") * np.longdouble(u2)
    z0, z1 = normal_pair(k0, k1, step, uav, stream, 0)
    assert abs(z0 - r * float(np.cos(turn))) <= 4e-16 * max(r, 1.0)
    assert abs(z1 - r * float(np.sin(turn))) <= 4e-16 * max(r, 1.0)


@njit(cache=True)
def _angles(k0, k1, n):
    """The unit vectors (cos, sin) of n pairs (r divided out)."""
    out = np.empty((n, 2))
    for i in range(n):
        z0, z1 = normal_pair(k0, k1, i, 0, 0, 0)
        r = math.hypot(z0, z1)
        out[i, 0] = z0 / r
        out[i, 1] = z1 / r
    return out


def test_normal_pair_angle_is_on_the_unit_circle_and_uniform():
    unit = _angles(*stream_key(5, DISTURBANCE), 200_000)
    assert np.abs(np.hypot(unit[:, 0], unit[:, 1]) - 1).max() < 1e-15
    angle = np.arctan2(unit[:, 1], unit[:, 0]) / (2 * np.pi) % 1.0
    assert stats.kstest(angle, "uniform").pvalue > 1e-4


# -- normals: the distribution -------------------------------------------------------------
@pytest.fixture(scope="module", params=[0, 12345, 2**63 - 1])
def sample(request):
    """A million disturbance normals of one seed: 1000 steps x 500 UAVs x the pair."""
    return standard_normals(request.param, DISTURBANCE, 1000, 500)


def test_normals_moments_match_the_standard_normal(sample):
    z = sample.ravel()
    n = z.size
    assert abs(z.mean()) < 5 / math.sqrt(n)
    assert abs(z.var() - 1) < 5 * math.sqrt(2 / n)
    assert abs(stats.skew(z)) < 5 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < 5 * math.sqrt(24 / n)  # excess kurtosis


def test_normals_pass_kolmogorov_smirnov(sample):
    assert stats.kstest(sample.ravel(), "norm").pvalue > 1e-4
    for axis in (0, 1):  # each of the pair's values alone
        assert stats.kstest(sample[..., axis].ravel(), "norm").pvalue > 1e-4


@pytest.mark.parametrize("threshold", [1.0, 2.0, 3.0, 4.0])
def test_normals_tails_have_the_normal_mass(sample, threshold):
    z = sample.ravel()
    p = 2 * stats.norm.sf(threshold)
    observed = np.mean(np.abs(z) > threshold)
    assert abs(observed - p) < 5 * math.sqrt(p * (1 - p) / z.size) + 1 / z.size


def test_pairs_and_neighbours_are_uncorrelated(sample):
    z0, z1 = sample[..., 0].ravel(), sample[..., 1].ravel()
    limit = 5 / math.sqrt(z0.size)
    assert abs(np.corrcoef(z0, z1)[0, 1]) < limit
    assert abs(np.corrcoef(z0**2, z1**2)[0, 1]) < limit  # independent, not just uncorrelated
    next_step = np.corrcoef(sample[1:, :, 0].ravel(), sample[:-1, :, 0].ravel())[0, 1]
    next_uav = np.corrcoef(sample[:, 1:, 0].ravel(), sample[:, :-1, 0].ravel())[0, 1]
    assert abs(next_step) < limit
    assert abs(next_uav) < limit


def test_streams_and_seeds_are_uncorrelated():
    base = standard_normals(3, DISTURBANCE, 500, 200)[..., 0].ravel()
    limit = 5 / math.sqrt(base.size)
    for other in (
        standard_normals(3, RANGE_NOISE, 500, 200, dims=1).ravel(),
        standard_normals(4, DISTURBANCE, 500, 200)[..., 0].ravel(),
        standard_normals(3 + 2**32, DISTURBANCE, 500, 200)[..., 0].ravel(),
    ):
        assert abs(np.corrcoef(base, other)[0, 1]) < limit


# -- different coordinates, different draws ------------------------------------------------
def test_every_step_uav_stream_and_seed_draws_its_own_values():
    draws = [
        standard_normals(seed, stream, 300, 100)
        for seed in (0, 1, 2**32, 2**63 - 1)
        for stream in (DISTURBANCE, RANGE_NOISE)
    ]
    values = np.concatenate([d.ravel() for d in draws])
    assert np.unique(values).size == values.size


def test_counter_words_each_change_the_draw():
    key = stream_key(0, DISTURBANCE)
    base = normal_pair(*key, 0, 0, 0, 0)
    for counter in ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)):
        assert normal_pair(*key, *counter) != base
    assert normal_pair(key[0] ^ 1, key[1], 0, 0, 0, 0) != base
    assert normal_pair(key[0], key[1] ^ 1, 0, 0, 0, 0) != base


# -- keys ----------------------------------------------------------------------------------
def test_stream_key_is_the_seed_sequence_of_seed_and_stream():
    for seed, stream in ((0, 0), (1, 1), (2**63 - 1, RANGE_NOISE), (2**40 + 3, 7)):
        words = np.random.SeedSequence(seed, spawn_key=(KEY_DOMAIN, stream)).generate_state(
            2, np.uint32
        )
        assert stream_key(seed, stream) == (int(words[0]), int(words[1]))


def test_stream_keys_are_distinct_and_well_mixed():
    keys = [stream_key(s, t) for s in range(5000) for t in (DISTURBANCE, RANGE_NOISE)]
    assert len(set(keys)) == len(keys)
    bits = np.array([k0 | (k1 << 32) for k0, k1 in keys], dtype=np.uint64)
    ones = np.unpackbits(bits.view(np.uint8)).reshape(len(keys), 64).mean(axis=0)
    # neighbouring seeds: every key bit is set half the time (no bit follows the seed)
    assert np.abs(ones - 0.5).max() < 5 * math.sqrt(0.25 / len(keys))


def test_stream_keys_differ_from_the_drivers_spawned_streams():
    """The keys are not the first words of the NumPy streams spawned from the same seed."""
    for seed in range(20):
        spawned = {
            tuple(int(w) for w in child.generate_state(2, np.uint32))
            for child in np.random.SeedSequence(seed).spawn(8)
        }
        assert stream_key(seed, DISTURBANCE) not in spawned
        assert stream_key(seed, RANGE_NOISE) not in spawned


@given(st.integers(0, 2**63 - 1), st.integers(0, 2**32 - 1))
def test_stream_key_words_are_32_bit_and_deterministic(seed, stream):
    k0, k1 = stream_key(seed, stream)
    assert 0 <= k0 < 2**32
    assert 0 <= k1 < 2**32
    assert stream_key(np.int64(seed), np.uint32(stream)) == (k0, k1)


@pytest.mark.parametrize(
    ("seed", "stream", "field"),
    [(-1, 0, "seed"), (2**63, 0, "seed"), (1.5, 0, "seed"), (True, 0, "seed"),
     (0, -1, "stream"), (0, 2**32, "stream"), (0, "0", "stream")],
)  # fmt: skip
def test_stream_key_refuses_out_of_range_arguments(seed, stream, field):
    with pytest.raises(FieldError) as info:
        stream_key(seed, stream)
    assert info.value.field == field


# -- determinism: the same bits whatever is drawn, in whatever order -----------------------
def test_standard_normals_are_the_kernels_normal_pairs():
    seed, stream = 2024, DISTURBANCE
    z = standard_normals(seed, stream, 20, 6)
    key = stream_key(seed, stream)
    for k in range(20):
        for m in range(6):
            assert tuple(z[k, m]) == normal_pair(*key, k, m, stream, 0)
    ranges = standard_normals(seed, RANGE_NOISE, 20, 6, dims=1)
    range_key = stream_key(seed, RANGE_NOISE)
    assert ranges[7, 3, 0] == normal_pair(*range_key, 7, 3, RANGE_NOISE, 0)[0]


def test_subsets_and_orders_of_steps_and_uavs_draw_the_same_bits():
    full = standard_normals(9, DISTURBANCE, 400, 30)
    rng = np.random.default_rng(0)
    steps = rng.permutation(400)[:57]
    uavs = rng.permutation(30)[:11]
    part = standard_normals(9, DISTURBANCE, steps, uavs)
    assert np.array_equal(part, full[np.ix_(steps, uavs)])
    assert np.array_equal(standard_normals(9, DISTURBANCE, 400, 30), full)  # again
    assert np.array_equal(standard_normals(9, DISTURBANCE, 400, 30, dims=1), full[..., :1])
    longer = standard_normals(9, DISTURBANCE, 1000, 64)  # a longer mission, more UAVs
    assert np.array_equal(longer[:400, :30], full)


def test_far_counters_are_reachable_directly():
    last = 2**32 - 1
    z = standard_normals(1, RANGE_NOISE, [last, 0], [last])
    key = stream_key(1, RANGE_NOISE)
    assert tuple(z[0, 0]) == normal_pair(*key, last, last, RANGE_NOISE, 0)
    assert tuple(z[1, 0]) == normal_pair(*key, 0, last, RANGE_NOISE, 0)


@njit(cache=True)
def _backwards(k0, k1, steps, uavs):
    out = np.empty((steps, uavs, 2))
    for m in range(uavs - 1, -1, -1):
        for k in range(steps - 1, -1, -1):
            out[k, m, 0], out[k, m, 1] = normal_pair(k0, k1, k, m, DISTURBANCE, 0)
    return out


def test_compiled_draws_in_another_order_and_with_array_keys_are_the_same():
    key = np.array(stream_key(77, DISTURBANCE), dtype=np.uint32)  # as a kernel holds it
    got = _backwards(key[0], key[1], 50, 8)
    assert np.array_equal(got, standard_normals(77, DISTURBANCE, 50, 8))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"steps": -1}, "steps"), ({"steps": 2**32 + 1}, "steps"), ({"steps": 2.0}, "steps"),
     ({"steps": [0, 2**32]}, "steps"), ({"steps": [[0]]}, "steps"), ({"uavs": [0.5]}, "uavs"),
     ({"uavs": [-1]}, "uavs"), ({"dims": 3}, "dims"), ({"dims": True}, "dims"),
     ({"seed": -1}, "seed"), ({"stream": 2**32}, "stream")],
)  # fmt: skip
def test_standard_normals_refuses_bad_arguments(kwargs, field):
    args = {"seed": 0, "stream": DISTURBANCE, "steps": 3, "uavs": 2, "dims": 2} | kwargs
    with pytest.raises(FieldError) as info:
        standard_normals(**args)
    assert info.value.field == field


def test_standard_normals_of_nothing_is_empty():
    assert standard_normals(0, DISTURBANCE, 0, 5).shape == (0, 5, 2)
    assert standard_normals(0, RANGE_NOISE, [], 5, dims=1).shape == (0, 5, 1)
