"""Figures of the paper, drawn from experiment results.

Every function takes a result object and an optional Matplotlib ``ax``, draws on it, and
returns the :class:`matplotlib.figure.Figure`. Nothing here calls ``plt.show()``, saves a
file or touches pyplot's global state: figures are built with the object-oriented API, so
they work on a machine without a display. Only the CLI saves files.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure, SubFigure
from matplotlib.patches import Circle, Polygon, Rectangle

from .errors import FieldError
from .experiments import FORMATION_LABELS, AltitudeSweep, ElevationCurve
from .montecarlo import EstimatorSweep
from .results import MissionResult

__all__ = [
    "mission_snapshot_steps",
    "passage_interval",
    "plot_crlb_vs_altitude",
    "plot_estimation_timeseries",
    "plot_estimator_vs_altitude",
    "plot_mission_timeseries",
    "plot_mission_trajectories",
    "plot_optimal_elevation",
]

_STYLES: dict[str, dict[str, Any]] = {
    "optimal": {"color": "C3", "lw": 2.2, "marker": "o", "ms": 4},
    "fixed_polygon": {"color": "C0", "marker": "s", "ms": 3.5},
    "arc": {"color": "C2", "marker": "^", "ms": 3.5},
    "line": {"color": "C1", "marker": "v", "ms": 3.5},
    "random_disc": {"color": "C4", "marker": "D", "ms": 3},
}


def _figure_of(ax: Axes) -> Figure:
    """The (root) figure holding ``ax``."""
    fig = ax.figure
    return fig.figure if isinstance(fig, SubFigure) else fig


def plot_crlb_vs_altitude(
    sweep: AltitudeSweep, ax: Axes | None = None, ratio_ax: Axes | None = None
) -> Figure:
    """Fig. 2: CRLB against altitude for F* and every benchmark formation (log scale).

    With no axes given, the figure has two panels: the CRLB itself (as in the paper) and
    the CRLB divided by the bound 4/sum(w*), on which F* is the line 1 and every benchmark
    sits above it at every altitude.

    Parameters
    ----------
    sweep : AltitudeSweep
        Result of :func:`crlbswarm.crlb_vs_altitude`.
    ax : matplotlib.axes.Axes, optional
        Axes for the CRLB panel; if omitted a new two-panel figure is made.
    ratio_ax : matplotlib.axes.Axes, optional
        Axes for the ratio panel; drawn only if given or if ``ax`` is omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if ax is None:
        fig = Figure(figsize=(6.4, 7.2), layout="constrained")
        ax, ratio_ax = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    fig = _figure_of(ax)
    h = sweep.altitude
    for name, values in sweep.crlb.items():
        label = FORMATION_LABELS.get(name, name)
        if name == "fixed_polygon":
            label = f"regular polygon, r = {sweep.parameters['fixed_radius_m']:g} m"
        style = _STYLES.get(name, {})
        sem = sweep.sem.get(name)
        for axis, scale in ((ax, 1.0), (ratio_ax, sweep.bound)):
            if axis is None:
                continue
            axis.plot(h, values / scale, label=label, **style)
            if sem is not None and np.any(sem):
                axis.fill_between(
                    h,
                    (values - 2 * sem) / scale,
                    (values + 2 * sem) / scale,
                    color=style.get("color"),
                    alpha=0.2,
                    lw=0,
                )
    ax.plot(h, sweep.bound, "k--", lw=1.0, label=r"bound $4/\sum_m w_m^*$, eq. (11)")
    ax.set_yscale("log")
    ax.set_ylabel(r"CRLB tr$(\mathbf{J}_s^{-1})$ (m$^2$)")
    ax.set_title(f"CRLB vs altitude, M = {sweep.n_uavs} UAVs")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    last = ax
    if ratio_ax is not None:
        ratio_ax.axhline(1.0, color="k", ls="--", lw=1.0)
        ratio_ax.set_yscale("log")
        ratio_ax.set_ylabel("CRLB / bound")
        ratio_ax.grid(True, which="both", alpha=0.3)
        last = ratio_ax
    last.set_xlabel("flight altitude H (m)")
    return fig


def plot_optimal_elevation(curve: ElevationCurve, ax: Axes | None = None) -> Figure:
    """Optimal elevation against altitude on a log axis, with its limits 54.74 and 45 deg.

    Parameters
    ----------
    curve : ElevationCurve
        Result of :func:`crlbswarm.optimal_elevation_curve`.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure is made if omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if ax is None:
        ax = Figure(figsize=(6.4, 4.0), layout="constrained").add_subplot()
    fig = _figure_of(ax)
    ax.plot(curve.altitude, np.degrees(curve.elevation), color="C3", lw=2, label=r"$\phi^*(H)$")
    upper = np.degrees(np.arctan(np.sqrt(2.0)))
    ax.axhline(
        upper, color="0.3", ls="--", lw=1, label=rf"$\arctan\sqrt{{2}}$ = {upper:.2f}° ($H \to 0$)"
    )
    ax.axhline(45.0, color="0.3", ls=":", lw=1, label=r"45° ($H \to \infty$)")
    ax.set_xscale("log")
    ax.set_xlabel("flight altitude H (m)")
    ax.set_ylabel(r"optimal elevation $\phi^*$ (deg)")
    ax.set_ylim(44.0, 56.0)
    ax.set_title("CRLB-optimal elevation angle")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    return fig


def _check_run(result: MissionResult, run: int) -> int:
    return result.run_index(run)


def passage_interval(result: MissionResult, run: int = 0) -> tuple[float, float] | None:
    """First and last time a UAV of ``run`` is within the safety radius of an obstacle.

    Parameters
    ----------
    result : MissionResult
        Simulation result.
    run : int, default 0
        Index of the run in the batch.

    Returns
    -------
    (float, float) or None
        Start and end of the passage, s; ``None`` if no UAV came that close.
    """
    near = result.clearance[_check_run(result, run)] < result.scenario.control.safety_radius
    if not near.any():
        return None
    idx = np.flatnonzero(near)
    return float(result.time[idx[0]]), float(result.time[idx[-1]])


def mission_snapshot_steps(result: MissionResult, run: int = 0) -> list[int]:
    """Steps at which Fig. 3 draws the formation: start, narrowest, after the passage, end.

    Parameters
    ----------
    result : MissionResult
        Simulation result.
    run : int, default 0
        Index of the run in the batch.

    Returns
    -------
    list of int
        Sorted distinct step indices: 0, the middle of the interval where eta is smallest,
        the first step after it where eta is back at 1, and the last step.
    """
    eta = result.eta[_check_run(result, run)]
    last = eta.shape[0] - 1
    steps = {0, last}
    low = np.flatnonzero(eta <= eta.min() + 1e-12)
    if eta.min() < 1.0:
        steps.add(int(low[low.shape[0] // 2]))
        after = np.flatnonzero((np.arange(eta.shape[0]) > low[-1]) & (eta >= 1.0))
        if after.size:
            steps.add(int(after[0]))
    return sorted(steps)


def _draw_obstacles(ax: Axes, result: MissionResult) -> None:
    obstacles = result.scenario.obstacle_set
    for i, (x0, x1, y0, y1) in enumerate(obstacles.rectangles):
        ax.add_patch(
            Rectangle(
                (x0, y0),
                x1 - x0,
                y1 - y0,
                color="0.55",
                alpha=0.8,
                lw=0,
                label="obstacle" if i == 0 else None,
            )
        )
    for i, (cx, cy, r) in enumerate(obstacles.circles):
        ax.add_patch(
            Circle(
                (cx, cy),
                r,
                color="0.55",
                alpha=0.8,
                lw=0,
                label="obstacle" if i == 0 and not len(obstacles.rectangles) else None,
            )
        )


def plot_mission_trajectories(
    result: MissionResult, run: int = 0, ax: Axes | None = None, steps: list[int] | None = None
) -> Figure:
    """Fig. 3: UAV trajectories, obstacles and formation snapshots (the shrink in a passage).

    Parameters
    ----------
    result : MissionResult
        Simulation result with trajectories (``keep_trajectories=True``).
    run : int, default 0
        Index of the run in the batch.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure is made if omitted.
    steps : list of int, optional
        Steps at which to draw the formation; by default :func:`mission_snapshot_steps`.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if result.positions is None:
        raise FieldError("result", "has no trajectories (simulated with keep_trajectories=False)")
    q = result.positions[_check_run(result, run)]
    if ax is None:
        # Size the figure to the scene's aspect ratio (a long chase is wide, not square).
        span = np.ptp(np.concatenate([q.reshape(-1, 2), result.target[run]]), axis=0) + 20.0
        height = float(np.clip(6.4 * span[1] / span[0], 3.2, 7.0)) + 0.8
        ax = Figure(
            figsize=(6.4 if height > 4.5 else 9.0, height), layout="constrained"
        ).add_subplot()
    fig = _figure_of(ax)
    _draw_obstacles(ax, result)
    leader = result.scenario.uavs.leader
    for m in range(q.shape[1]):
        ax.plot(
            q[:, m, 0],
            q[:, m, 1],
            lw=1.6 if m == leader else 0.8,
            color="C3" if m == leader else f"C{m % 10}" if m % 10 != 3 else "C9",
            alpha=0.9,
            label="leader" if m == leader else None,
        )
    for k in steps if steps is not None else mission_snapshot_steps(result, run):
        shape = q[k]
        ax.add_patch(Polygon(shape, closed=True, fill=False, ec="k", lw=1.0, ls="-"))
        ax.plot(shape[:, 0], shape[:, 1], "o", ms=3.5, color="k")
        ax.annotate(
            f"t = {result.time[k]:.0f} s\n$\\eta$ = {result.eta[run, k]:.2f}",
            shape.max(axis=0),
            fontsize=7,
            xytext=(3, 3),
            textcoords="offset points",
        )
    # F* over the target where it is at the end (the target may move).
    target_path = result.target[run]
    final_target = target_path[-1]
    slots = result.scenario.slots - np.asarray(result.scenario.target) + final_target
    ax.add_patch(
        Polygon(
            slots, closed=True, fill=False, ec="C3", ls="--", lw=1.0, label="F* (CRLB-optimal)"
        )
    )
    if np.ptp(target_path, axis=0).max() > 0:
        ax.plot(*target_path.T, color="C3", lw=1.0, ls=":", label="target path")
    if result.estimate is not None:
        ax.plot(*result.estimate[run].T, color="k", lw=0.8, ls="--", alpha=0.8,
                label="UAVs' estimate")  # fmt: skip
    ax.plot(*final_target, marker="*", ms=12, color="C3", ls="none", label="target")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(
        f"Formation evolution, scenario '{result.scenario.name}', seed {result.seeds[run]}"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return fig


def plot_mission_timeseries(
    result: MissionResult, run: int = 0, axes: Sequence[Axes] | None = None
) -> Figure:
    """Fig. 4: CRLB and control cost against time, with the bound and the passage shaded.

    A third panel shows the scaling factor eta and the smallest obstacle clearance.

    Parameters
    ----------
    result : MissionResult
        Simulation result.
    run : int, default 0
        Index of the run in the batch.
    axes : sequence of three matplotlib.axes.Axes, optional
        Axes for the CRLB, cost and eta panels; a new figure is made if omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the three panels.
    """
    b = _check_run(result, run)
    if axes is None:
        fig = Figure(figsize=(6.4, 7.0), layout="constrained")
        axes = fig.subplots(3, 1, sharex=True, height_ratios=(3, 3, 2))
    if len(axes) != 3:
        raise FieldError("axes", f"expected three axes, got {len(axes)}")
    ax_crlb, ax_cost, ax_eta = axes
    fig = _figure_of(ax_crlb)
    t = result.time
    ax_crlb.plot(t, result.crlb[b], color="C0", label="CRLB at the UAV positions")
    ax_crlb.axhline(
        result.bound,
        color="k",
        ls="--",
        lw=1.0,
        label=rf"bound $4/\sum_m w_m^*$ = {result.bound:.3g} m$^2$",
    )
    ax_crlb.set_yscale("log")
    ax_crlb.set_ylabel(r"CRLB (m$^2$)")
    ax_crlb.legend(fontsize=8)
    ax_cost.plot(t[:-1], result.cost[b], color="C1")
    ax_cost.set_yscale("log")
    ax_cost.set_ylabel(r"cost $\mathcal{L}_{tot}$, eq. (15)")
    ax_eta.plot(t, result.eta[b], color="C2", label=r"$\eta$")
    ax_eta.set_ylim(0.0, 1.05)
    ax_eta.set_ylabel(r"scaling $\eta$")
    ax_clear = ax_eta.twinx()
    clearance = np.minimum(result.clearance[b], 1e3)
    ax_clear.plot(t, clearance, color="0.4", lw=0.8, label="min clearance")
    ax_clear.axhline(result.scenario.control.safety_radius, color="0.4", ls=":", lw=0.8)
    ax_clear.set_ylabel("min clearance (m)")
    ax_eta.set_xlabel("time (s)")
    window = passage_interval(result, b)
    for axis in (ax_crlb, ax_cost, ax_eta):
        axis.grid(True, which="both", alpha=0.3)
        if window is not None:
            axis.axvspan(*window, color="0.85", zorder=0)
    ax_crlb.set_title(
        "CRLB and control cost over time"
        + (f" (shaded: passage, {window[0]:.0f}-{window[1]:.0f} s)" if window else "")
    )
    return fig


def plot_estimator_vs_altitude(
    sweep: EstimatorSweep, axes: Sequence[Axes] | None = None
) -> Figure:
    """MSE of the MLE (markers, 95 % intervals) beside each formation's CRLB (lines).

    The lower panel shows MSE / CRLB: 1 for an efficient estimator; above 1 where the
    likelihood is no longer locally Gaussian (low SNR, poor geometry); below 1 where the
    MLE is biased (the CRLB bounds unbiased estimators only).

    Parameters
    ----------
    sweep : EstimatorSweep
        Result of :func:`crlbswarm.estimator_vs_altitude`.
    axes : sequence of two matplotlib.axes.Axes, optional
        Axes for the two panels; a new figure is made if omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if axes is None:
        fig = Figure(figsize=(6.4, 7.2), layout="constrained")
        axes = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    if len(axes) != 2:
        raise FieldError("axes", f"expected two axes, got {len(axes)}")
    ax, ratio_ax = axes
    fig = _figure_of(ax)
    h = sweep.altitude
    cols = sweep.columns()
    for name in sweep.results:
        style = _STYLES.get(name, {})
        color = style.get("color")
        bound = cols[f"crlb_{name}_m2"]
        mse = cols[f"mse_{name}_m2"]
        err = np.abs(
            np.stack([mse - cols[f"mse_low_{name}_m2"], cols[f"mse_high_{name}_m2"] - mse])
        )
        label = FORMATION_LABELS.get(name, name)
        if name == "random_disc":
            label = "random in disc of radius 2r* (one draw)"
        ax.plot(h, bound, color=color, lw=1.2, label=f"{label}: CRLB")
        ax.errorbar(h, mse, yerr=err, fmt=style.get("marker", "o"), color=color, ms=4,
                    capsize=2, ls="none", label=f"{label}: MSE of the MLE")  # fmt: skip
        ratio_ax.errorbar(h, mse / bound, yerr=err / bound, fmt=style.get("marker", "o"),
                          color=color, ms=4, capsize=2, ls="-", lw=0.8)  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylabel(r"MSE or CRLB (m$^2$)")
    ax.set_title(f"MLE vs CRLB, {sweep.n_trials} trials per point")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    ratio_ax.axhline(1.0, color="k", ls="--", lw=1.0)
    ratio_ax.set_yscale("log")
    ratio_ax.set_ylabel("MSE / CRLB")
    ratio_ax.set_xlabel("flight altitude H (m)")
    ratio_ax.grid(True, which="both", alpha=0.3)
    return fig


def plot_estimation_timeseries(
    result: MissionResult, axes: Sequence[Axes] | None = None
) -> Figure:
    """Sensing in the loop over time: the UAVs' estimation error beside the bounds.

    Upper panel: RMS over the runs of the estimation error, with the square roots of the
    posterior CRLB (the bound for the fused estimate) and of the mean instantaneous CRLB
    (the bound for one snapshot of ranges). Lower panel: RMS distance from the formation
    centroid to the true target.

    Parameters
    ----------
    result : MissionResult
        Result of a scenario with ``estimation.enabled``.
    axes : sequence of two matplotlib.axes.Axes, optional
        Axes for the two panels; a new figure is made if omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    error, pcrb = result.estimation_error, result.pcrb
    if error is None or pcrb is None:
        raise FieldError("result", "has no estimates (simulate a scenario with estimation on)")
    if axes is None:
        fig = Figure(figsize=(6.4, 6.0), layout="constrained")
        axes = fig.subplots(2, 1, sharex=True)
    if len(axes) != 2:
        raise FieldError("axes", f"expected two axes, got {len(axes)}")
    ax, ax_c = axes
    fig = _figure_of(ax)
    t = result.time
    ax.plot(t, np.sqrt(np.mean(error**2, axis=0)), color="C0",
            label=f"RMS estimation error ({result.n_runs} runs)")  # fmt: skip
    ax.plot(t, np.sqrt(pcrb), color="k", ls="--", lw=1.0, label=r"$\sqrt{\mathrm{PCRB}}$")
    ax.plot(t, np.sqrt(result.crlb.mean(axis=0)), color="0.5", ls=":", lw=1.0,
            label=r"$\sqrt{\mathrm{CRLB}}$ of one snapshot")  # fmt: skip
    ax.set_yscale("log")
    ax.set_ylabel("position error (m)")
    ax.set_title(f"Sensing in the loop, scenario '{result.scenario.name}'")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax_c.plot(t, np.sqrt(np.mean(result.centroid_error**2, axis=0)), color="C2")
    ax_c.axhline(0.5, color="0.4", ls=":", lw=0.8)
    ax_c.set_yscale("log")
    ax_c.set_ylabel("centroid to true target (m, RMS)")
    ax_c.set_xlabel("time (s)")
    ax_c.grid(True, which="both", alpha=0.3)
    return fig
