"""Speed of the mission simulator on the paper scenario (issue 3's targets).

Run: ``python benchmarks/bench_mission.py [--runs 1000] [--repeat 5]``. Prints a Markdown
table for docs/performance.md: one paper mission (1500 steps, all metrics: CRLB, cost,
clearance, separation, eta) and a batch of ``--runs`` missions in one call, best of
``--repeat`` after a warm-up call (which also compiles the Numba kernels).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numba
import numpy as np

import crlbswarm as cs
from timing import best_of


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    scenario = cs.load_scenario("paper")
    t_compile = time.perf_counter()
    cs.simulate(scenario, seed=0)
    t_compile = time.perf_counter() - t_compile

    rows = [
        ("one paper mission (1500 steps, all metrics)", best_of(
            lambda: cs.simulate(scenario, seed=0), args.repeat)),
        (f"{args.runs} paper missions, one batch", best_of(
            lambda: cs.simulate(scenario, seeds=range(args.runs)), max(1, args.repeat // 2))),
        (f"{args.runs} paper missions, one batch, metrics only", best_of(
            lambda: cs.simulate(scenario, seeds=range(args.runs), keep_trajectories=False),
            max(1, args.repeat // 2))),
    ]  # fmt: skip
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, NumPy {np.__version__}, Numba {numba.__version__} "
        f"({numba.get_num_threads()} threads)"
    )
    print(f"first call (loads or compiles the kernels): {t_compile:.2f} s")
    print()
    print("| computation | best time (s) |")
    print("|---|---:|")
    for label, t in rows:
        print(f"| {label} | {t:.4f} |")


if __name__ == "__main__":
    main()
