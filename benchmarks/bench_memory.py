"""Peak memory of one large mission without trajectories (issue 12).

Run: ``python benchmarks/bench_memory.py [--uavs 100000] [--steps 150 1500]``.

Each mission runs in a fresh process (``crlbswarm.simulate(..., keep_trajectories=False)``
on the large-swarm scenario of ``bench_scaling.py``) and reports its peak resident memory
(``ru_maxrss``), the memory of the process after ``import crlbswarm`` and the scenario's
validation, and the difference: the memory the mission itself took. The disturbance is
drawn inside the kernel (``crlbswarm.counter_rng``) and the state of a step lives in a few
arrays of shape (M, 2), so the mission's memory should not grow with the number of steps;
its time series (a few values per step) are the only part that does.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

_CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, {bench!r})
from bench_scaling import swarm_scenario
import crlbswarm as cs
sc = swarm_scenario({uavs}, {steps})
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
r = cs.simulate(sc, seed=1, keep_trajectories=False)
elapsed = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({{"before_kib": before, "peak_kib": peak, "seconds": elapsed,
                  "final_crlb": float(r.crlb[0, -1])}}))
"""


def measure(uavs: int, steps: int) -> dict:
    """Peak memory of one mission in a fresh process."""
    code = _CHILD.format(bench=str(Path(__file__).parent), uavs=uavs, steps=steps)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--uavs", type=int, default=100_000)
    parser.add_argument("--steps", type=int, nargs="+", default=[150, 1500])
    args = parser.parse_args()
    print("| UAVs | steps | process peak | after import and scenario | mission | time |")
    print("|---:|---:|---:|---:|---:|---:|")
    rows = []
    for steps in args.steps:
        m = measure(args.uavs, steps)
        rows.append(m)
        mission = (m["peak_kib"] - m["before_kib"]) / 1024
        print(
            f"| {args.uavs} | {steps} | {m['peak_kib'] / 1024:.0f} MiB | "
            f"{m['before_kib'] / 1024:.0f} MiB | {mission:.0f} MiB | {m['seconds']:.1f} s |"
        )
    if len(rows) >= 2:
        ratio = rows[-1]["peak_kib"] / rows[0]["peak_kib"]
        print(f"\npeak of {args.steps[-1]} steps / peak of {args.steps[0]} steps: {ratio:.3f}")


if __name__ == "__main__":
    main()
