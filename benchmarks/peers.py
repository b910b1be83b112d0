"""The peers a user would otherwise pick, timed on the same problems as crlbswarm.

Each function returns ``(crlbswarm seconds per item, peer seconds per item, agreement)``
or raises :class:`NotInstalled`. The problems (M = 6 UAVs on F* around the target at
H = 20 m, paper radar):

* CRLB of a formation (eq. (10)): ewgeo's ``compute_crlb_gaussian`` (not installable here:
  ewgeo requires Python >= 3.12);
* range-only ML localisation: ``crlbswarm.estimate_target`` on a batch of trials against
  ``scipy.optimize.least_squares`` (the weighted residuals ``(d_hat - d(s)) / sigma(d_hat)``,
  analytic Jacobian) and ``scipy.optimize.minimize(method="BFGS")`` on the exact negative
  log-likelihood with its gradient, one trial per call;
* one range-only EKF update (2-state static target, one linearisation, the noise of each
  range ``d^4 / A`` at the prior): crlbswarm's compiled update against filterpy's
  ``ExtendedKalmanFilter.update`` and Stone Soup's ``ExtendedKalmanUpdater.update`` with a
  range-only measurement model (analytic Jacobian).
"""

from __future__ import annotations

import numpy as np

import crlbswarm as cs
from timing import best_of

TARGET = np.array([80.0, 90.0])
H = 20.0


class NotInstalled(Exception):
    """The peer package is not importable."""


def _per_item(fn, items: int, repeat: int) -> float:
    """Best time of ``fn`` (:func:`timing.best_of`) per item it handles."""
    return best_of(fn, repeat) / items


def _formation():
    return cs.optimal_formation(6, TARGET, H)


def crlb_vs_ewgeo(repeat: int = 3):
    try:
        import ewgeo  # noqa: F401
    except ImportError:
        raise NotInstalled("not installed (ewgeo requires Python >= 3.12)") from None
    raise NotInstalled("ewgeo imported, but its range-only CRLB call is not wired up here")


# ---------------------------------------------------------------------------------------
# Range-only ML localisation
# ---------------------------------------------------------------------------------------
def _trials(n: int, seed: int = 0):
    q = np.broadcast_to(_formation(), (n, 6, 2))
    ranges = cs.measure_ranges(q, TARGET, H, rng=np.random.default_rng(seed))
    return q, ranges


def _start(q, ranges):
    """A common start for the scipy solvers: crlbswarm's closed-form linearised estimate
    (the same start ``estimate_target`` uses), so only the iterations are compared."""
    return cs.linearised_estimate(q, ranges, H)


def mle_vs_scipy(n_batch: int = 20_000, n_scipy: int = 300, repeat: int = 3):
    """Seconds per trial: crlbswarm's batch, scipy least_squares, scipy BFGS; the largest
    distance between the scipy and crlbswarm estimates (m)."""
    from scipy.optimize import least_squares, minimize

    a = float(cs.Radar().snr_constant)
    h2 = H * H
    qb, rb = _trials(n_batch)
    t_cs = _per_item(lambda: cs.estimate_target(qb, rb, H), n_batch, repeat)
    q, ranges = qb[:n_scipy], rb[:n_scipy]
    starts = _start(q, ranges)
    ref = cs.estimate_target(q, ranges, H)
    ref_xy = np.asarray(getattr(ref, "position", getattr(ref, "estimate", ref)))

    def ls_one(qm, dh, s0):
        w = np.sqrt(a) / dh**2  # 1/sigma at the measured range (weighted least squares)

        def res(s):
            u = s - qm
            return w * (dh - np.sqrt((u * u).sum(-1) + h2))

        def jac(s):
            u = s - qm
            d = np.sqrt((u * u).sum(-1) + h2)
            return -(w / d)[:, None] * u

        return least_squares(res, s0, jac=jac, method="lm").x

    def nll_one(qm, dh, s0):
        def f(s):
            u = s - qm
            d2 = (u * u).sum(-1) + h2
            d = np.sqrt(d2)
            inv_var = a / (d2 * d2)
            e = dh - d
            val = 0.5 * (inv_var * e * e).sum() + np.log(d2).sum()  # log sigma^2 = 2 log d2
            # d/ds: derivative through d in the residual and in sigma(d)
            dval_dd = -inv_var * e - 2.0 * inv_var * e * e / d + 2.0 / d
            grad = ((dval_dd / d)[:, None] * u).sum(0)
            return val, grad

        return minimize(f, s0, jac=True, method="BFGS", options={"gtol": 1e-10}).x

    def run(solver):
        return np.array([solver(q[i], ranges[i], starts[i]) for i in range(n_scipy)])

    t_ls = _per_item(lambda: run(ls_one), n_scipy, 1)
    t_bfgs = _per_item(lambda: run(nll_one), n_scipy, 1)
    est_ls, est_bfgs = run(ls_one), run(nll_one)
    return {
        "crlbswarm": t_cs,
        "least_squares": t_ls,
        "bfgs": t_bfgs,
        "diff_ls": float(np.abs(est_ls - ref_xy).max()),
        "diff_bfgs": float(np.abs(est_bfgs - ref_xy).max()),
    }


# ---------------------------------------------------------------------------------------
# One range-only EKF update
# ---------------------------------------------------------------------------------------
def _ekf_problem(seed: int = 1):
    rng = np.random.default_rng(seed)
    q = np.ascontiguousarray(_formation())
    z = cs.measure_ranges(q, TARGET, H, rng=rng)
    x0 = TARGET + np.array([3.0, -2.0])
    p0 = np.diag([25.0, 25.0])
    a = float(cs.Radar().snr_constant)
    u = x0 - q
    d_prior = np.sqrt((u * u).sum(-1) + H * H)
    r = np.diag(d_prior**4 / a)  # the noise of each range at the prior
    return q, z, x0, p0, a, r


def _crlbswarm_update():
    """crlbswarm's compiled filter update (one linearisation), or None if its signature
    changed (others are reworking the filter)."""
    try:
        from crlbswarm.tracking import update
    except ImportError:
        return None
    q, z, x0, p0, a, _ = _ekf_problem()
    try:
        update(x0.copy(), p0.copy(), q, z, H, a, 1)
    except TypeError:
        return None
    return update


def ekf_vs_peers(n_calls: int = 2000, repeat: int = 3) -> dict:
    """Seconds per update: crlbswarm, filterpy, Stone Soup (None where missing), and each
    peer's largest difference in the updated state from crlbswarm's (m)."""
    q, z, x0, p0, a, r = _ekf_problem()
    out: dict = {}
    upd = _crlbswarm_update()
    x_ref = None
    if upd is not None:
        out["crlbswarm"] = _per_item(
            lambda: [upd(x0, p0, q, z, H, a, 1) for _ in range(n_calls)], n_calls, repeat
        )
        x_ref = upd(x0, p0, q, z, H, a, 1)[0]

    def hx(x):
        u = x[:2].ravel() - q
        return np.sqrt((u * u).sum(-1) + H * H)

    def jac(x):
        u = x[:2].ravel() - q
        d = np.sqrt((u * u).sum(-1) + H * H)
        return u / d[:, None]

    try:
        from filterpy.kalman import ExtendedKalmanFilter
    except ImportError:
        out["filterpy"] = None
    else:

        def fp():
            f = ExtendedKalmanFilter(dim_x=2, dim_z=6)
            f.x = x0.reshape(2, 1).copy()
            f.P = p0.copy()
            f.update(z.reshape(6, 1), jac, lambda x: hx(x).reshape(6, 1), R=r)
            return f.x.ravel()

        out["filterpy"] = _per_item(lambda: [fp() for _ in range(n_calls)], n_calls, repeat)
        out["filterpy_diff"] = None if x_ref is None else float(np.abs(fp() - x_ref).max())

    try:
        from stonesoup.models.measurement.nonlinear import NonLinearGaussianMeasurement
        from stonesoup.types.array import StateVector
        from stonesoup.types.detection import Detection
        from stonesoup.types.hypothesis import SingleHypothesis
        from stonesoup.types.prediction import GaussianStatePrediction
        from stonesoup.updater.kalman import ExtendedKalmanUpdater
    except ImportError:
        out["stonesoup"] = None
        return out

    class RangeOnly(NonLinearGaussianMeasurement):
        """Ranges from M UAVs at altitude H to a ground target (state x, y)."""

        @property
        def ndim_meas(self) -> int:
            return q.shape[0]

        def function(self, state, noise=False, **kwargs):
            return StateVector(hx(np.asarray(state.state_vector, dtype=float)))

        def jacobian(self, state, **kwargs):
            return jac(np.asarray(state.state_vector, dtype=float))

    model = RangeOnly(ndim_state=2, mapping=(0, 1), noise_covar=r)
    updater = ExtendedKalmanUpdater(measurement_model=model)
    det = Detection(StateVector(z), measurement_model=model)

    def ss():
        pred = GaussianStatePrediction(StateVector(x0), p0)
        post = updater.update(SingleHypothesis(pred, det))
        return np.asarray(post.state_vector, dtype=float).ravel()

    n_ss = max(1, n_calls // 10)
    out["stonesoup"] = _per_item(lambda: [ss() for _ in range(n_ss)], n_ss, repeat)
    out["stonesoup_diff"] = None if x_ref is None else float(np.abs(ss() - x_ref).max())
    return out


def crlb_batch_time(n: int = 100_000, repeat: int = 3) -> float:
    """crlbswarm's CRLB, seconds per formation in a batch of ``n`` (M = 6)."""
    rng = np.random.default_rng(0)
    q = TARGET + rng.uniform(-30.0, 30.0, size=(n, 6, 2))
    return _per_item(lambda: cs.crlb(q, TARGET, H), n, repeat)
