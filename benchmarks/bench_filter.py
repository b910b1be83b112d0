"""Speed of the filter, the posterior CRLB and the MLE's fixed cost per call (issue 12).

Run: ``python benchmarks/bench_filter.py [--trials 20000] [--repeat 5]``. Prints Markdown
tables for docs/performance.md:

* one filter step (``predict`` + the 3-iteration ``update`` with 6 ranges, 4-state
  constant-velocity target) in a compiled loop: as the mission kernel calls it
  (``predict_into`` / ``update_into`` with a work array allocated once), through the public
  allocating ``predict``/``update``; then one step called from Python (the dispatch of a
  compiled function dominates). (The previous, allocating filter is kept in
  ``tests/test_compiled_filter_mle.py`` as the reference the in-place one equals bit for
  bit; docs/performance.md gives its times.)
* ``posterior_crlb`` over 1501 steps;
* ``estimate_target`` per trial for batches of 1, 10, 100, 1000 and ``--trials`` trials (F*,
  M = 6, H = 20 m, paper radar), every batch size estimating the same trials, and the ratio of
  each to the largest batch.

Times are per call, best of ``--repeat`` loops of many calls, after a warm-up (compilation).
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np
from numba import njit

import crlbswarm as cs
from crlbswarm import tracking
from crlbswarm.mission_kernel import FILTER_ITERATIONS
from timing import best_of


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
    """Best time per call of ``repeat`` loops of ``calls`` calls of ``fn`` (after a warm-up
    loop; :func:`timing.best_of`)."""
    return best_of(lambda: [fn() for _ in range(calls)], repeat) / calls


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
        ("public `predict`/`update` (new arrays per call)", loop_public),
        ("`predict_into`/`update_into`, as the mission kernel calls them", loop_into),
    ):
        t = per_call(lambda lp=loop: lp(x0, p0, f, q, uav, ranges, h, a, steps), 1, args.repeat)
        print(f"| {label} | {t / steps * 1e6:.3f} |")

    def step():
        xu, pu = tracking.update(x0, p0, uav, ranges, h, a, FILTER_ITERATIONS)
        tracking.predict(xu, pu, f, q)

    t = per_call(step, 2000, args.repeat)
    print(f"| public `predict`/`update`, one call of each from Python | {t * 1e6:.3f} |")
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
