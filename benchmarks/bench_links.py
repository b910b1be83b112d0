"""Cost of the communication links (issue 14): a batch with links on against links off.

Run: ``python benchmarks/bench_links.py [--scenario paper] [--runs 200] [--repeat 5]``.
Prints a Markdown table for docs/links.md: a batch of ``--runs`` missions of the scenario
(metrics only, one call) without a ``[links]`` table, with perfect links (``[links]``
empty: every message of the step, instantly, through the link layer), and with 20 % loss
and 3 steps of delay, each the best of ``--repeat`` after a warm-up call (which also
compiles the kernels), and each time's ratio to links off (the target: at most 1.3).
The three batches alternate, so a busy machine slows them alike.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numba
import numpy as np

import crlbswarm as cs

CASES = {
    "links off (no [links] table)": None,
    "perfect links ([links] empty)": {},
    "20 % loss, 3 steps of delay": {"loss": 0.2, "delay": 3},
}


def scenario_with(name: str, links: dict[str, object] | None) -> cs.Scenario:
    """The built-in scenario ``name`` with the ``[links]`` table ``links`` (None: none)."""
    data = cs.load_scenario(name).model_dump(exclude_none=True)
    if links is not None:
        data["links"] = links
    return cs.Scenario.from_dict(data, source=f"{name} with links {links}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper")
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    scenarios = {label: scenario_with(args.scenario, links) for label, links in CASES.items()}
    times: dict[str, list[float]] = {label: [] for label in CASES}
    for sc in scenarios.values():  # warm-up: compile or load the kernels
        cs.simulate(sc, seeds=range(min(4, args.runs)), keep_trajectories=False)
    for _ in range(args.repeat):
        for label, sc in scenarios.items():
            t0 = time.perf_counter()
            cs.simulate(sc, seeds=range(args.runs), keep_trajectories=False)
            times[label].append(time.perf_counter() - t0)
    best = {label: min(t) for label, t in times.items()}
    off = best[next(iter(CASES))]
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, NumPy {np.__version__}, Numba {numba.__version__} "
        f"({numba.get_num_threads()} threads)"
    )
    print()
    print(f"| {args.runs} `{args.scenario}` missions, metrics only | best (s) | / links off |")
    print("|---|---:|---:|")
    for label, t in best.items():
        print(f"| {label} | {t:.3f} | {t / off:.3f} |")


if __name__ == "__main__":
    main()
