"""Formation design beyond the regular polygon (issue 11): timings and figures.

Times the closed-form design of unequal UAVs (M = 12 and M = 100), the allocation of 9
UAVs to 3 targets (exhaustive, 3^9 assignments) and of 30 UAVs to 5 targets (the local
search), beside a plain baseline for each: a multistart L-BFGS-B search over all horizontal
positions for the design, and a Python loop over the assignments for the allocation. With
``--figures DIR`` it draws ``unequal_uavs.png`` (a weighted isotropic geometry and a
dominant-UAV geometry) and ``multitarget.png`` (an allocation of 12 unequal UAVs to 3
targets) into DIR.

Run: ``python benchmarks/bench_design.py [--figures docs]``.
"""

from __future__ import annotations

import argparse
import itertools
import platform
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

import crlbswarm as cs
from timing import best_of

H = 20.0


def multistart(radar: cs.Radar, m: int, starts: int, seed: int = 0) -> float:
    """A plain search: L-BFGS-B on the 2M coordinates (numerical gradient) from random
    starts; the best CRLB found."""
    rng = np.random.default_rng(seed)
    best = np.inf
    for _ in range(starts):
        x0 = rng.uniform(-40.0, 40.0, 2 * m)
        res = minimize(lambda x: float(np.log(cs.crlb(x.reshape(m, 2), (0.0, 0.0), H, radar))),
                       x0, method="L-BFGS-B")  # fmt: skip
        best = min(best, float(np.exp(res.fun)))
    return best


def loop_allocation(weights: np.ndarray, k: int) -> float:
    """A plain loop over the K^M assignments (sum of the groups' attainable CRLBs)."""
    best = np.inf
    for labels in itertools.product(range(k), repeat=weights.shape[0]):
        labels_arr = np.array(labels)
        total = 0.0
        for j in range(k):
            w = weights[labels_arr == j]
            if w.size < 3:
                break
            total += float(cs.attainable_crlb(w))
        else:
            best = min(best, total)
    return best


def figures(folder: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crlbswarm.output import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(9, 4.3))
    cases = [("no UAV dominates: weights close a polygon", [0.1, 0.3, 0.1, 0.2, 0.1, 0.15]),
             ("one UAV dominates (1 W vs 0.1 W)", [1.0, 0.1, 0.1, 0.1])]  # fmt: skip
    for ax, (title, power) in zip(axes, cases, strict=True):
        radar = cs.Radar(tx_power=power)
        m = len(power)
        f = cs.optimal_formation(m, (0.0, 0.0), H, radar)
        w = cs.optimal_weights(m, H, radar)
        ax.scatter(f[:, 0], f[:, 1], s=600 * w / w.max(), c="C0", zorder=3)
        for i, (x, y) in enumerate(f):
            ax.plot([0, x], [0, y], "C0-", lw=0.8)
            ax.annotate(f"{power[i]:g} W", (x, y), textcoords="offset points", xytext=(6, 6))
        ax.plot(0, 0, "r*", ms=14)
        crlb = float(cs.crlb(f, (0.0, 0.0), H, radar))
        ax.set_title(f"{title}\nCRLB {crlb:.3e} m² = attainable optimum", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y (m)")
    fig.tight_layout()
    save_figure(fig, folder / "unequal_uavs.png")
    plt.close(fig)

    rng = np.random.default_rng(3)
    radar = cs.Radar(tx_power=10 ** rng.uniform(-1.5, 0.0, 12))
    targets = np.array([[0.0, 0.0], [90.0, 10.0], [40.0, 80.0]])
    a = cs.allocate_targets(targets, 12, H, radar, objective="max")
    fig, ax = plt.subplots(figsize=(5.5, 5))
    for j, members in enumerate(a.groups):
        p = a.positions[members]
        label = f"target {j + 1}: {len(members)} UAVs, CRLB {a.crlb[j]:.2e} m²"
        ax.scatter(p[:, 0], p[:, 1], s=40 + 400 * radar.tx_power[members], c=f"C{j}",
                   label=label)  # fmt: skip
        for x, y in p:
            ax.plot([targets[j, 0], x], [targets[j, 1], y], f"C{j}-", lw=0.6)
        ax.plot(*targets[j], "*", c=f"C{j}", ms=14, mec="k")
    ax.set_title(f"12 unequal UAVs, 3 targets, min-max CRLB (exhaustive: {a.exhaustive})",
                 fontsize=9)  # fmt: skip
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, folder / "multitarget.png")
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--figures", type=Path, default=None)
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, "
          f"crlbswarm {cs.__version__}\n")  # fmt: skip
    rng = np.random.default_rng(0)
    radar12 = cs.Radar(tx_power=10 ** rng.uniform(-2.0, 0.0, 12))
    radar100 = cs.Radar(tx_power=10 ** rng.uniform(-2.0, 0.0, 100))
    t12 = best_of(lambda: cs.optimal_formation(12, (0.0, 0.0), H, radar12), 20)
    t100 = best_of(lambda: cs.optimal_formation(100, (0.0, 0.0), H, radar100), 5)
    t_ms = best_of(lambda: multistart(radar12, 12, 10), 1) * 20  # 200 starts
    r9 = cs.Radar(tx_power=10 ** rng.uniform(-2.0, 0.0, 9))
    w9 = cs.optimal_weights(9, H, r9)
    targets3 = np.array([[0.0, 0.0], [200.0, 0.0], [0.0, 300.0]])
    t_ex = best_of(lambda: cs.allocate_targets(targets3, 9, H, r9), 3)
    t_loop = best_of(lambda: loop_allocation(w9, 3), 1)
    r30 = cs.Radar(tx_power=10 ** rng.uniform(-2.0, 0.0, 30))
    targets5 = np.array([[0.0, 0.0], [200.0, 0.0], [0.0, 300.0], [400, 400], [800, 0]], float)
    t_k5 = best_of(lambda: cs.allocate_targets(targets5, 30, H, r30), 3)
    print("| computation | crlbswarm (s) | baseline (s) | ratio |")
    print("|---|---:|---:|---:|")
    print(f"| unequal UAVs, M = 12, closed form vs 200-start L-BFGS-B (estimated from 10) | "
          f"{t12:.4g} | {t_ms:.4g} | {t_ms / t12:.0f}x |")  # fmt: skip
    print(f"| unequal UAVs, M = 100, closed form | {t100:.4g} | | |")
    print(f"| 9 UAVs to 3 targets, exhaustive (3^9), vectorised vs a Python loop | {t_ex:.4g} | "
          f"{t_loop:.4g} | {t_loop / t_ex:.0f}x |")  # fmt: skip
    print(f"| 30 UAVs to 5 targets, local search | {t_k5:.4g} | | |")
    if args.figures is not None:
        figures(args.figures)
        print(f"wrote {args.figures / 'unequal_uavs.png'}, {args.figures / 'multitarget.png'}")


if __name__ == "__main__":
    main()
