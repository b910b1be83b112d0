"""Issue 5's performance table: each computation vectorised/compiled beside a plain loop.

Run: ``python benchmarks/bench_summary.py``. The plain loops are written for the comparison:

* CRLB: one formation at a time, one UAV at a time (``bench_crlb.plain_loop_crlb``);
* missions: the *same* simulator code run by the Python interpreter, one UAV and one step at a
  time (``NUMBA_DISABLE_JIT=1`` in a subprocess; its results are bit-identical);
* static MLE: one trial at a time with ``scipy.optimize.minimize`` (BFGS) on the likelihood.

Plain-loop figures are measured on a subset and extrapolated linearly (they are loops).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
from scipy.optimize import minimize

import crlbswarm as cs
from bench_crlb import plain_loop_crlb
from bench_scaling import swarm_scenario
from timing import best_of

PLAIN_MISSION = """
import time, crlbswarm as cs
from bench_scaling import swarm_scenario
sc = {scenario}
t0 = time.perf_counter()
for seed in range({n}):
    cs.simulate(sc, seed=seed, keep_trajectories=False)
print((time.perf_counter() - t0) / {n})
"""


def plain_mission_time(scenario: str, n: int) -> float:
    """Seconds per mission of the simulator run by the Python interpreter (no Numba);
    ``scenario`` is a Python expression building it."""
    here = os.path.dirname(os.path.abspath(__file__))
    env = {
        **os.environ,
        "NUMBA_DISABLE_JIT": "1",
        "PYTHONPATH": os.pathsep.join([here, os.environ.get("PYTHONPATH", "")]),
    }
    code = PLAIN_MISSION.format(scenario=scenario, n=n)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True)  # fmt: skip
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    rows = []
    target = np.array([80.0, 90.0])
    rng = np.random.default_rng(0)

    q = target + rng.uniform(-30.0, 30.0, size=(1_000_000, 6, 2))
    t = best_of(lambda: cs.crlb(q, target, 20.0), 3)
    t0 = time.perf_counter()
    plain_loop_crlb(q[:20_000], target, 20.0, cs.Radar().snr_constant)
    plain = (time.perf_counter() - t0) * 50
    rows.append(("CRLB of 10^6 formations (M = 6)", t, plain))

    paper = cs.load_scenario("paper")
    t = best_of(lambda: cs.simulate(paper, seed=0), 5)
    plain_one = plain_mission_time('cs.load_scenario("paper")', 2)
    rows.append(("one paper mission (1500 steps, all metrics)", t, plain_one))
    t = best_of(lambda: cs.simulate(paper, seeds=range(1000), keep_trajectories=False), 1)
    rows.append(("1000 paper missions, one batch", t, 1000 * plain_one))

    swarm = swarm_scenario(10_000, 20)
    t = best_of(lambda: cs.simulate(swarm, seed=0, keep_trajectories=False), 1) / 20
    # Plain loop: a 2-step mission of 1000 UAVs, per step, scaled linearly to 10 000 UAVs.
    plain_step = plain_mission_time("swarm_scenario(1000, 2)", 1) / 2 * 10
    rows.append(("one step of a 10 000-UAV swarm (ring, 40 obstacles)", t, plain_step))

    f = cs.optimal_formation(6, target, 20.0)
    batch = np.broadcast_to(f, (100_000, 6, 2))
    ranges = cs.measure_ranges(batch, target, 20.0, rng=np.random.default_rng(1))
    t = best_of(lambda: cs.estimate_target(batch, ranges, 20.0), 2)
    t0 = time.perf_counter()
    for i in range(200):
        x0 = cs.linearised_estimate(f, ranges[i], 20.0)
        minimize(lambda s, i=i: cs.negative_log_likelihood(s, f, ranges[i], 20.0), x0,
                 method="BFGS")  # fmt: skip
    plain = (time.perf_counter() - t0) / 200 * 100_000
    rows.append(("10^5 static MLE trials", t, plain))

    print("| computation | crlbswarm (s) | plain loop (s) | speed-up |")
    print("|---|---:|---:|---:|")
    for label, fast, slow in rows:
        print(f"| {label} | {fast:.4g} | {slow:.4g} | {slow / fast:.0f}x |")


if __name__ == "__main__":
    main()
