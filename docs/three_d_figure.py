"""Draw docs/three_d.png: optimal designs for a known and an unknown target height.

Run from the repository root: ``PYTHONPATH=src python docs/three_d_figure.py``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from crlbswarm import design_3d

TARGET = np.zeros(3)
CASES = [
    ("6 UAVs at 20 m", np.full(6, 20.0)),
    ("6 UAVs at 20-26 m", np.array([20.0, 26.0, 22.0, 24.0, 21.0, 25.0])),
]
STYLE = {"known": ("o", "tab:blue"), "unknown": ("s", "tab:red")}


def main() -> None:
    fig, axes = plt.subplots(2, 2, figsize=(10, 8.5))
    for col, (title, heights) in enumerate(CASES):
        top, side = axes[0, col], axes[1, col]
        for case, (marker, color) in STYLE.items():
            d = design_3d(heights, TARGET, target_height=case, starts=32, seed=0)
            p = d.positions
            phis = np.degrees(d.elevations)
            label = (f"height {case}: {d.method}, CRLB {d.crlb * 1e3:.3f}e-3 m$^2$ "
                     f"(bound {d.bound * 1e3:.3f}e-3)")  # fmt: skip
            top.plot(*p[:, :2].T, marker, color=color, mfc="none", ms=9, label=label)
            radius = np.hypot(p[:, 0], p[:, 1])
            span = f"elevations {phis.min():.2f}-{phis.max():.2f} deg"
            side.plot(radius, p[:, 2], marker, color=color, mfc="none", ms=9,
                      label=f"height {case}: {span}")  # fmt: skip
            for r, z in zip(radius, p[:, 2], strict=True):
                side.plot([0, r], [0, z], color=color, lw=0.5, alpha=0.5)
        for ax in (top, side):
            ax.plot(0, 0, "k*", ms=12)
        top.set(title=f"{title}: top view", xlim=(-25, 25), ylim=(-25, 25), aspect="equal",
                xlabel="x (m)", ylabel="y (m)")  # fmt: skip
        side.set(title=f"{title}: side view (radius, height)", xlim=(0, 25), ylim=(0, 32),
                 aspect="equal", xlabel="horizontal distance from the target (m)",
                 ylabel="height above the target (m)")  # fmt: skip
        top.legend(loc="lower left", fontsize=7)
        side.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    fig.savefig(Path(__file__).with_name("three_d.png"), dpi=100)


if __name__ == "__main__":
    main()
