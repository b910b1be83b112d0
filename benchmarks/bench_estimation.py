"""Speed of the static MLE: trials per second in one batch (issue 4's target).

Run: ``python benchmarks/bench_estimation.py [--n 100000] [--repeat 3]``. The trials are
independent sets of ranges from F* (M = 6, H = 20 m, paper radar); each is estimated from
the closed-form linearised start by the two-stage MLE of ``crlbswarm.estimate_target``.
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np

import crlbswarm as cs
from timing import best_of


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000, help="trials per batch")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    target = np.array([80.0, 90.0])
    formation = cs.optimal_formation(6, target, 20.0)
    batch = np.broadcast_to(formation, (args.n, 6, 2))
    ranges = cs.measure_ranges(batch, target, 20.0, rng=np.random.default_rng(0))
    t = best_of(lambda: cs.estimate_target(batch, ranges, 20.0), args.repeat)
    est = cs.estimate_target(batch, ranges, 20.0)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, NumPy {np.__version__}"
    )
    print()
    print("| computation | best time (s) | trials per second |")
    print("|---|---:|---:|")
    print(f"| `estimate_target`, {args.n:.0e} static MLE trials, one batch | {t:.3f} | "
          f"{args.n / t:.3g} |")  # fmt: skip
    print()
    print(f"converged: {est.converged.mean():.4%}, iterations (both stages): median "
          f"{np.median(est.iterations):.0f}, max {est.iterations.max()}")  # fmt: skip


if __name__ == "__main__":
    main()
