"""A 10 000-run campaign of the paper scenario on a local Dask cluster (issue 5's target).

Run: ``python benchmarks/bench_campaign.py [--runs 10000] [--workers 2]``. Reports the wall
time of `crlbswarm sweep`'s engine (cluster start-up included) and the peak memory of the
whole process tree (driver, scheduler, workers), sampled every 0.1 s with psutil.
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import threading
import time
from pathlib import Path

import pandas as pd
import psutil

from crlbswarm.campaign import CampaignSpec, run_campaign


def tree_rss() -> int:
    me = psutil.Process()
    total = me.memory_info().rss
    for child in me.children(recursive=True):
        with contextlib.suppress(psutil.Error):  # a child may exit while we look
            total += child.memory_info().rss
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--batch", type=int, default=250)
    args = parser.parse_args()
    text = f'base = "paper"\nbatch_size = {args.batch}\n[seeds]\ncount = {args.runs}\n'
    spec = CampaignSpec.from_toml(text)

    peak = [0]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], tree_rss())
            time.sleep(0.1)

    thread = threading.Thread(target=sample, daemon=True)
    with tempfile.TemporaryDirectory() as tmp:
        thread.start()
        t0 = time.perf_counter()
        counts = run_campaign(spec, Path(tmp), n_workers=args.workers)
        elapsed = time.perf_counter() - t0
        stop.set()
        thread.join()
        rows = len(pd.read_parquet(Path(tmp) / "runs"))
    print(f"{args.runs} paper missions in {counts['tasks']} tasks of {args.batch}, "
          f"{args.workers} workers: {elapsed:.1f} s wall, peak memory {peak[0] / 2**30:.2f} GiB "
          f"(driver + scheduler + workers), {rows} rows written")  # fmt: skip


if __name__ == "__main__":
    main()
