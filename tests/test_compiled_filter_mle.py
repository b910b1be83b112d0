"""The compiled filter, posterior CRLB and MLE loops (issue 12) against independent references.

* ``update``/``predict`` and their in-place forms against the previous allocating
  implementation, transcribed below and run as plain Python (the same arithmetic in the
  same order: bit-identical);
* ``posterior_crlb`` against the previous NumPy loop (``numpy.linalg.inv`` on every step),
  transcribed below: equal to rounding;
* the MLE: a trial's estimate does not depend on its batch (bit-identical alone and inside
  any batch), and the compiled damped Newton follows the rules of the NumPy loop that
  ``damped_newton`` runs for any other ``terms`` callable.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import crlbswarm as cs
from crlbswarm import estimation
from crlbswarm.three_d import estimate_target_3d, measure_ranges_3d
from crlbswarm.tracking import (
    filter_work,
    motion_matrices,
    posterior_crlb,
    predict,
    predict_into,
    update,
    update_into,
)


# -- references: the previous implementations, as plain Python --------------------------------
def ref_predict(x, p, f, q):
    n = x.shape[0]
    x_new = np.zeros(n)
    for r in range(n):
        for c in range(n):
            x_new[r] += f[r, c] * x[c]
    fp = np.zeros((n, n))
    for r in range(n):
        for c in range(n):
            for j in range(n):
                fp[r, c] += f[r, j] * p[j, c]
    p_new = np.empty((n, n))
    for r in range(n):
        for c in range(n):
            acc = q[r, c]
            for j in range(n):
                acc += fp[r, j] * f[c, j]
            p_new[r, c] = acc
    return x_new, p_new


def ref_solve(a, b, n):
    m = a[:n, :n].copy()
    x = b[:n].copy()
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if piv != c:
            m[[c, piv]] = m[[piv, c]]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, n):
            f = m[r, c] / m[c, c]
            for j in range(c, n):
                m[r, j] -= f * m[c, j]
            x[r] -= f * x[c]
    for c in range(n - 1, -1, -1):
        acc = x[c]
        for j in range(c + 1, n):
            acc -= m[c, j] * x[j]
        x[c] = acc / m[c, c]
    return x


def ref_inverse(a, n):
    out = np.zeros((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        out[:, j] = ref_solve(a, e, n)
    return out


def ref_update(x, p, uav_xy, ranges, altitude, snr_constant, n_iter):
    n = x.shape[0]
    info0 = ref_inverse(p, n)
    xi = x.copy()
    h2 = altitude * altitude
    for _ in range(n_iter):
        info = info0.copy()
        rhs = np.zeros(n)
        for r in range(n):
            for c in range(n):
                rhs[r] -= info0[r, c] * (xi[c] - x[c])
        for m in range(uav_xy.shape[0]):
            dx = xi[0] - uav_xy[m, 0]
            dy = xi[1] - uav_xy[m, 1]
            d2 = dx * dx + dy * dy + h2
            d = math.sqrt(d2)
            w = snr_constant / (d2 * d2)
            hx, hy = dx / d, dy / d
            res = ranges[m] - d
            info[0, 0] += w * hx * hx
            info[0, 1] += w * hx * hy
            info[1, 0] += w * hx * hy
            info[1, 1] += w * hy * hy
            rhs[0] += w * hx * res
            rhs[1] += w * hy * res
        xi = xi + ref_solve(info, rhs, n)
    return xi, ref_inverse(info, n)


def ref_pcrb(fim, f, q, p0, n, every):
    """The previous posterior_crlb loop (numpy.linalg.inv at every step)."""
    fk, qk = f[:n, :n], q[:n, :n]
    out = np.empty(fim.shape[0])
    info = np.linalg.inv(p0[:n, :n])
    for k in range(fim.shape[0]):
        if k > 0:
            info = np.linalg.inv(qk + fk @ np.linalg.inv(info) @ fk.T)
        if k % every == 0:
            info = info.copy()
            info[:2, :2] += fim[k]
        out[k] = np.trace(np.linalg.inv(info)[:2, :2])
    return out


# -- the filter -----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("n_state", [2, 4])
def test_filter_step_is_bit_identical_to_the_previous_implementation(seed, n_state):
    rng = np.random.default_rng(seed)
    radar = cs.Radar()
    target = rng.uniform(-50.0, 50.0, 2)
    uav = target + rng.uniform(-60.0, 60.0, (6, 2))
    f, q, _ = motion_matrices("constant_velocity", 0.1, acceleration_noise=0.5)
    f, q = np.ascontiguousarray(f[:n_state, :n_state]), np.ascontiguousarray(q[:n_state, :n_state])
    x = np.concatenate([target + rng.normal(0.0, 3.0, 2), rng.normal(0.0, 1.0, 2)])[:n_state]
    a = rng.standard_normal((n_state, n_state))
    p = a @ a.T + np.eye(n_state)
    x_ref, p_ref = x.copy(), p.copy()
    x_in, p_in = x.copy(), p.copy()
    work = filter_work()
    for _ in range(20):
        target = target + rng.normal(0.0, 0.5, 2)
        ranges = cs.measure_ranges(uav, target, 20.0, radar, rng=rng)
        args = (uav, ranges, 20.0, radar.snr_constant, 3)
        x_ref, p_ref = ref_update(x_ref, p_ref, *args)
        x_pub, p_pub = update(x, p, *args)
        update_into(x_in, p_in, *args, work)
        for got in ((x_pub, p_pub), (x_in, p_in)):
            np.testing.assert_array_equal(got[0], x_ref)
            np.testing.assert_array_equal(got[1], p_ref)
        x_ref, p_ref = ref_predict(x_ref, p_ref, f, q)
        x, p = predict(x_pub, p_pub, f, q)
        predict_into(x_in, p_in, f, q, work)
        for got in ((x, p), (x_in, p_in)):
            np.testing.assert_array_equal(got[0], x_ref)
            np.testing.assert_array_equal(got[1], p_ref)


def test_public_filter_functions_leave_their_inputs_alone():
    x, p = np.array([1.0, 2.0, 0.1, 0.2]), np.diag([4.0, 5.0, 1.0, 1.0])
    f, q, _ = motion_matrices("constant_velocity", 0.1, acceleration_noise=0.5)
    uav = cs.optimal_formation(6, (0.0, 0.0), 20.0)
    ranges = cs.slant_ranges(uav, (0.0, 0.0), 20.0)
    copies = x.copy(), p.copy()
    predict(x, p, f, q)
    update(x, p, uav, ranges, 20.0, cs.Radar().snr_constant, 3)
    np.testing.assert_array_equal(x, copies[0])
    np.testing.assert_array_equal(p, copies[1])


# -- posterior CRLB ---------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("model", ["static", "constant_velocity", "turning"])
@pytest.mark.parametrize("every", [1, 3])
def test_compiled_pcrb_equals_the_numpy_loop(seed, model, every):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-30.0, 30.0, (400, 2, 2))
    fims = a @ a.transpose(0, 2, 1)
    f, q, n = motion_matrices(model, 0.1, 0.05, 0.0 if model == "static" else 0.4)
    p0 = np.diag([400.0, 300.0, 25.0, 16.0])
    got = posterior_crlb(fims, f, q, p0, n, every)
    np.testing.assert_allclose(got, ref_pcrb(fims, f, q, p0, n, every), rtol=1e-11)


def test_compiled_pcrb_reports_a_singular_prediction():
    # F = 0 and Q = 0: the predicted information Q + F J^-1 F^T is the zero matrix.
    with pytest.raises(ValueError, match=r"^q"):
        posterior_crlb(np.ones((3, 2, 2)), np.zeros((4, 4)), np.zeros((4, 4)), np.eye(4), 4)


# -- MLE: batch invariance and the rules of the NumPy loop -------------------------------------
def _trials(n, seed=0, altitude=20.0):
    rng = np.random.default_rng(seed)
    target = np.array([80.0, 90.0])
    # a mix of formations (F*, random discs) and SNRs, so that some trials fail
    forms = np.concatenate(
        [
            np.broadcast_to(cs.optimal_formation(6, target, altitude), (n // 2, 6, 2)),
            target + rng.uniform(-40.0, 40.0, (n - n // 2, 6, 2)),
        ]
    )
    radar = cs.Radar(tx_power=rng.choice([0.1, 1e-5]))
    return forms, cs.measure_ranges(forms, target, altitude, radar, rng=rng), radar


def _fields(est, index=...):
    return [np.asarray(getattr(est, k))[index] for k in ("position", "converged", "iterations",
                                                          "nll")]  # fmt: skip


def test_estimate_target_does_not_depend_on_the_batch():
    forms, ranges, radar = _trials(60)
    whole = _fields(cs.estimate_target(forms, ranges, 20.0, radar))
    for i in (0, 1, 29, 30, 59):
        alone = _fields(cs.estimate_target(forms[i], ranges[i], 20.0, radar))
        for a, b in zip(alone, whole, strict=True):
            np.testing.assert_array_equal(a, b[i])
    for lo, hi in ((0, 7), (7, 30), (25, 60)):
        part = _fields(cs.estimate_target(forms[lo:hi], ranges[lo:hi], 20.0, radar))
        for a, b in zip(part, whole, strict=True):
            np.testing.assert_array_equal(a, b[lo:hi])
    # a batch of shape (3, 20) is the same trials
    grid = _fields(cs.estimate_target(forms.reshape(3, 20, 6, 2), ranges.reshape(3, 20, 6),
                                      20.0, radar))  # fmt: skip
    for a, b in zip(grid, whole, strict=True):
        np.testing.assert_array_equal(a.reshape(b.shape), b)


def test_estimate_target_3d_does_not_depend_on_the_batch():
    rng = np.random.default_rng(4)
    q = np.column_stack([cs.optimal_formation(6, (0.0, 0.0), 20.0), 20.0 + rng.uniform(0, 5, 6)])
    batch = np.broadcast_to(q, (40, 6, 3))
    ranges = measure_ranges_3d(batch, np.array([3.0, -2.0, 0.0]), rng=rng)
    whole = _fields(estimate_target_3d(batch, ranges))
    for i in (0, 17, 39):
        alone = _fields(estimate_target_3d(q, ranges[i]))
        for a, b in zip(alone, whole, strict=True):
            np.testing.assert_array_equal(a, b[i])


@pytest.mark.parametrize("exact", [False, True])
def test_compiled_damped_newton_follows_the_numpy_loop(exact):
    """damped_newton runs the compiled loop for wls_terms/nll_terms and the NumPy loop for
    any other callable: the same rules, so the same minima (to rounding) and flags."""
    forms, ranges, radar = _trials(200, seed=3)
    a = radar.snr_constant
    h2 = np.full((200, 1), 400.0)
    w = a / np.maximum(np.abs(ranges), 20.0) ** 4
    s0 = estimation.linearised_estimate(forms, ranges, 20.0)
    terms = estimation.nll_terms if exact else estimation.wls_terms
    q = np.ascontiguousarray(forms)
    got = estimation.damped_newton(terms, s0.copy(), q, ranges, h2, a, w, 100, 1e-10)
    ref = estimation.damped_newton(lambda *args: terms(*args), s0.copy(), q, ranges, h2, a, w,
                                   100, 1e-10)  # fmt: skip
    same = got[2] & ref[2]  # converged in both (a few low-SNR trials may not)
    assert same.mean() > 0.9
    np.testing.assert_allclose(got[0][same], ref[0][same], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got[1][same], ref[1][same], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(got[4][same], ref[4][same])
    assert np.mean(got[2] == ref[2]) > 0.98
