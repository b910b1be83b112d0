"""Convergence of the paper mission against message loss and delay (issue 14): one campaign.

Run from the repository root::

    python benchmarks/links_sweep.py [--seeds 20] [--duration 300] [--out DIR]
                                     [--workers 2] [--figure docs/links_sweep.png]

Runs ONE ``crlbswarm sweep`` campaign (:func:`crlbswarm.campaign.run_campaign`, a local Dask
cluster) on the built-in ``paper`` scenario with a ``[links]`` table of perfect range on the
paper's graph (no ``range``, ``use_graph = true``) and a mission of ``--duration`` seconds
(the paper's is 150 s; longer, to see the slow convergence of long delays), sweeping
``links.loss`` over 0-50 % and ``links.delay`` over 0-10 steps (the grid below), seeds
``0 .. --seeds - 1`` of each. The campaign is written under ``DIR/campaign`` (re-running the
same command resumes it; another ``--seeds`` or ``--duration`` needs another ``--out``).

Then it reads the campaign's Parquet dataset and prints, per (loss, delay), a plain-text
table (also saved as ``DIR/links_sweep.txt``), and draws the figure (``--figure``): (a) the
median convergence time against the loss, one line per delay, (b) the final CRLB / bound
(median and 90th percentile), (c) the fraction of runs converged by 140 s over (loss,
delay): those converge within the paper's 150 s mission too (the bound held for 10 s).

"Converged" is the project's ``convergence_time_s`` (:mod:`crlbswarm.results`): the first
time from which the CRLB stays within 1 % of the bound (``CRLB_TOL``) and the centroid within
0.5 m of its place (``CENTROID_TOL``) until the end of the mission, for at least
``time.hold`` (10 s); a run converged when that time exists (it is not null). The
``outcome`` column is not used: in the paper mission many runs end with outcome
``collision`` from the start (two UAVs passing closer than 1 m), with or without links,
and yet reach and hold the bound.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import crlbswarm as cs
from crlbswarm.campaign import CampaignSpec, run_campaign
from crlbswarm.results import CRLB_TOL

LOSSES = [0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5]
DELAYS = [0, 1, 2, 3, 5, 7, 10]
#: The paper mission's duration, s: a run that converged by PAPER_S - hold converges in it.
PAPER_S = 150.0
FIGURE = Path(__file__).resolve().parents[1] / "docs" / "links_sweep.png"


def write_spec(out: Path, seeds: int, duration: float) -> tuple[CampaignSpec, str]:
    """Write the base scenario and the campaign spec under ``out``; return the spec."""
    data = cs.load_scenario("paper").model_dump(exclude_none=True)
    data["links"] = {}  # perfect links on the paper's graph; the grid sets loss and delay
    data["time"]["duration"] = duration
    base = cs.Scenario.from_dict(data, source=f"paper, links, {duration:g} s")
    out.mkdir(parents=True, exist_ok=True)
    (out / "links_sweep_base.toml").write_text(base.to_toml())
    text = (
        'base = "links_sweep_base.toml"\n'
        f"batch_size = {seeds}\n"
        f"[seeds]\nstart = 0\ncount = {seeds}\n"
        f'[grid]\n"links.loss" = {LOSSES}\n"links.delay" = {DELAYS}\n'
    )
    path = out / "links_sweep.toml"
    path.write_text(text)
    return CampaignSpec.from_file(path)


def summarise(runs: pd.DataFrame, hold: float) -> pd.DataFrame:
    """Per (loss, delay): runs, converged fraction (in the mission, and by the end of the
    paper's 150 s one), convergence time (median, range), final CRLB / bound."""
    rows = []
    for (loss, delay), g in runs.groupby(["links.loss", "links.delay"]):
        conv = g["convergence_time_s"].to_numpy(dtype=float)  # null -> NaN
        ratio = g["final_crlb_ratio"].to_numpy(dtype=float)
        done = np.isfinite(conv)
        rows.append({
            "loss": loss,
            "delay": delay,
            "runs": len(g),
            "converged": done.mean(),
            "converged_150": (conv <= PAPER_S - hold + 1e-9).mean(),
            "final_within_1pc": (ratio <= 1.0 + CRLB_TOL).mean(),
            "conv_median_s": np.median(conv[done]) if done.any() else np.nan,
            "conv_min_s": conv[done].min() if done.any() else np.nan,
            "conv_max_s": conv[done].max() if done.any() else np.nan,
            "ratio_median": np.median(ratio),
            "ratio_p90": np.percentile(ratio, 90),
            "ratio_max": ratio.max(),
            "collision": (g["outcome"] == "collision").mean(),
            "min_sep_median_m": g["min_separation_m"].median(),
        })  # fmt: skip
    return pd.DataFrame(rows)


def table_text(s: pd.DataFrame, duration: float) -> str:
    """The plain-text table of :func:`summarise`."""
    head = (
        f"{'loss':>5} {'delay':>5} {'runs':>4} {'conv.':>6} {'by 150s':>7} {'final<1%':>8} "
        f"{'median conv. (s)':>16} {'range (s)':>13} {'med. CRLB/bound':>15} "
        f"{'p90 CRLB/bound':>14} {'collision':>9} {'min sep. (m)':>12}"
    )
    lines = [
        f"paper mission, {duration:g} s, [links] on the paper's graph, perfect range; "
        "conv. = convergence_time_s not null (CRLB within 1 % of the bound and centroid "
        "within 0.5 m, held to the end); by 150s = converged by 140 s (counts in the "
        "paper's 150 s mission); collision = outcome collision (two UAVs closer than 1 m "
        "at some step); min sep. = median of the runs' smallest distance between two UAVs",
        head,
    ]
    for r in s.itertuples():
        span = "-" if np.isnan(r.conv_min_s) else f"{r.conv_min_s:.1f}-{r.conv_max_s:.1f}"
        med = "-" if np.isnan(r.conv_median_s) else f"{r.conv_median_s:.1f}"
        lines.append(
            f"{r.loss:>5.0%} {r.delay:>5d} {r.runs:>4d} {r.converged:>6.0%} "
            f"{r.converged_150:>7.0%} {r.final_within_1pc:>8.0%} {med:>16} {span:>13} "
            f"{r.ratio_median:>15.6f} {r.ratio_p90:>14.6f} {r.collision:>9.0%} "
            f"{r.min_sep_median_m:>12.2f}"
        )
    return "\n".join(lines)


def draw(s: pd.DataFrame, duration: float, seeds: int, path: Path) -> None:
    """The three panels: convergence time, final CRLB / bound, fraction converged."""
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 5.2), width_ratios=[1.15, 1.15, 1])
    colors = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, len(DELAYS)))
    for delay, color in zip(DELAYS, colors, strict=True):
        g = s[s["delay"] == delay].sort_values("loss")
        loss = 100 * g["loss"].to_numpy()
        label = f"delay {delay} step{'' if delay == 1 else 's'} ({delay * 0.1:g} s)"
        a.plot(loss, g["conv_median_s"], "-", color=color, label=label)
        full = g["converged"].to_numpy() == 1.0
        a.plot(loss[full], g["conv_median_s"][full], "o", color=color, ms=6)
        a.plot(loss[~full], g["conv_median_s"][~full], "o", color=color, mfc="white", ms=7)
        b.plot(loss, g["ratio_median"] - 1.0, "-o", color=color, ms=4)
        b.plot(loss, g["ratio_p90"] - 1.0, "--", color=color, lw=1)
    delays = a.get_legend_handles_labels()
    a.axhline(PAPER_S, color="0.4", lw=0.8, ls=":")
    a.text(1, PAPER_S - 4, "end of the paper's 150 s mission", fontsize=8, color="0.3")
    marks = [
        a.plot([], [], "o", color="0.3", label=f"every run converged within {duration:g} s")[0],
        a.plot([], [], "o", color="0.3", mfc="white", label="some runs did not")[0],
    ]
    a.set(xlabel="message loss (%)", ylabel="median convergence time (s)",
          title="(a) convergence time (median of the runs that converged)")  # fmt: skip
    a.legend(handles=marks, fontsize=8, loc="center left", bbox_to_anchor=(0.0, 0.6))
    b.axhline(CRLB_TOL, color="tab:red", lw=0.8, ls=":")
    b.text(1, CRLB_TOL * 0.6, "1 % above the bound (the convergence test)", fontsize=8,
           color="tab:red")  # fmt: skip
    b.plot([], [], "-", color="0.3", label="median")
    b.plot([], [], "--", color="0.3", lw=1, label="90th percentile")
    b.set(
        xlabel="message loss (%)", ylabel="final CRLB / bound − 1", yscale="log",
        ylim=(1e-5, 3e-2), title=f"(b) final CRLB / bound at {duration:g} s (all runs)",
    )  # fmt: skip
    b.legend(fontsize=8, loc="center right")
    grid = s.pivot(index="delay", columns="loss", values="converged_150").loc[DELAYS, LOSSES]
    im = c.imshow(100 * grid.to_numpy(), origin="lower", cmap="RdYlGn", vmin=0, vmax=100,
                  aspect="auto")  # fmt: skip
    for i in range(len(DELAYS)):
        for j in range(len(LOSSES)):
            c.text(j, i, f"{100 * grid.iat[i, j]:.0f}", ha="center", va="center", fontsize=8)
    c.set_xticks(range(len(LOSSES)), [f"{100 * v:g}" for v in LOSSES])
    c.set_yticks(range(len(DELAYS)), [str(d) for d in DELAYS])
    c.set(xlabel="message loss (%)", ylabel="delay (steps of 0.1 s)",
          title="(c) runs converged by 140 s (%): within the\npaper's 150 s mission")  # fmt: skip
    fig.colorbar(im, ax=c, label="converged by 140 s (% of runs)")
    fig.legend(*delays, loc="lower center", ncol=len(DELAYS), fontsize=9, frameon=False)
    fig.suptitle(f"Paper mission with lossy, delayed links: {seeds} seeds per cell, "
                 f"{duration:g} s missions, one campaign", fontsize=11)  # fmt: skip
    fig.tight_layout(rect=(0.0, 0.05, 1.0, 1.0))
    fig.savefig(path, dpi=80)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="seeds per (loss, delay)")
    parser.add_argument("--duration", type=float, default=300.0, help="mission length, s")
    parser.add_argument("--out", type=Path, default=Path("links_sweep_out"))
    parser.add_argument("--workers", type=int, default=None, help="default: one per core")
    parser.add_argument("--figure", type=Path, default=FIGURE)
    args = parser.parse_args()
    spec, text = write_spec(args.out, args.seeds, args.duration)
    t0 = time.perf_counter()
    counts = run_campaign(spec, args.out / "campaign", n_workers=args.workers, spec_text=text)
    elapsed = time.perf_counter() - t0
    runs = pd.read_parquet(args.out / "campaign" / "runs")
    hold = cs.load_scenario("paper").time.hold
    summary = summarise(runs, hold)
    text = table_text(summary, args.duration)
    print(text)
    (args.out / "links_sweep.txt").write_text(text + "\n")
    draw(summary, args.duration, args.seeds, args.figure)
    print(f"{len(runs)} runs, {counts['tasks']} tasks ({counts['ran']} ran): {elapsed:.1f} s "
          f"wall; figure {args.figure}")  # fmt: skip


if __name__ == "__main__":
    main()
