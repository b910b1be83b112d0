"""Moving targets (crlbswarm.tracking): motion models, target trajectories and the PCRB.

Every reference here is written independently of crlbswarm:

* the constant-velocity and coordinated-turn matrices are typed in from the textbook
  (Bar-Shalom, Li, Kirubarajan 2001, Sec. 6.3.2 and eq. (11.7.1-4)), the latter in the
  book's interleaved state order (x, vx, y, vy) and permuted here;
* noiseless trajectories are compared with the closed-form motion (straight line, circle);
* noisy trajectories are checked statistically (many runs) and by the exact identity between
  the position and the velocity increments that a common acceleration implies;
* the posterior CRLB is compared with a direct accumulation of information (static target),
  with the Kalman-filter Riccati recursion in covariance (Joseph) form, which for a
  linear-Gaussian model equals the Tichavsky recursion, and with scipy's discrete algebraic
  Riccati solver in steady state;
* the range information is compared with conftest's Slepian-Bangs FIM.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, strategies as st

from crlbswarm import Radar
from crlbswarm.tracking import (
    motion_matrices,
    posterior_crlb,
    summed_range_information,
    target_trajectories,
)
from kalman_reference import kf_position_mse

SEEDS = [0, 1, 7, 2024]
I2 = np.eye(2)
Z2 = np.zeros((2, 2))


# -- independent references -------------------------------------------------------------------
def cv_reference(dt: float) -> np.ndarray:
    """Constant-velocity F for the state (x, y, vx, vy): x' = x + dt vx, v' = v."""
    return np.block([[I2, dt * I2], [Z2, I2]])


def dwna_q_reference(dt: float, sigma_a: float) -> np.ndarray:
    """Discrete white-noise acceleration Q (Bar-Shalom eq. (6.3.2-4)), entries typed in."""
    q1 = np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt**2]])  # per axis (pos, vel)
    q = np.zeros((4, 4))
    for axis in range(2):
        idx = [axis, axis + 2]
        q[np.ix_(idx, idx)] = q1
    return sigma_a**2 * q


def ct_reference(dt: float, w: float) -> np.ndarray:
    """Coordinated turn with known rate w, Bar-Shalom eq. (11.7.1-4), state (x, vx, y, vy),
    permuted to crlbswarm's order (x, y, vx, vy)."""
    s, c = math.sin(w * dt), math.cos(w * dt)
    book = np.array(
        [
            [1.0, s / w, 0.0, -(1.0 - c) / w],
            [0.0, c, 0.0, -s],
            [0.0, (1.0 - c) / w, 1.0, s / w],
            [0.0, s, 0.0, c],
        ]
    )
    order = [0, 2, 1, 3]  # crlbswarm index i is the book's index order[i]
    return book[np.ix_(order, order)]


def random_fims(rng: np.random.Generator, steps: int, scale: float = 1.0) -> np.ndarray:
    """(steps, 2, 2) random symmetric positive-definite matrices."""
    a = rng.standard_normal((steps, 2, 2))
    return scale * (a @ np.swapaxes(a, -1, -2) + 0.1 * I2)


def rngs_for(seeds) -> list[np.random.Generator]:
    return [np.random.default_rng(s) for s in seeds]


# =============================================================================================
# motion_matrices
# =============================================================================================
@pytest.mark.parametrize("dt", [0.01, 0.1, 1.0, 2.5])
@pytest.mark.parametrize("sigma_a", [0.0, 0.05, 3.0])
def test_constant_velocity_matrices_are_the_textbook_ones(dt, sigma_a):
    f, q, n_state = motion_matrices("constant_velocity", dt, acceleration_noise=sigma_a)
    assert n_state == 4
    np.testing.assert_array_equal(f, cv_reference(dt))
    np.testing.assert_allclose(q, dwna_q_reference(dt, sigma_a), rtol=1e-14, atol=0)
    # Q = sigma_a^2 G G^T with G = [dt^2/2 I; dt I].
    g = np.vstack([0.5 * dt**2 * I2, dt * I2])
    np.testing.assert_allclose(q, sigma_a**2 * g @ g.T, rtol=1e-14, atol=0)


@pytest.mark.parametrize("dt", [0.1, 1.0])
@pytest.mark.parametrize("w", [0.02, -0.3, 1.0, math.pi])
def test_coordinated_turn_matrix_is_the_textbook_one(dt, w):
    f, q, n_state = motion_matrices("turning", dt, turn_rate=w, acceleration_noise=0.2)
    assert n_state == 4
    np.testing.assert_allclose(f, ct_reference(dt, w), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(q, dwna_q_reference(dt, 0.2), rtol=1e-14, atol=0)


@pytest.mark.parametrize("dt", [0.1, 1.0])
def test_coordinated_turn_tends_to_constant_velocity(dt):
    """F_CT(w) - F_CV = O(w): the largest entries are sin(w dt) ~ w dt (velocity rotation)
    and (1 - cos w dt)/w ~ w dt^2 / 2 (position), so the gap shrinks linearly with w."""
    scale = max(dt, dt**2 / 2)
    gaps = []
    for w in (1e-2, 1e-3, 1e-4, 1e-5, 1e-7):
        for sign in (1.0, -1.0):
            f = motion_matrices("turning", dt, turn_rate=sign * w)[0]
            gap = np.abs(f - cv_reference(dt)).max()
            assert gap <= 1.001 * w * scale + 1e-15, (w, gap)
            assert gap >= 0.99 * w * scale, (w, gap)
        gaps.append(gap)
    np.testing.assert_allclose(
        motion_matrices("turning", dt, turn_rate=1e-7)[0], cv_reference(dt), rtol=0, atol=2e-7
    )
    assert np.all(np.diff(gaps) < 0)


@given(
    dt=st.floats(1e-3, 5.0),
    w=st.floats(1e-3, 3.0) | st.floats(-3.0, -1e-3),
    vx=st.floats(-50.0, 50.0),
    vy=st.floats(-50.0, 50.0),
)
def test_coordinated_turn_preserves_speed(dt, w, vx, vy):
    f = motion_matrices("turning", dt, turn_rate=w)[0]
    state = np.array([3.0, -4.0, vx, vy])
    after = f @ state
    assert math.hypot(*after[2:]) == pytest.approx(math.hypot(vx, vy), rel=1e-14, abs=1e-14)
    # The velocity block is a rotation by w dt (counter-clockwise for w > 0).
    np.testing.assert_allclose(f[2:, :2], Z2, atol=0)
    np.testing.assert_allclose(f[2:, 2:].T @ f[2:, 2:], I2, rtol=0, atol=1e-15)
    assert np.linalg.det(f[2:, 2:]) == pytest.approx(1.0, abs=1e-14)
    assert math.atan2(f[3, 2], f[2, 2]) == pytest.approx(math.remainder(w * dt, math.tau))


@given(
    model=st.sampled_from(["constant_velocity", "turning"]),
    dt1=st.floats(1e-3, 2.0),
    dt2=st.floats(1e-3, 2.0),
    w=st.floats(0.01, 1.0),
)
def test_transition_is_a_semigroup(model, dt1, dt2, w):
    """The exact motion satisfies F(dt1) F(dt2) = F(dt1 + dt2)."""
    rate = w if model == "turning" else 0.0
    f1 = motion_matrices(model, dt1, turn_rate=rate)[0]
    f2 = motion_matrices(model, dt2, turn_rate=rate)[0]
    f12 = motion_matrices(model, dt1 + dt2, turn_rate=rate)[0]
    np.testing.assert_allclose(f1 @ f2, f12, rtol=1e-12, atol=1e-12)


def test_static_model_is_two_state_and_noiseless():
    f, q, n_state = motion_matrices("static", 0.1, acceleration_noise=2.0)
    assert n_state == 2
    np.testing.assert_array_equal(f, np.eye(4))
    np.testing.assert_array_equal(q, np.zeros((4, 4)))


@pytest.mark.parametrize("model", ["ballistic", "CV", "", "Turning"])
def test_unknown_model_raises_naming_model(model):
    with pytest.raises(ValueError, match=r"^model: ") as info:
        motion_matrices(model, 0.1)
    assert repr(model) in str(info.value)


# Regression (fixed): motion_matrices("turning", 0.1, turn_rate=0.0) raises ZeroDivisionError
# ("float division by zero") from s / w. Expected, by STYLE.md point 3, a ValueError naming
# turn_rate, or else the w -> 0 limit (the constant-velocity matrix). Scenario validation
# refuses turn_rate = 0 for 'turning', so only direct callers of the public function see it.
def test_turning_with_zero_rate_is_an_error_naming_turn_rate_or_the_cv_limit():
    try:
        f = motion_matrices("turning", 0.1, turn_rate=0.0)[0]
    except ValueError as exc:
        f, message = None, str(exc)
    if f is None:
        assert "turn_rate" in message
    else:
        np.testing.assert_allclose(f, cv_reference(0.1), atol=1e-15)


# =============================================================================================
# target_trajectories
# =============================================================================================
@pytest.mark.parametrize("dt", [0.1, 0.5])
def test_noiseless_constant_velocity_is_a_straight_line(dt):
    s0, v0, k = np.array([60.0, -20.0]), np.array([3.0, -1.5]), 1000
    traj = target_trajectories(s0, v0, "constant_velocity", dt, k, rngs_for([0, 1]))
    assert traj.shape == (2, k + 1, 4)
    t = np.arange(k + 1) * dt
    line = np.broadcast_to(s0 + t[:, None] * v0, (2, k + 1, 2))
    np.testing.assert_allclose(traj[:, :, :2], line, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(traj[:, :, 2:], np.broadcast_to(v0, (2, k + 1, 2)))


@pytest.mark.parametrize("w", [0.02, -0.05, 0.5])
def test_noiseless_turn_is_a_circle_at_constant_speed(w):
    s0, v0, dt, k = np.array([60.0, 60.0]), np.array([3.0, 0.0]), 0.1, 3000
    traj = target_trajectories(s0, v0, "turning", dt, k, rngs_for([5]), turn_rate=w)[0]
    t = np.arange(k + 1) * dt
    s, c = np.sin(w * t), np.cos(w * t)
    # Closed form: v(t) = R(wt) v0, s(t) = s0 + [sin wt, -(1 - cos wt); 1 - cos wt, sin wt] v0/w.
    x = s0[0] + (v0[0] * s - v0[1] * (1.0 - c)) / w
    y = s0[1] + (v0[0] * (1.0 - c) + v0[1] * s) / w
    np.testing.assert_allclose(traj[:, 0], x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj[:, 1], y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj[:, 2], v0[0] * c - v0[1] * s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj[:, 3], v0[0] * s + v0[1] * c, rtol=0, atol=1e-12)
    # Each step is an exact rotation: the speed drifts only by accumulated rounding.
    speed = np.hypot(traj[:, 2], traj[:, 3])
    np.testing.assert_allclose(speed, np.full(k + 1, np.hypot(*v0)), rtol=1e-12)
    # On the circle of radius |v|/|w| about s0 + (-vy, vx)/w.
    centre = s0 + np.array([-v0[1], v0[0]]) / w
    radius = np.hypot(traj[:, 0] - centre[0], traj[:, 1] - centre[1])
    np.testing.assert_allclose(radius, np.full(k + 1, np.hypot(*v0) / abs(w)), rtol=1e-11)


def test_static_target_stays_put_with_zero_velocity():
    traj = target_trajectories(
        np.array([1.0, 2.0]), np.array([3.0, 4.0]), "static", 0.1, 50, rngs_for([0, 1, 2])
    )
    np.testing.assert_array_equal(traj[..., :2], np.broadcast_to([1.0, 2.0], (3, 51, 2)))
    np.testing.assert_array_equal(traj[..., 2:], 0.0)


@pytest.mark.parametrize("model", ["constant_velocity", "turning"])
def test_noisy_increments_have_the_dwna_statistics(model):
    """v_{k+1} - F_v v_k = dt a_k: zero mean, covariance sigma_a^2 dt^2 I, white in time;
    and the position increment is consistent with the same acceleration, exactly."""
    dt, sigma_a, k, w = 0.1, 0.3, 100, 0.2
    rate = w if model == "turning" else 0.0
    traj = target_trajectories(
        np.array([0.0, 0.0]), np.array([3.0, 1.0]), model, dt, k, rngs_for(range(2000)),
        turn_rate=rate, acceleration_noise=sigma_a,
    )  # fmt: skip
    f = ct_reference(dt, w) if model == "turning" else cv_reference(dt)
    g = np.vstack([0.5 * dt**2 * I2, dt * I2])
    residual = traj[:, 1:] - traj[:, :-1] @ f.T  # (B, K, 4) = G a_k
    accel = residual[..., 2:] / dt  # a_k
    # Exact: the position part of the residual is G_pos a_k (same a_k as the velocity).
    np.testing.assert_allclose(residual, accel @ g.T, rtol=0, atol=1e-12)
    samples = accel.reshape(-1, 2)
    n = samples.shape[0]  # 200 000 draws
    assert np.all(np.abs(samples.mean(axis=0)) < 5 * sigma_a / math.sqrt(n))
    cov = np.cov(samples.T) * dt**2  # covariance of the velocity increments
    # The sample variance of n normal draws has relative sd sqrt(2/n) ~ 0.3%.
    np.testing.assert_allclose(np.diag(cov), sigma_a**2 * dt**2, rtol=5 * math.sqrt(2 / n))
    assert abs(cov[0, 1]) < 5 * sigma_a**2 * dt**2 / math.sqrt(n)
    lag1 = np.mean(accel[:, 1:, 0] * accel[:, :-1, 0]) / sigma_a**2
    assert abs(lag1) < 5 / math.sqrt(n)


def test_noisy_position_spread_matches_the_integrated_acceleration():
    """Var(x_k - x_0 - k dt v_0) = sigma_a^2 dt^4 sum_{i<k} (i + 1/2)^2 per axis."""
    dt, sigma_a, k = 0.1, 0.5, 200
    v0 = np.array([3.0, 0.0])
    traj = target_trajectories(
        np.array([60.0, 60.0]), v0, "constant_velocity", dt, k, rngs_for(range(4000)),
        acceleration_noise=sigma_a,
    )  # fmt: skip
    t = np.arange(k + 1) * dt
    dev = traj[:, :, :2] - (np.array([60.0, 60.0]) + t[:, None] * v0)
    expected = sigma_a**2 * dt**4 * np.concatenate([[0.0], np.cumsum((np.arange(k) + 0.5) ** 2)])
    var = dev.var(axis=0).mean(axis=-1)  # 8000 samples per step
    np.testing.assert_allclose(var[1:], expected[1:], rtol=0.1)
    assert var[0] == 0.0


TURN_ARGS = (np.array([5.0, 5.0]), np.array([1.0, 2.0]), "turning", 0.1, 300)
TURN_KW = {"turn_rate": 0.1, "acceleration_noise": 0.2}


def test_one_stream_per_run_and_deterministic():
    batch = target_trajectories(*TURN_ARGS, rngs_for([11, 12, 13]), **TURN_KW)
    again = target_trajectories(*TURN_ARGS, rngs_for([11, 12, 13]), **TURN_KW)
    np.testing.assert_array_equal(batch, again)
    # Run b depends on rngs[b] only (bit-identity: see the test below).
    single = target_trajectories(*TURN_ARGS, rngs_for([12]), **TURN_KW)
    np.testing.assert_allclose(batch[1], single[0], rtol=1e-13, atol=1e-13)
    reordered = target_trajectories(*TURN_ARGS, rngs_for([13, 11]), **TURN_KW)
    np.testing.assert_allclose(reordered, batch[[2, 0]], rtol=1e-13, atol=1e-13)
    assert np.abs(batch[0] - batch[1]).max() > 0.1


# Regression (fixed): run b of a batch is not bit-identical to the same run alone. Input: the call
# above (turning, w = 0.1, sigma_a = 0.2, 300 steps), rngs seeds [11, 12, 13] vs [12].
# Expected: batch[1] == single[0] bit for bit. Got: differences of ~1e-15 relative in about
# half the entries. Cause: the step ``out[:, k] @ f.T + accel[:, k] @ g.T`` is a BLAS matmul
# whose rounding (FMA, summation order) depends on the number of rows. simulate() computes
# the truth per chunk of runs with this function, so its documented promise "run b of a batch
# is bit-identical to the single run" breaks for moving targets (see test_sensing_loop.py).
def test_run_of_a_batch_is_bit_identical_to_the_run_alone():
    batch = target_trajectories(*TURN_ARGS, rngs_for([11, 12, 13]), **TURN_KW)
    single = target_trajectories(*TURN_ARGS, rngs_for([12]), **TURN_KW)
    np.testing.assert_array_equal(batch[1], single[0])


def test_zero_noise_leaves_the_streams_alone(make_readonly):
    rngs = rngs_for([3, 4])
    before = [r.bit_generator.state for r in rngs]
    start, vel = make_readonly([1.0, 1.0]), make_readonly([2.0, 0.0])
    target_trajectories(start, vel, "constant_velocity", 0.1, 20, rngs)
    assert [r.bit_generator.state for r in rngs] == before
    np.testing.assert_array_equal(start, [1.0, 1.0])


# =============================================================================================
# posterior_crlb
# =============================================================================================
@pytest.mark.parametrize("seed", SEEDS)
def test_pcrb_static_target_accumulates_information(seed, make_readonly):
    rng = np.random.default_rng(seed)
    k = 40
    fims = random_fims(rng, k)
    p0 = np.diag([400.0, 250.0, 25.0, 25.0])
    f, q, n_state = motion_matrices("static", 0.1)
    got = posterior_crlb(make_readonly(fims), make_readonly(f), make_readonly(q), p0, n_state)
    info = np.linalg.inv(p0[:2, :2]) + np.cumsum(fims, axis=0)
    expected = np.trace(np.linalg.inv(info), axis1=-2, axis2=-1)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    assert np.all(np.diff(got) < 0)  # information only grows


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("model", ["constant_velocity", "turning"])
def test_pcrb_equals_the_kalman_filter_covariance(seed, model):
    """Linear-Gaussian motion, time-varying J_z: the Tichavsky recursion equals the KF
    Riccati recursion with H = [I 0], R_k = J_k^-1 (covariance form, written above)."""
    rng = np.random.default_rng(seed)
    dt, k = 0.1, 300
    fims = random_fims(rng, k + 1, scale=50.0)
    f, q, n_state = motion_matrices(model, dt, turn_rate=0.05, acceleration_noise=0.4)
    p0 = np.diag([400.0, 400.0, 25.0, 25.0])
    got = posterior_crlb(fims, f, q, p0, n_state)
    np.testing.assert_allclose(got, kf_position_mse(fims, f, q, p0), rtol=1e-9)


def test_pcrb_constant_information_reaches_the_riccati_steady_state():
    """Constant J_z and CV motion: the PCRB settles at the filtered covariance of the DARE
    solution (scipy), and matches the KF at every step on the way."""
    dt, sigma_a, k = 0.1, 0.05, 2000
    jz = np.array([[900.0, 200.0], [200.0, 400.0]])
    fims = np.broadcast_to(jz, (k + 1, 2, 2))
    f, q, n_state = motion_matrices("constant_velocity", dt, acceleration_noise=sigma_a)
    p0 = np.diag([400.0, 400.0, 25.0, 25.0])
    got = posterior_crlb(fims, f, q, p0, n_state)
    np.testing.assert_allclose(got, kf_position_mse(fims, f, q, p0), rtol=1e-9)
    h = np.hstack([I2, Z2])
    p_pred = scipy.linalg.solve_discrete_are(f.T, h.T, q, np.linalg.inv(jz))
    p_filt = np.linalg.inv(np.linalg.inv(p_pred) + h.T @ jz @ h)
    steady = np.trace(p_filt[:2, :2])
    assert got[-1] == pytest.approx(steady, rel=1e-8)
    assert np.ptp(got[-200:]) <= 1e-9 * steady
    assert got[-1] > 0.0


@pytest.mark.parametrize("every", [2, 5, 7])
def test_pcrb_measure_every_adds_information_only_on_those_steps(every):
    rng = np.random.default_rng(every)
    k = 60
    fims = random_fims(rng, k + 1, scale=20.0)
    # Static: nothing changes between measurements; information adds on multiples of every.
    f, q, n_state = motion_matrices("static", 0.1)
    p0 = np.diag([100.0, 100.0, 1.0, 1.0])
    got = posterior_crlb(fims, f, q, p0, n_state, measure_every=every)
    steps = np.arange(k + 1)
    used = np.where((steps % every == 0)[:, None, None], fims, 0.0)
    info = np.linalg.inv(p0[:2, :2]) + np.cumsum(used, axis=0)
    np.testing.assert_allclose(got, np.trace(np.linalg.inv(info), axis1=1, axis2=2), rtol=1e-12)
    for kk in steps[1:]:
        if kk % every:
            assert got[kk] == pytest.approx(got[kk - 1], rel=1e-13)
        else:
            assert got[kk] < got[kk - 1]
    # Moving: prediction only between measurements (the KF with sparse updates).
    f, q, n_state = motion_matrices("constant_velocity", 0.1, acceleration_noise=0.3)
    got = posterior_crlb(fims, f, q, p0, n_state, measure_every=every)
    np.testing.assert_allclose(got, kf_position_mse(fims, f, q, p0, every), rtol=1e-9)
    # Fewer measurements, less information: the bound is higher (the Riccati map is monotone).
    dense = posterior_crlb(fims, f, q, p0, n_state)
    assert np.all(got >= dense * (1 - 1e-12))


def test_pcrb_does_not_modify_its_inputs():
    rng = np.random.default_rng(3)
    fims = random_fims(rng, 10)
    f, q, _ = motion_matrices("constant_velocity", 0.1, acceleration_noise=0.1)
    p0 = np.diag([4.0, 4.0, 1.0, 1.0])
    copies = [a.copy() for a in (fims, f, q, p0)]
    posterior_crlb(fims, f, q, p0, 4, measure_every=3)
    for a, b in zip((fims, f, q, p0), copies, strict=True):
        np.testing.assert_array_equal(a, b)


# =============================================================================================
# summed_range_information
# =============================================================================================
@pytest.mark.parametrize("seed", SEEDS)
def test_summed_range_information_is_the_sum_of_the_reference_fims(seed, ref):
    rng = np.random.default_rng(seed)
    b, k1, m, altitude = 3, 4, 5, 20.0
    targets = rng.uniform(-50.0, 50.0, (b, k1, 2))
    uavs = targets[:, :, None, :] + rng.uniform(-40.0, 40.0, (b, k1, m, 2))
    got = summed_range_information(uavs, targets, altitude, Radar())
    assert got.shape == (k1, 2, 2)
    prm = ref.radar_params()
    expected = np.array(
        [
            sum(ref.fim_slepian_bangs(uavs[i, k], targets[i, k], altitude, prm) for i in range(b))
            for k in range(k1)
        ]
    )
    np.testing.assert_allclose(got, expected, rtol=1e-9)


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: motion_matrices("constant_velocity", -1.0), "dt"),
        (lambda: motion_matrices("constant_velocity", float("nan")), "dt"),
        (lambda: motion_matrices("constant_velocity", 0.1, acceleration_noise=-1.0),
         "acceleration_noise"),
        (lambda: posterior_crlb(np.zeros((3, 2, 2)), np.eye(4), np.zeros((4, 4)), np.eye(4), 3),
         "n_state"),
        (lambda: posterior_crlb(np.zeros((3, 2, 2)), np.eye(4), np.zeros((4, 4)), np.eye(4), 2,
                                measure_every=0), "measure_every"),
        (lambda: posterior_crlb(np.zeros((3, 2)), np.eye(4), np.zeros((4, 4)), np.eye(4), 2),
         "mean_fim"),
        (lambda: posterior_crlb(np.zeros((3, 2, 2)), np.eye(4), np.zeros((4, 4)),
                                np.zeros((4, 4)), 2), "p0"),
        (lambda: target_trajectories(np.zeros(2), np.zeros(2), "constant_velocity", 0.1, -1,
                                     [np.random.default_rng(0)]), "n_steps"),
        (lambda: target_trajectories(np.zeros(2), np.zeros(2), "static", 0.1, 5,
                                     [np.random.default_rng(0)], acceleration_noise=1.0),
         "acceleration_noise"),
        (lambda: target_trajectories(np.zeros(2), np.zeros(2), "constant_velocity", 0.1, 5,
                                     [None], acceleration_noise=1.0), "rngs"),
    ],
)  # fmt: skip
def test_bad_arguments_name_themselves(call, name):
    with pytest.raises(ValueError, match=rf"^{name}"):
        call()
