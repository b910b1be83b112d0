"""Speed of the filter, the posterior CRLB and the MLE's fixed cost per call (issue 12).

Run: ``python benchmarks/bench_filter.py [--trials 20000] [--repeat 5]``. Prints Markdown
tables for docs/performance.md:

* one filter step (``predict`` + the 3-iteration ``update`` with 6 ranges, 4-state
  constant-velocity target) in a compiled loop: as the mission kernel calls it
  (``predict_into`` / ``update_into`` with a work array allocated once), through the public
  allocating ``predict``/``update``, and through the previous implementation (kept below,
  compiled the same way, for the comparison); then one step called from Python (the
  dispatch of a compiled function dominates);
* ``posterior_crlb`` over 1501 steps;
* ``estimate_target`` per trial for batches of 1, 10, 100, 1000 and ``--trials`` trials (F*,
  M = 6, H = 20 m, paper radar), every batch size estimating the same trials, and the ratio of
  each to the largest batch.

Times are per call, best of ``--repeat`` loops of many calls, after a warm-up (compilation).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np
from numba import njit

import crlbswarm as cs
from crlbswarm import tracking
from crlbswarm.mission_kernel import FILTER_ITERATIONS


# -- the previous filter (allocating), kept for the comparison ----------------------------
@njit(cache=True)
def old_predict(x, P, F, Q):
    n = x.shape[0]
    x_new = np.zeros(n)
    for r in range(n):
        for c in range(n):
            x_new[r] += F[r, c] * x[c]
    fp = np.zeros((n, n))
    for r in range(n):
        for c in range(n):
            for j in range(n):
                fp[r, c] += F[r, j] * P[j, c]
    p_new = np.empty((n, n))
    for r in range(n):
        for c in range(n):
            acc = Q[r, c]
            for j in range(n):
                acc += fp[r, j] * F[c, j]
            p_new[r, c] = acc
    return x_new, p_new


@njit(cache=True)
def old_update(x, P, uav_xy, ranges, altitude, snr_constant, n_iter):
    n = x.shape[0]
    info0 = _old_inverse(P, n)
    xi = x.copy()
    info = np.zeros((n, n))
    h2 = altitude * altitude
    for _ in range(n_iter):
        info[:, :] = info0
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
            hx = dx / d
            hy = dy / d
            res = ranges[m] - d
            info[0, 0] += w * hx * hx
            info[0, 1] += w * hx * hy
            info[1, 0] += w * hx * hy
            info[1, 1] += w * hy * hy
            rhs[0] += w * hx * res
            rhs[1] += w * hy * res
        step = _old_solve(info, rhs, n)
        for r in range(n):
            xi[r] += step[r]
    return xi, _old_inverse(info, n)


@njit(cache=True)
def _old_solve(a, b, n):
    m = a[:n, :n].copy()
    x = b[:n].copy()
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if piv != c:
            for j in range(n):
                m[c, j], m[piv, j] = m[piv, j], m[c, j]
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


@njit(cache=True)
def _old_inverse(a, n):
    out = np.zeros((n, n))
    e = np.zeros(n)
    for j in range(n):
        e[:] = 0.0
        e[j] = 1.0
        col = _old_solve(a, e, n)
        for i in range(n):
            out[i, j] = col[i]
    return out


# -- loops of filter steps, compiled, so that the call overhead of Python is not timed -------
@njit(cache=True)
def loop_old(x, p, f, q, uav, ranges, h, a, steps):
    for _ in range(steps):
        x, p = old_update(x, p, uav, ranges, h, a, FILTER_ITERATIONS)
        x, p = old_predict(x, p, f, q)
    return x


@njit(cache=True)
def loop_public(x, p, f, q, uav, ranges, h, a, steps):
    for _ in range(steps):
        x, p = tracking.update(x, p, uav, ranges, h, a, FILTER_ITERATIONS)
        x, p = tracking.predict(x, p, f, q)
    return x


@njit(cache=True)
def loop_into(x, p, f, q, uav, ranges, h, a, steps):
    work = tracking.filter_work()
    x = x.copy()
    p = p.copy()
    for _ in range(steps):
        tracking.update_into(x, p, uav, ranges, h, a, FILTER_ITERATIONS, work)
        tracking.predict_into(x, p, f, q, work)
    return x


def per_call(fn, calls: int, repeat: int) -> float:
    """Best time per call of ``repeat`` loops of ``calls`` calls of ``fn`` (after a warm-up)."""
    fn()
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20_000, help="largest MLE batch")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, NumPy {np.__version__}"
    )
    print()

    # -- filter step ------------------------------------------------------------------------
    radar = cs.Radar()
    h, a = 20.0, radar.snr_constant
    target = np.array([80.0, 90.0])
    uav = np.ascontiguousarray(cs.optimal_formation(6, target, h))
    ranges = cs.measure_ranges(uav, target, h, rng=np.random.default_rng(1))
    f, q, _ = tracking.motion_matrices("constant_velocity", 0.1, acceleration_noise=0.3)
    x0 = np.array([78.0, 93.0, 0.5, -0.2])
    p0 = np.diag([25.0, 25.0, 4.0, 4.0])
    steps = 20_000
    print(
        "| filter step (predict + 3-iteration update, 6 ranges, 4 states) | time per step (µs) |"
    )
    print("|---|---:|")
    for label, loop in (
        ("previous implementation (allocating)", loop_old),
        ("public `predict`/`update` (new arrays per call)", loop_public),
        ("`predict_into`/`update_into`, as the mission kernel calls them", loop_into),
    ):
        t = per_call(lambda lp=loop: lp(x0, p0, f, q, uav, ranges, h, a, steps), 1, args.repeat)
        print(f"| {label} | {t / steps * 1e6:.3f} |")
    for label, upd, pred in (
        ("previous implementation, one call of each from Python", old_update, old_predict),
        ("public `predict`/`update`, one call of each from Python", tracking.update,
         tracking.predict),
    ):  # fmt: skip

        def step(upd=upd, pred=pred):
            xu, pu = upd(x0, p0, uav, ranges, h, a, FILTER_ITERATIONS)
            pred(xu, pu, f, q)

        t = per_call(step, 2000, args.repeat)
        print(f"| {label} | {t * 1e6:.3f} |")
    np.testing.assert_array_equal(  # the same arithmetic: bit-identical
        loop_old(x0, p0, f, q, uav, ranges, h, a, 50),
        loop_into(x0, p0, f, q, uav, ranges, h, a, 50),
    )
    print()

    # -- posterior CRLB ---------------------------------------------------------------------
    k1 = 1501
    fims = np.broadcast_to(cs.fisher_information(uav, target, h, radar), (k1, 2, 2))
    t = per_call(lambda: tracking.posterior_crlb(fims, f, q, p0, 4), 20, args.repeat)
    print("| computation | time per call (ms) |")
    print("|---|---:|")
    print(f"| `posterior_crlb`, {k1} steps, 4 states | {t * 1e3:.3f} |")
    print()

    # -- MLE per trial by batch size --------------------------------------------------------
    n = args.trials
    formation = cs.optimal_formation(6, target, h)
    batch = np.broadcast_to(formation, (n, 6, 2))
    all_ranges = cs.measure_ranges(batch, target, h, rng=np.random.default_rng(0))
    print("| `estimate_target` batch size | trials timed | time per trial (µs) | ratio to the "
          "largest batch |")  # fmt: skip
    print("|---:|---:|---:|---:|")
    rows = []
    for size in (1, 10, 100, 1000, n):
        timed = min(n, max(size, 2000))  # enough trials to average iteration counts
        calls = timed // size
        chunks = [(batch[i * size : (i + 1) * size], all_ranges[i * size : (i + 1) * size])
                  for i in range(calls)]  # fmt: skip

        def run(chunks=chunks):
            for qb, rb in chunks:
                cs.estimate_target(qb, rb, h)

        t = per_call(run, 1, args.repeat if size < n else max(2, args.repeat // 2))
        rows.append((size, calls * size, t / (calls * size)))
    large = rows[-1][2]
    for size, timed, per in rows:
        print(f"| {size} | {timed} | {per * 1e6:.2f} | {per / large:.2f} |")


if __name__ == "__main__":
    main()
