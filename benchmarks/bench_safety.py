"""Safe missions (issue 9): outcomes, separation, clearance and convergence per layout.

Runs the built-in ``paper_safe`` (the paper's mission with every layer on) for 1000 seeds,
every layout of ``benchmarks/layouts`` for 50 seeds, and prints a Markdown table: outcome
counts, the smallest UAV-UAV separation and obstacle clearance over every step of every run,
the worst final CRLB / bound and the median convergence time. It also times one mission
and a batch of 1000 of ``paper`` and ``paper_safe`` in one run and reports the ratio, and
with ``--figure`` draws the U-shaped trap flown with the paper's laws and with every layer.

Run: ``python benchmarks/bench_safety.py [--runs 50] [--paper-runs 1000] [--figure PNG]``.
"""

from __future__ import annotations

import argparse
import os
import platform
from pathlib import Path

import numpy as np

import crlbswarm as cs
from timing import best_of

LAYOUTS = Path(__file__).resolve().parent / "layouts"


def row(name: str, result: cs.MissionResult) -> str:
    m = result.metrics
    counts = result.outcome_counts
    outcomes = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
    conv = m["convergence_time_s"]
    median = f"{np.nanmedian(conv):.1f}" if np.isfinite(conv).any() else "-"
    return (
        f"| {name} | {result.n_runs} | {outcomes} | {m['min_separation_m'].min():.3f} | "
        f"{m['min_clearance_m'].min():.3f} | {m['final_crlb_ratio'].max():.5f} | {median} |"
    )


def trap_figure(path: Path) -> None:
    """The U-shaped trap flown with the paper's laws (layers off) and with every layer."""
    from matplotlib.figure import Figure

    from crlbswarm.plots import plot_mission_trajectories
    from crlbswarm.scenario import Scenario

    safe = cs.load_scenario(LAYOUTS / "u_trap.toml")
    data = safe.model_dump(exclude_none=True)
    data["safety"] = {"enabled": False}
    data["guidance"] = {"planner": False}
    data["formation"] = {"assignment": "index"}
    data["control"].update(epsilon=0.01, gamma=0.25)
    paper = Scenario.from_dict(data, "u_trap with the paper's laws")
    fig = Figure(figsize=(11.0, 5.0), layout="constrained")
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    for ax, sc, title in ((axes[0], paper, "the paper's laws"), (axes[1], safe, "every layer")):
        result = cs.simulate(sc, seed=0)
        plot_mission_trajectories(result, ax=ax)
        outcome = result.metrics["outcome"][0]
        ax.set_title(f"{title}: {outcome}, min separation "
                     f"{result.metrics['min_separation_m'][0]:.2f} m")  # fmt: skip
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50, help="seeds per layout")
    parser.add_argument("--paper-runs", type=int, default=1000, help="seeds of paper_safe")
    parser.add_argument("--figure", type=Path, default=None, help="write the trap figure here")
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, crlbswarm {cs.__version__}\n")  # fmt: skip
    print("| layout | runs | outcomes | min separation (m) | min clearance (m) | "
          "worst final CRLB/bound | median convergence (s) |")  # fmt: skip
    print("|---|---:|---|---:|---:|---:|---:|")
    for name in ("paper", "paper_safe"):
        sc = cs.load_scenario(name)
        print(row(name, cs.simulate(sc, seeds=range(args.paper_runs), keep_trajectories=False)))
    for path in sorted(LAYOUTS.glob("*.toml")):
        sc = cs.load_scenario(path)
        print(row(sc.name, cs.simulate(sc, seeds=range(args.runs), keep_trajectories=False)))
    print("\n| timing | paper (s) | paper_safe (s) | ratio |\n|---|---:|---:|---:|")
    paper_sc, safe_sc = cs.load_scenario("paper"), cs.load_scenario("paper_safe")
    for label, kwargs in (
        ("one mission", {"seed": 0}),
        ("1000 missions, one batch", {"seeds": range(1000), "keep_trajectories": False}),
    ):
        paper = best_of(lambda kw=kwargs: cs.simulate(paper_sc, **kw), 5)
        safe = best_of(lambda kw=kwargs: cs.simulate(safe_sc, **kw), 5)
        print(f"| {label} | {paper:.4g} | {safe:.4g} | {safe / paper:.2f} |")
    if args.figure is not None:
        trap_figure(args.figure)


if __name__ == "__main__":
    main()
