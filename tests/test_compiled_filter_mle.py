"""The compiled filter, posterior CRLB and MLE loops (issue 12) against independent references.

* ``update``/``predict`` and their in-place forms against the previous allocating
  implementation, transcribed below and run as plain Python (the same arithmetic in the
  same order: bit-identical);
* ``posterior_crlb`` against the previous NumPy loop (``numpy.linalg.inv`` on every step),
  transcribed below: equal to rounding;
* the MLE: a trial's estimate does not depend on its batch (bit-identical alone and inside
  any batch), and the compiled damped Newton follows the rules of a NumPy transcription
  (all trials at once) kept below as the reference.
"""

from __future__ import annotations

import math
import re

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


def _plain_cases():
    """Calls of ``estimate_target`` that take its plain path (float64 NumPy arrays, a float
    altitude or one per trial, ...), by name: keyword arguments."""
    forms, ranges, radar = _trials(24, seed=3)
    rng = np.random.default_rng(8)
    f_star = np.ascontiguousarray(forms[0])
    per_uav = cs.Radar(tx_power=rng.uniform(0.05, 0.2, 6))
    read_only = ranges.copy()
    read_only.flags.writeable = False
    return {
        "one trial": dict(uav_xy=forms[3], measured_ranges=ranges[3], altitude=20.0),
        "batch": dict(uav_xy=forms, measured_ranges=ranges, altitude=20.0, radar=radar),
        "broadcast formation": dict(uav_xy=np.broadcast_to(f_star, (12, 6, 2)),
                                    measured_ranges=ranges[:12], altitude=20.0),
        "one formation": dict(uav_xy=f_star, measured_ranges=ranges[:12], altitude=20),
        "altitude per trial": dict(uav_xy=forms, measured_ranges=ranges,
                                   altitude=rng.uniform(15.0, 25.0, 24)),
        "per-UAV radar": dict(uav_xy=forms, measured_ranges=ranges, altitude=20.0,
                              radar=per_uav),
        "init": dict(uav_xy=forms, measured_ranges=ranges, altitude=20.0,
                     init=rng.uniform(60.0, 100.0, (24, 2)), max_iter=7, tol=1e-6),
        "one init": dict(uav_xy=forms, measured_ranges=ranges, altitude=np.float64(20.0),
                         init=np.array([80.0, 90.0])),
        "read-only, strided": dict(uav_xy=forms[:, ::-1], measured_ranges=read_only[:, ::-1],
                                   altitude=20.0),
        "astronomical ranges": dict(uav_xy=f_star, measured_ranges=np.full(6, 1e30),
                                    altitude=20.0),
    }  # fmt: skip


@pytest.mark.parametrize("case", list(_plain_cases()))
def test_estimate_target_plain_path_equals_the_general_path(case, monkeypatch):
    """The plain path (no Python checks, one compiled call) gives the general path's
    results bit for bit: the general path gets the same numbers as lists."""
    args = _plain_cases()[case]
    general = {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in args.items()}
    expected = cs.estimate_target(**general)
    monkeypatch.setattr(estimation, "_estimate", None)  # (the general path would fail)
    got = cs.estimate_target(**args)
    for a, b in zip(_fields(got), _fields(expected), strict=True):
        assert a.shape == b.shape
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("max_iter", [1, 100])
@pytest.mark.parametrize("plain", [True, False])
def test_estimate_target_is_its_two_stages_with_the_documented_weights(plain, max_iter):
    """Both paths of ``estimate_target`` are, bit for bit, the closed-form start, stage 1
    with the weights A / ((p p)(p p)), p = max(|range|, H), and stage 2, each run by
    ``damped_newton`` (the same compiled trial loop); some ranges below the altitude or
    negative take the floor. (Stopped after 1 iteration, the estimates carry the last bits
    of the weights: those of NumPy's power would not pass.)"""
    forms, ranges, radar = _trials(30, seed=5)  # (a low SNR)
    ranges = ranges.copy()
    ranges[0, :2] = (5.0, -3.0)
    ranges[17, 4] = -21.0
    n, h = len(ranges), 20.0
    args = (forms, ranges) if plain else (forms.tolist(), ranges.tolist())
    est = cs.estimate_target(*args, h, radar, max_iter=max_iter)
    a = np.broadcast_to(radar.snr_constant, ranges.shape)
    p = np.maximum(np.abs(ranges), h)
    w = a / ((p * p) * (p * p))
    h2 = np.full((n, 1), h * h)
    q = np.ascontiguousarray(forms)
    s = estimation.linearised_estimate(forms, ranges, h)
    s, _, _, it1, _ = estimation.damped_newton(False, s, q, ranges, h2, a, w, max_iter, 1e-6)
    s, nll, converged, it2, minimum = estimation.damped_newton(
        True, s, q, ranges, h2, a, w, max_iter, 1e-10
    )
    np.testing.assert_array_equal(est.position, s)
    np.testing.assert_array_equal(est.nll, nll)
    np.testing.assert_array_equal(est.converged, converged & minimum)
    np.testing.assert_array_equal(est.iterations, it1 + it2)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"measured_ranges": np.array([24.5, np.nan, 24.5, 24.5, 24.5, 24.5])},
         "measured_ranges: must be finite"),
        ({"measured_ranges": np.array([24.5, 2e30, 24.5, 24.5, 24.5, 24.5])},
         "measured_ranges: must be between -1e+30 and 1e+30 m"),
        ({"uav_xy": np.full((6, 2), 2e7)}, "uav_xy: must be between -1e+07 and 1e+07 m"),
        ({"altitude": 0.05}, "altitude: must be between 0.1 and 100000 m"),
        ({"altitude": np.array(math.inf)}, "altitude: must be finite"),
        ({"init": np.array([np.nan, 0.0])}, "init: must be finite"),
        ({"tol": math.nan}, "tol: must be finite"),
        ({"max_iter": 0}, "max_iter: must be at least 1"),
    ],
)  # fmt: skip
def test_estimate_target_plain_call_with_bad_values_raises_the_general_error(change, message):
    args = {"uav_xy": cs.optimal_formation(6, (0.0, 0.0), 20.0),
            "measured_ranges": np.full(6, 24.5), "altitude": 20.0, **change}  # fmt: skip
    with pytest.raises(cs.FieldError, match="^" + re.escape(message)):
        cs.estimate_target(**args)


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


# -- the NumPy transcription of the damped Newton (the estimators' rules, all trials at
# once): an independent reference for the compiled loop of crlbswarm.estimation --------------
def ref_wls_terms(s, q, d_hat, h2, a, w):
    """Stage 1 of the estimators: weighted least squares on the range residuals with frozen
    weights ``w`` = A / d_hat^4, for k unknown coordinates (k = 2: the target's horizontal
    position, its height known; k = 3: its 3-D position).

    Parameters
    ----------
    s : ndarray, shape (n, k)
        Points, m.
    q : ndarray, shape (n, M, k)
        UAV coordinates, m.
    d_hat : ndarray, shape (n, M)
        Measured ranges, m.
    h2 : ndarray or float
        The known squared offset added to every squared distance, m^2: :math:`H^2`,
        shape (n, 1), for k = 2; 0 for k = 3.
    a : ndarray or float
        :math:`A_m` (unused here).
    w : ndarray, shape (n, M)
        The frozen weights.

    Returns
    -------
    cost, gradient, hessian, trace : ndarray
        Shapes (n,), (n, k), (n, k, k) (Gauss-Newton) and (n,) (its trace).
    """
    diff = s[..., None, :] - q
    d = np.sqrt(np.sum(diff * diff, axis=-1) + h2)
    r = d_hat - d
    u = diff / d[..., None]
    cost = 0.5 * np.sum(w * r * r, axis=-1)
    grad = -np.sum((w * r)[..., None] * u, axis=-2)
    hess = np.einsum("nm,nmi,nmj->nij", w, u, u)
    return cost, grad, hess, np.einsum("nii->n", hess)


def ref_nll_terms(s, q, d_hat, h2, a, w):
    """Stage 2 of the estimators: the exact negative log-likelihood (module docstring), its
    gradient, its exact Hessian, and the trace of the FIM of the k unknowns (eq. (8), to
    scale the damping), for k = 2 or 3 unknown coordinates as :func:`wls_terms`.

    Parameters
    ----------
    s : ndarray, shape (n, k)
        Points, m.
    q : ndarray, shape (n, M, k)
        UAV coordinates, m.
    d_hat : ndarray, shape (n, M)
        Measured ranges, m.
    h2 : ndarray or float
        Known squared offset of every squared distance, m^2 (:math:`H^2` or 0).
    a : ndarray or float
        :math:`A_m`, per UAV (n, M) or one value.
    w : ndarray
        Unused (the frozen weights of stage 1).

    Returns
    -------
    nll, gradient, hessian, fim_trace : ndarray
        Shapes (n,), (n, k), (n, k, k) and (n,).
    """
    diff = s[..., None, :] - q  # s - q_m, so that d d_m / d s = diff / d_m
    d2 = np.sum(diff * diff, axis=-1) + h2
    d = np.sqrt(d2)
    r = d_hat - d
    inv_d4 = 1.0 / (d2 * d2)
    nll = np.sum(np.log(d2) + 0.5 * a * r * r * inv_d4, axis=-1)
    # d nll / d d_m = 2/d - A r / d^4 - 2 A r^2 / d^5
    dl_dd = 2.0 / d - a * r * inv_d4 - 2.0 * a * r * r * inv_d4 / d
    # d^2 nll / d d_m^2 = -2/d^2 + A/d^4 + 8 A r/d^5 + 10 A r^2/d^6
    d2l_dd2 = -2.0 / d2 + a * inv_d4 * (1.0 + 8.0 * r / d + 10.0 * r * r / d2)
    u = diff / d[..., None]
    grad = np.sum(dl_dd[..., None] * u, axis=-2)
    # Hessian: sum_m l''_m u u^T + l'_m (I - u u^T) / d_m   (d^2 d_m / d s^2 = (I - u u^T)/d)
    c = dl_dd / d
    hess = np.einsum("nm,nmi,nmj->nij", d2l_dd2 - c, u, u)
    hess += np.sum(c, axis=-1)[:, None, None] * np.eye(s.shape[-1])
    fim_trace = np.sum((a * inv_d4 + 8.0 / d2) * np.sum(u * u, axis=-1), axis=-1)  # tr J
    return nll, grad, hess, fim_trace


def ref_solve_definite(h: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(h^-1 g, positive definite)`` for a batch of symmetric 2x2 or 3x3 matrices, in
    closed form (cofactors; Sylvester's criterion for definiteness); the solution of a
    singular matrix is 0.

    Parameters
    ----------
    h : ndarray, shape (n, k, k)
        Symmetric matrices, k = 2 or 3.
    g : ndarray, shape (n, k)
        Right-hand sides.

    Returns
    -------
    x : ndarray, shape (n, k)
        The solutions (0 where not finite).
    definite : ndarray of bool, shape (n,)
        Whether each matrix is positive definite.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if h.shape[-1] == 2:
            a00, a11, a01 = h[:, 0, 0], h[:, 1, 1], h[:, 0, 1]
            det = a00 * a11 - a01 * a01
            g0, g1 = g[:, 0], g[:, 1]
            x = np.stack([(a11 * g0 - a01 * g1) / det, (a00 * g1 - a01 * g0) / det], axis=-1)
            definite = (det > 0) & (a00 > 0)
        else:
            a00, a11, a22 = h[:, 0, 0], h[:, 1, 1], h[:, 2, 2]
            a01, a02, a12 = h[:, 0, 1], h[:, 0, 2], h[:, 1, 2]
            c00 = a11 * a22 - a12 * a12
            c01 = a02 * a12 - a01 * a22
            c02 = a01 * a12 - a02 * a11
            c11 = a00 * a22 - a02 * a02
            c12 = a01 * a02 - a00 * a12
            c22 = a00 * a11 - a01 * a01
            det = a00 * c00 + a01 * c01 + a02 * c02
            g0, g1, g2 = g[:, 0], g[:, 1], g[:, 2]
            x = np.stack([c00 * g0 + c01 * g1 + c02 * g2, c01 * g0 + c11 * g1 + c12 * g2,
                          c02 * g0 + c12 * g1 + c22 * g2], axis=-1) / det[:, None]  # fmt: skip
            definite = (a00 > 0) & (c22 > 0) & (det > 0)
    return np.where(np.isfinite(x), x, 0.0), definite


def ref_damped_newton(terms, s, q, d_hat, h2, a, w, n_iter, tolerance):
    """Levenberg-Marquardt-damped Newton minimisation of ``terms`` (:func:`wls_terms` or
    :func:`nll_terms`) for every row of ``s``, with k = 2 or 3 unknowns (the rules of
    :func:`estimate_target`, module docstring).

    Parameters
    ----------
    terms : callable
        ``terms(s, q, d_hat, h2, a, w) -> (cost, gradient, hessian, trace)``.
    s : ndarray, shape (n, k)
        Starting points, m (updated in place and returned).
    q : ndarray, shape (n, M, k)
        UAV coordinates, m.
    d_hat : ndarray, shape (n, M)
        Measured ranges, m.
    h2 : ndarray, shape (n, 1), or float
        Known squared offset of every squared distance, m^2.
    a : ndarray or float
        :math:`A_m` (per trial and UAV, or one value).
    w : ndarray, shape (n, M)
        Frozen weights of stage 1.
    n_iter : int
        Largest number of iterations.
    tolerance : float
        Convergence when the nearly undamped step is below ``tolerance`` times (1 m + the
        distance from the UAVs' centroid).

    Returns
    -------
    s, cost, converged, iterations, positive_definite : ndarray
        ``s`` is updated only by steps that lower the cost, so it stays finite;
        ``positive_definite`` tells whether the curvature at the final ``s`` is positive
        definite (a minimum, not a maximum or saddle).

    Notes
    -----
    With :func:`wls_terms` or :func:`nll_terms` the iteration runs compiled, one trial at a
    time (:func:`_newton_batch`: the same rules, sums over the UAVs in order), so a trial's
    result does not depend on its batch; any other ``terms`` runs the NumPy loop below, all
    trials together.
    """
    n, k = s.shape
    per = np.ndim(a) > 0
    per_h = np.ndim(h2) > 0

    def at(x, idx):
        return terms(x, q[idx], d_hat[idx], h2[idx] if per_h else h2, a[idx] if per else a,
                     w[idx])  # fmt: skip

    centroid = q.mean(axis=1)  # fixed: the convergence scale needs it every iteration
    cost, grad, hess, htr = at(s, np.arange(n))
    mu = np.full(n, 1e-3)
    active = np.ones(n, dtype=bool)
    converged = np.zeros(n, dtype=bool)
    iterations = np.zeros(n, dtype=np.int64)
    for _ in range(n_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        iterations[idx] += 1
        # Damped Newton step: (Hess + mu tr/k I) delta = -grad, in closed form.
        damped = hess[idx] + (mu[idx] * htr[idx] / k)[:, None, None] * np.eye(k)
        step, descent = ref_solve_definite(damped, grad[idx])
        step = -step
        trial = s[idx] + step
        t_cost, t_grad, t_hess, t_tr = at(trial, idx)
        # Accept a step that lowers the cost; a positive definite damped matrix makes the
        # step a descent direction. Where the change of the cost is at the level of its
        # rounding error, a smaller gradient decides instead, so Newton's quadratic
        # convergence is not stopped by rounding near the minimum.
        # (The cost sums dozens of rounded terms: allow a few thousand ulps.)
        rounding = 1e-12 * (np.abs(cost[idx]) + 1.0)
        flat = np.abs(t_cost - cost[idx]) <= rounding
        smaller_grad = np.linalg.norm(t_grad, axis=-1) < np.linalg.norm(grad[idx], axis=-1)
        better = (
            descent
            & np.isfinite(t_cost)
            & ((t_cost < cost[idx] - rounding) | (flat & smaller_grad))
        )
        near_newton = mu[idx] <= 1e-2
        acc = idx[better]
        s[acc] = trial[better]
        cost[acc], grad[acc], htr[acc] = t_cost[better], t_grad[better], t_tr[better]
        hess[acc] = t_hess[better]
        mu[acc] = np.maximum(mu[acc] / 10.0, 1e-12)
        rej = idx[~better]
        mu[rej] = mu[rej] * 10.0
        scale = 1.0 + np.linalg.norm(s[idx] - centroid[idx], axis=-1)
        # Converged when the nearly undamped Newton step is negligible, accepted or not (at
        # that size the change of the cost is below its rounding error). A heavily damped
        # step is short whatever the distance to the minimum, so it never counts.
        done = (np.linalg.norm(step, axis=-1) <= tolerance * scale) & near_newton
        converged[idx[done]] = True
        active[idx[done]] = False
        active[idx[mu[idx] > 1e12]] = False  # hopeless damping: give up, report failed
    _, positive_definite = ref_solve_definite(hess, grad)
    return s, cost, converged, iterations, positive_definite


@pytest.mark.parametrize("exact", [False, True])
def test_compiled_damped_newton_follows_the_numpy_loop(exact):
    """The compiled damped Newton follows the rules of the NumPy transcription above: the
    same minima (to rounding) and flags."""
    forms, ranges, radar = _trials(200, seed=3)
    a = radar.snr_constant
    h2 = np.full((200, 1), 400.0)
    w = a / np.maximum(np.abs(ranges), 20.0) ** 4
    s0 = estimation.linearised_estimate(forms, ranges, 20.0)
    terms = ref_nll_terms if exact else ref_wls_terms
    q = np.ascontiguousarray(forms)
    got = estimation.damped_newton(exact, s0.copy(), q, ranges, h2, a, w, 100, 1e-10)
    ref = ref_damped_newton(terms, s0.copy(), q, ranges, h2, a, w, 100, 1e-10)
    same = got[2] & ref[2]  # converged in both (a few low-SNR trials may not)
    assert same.mean() > 0.9
    np.testing.assert_allclose(got[0][same], ref[0][same], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got[1][same], ref[1][same], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(got[4][same], ref[4][same])
    assert np.mean(got[2] == ref[2]) > 0.98
