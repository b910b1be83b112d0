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
  M = 6, H = 20 m, paper radar; the formation broadcast over the trials, as
  ``monte_carlo_mse`` passes it), the batches up to 1000 estimating the same 2000 trials,
  and the ratio of each to a batch of 1000 and to the largest batch (the acceptance
  criterion: small batches within 1.3x of large ones per trial).

Times are per call, best of ``--repeat`` loops of many calls, after a warm-up (compilation);
the MLE's are CPU times of the calling thread (the compiled loops run in it), the small
batches timed in short pieces (:func:`mle_per_trial`).
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


#: The small batches are timed in pieces of this many trials (the best CPU time of this
#: thread over ``--repeat`` rounds for each piece, the rounds going over every size in turn,
#: so that a slow spell of a loaded machine spoils one timing of each size rather than all
#: of one), ...
PIECE_TRIALS = 200
#: ... this many pieces, every size estimating the same trials.
PIECES = 10


def thread_best_of(fn, repeat: int) -> float:
    """Best CPU time of this thread over ``repeat`` calls of ``fn``, after a warm-up call
    (:func:`timing.best_of` in CPU time: a call of many milliseconds on a loaded machine is
    preempted, and the wall clock counts the other processes' share)."""
    fn()
    best = math.inf
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def mle_per_trial(batch, ranges, h, sizes, trials, repeat) -> dict[int, float]:
    """Best time per trial of ``estimate_target`` called on batches of each of ``sizes``
    over the first ``trials`` trials, in pieces of :data:`PIECE_TRIALS` trials (after a
    warm-up round)."""
    pieces = {
        size: [[(batch[i : i + size], ranges[i : i + size])
                for i in range(start, start + max(PIECE_TRIALS, size), size)]
               for start in range(0, trials, max(PIECE_TRIALS, size))]
        for size in sizes
    }  # fmt: skip
    best = {size: [math.inf] * len(p) for size, p in pieces.items()}
    for round_ in range(repeat + 1):
        for size, size_pieces in pieces.items():
            for k, calls in enumerate(size_pieces):
                t0 = time.thread_time()
                for qb, rb in calls:
                    cs.estimate_target(qb, rb, h)
                if round_:  # (round 0: the warm-up)
                    best[size][k] = min(best[size][k], time.thread_time() - t0)
    return {size: sum(times) / trials for size, times in best.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--trials", type=int, default=20_000, help="largest MLE batch (at least 2000)"
    )
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
    n = max(args.trials, PIECE_TRIALS * PIECES)
    formation = cs.optimal_formation(6, target, h)
    batch = np.broadcast_to(formation, (n, 6, 2))
    all_ranges = cs.measure_ranges(batch, target, h, rng=np.random.default_rng(0))
    sizes = (1, 10, 100, 1000)
    per = mle_per_trial(batch, all_ranges, h, sizes, PIECE_TRIALS * PIECES, args.repeat)
    per[n] = thread_best_of(lambda: cs.estimate_target(batch, all_ranges, h), args.repeat) / n
    print("| `estimate_target` batch size | trials timed | CPU time per trial (µs) | ratio to a "
          f"batch of 1000 | ratio to a batch of {n} |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|")
    for size, t in per.items():
        timed = n if size == n else PIECE_TRIALS * PIECES
        print(f"| {size} | {timed} | {t * 1e6:.2f} | {t / per[1000]:.2f} | {t / per[n]:.2f} |")


if __name__ == "__main__":
    main()
