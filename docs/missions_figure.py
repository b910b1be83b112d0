"""Draw docs/design_missions.png: two missions beyond the paper's layout, flown.

Left: ``paper_safe`` with its target moved to (52, 88), where a slot of F* falls inside the
upper wall; the mission flies the constrained design. Right: ten UAVs split between three
targets (``extra_targets``), each group with its own leader, flown together with the safety
filter across groups.

Run from the repository root: ``PYTHONPATH=src python docs/missions_figure.py``.
"""

from __future__ import annotations

import copy
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Rectangle

from crlbswarm import Scenario, load_scenario, simulate, simulate_groups

COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple")


def _blocked() -> Scenario:
    data = copy.deepcopy(load_scenario("paper_safe").model_dump())
    data.update(name="blocked", target=[52.0, 88.0])
    return Scenario.from_dict(data)


def _three_targets() -> Scenario:
    data = copy.deepcopy(load_scenario("paper_safe").model_dump())
    data.update(name="three targets", target=[60.0, 70.0],
                extra_targets=[[100.0, -20.0], [-60.0, 80.0]], obstacles=[])  # fmt: skip
    data["uavs"].update(count=10, start_region=[[-15.0, 15.0], [-15.0, 15.0]])
    return Scenario.from_dict(data)


def _obstacles(ax: plt.Axes, sc: Scenario) -> None:
    for x0, x1, y0, y1 in sc.obstacle_set.rectangles:
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color="0.75", zorder=0))


def _closed(points: np.ndarray) -> np.ndarray:
    centre = points.mean(axis=0)
    order = np.argsort(np.arctan2(*(points - centre).T[::-1]))
    ring = points[order]
    return np.vstack([ring, ring[:1]])


def main() -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 5.2))
    sc = _blocked()
    res = simulate(sc, seed=0)
    assert res.positions is not None
    _obstacles(left, sc)
    for m in range(sc.uavs.count):
        left.plot(*res.positions[0, :, m].T, lw=0.8, color="0.45")
    design = sc.formation_design
    fstar = design.slots  # the flown design
    blocked = _closed(np.asarray(_fstar(sc)))
    left.plot(*blocked.T, "o--", color="tab:red", mfc="none", label="$F^*$ (blocked)")
    left.plot(*_closed(res.positions[0, -1]).T, "s-", color="tab:blue",
              label=f"flown at t = {res.time[-1]:.0f} s (ratio {design.ratio:.4f})")  # fmt: skip
    left.plot(*fstar.T, "+", color="k", ms=9, label="constrained design")
    inside = blocked[np.argmin(np.hypot(*(blocked - (45.0, 76.0)).T))]
    left.annotate("slot of $F^*$ inside the wall", inside, (48, 58), fontsize=8,
                  arrowprops={"arrowstyle": "->", "lw": 0.8})  # fmt: skip
    left.plot(*sc.target, "k*", ms=12, label="target")
    left.set(title="blocked $F^*$: the constrained design is flown", xlabel="x (m)",
             ylabel="y (m)", aspect="equal", xlim=(-15, 80), ylim=(-15, 110))  # fmt: skip
    left.legend(loc="lower right", fontsize=8)

    sc = _three_targets()
    res3 = simulate_groups(sc, seed=0)
    for g, group in enumerate(res3.groups):
        colour = COLOURS[g]
        assert group.positions is not None
        for m in range(group.positions.shape[2]):
            right.plot(*group.positions[0, :, m].T, lw=0.8, color=colour, alpha=0.6)
        final = group.positions[0, -1]
        uavs = res3.plan.members[g]
        outcome = group.metrics["outcome"][0]
        right.plot(*_closed(final).T, "o-", color=colour,
                   label=f"group {g}: UAVs {uavs.tolist()}, {outcome}")  # fmt: skip
        right.plot(*group.scenario.target, "*", color="k", ms=12)
    sep = float(res3.groups[0].separation.min())
    right.set(title=f"10 UAVs, 3 targets (smallest separation {sep:.2f} m)", xlabel="x (m)",
              ylabel="y (m)", aspect="equal")  # fmt: skip
    right.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    out = Path(__file__).with_name("design_missions.png")
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def _fstar(sc: Scenario) -> np.ndarray:
    from crlbswarm import optimal_formation

    return optimal_formation(sc.uavs.count, sc.target, sc.altitude, sc.radar_model)


if __name__ == "__main__":
    main()
