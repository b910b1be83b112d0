"""Issue 14's acceptance for ``crlbswarm fly``: a UAV process killed with SIGKILL at
t = 100 s (a follower, then the leader), the other five re-form; over N seeds, the share of
flights whose final CRLB is within 1 % of the 5-UAV bound.

Run: ``python benchmarks/fly_faults.py --seeds 10 --out /tmp/fly_faults`` (needs the
``fly`` extra: eclipse-zenoh). Each flight is ``crlbswarm fly paper --kill UAV@100``, in
the stepped mode, with the paper's own 150 s mission.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import crlbswarm as c


def flight(out: Path, seed: int, uav: int, at: float) -> dict:
    """One flight with UAV ``uav`` killed at ``at`` s; its figures."""
    folder = out / f"uav{uav}_seed{seed}"
    began = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "crlbswarm.cli", "fly", "paper", "--out", str(folder),
         "--seed", str(seed), "--kill", f"{uav}@{at}", "--force"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    wall = time.monotonic() - began
    r = c.load_results(folder)
    k = round(at / r.scenario.time.step)
    ratio = float(r.crlb[0, -1] / r.bound_steps[-1])
    return {
        "seed": seed, "status": proc.returncode, "wall_s": wall, "ratio": ratio,
        "bound": float(r.bound), "outcome": str(r.metrics["outcome"][0]),
        "sep_after": float(r.separation[0, k:].min()),
        "conv": float(r.metrics["convergence_time_s"][0]),
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--out", type=Path, default=Path("fly_faults_out"))
    parser.add_argument("--at", type=float, default=100.0)
    args = parser.parse_args()
    five = c.load_scenario("paper")
    bound5 = c.crlb_bound(5, five.altitude, five.radar_model)
    print(f"5-UAV bound {bound5:.6g} m^2")
    for uav, label in ((2, "follower (UAV 2)"), (0, "leader (UAV 0)")):
        rows = [flight(args.out, s, uav, args.at) for s in range(args.seeds)]
        ratio = np.array([row["ratio"] for row in rows])
        within = np.abs(ratio - 1.0) <= 0.01
        print(f"{label} killed at {args.at:g} s, {args.seeds} flights: within 1 % of the "
              f"5-UAV bound {within.sum()}/{len(rows)}; final CRLB/bound median "
              f"{np.median(ratio):.5f}, max {ratio.max():.5f}; smallest separation after the "
              f"loss {min(r['sep_after'] for r in rows):.2f} m; outcomes "
              f"{sorted({r['outcome'] for r in rows})}; wall "
              f"{np.median([r['wall_s'] for r in rows]):.1f} s per flight")  # fmt: skip
        for row in rows:
            assert abs(row["bound"] - bound5) <= 1e-12 * bound5, row


if __name__ == "__main__":
    main()
