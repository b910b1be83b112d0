"""Time the constrained design of M = 100 UAVs (issue 11): three obstacles, a no-fly
polygon, clearance 1 m and a minimum separation, default radar, H = 20 m.

Run: ``PYTHONPATH=src python benchmarks/bench_constrained.py [starts]``. Prints the time per
start and the ratio to the unconstrained optimum; docs/constrained-design.md quotes it.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from crlbswarm import Obstacles, constrained_design


def main(starts: int = 4) -> None:
    obstacles = Obstacles(circles=[[14.0, 0.0, 4.0], [-10.0, 10.0, 3.0]],
                          rectangles=[[-5.0, 5.0, -20.0, -12.0]])  # fmt: skip
    no_fly = [np.array([[5.0, 5.0], [25.0, 5.0], [25.0, 25.0], [5.0, 25.0]])]
    for separation in (0.5, 1.0):
        t0 = time.perf_counter()
        d = constrained_design(100, (0.0, 0.0), 20.0, obstacles=obstacles, no_fly=no_fly,
                               clearance=1.0, min_separation=separation,
                               starts=starts)  # fmt: skip
        dt = time.perf_counter() - t0
        print(f"M=100 min_separation={separation} m: {dt:.1f} s for {starts} starts "
              f"({dt / starts:.1f} s/start), ratio {d.ratio:.6f}, "
              f"feasible {d.feasible_starts}/{d.starts}, active {len(d.active)}")  # fmt: skip


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
