"""Draw docs/constrained_design.png: a constrained design beside the blocked F*.

Run from the repository root: ``PYTHONPATH=src python docs/constrained_design_figure.py``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Circle, Polygon

from crlbswarm import Obstacles, constrained_design

L_SHAPE = np.array([(-60, -60), (60, -60), (60, 60), (0, 60), (0, 0), (-60, 0)], float)
CASES = [
    ("L-shaped no-fly zone, clearance 1 m", {"no_fly": [L_SHAPE], "clearance": 1.0}),
    ("disc obstacle over slot 1, min separation 18 m",
     {"obstacles": Obstacles(circles=[[14.14, 0.0, 6.0]]), "clearance": 1.0,
      "min_separation": 18.0}),
]  # fmt: skip


def main() -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 5))
    for ax, (title, kw) in zip(axes, CASES, strict=True):
        d = constrained_design(6, (0.0, 0.0), 20.0, starts=32, **kw)
        for zone in kw.get("no_fly", []):
            ax.add_patch(Polygon(zone, color="0.8", label="no-fly zone"))
        if "obstacles" in kw:
            for x, y, r in kw["obstacles"].circles:
                ax.add_patch(Circle((x, y), r, color="0.6", label="obstacle"))
        f = np.vstack([d.unconstrained_positions, d.unconstrained_positions[:1]])
        ax.plot(f[:, 0], f[:, 1], "o--", color="tab:red", mfc="none", label="blocked $F^*$")
        ax.plot(*d.positions.T, "s", color="tab:blue", label=f"constrained, ratio {d.ratio:.4f}")
        ax.plot(0, 0, "k*", ms=12, label="target")
        ax.set(title=title, xlim=(-30, 30), ylim=(-30, 30), aspect="equal", xlabel="x (m)",
               ylabel="y (m)")  # fmt: skip
        ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(Path(__file__).with_name("constrained_design.png"), dpi=110)


if __name__ == "__main__":
    main()
