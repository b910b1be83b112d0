"""Speed of the sensing core: CRLB and friends over large batches of formations.

Run: ``python benchmarks/bench_crlb.py [--n 1000000] [--repeat 5]``. Prints a Markdown
table (best of ``--repeat`` runs, after one warm-up call) for docs/performance.md. The
"plain loop" row is a per-formation Python loop over the same model (numpy.linalg on each
2x2 FIM), written for the comparison and timed on fewer formations.
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np

import crlbswarm as cs
from timing import best_of


def plain_loop_crlb(q: np.ndarray, s: np.ndarray, h: float, a: float) -> np.ndarray:
    """One formation at a time, one UAV at a time: the computation without vectorisation."""
    out = np.empty(q.shape[0])
    for b in range(q.shape[0]):
        j = np.zeros((2, 2))
        for m in range(q.shape[1]):
            u = s - q[b, m]
            d2 = float(u @ u) + h * h
            j += (a / d2**2 + 8.0 / d2) / d2 * np.outer(u, u)
        out[b] = np.trace(np.linalg.inv(j))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000, help="formations per call")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    target = np.array([80.0, 90.0])
    q = target + rng.uniform(-30.0, 30.0, size=(args.n, 6, 2))
    h = 20.0
    rows = []
    for name, fn in [
        ("crlb", lambda: cs.crlb(q, target, h)),
        ("fisher_information", lambda: cs.fisher_information(q, target, h)),
        ("d_optimality", lambda: cs.d_optimality(q, target, h)),
        ("e_optimality", lambda: cs.e_optimality(q, target, h)),
    ]:
        t = best_of(fn, args.repeat)
        rows.append((f"`{name}`, {args.n:.0e} formations of M = 6, one call", t, args.n / t))

    n_loop = min(args.n, 20_000)
    a = cs.Radar().snr_constant
    t_loop = best_of(lambda: plain_loop_crlb(q[:n_loop], target, h, a), 1)
    ref = plain_loop_crlb(q[:100], target, h, a)
    assert np.allclose(ref, cs.crlb(q[:100], target, h), rtol=1e-10)
    rows.append((f"plain Python loop, {n_loop:.0e} formations of M = 6", t_loop, n_loop / t_loop))

    altitudes = np.linspace(5.0, 5000.0, args.n)
    t = best_of(lambda: cs.crlb_bound(6, altitudes), args.repeat)
    rows.append((f"`crlb_bound`, {args.n:.0e} altitudes", t, args.n / t))

    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, NumPy {np.__version__}"
    )
    print()
    print("| computation | best time (s) | per second |")
    print("|---|---:|---:|")
    for label, t, rate in rows:
        print(f"| {label} | {t:.3f} | {rate:.3g} |")
    speedup = (n_loop / t_loop) and rows[0][2] / (n_loop / t_loop)
    print()
    print(f"vectorised crlb vs plain loop: {speedup:.0f}x more formations per second")


if __name__ == "__main__":
    main()
