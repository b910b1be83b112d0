"""Figures of the paper, drawn from experiment results.

Every function takes a result object and an optional Matplotlib ``ax``, draws on it, and
returns the :class:`matplotlib.figure.Figure`. Nothing here calls ``plt.show()``, saves a
file or touches pyplot's global state: figures are built with the object-oriented API, so
they work on a machine without a display. Only the CLI saves files.

Every axis label carries its unit in parentheses, ``(-)`` for a dimensionless quantity,
and every axes with more than one labelled curve has a legend.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure, SubFigure
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Polygon, Rectangle
from matplotlib.patheffects import withStroke
from numpy.typing import ArrayLike

from .design import formation_labels
from .errors import FieldError
from .experiments import FORMATION_LABELS, AltitudeSweep, ElevationCurve
from .geometry import outline_order
from .montecarlo import EstimatorSweep
from .obstacles import Obstacles
from .results import CENTROID_TOL, MissionResult

__all__ = [
    "SNAPSHOT_GID",
    "draw_obstacles",
    "mission_snapshot_steps",
    "passage_interval",
    "plot_crlb_vs_altitude",
    "plot_estimation_timeseries",
    "plot_estimator_vs_altitude",
    "plot_mission_timeseries",
    "plot_mission_trajectories",
    "plot_optimal_elevation",
]

#: ``gid`` of the formation polygons that :func:`plot_mission_trajectories` draws at the
#: snapshot steps (their labels carry ``SNAPSHOT_GID + "-label"``), to find them again.
SNAPSHOT_GID = "formation-snapshot"

_STYLES: dict[str, dict[str, Any]] = {
    "optimal": {"color": "C3", "lw": 2.2, "marker": "o", "ms": 4},
    "fixed_polygon": {"color": "C0", "marker": "s", "ms": 3.5},
    "arc": {"color": "C2", "marker": "^", "ms": 3.5},
    "line": {"color": "C1", "marker": "v", "ms": 3.5},
    "random_disc": {"color": "C4", "marker": "D", "ms": 3},
    "fixed_disc": {"color": "C5", "marker": "P", "ms": 4},
}

#: Largest number of UAVs whose tracks get one legend entry each (beyond: "followers").
_MAX_TRACK_ENTRIES = 10


def _figure_of(ax: Axes) -> Figure:
    """The (root) figure holding ``ax``."""
    fig = ax.figure
    return fig.figure if isinstance(fig, SubFigure) else fig


def _formation_label(name: str, parameters: dict[str, float]) -> str:
    """Legend label of a Fig. 2 formation, with the sizes fixed in metres spelled out."""
    if name == "fixed_polygon" and "fixed_radius_m" in parameters:
        return f"regular polygon, fixed r = {parameters['fixed_radius_m']:g} m"
    if name == "fixed_disc" and "fixed_disc_radius_m" in parameters:
        return f"random in a fixed disc, r = {parameters['fixed_disc_radius_m']:g} m (mean)"
    return FORMATION_LABELS.get(name, name)


def plot_crlb_vs_altitude(
    sweep: AltitudeSweep, ax: Axes | None = None, ratio_ax: Axes | None = None
) -> Figure:
    """Fig. 2: CRLB against altitude for F* and every benchmark formation (log scale).

    With no axes given, the figure has two panels: the CRLB itself (as in the paper) and
    the CRLB divided by the bound 4/sum(w*), on which F* is the line 1 and every benchmark
    sits above it at every altitude. The benchmarks of a fixed size in metres
    (``fixed_polygon``, ``fixed_disc``) fall further behind F* as the altitude grows; those
    scaled with r* keep a constant ratio.

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
        fig = Figure(figsize=(6.4, 7.4), layout="constrained")
        ax, ratio_ax = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    fig = _figure_of(ax)
    h = sweep.altitude
    for name, values in sweep.crlb.items():
        label = _formation_label(name, sweep.parameters)
        style = _STYLES.get(name, {})
        sem = sweep.sem.get(name)
        for axis, scale in ((ax, 1.0), (ratio_ax, sweep.bound)):
            if axis is None:
                continue
            # (labelled once: the ratio panel shares the legend of the CRLB panel)
            axis.plot(h, values / scale, label=label if axis is ax else None, **style)
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
    ax.legend(fontsize=7, loc="lower right")
    last = ax
    if ratio_ax is not None:
        ratio_ax.axhline(1.0, color="k", ls="--", lw=1.0)
        ratio_ax.set_yscale("log")
        ratio_ax.set_ylabel("CRLB / bound (-)")
        ratio_ax.grid(True, which="both", alpha=0.3)
        last = ratio_ax
    last.set_xlabel("flight altitude H (m)")
    return fig


def plot_optimal_elevation(
    curve: ElevationCurve, ax: Axes | None = None, radius_ax: Axes | None = None
) -> Figure:
    """Optimal elevation and radius against altitude on a log axis, with their limits.

    The elevation tends to arctan(sqrt 2) = 54.74 deg as H -> 0 and to 45 deg as
    H -> infinity, so the radius r* = H / tan(phi*) tends to H / sqrt(2) and to H.

    Parameters
    ----------
    curve : ElevationCurve
        Result of :func:`crlbswarm.optimal_elevation_curve`.
    ax : matplotlib.axes.Axes, optional
        Axes for the elevation; if omitted a new two-panel figure (elevation, radius) is
        made.
    radius_ax : matplotlib.axes.Axes, optional
        Axes for the radius r*; drawn only if given or if ``ax`` is omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if ax is None:
        fig = Figure(figsize=(6.4, 6.4), layout="constrained")
        ax, radius_ax = fig.subplots(2, 1, sharex=True, height_ratios=(1, 1))
    fig = _figure_of(ax)
    h = curve.altitude
    ax.plot(h, np.degrees(curve.elevation), color="C3", lw=2, label=r"$\phi^*(H)$")
    upper = np.degrees(np.arctan(np.sqrt(2.0)))
    ax.axhline(
        upper, color="0.3", ls="--", lw=1, label=rf"$\arctan\sqrt{{2}}$ = {upper:.2f}° ($H \to 0$)"
    )
    ax.axhline(45.0, color="0.3", ls=":", lw=1, label=r"45° ($H \to \infty$)")
    ax.set_xscale("log")
    ax.set_ylabel(r"optimal elevation $\phi^*$ (deg)")
    ax.set_ylim(44.0, 56.0)
    ax.set_title(r"CRLB-optimal elevation angle $\phi^*$ and radius $r^*$")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    last = ax
    if radius_ax is not None:
        radius_ax.plot(h, curve.radius, color="C0", lw=2, label=r"$r^*(H) = H/\tan\phi^*$")
        radius_ax.plot(h, h / np.sqrt(2.0), color="0.3", ls="--", lw=1,
                       label=r"$H/\sqrt{2}$ ($H \to 0$)")  # fmt: skip
        radius_ax.plot(h, h, color="0.3", ls=":", lw=1, label=r"$H$ ($H \to \infty$)")
        radius_ax.set_xscale("log")
        radius_ax.set_yscale("log")
        radius_ax.set_ylabel(r"optimal radius $r^*$ (m)")
        radius_ax.grid(True, which="both", alpha=0.3)
        radius_ax.legend(fontsize=8, loc="upper left")
        last = radius_ax
    last.set_xlabel("flight altitude H (m)")
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


def _nearest_points(centres: np.ndarray, obstacles: Obstacles) -> np.ndarray:
    """Nearest point of every obstacle to each centre, shape (K, n_obstacles, 2) (the
    centre itself where it is inside an obstacle)."""
    c = centres[:, None, :]
    rects = obstacles.rectangles
    on_rect = np.stack(
        [
            np.clip(c[..., 0], rects[:, 0], rects[:, 1]),
            np.clip(c[..., 1], rects[:, 2], rects[:, 3]),
        ],
        axis=-1,
    )
    circles = obstacles.circles
    off = c - circles[:, :2]
    dist = np.hypot(off[..., 0], off[..., 1])
    scale = np.minimum(1.0, circles[:, 2] / np.maximum(dist, 1e-300))
    on_circle = circles[:, :2] + off * scale[..., None]
    return np.concatenate([on_rect, on_circle], axis=1)


def _passage_widths(centres: np.ndarray, obstacles: Obstacles, reach: float) -> np.ndarray:
    """Width of the passage between obstacles at each centre, shape (K,).

    The least ``d_i + d_j`` over pairs of obstacles whose nearest points lie on opposite
    sides of the centre (the vectors to them at more than 90 degrees), both nearer than
    ``reach``; ``inf`` where there is no such pair (the centre is not between obstacles).
    """
    width = np.full(centres.shape[0], np.inf)
    if obstacles.count < 2:
        return width
    for lo in range(0, centres.shape[0], 256):  # bounded memory for many obstacles
        off = _nearest_points(centres[lo : lo + 256], obstacles) - centres[lo : lo + 256, None]
        dist = np.hypot(off[..., 0], off[..., 1])
        close = (dist < reach) & (dist > 0.0)
        for i in np.flatnonzero(close.sum(axis=1) >= 2):
            o, d = off[i, close[i]], dist[i, close[i]]
            opposite = (o @ o.T) < 0.0
            if opposite.any():
                width[lo + i] = float(np.min((d[:, None] + d[None, :])[opposite]))
    return width


def _narrowest_passage(result: MissionResult, b: int) -> int | None:
    """The step at which the formation's centroid is in the narrowest passage between
    obstacles that is narrower than the full formation needs (its diameter plus twice the
    safety radius), the middle of the steps within 1 % of that width; None if there is
    none."""
    sc = result.scenario
    slots = np.asarray(sc.slots, dtype=float)
    radius = float(np.max(np.hypot(*(slots - slots.mean(axis=0)).T)))
    reach = 2.0 * (radius + sc.control.safety_radius)
    width = _passage_widths(result.centroid[b], sc.obstacle_set, reach)
    if not np.any(width < reach):
        return None
    narrow = np.flatnonzero(width <= 1.01 * width.min())
    return int(narrow[narrow.shape[0] // 2])


def mission_snapshot_steps(result: MissionResult, run: int = 0) -> list[int]:
    """Steps at which Fig. 3 draws the formation: start, in the passage, after it, end.

    Parameters
    ----------
    result : MissionResult
        Simulation result.
    run : int, default 0
        Index of the run in the batch.

    Returns
    -------
    list of int
        Sorted distinct step indices: 0; the step at which the formation's centroid is in
        the narrowest passage between two obstacles (the least sum of its distances to two
        obstacles on opposite sides of it, among passages narrower than the formation's
        diameter plus twice the safety radius; the middle of the steps within 1 % of it),
        or, with no such passage, the middle of the interval where eta is smallest; the
        first step after eta's smallest values where eta is back at 1; and the last step.
    """
    b = _check_run(result, run)
    eta = result.eta[b]
    last = eta.shape[0] - 1
    steps = {0, last}
    low = np.flatnonzero(eta <= eta.min() + 1e-12)
    passage = _narrowest_passage(result, b)
    if passage is not None:
        steps.add(passage)
    elif eta.min() < 1.0:
        steps.add(int(low[low.shape[0] // 2]))
    if eta.min() < 1.0:
        after = np.flatnonzero((np.arange(eta.shape[0]) > low[-1]) & (eta >= 1.0))
        if after.size:
            steps.add(int(after[0]))
    return sorted(steps)


def draw_obstacles(ax: Axes, obstacles: Obstacles) -> None:
    """Draw obstacles as grey patches (the first labelled "obstacle" for a legend).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Axes to draw on (data coordinates in metres).
    obstacles : Obstacles
        The obstacles (``scenario.obstacle_set``).
    """
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


def _track_style(m: int, leader: int, n_uavs: int, name: int) -> dict[str, Any]:
    """Colour, width and legend label of UAV m's track (leader red and thicker), the UAV
    called "UAV ``name + 1``" (``name``: its index in the swarm)."""
    if m == leader:
        return {"color": "C3", "lw": 1.6, "label": f"UAV {name + 1} (leader)", "zorder": 2.2}
    colour = f"C{m % 10}" if m % 10 != 3 else "C9"
    if n_uavs <= _MAX_TRACK_ENTRIES:
        label: str | None = f"UAV {name + 1}"
    else:
        label = "followers (colour per UAV)" if m == (1 if leader == 0 else 0) else None
    return {"color": colour, "lw": 0.8, "label": label, "zorder": 2.0}


def _scene_box(result: MissionResult, b: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corners of what Fig. 3 shows: the tracks, the target's
    path and F* around the target's final position, and the UAVs' estimate where it is not
    far off (within half the scene's size of it), with a margin, m."""
    assert result.positions is not None
    target = result.target[b]
    slots = result.scenario.slots - np.asarray(result.scenario.target) + target[-1]
    pts = np.concatenate([result.positions[b].reshape(-1, 2), target, slots])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    if result.estimate is not None:
        reach = 0.5 * float(np.max(hi - lo))
        est = result.estimate[b]
        est = est[np.all((est >= lo - reach) & (est <= hi + reach), axis=1)]
        if est.size:
            lo, hi = np.minimum(lo, est.min(axis=0)), np.maximum(hi, est.max(axis=0))
    pad = 0.04 * float(np.max(hi - lo)) + 2.0
    return lo - pad, hi + pad


def _trajectory_figure(lo: np.ndarray, hi: np.ndarray, entries: int) -> tuple[Axes, bool]:
    """A figure sized to the scene's aspect ratio (so that no band of it stays empty) and
    its axes; True if the legend (of about ``entries`` lines) goes below the axes (a wide
    scene), else to the right. Sizes in inches: title and x axis take about 0.9."""
    aspect = float((hi[1] - lo[1]) / (hi[0] - lo[0]))
    if aspect >= 0.5:
        width = min(5.2, 7.0 / aspect)
        size = (width + 2.4, width * aspect + 0.9)
    else:
        width = 9.0
        legend = 0.19 * -(-entries // 4) + 0.25
        size = (width + 0.8, max(width * aspect, 1.8) + 0.9 + legend)
    return Figure(figsize=size, layout="constrained").add_subplot(), aspect < 0.5


def _legend_entries(ax: Axes) -> tuple[list[Any], list[str]]:
    """Handles and labels of ``ax``, each label once (first occurrence)."""
    handles, labels = ax.get_legend_handles_labels()
    seen: dict[str, Any] = {}
    for handle, label in zip(handles, labels, strict=True):
        seen.setdefault(label, handle)
    return list(seen.values()), list(seen)


def plot_mission_trajectories(  # long: one figure, drawn layer by layer
    result: MissionResult,
    run: int = 0,
    ax: Axes | None = None,
    steps: list[int] | None = None,
    *,
    uavs: Sequence[int] | None = None,
) -> Figure:
    """Fig. 3: UAV trajectories, obstacles and formation snapshots (the shrink in a passage).

    The formation is drawn at the steps of :func:`mission_snapshot_steps` as a polygon
    joining the UAVs in :func:`~crlbswarm.geometry.outline_order` (never self-crossing),
    each labelled with its time and eta at a free place beside it (off the tracks). The
    legend names every track (one entry per UAV up to 10 UAVs; with ``uavs``, by their
    indices in the swarm) and the formation over the target (F*, or the constrained design
    flown when F* is blocked); a moving target's path is drawn above the tracks.

    Parameters
    ----------
    result : MissionResult
        Simulation result with trajectories (``keep_trajectories=True``).
    run : int, default 0
        Index of the run in the batch.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure, sized to the scene, is made if omitted.
    steps : list of int, optional
        Steps at which to draw the formation; by default :func:`mission_snapshot_steps`.
        Where positions were kept every few steps only (``trajectory_stride``), each is
        drawn at the nearest kept step.
    uavs : sequence of int, optional
        The UAVs' indices in the swarm, for their legend labels ("UAV i + 1"): a group's
        members (``plan.members[g]`` of a :class:`~crlbswarm.results.GroupMissionResult`)
        for group g of a mission with several targets; by default ``0 .. M-1``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.
    """
    if result.positions is None:
        raise FieldError("result", "has no trajectories (simulated with "
                         "keep_trajectories=False or --no-trajectories)")  # fmt: skip
    b = _check_run(result, run)
    q = result.positions[b]
    names = _uav_names(uavs, q.shape[1])
    lo, hi = _scene_box(result, b)
    own = ax is None
    legend_below = False
    if ax is None:
        entries = min(q.shape[1], _MAX_TRACK_ENTRIES + 1) + 6
        ax, legend_below = _trajectory_figure(lo, hi, entries)
    fig = _figure_of(ax)
    draw_obstacles(ax, result.scenario.obstacle_set)
    leader = result.scenario.uavs.leader
    for m in range(q.shape[1]):
        ax.plot(q[:, m, 0], q[:, m, 1], alpha=0.9,
                **_track_style(m, leader, q.shape[1], names[m]))  # fmt: skip
    shapes, texts = [], []
    kept = result.trajectory_steps  # the steps whose positions are kept (all by default)
    for i, step in enumerate(steps if steps is not None else mission_snapshot_steps(result, b)):
        row = int(np.argmin(np.abs(kept - step)))  # the nearest kept step
        k = int(kept[row])
        shape = q[row][outline_order(q[row])]
        label = None if i else "formation snapshot"
        ax.add_patch(Polygon(shape, closed=True, fill=False, ec="k", lw=1.0, zorder=3,
                             gid=SNAPSHOT_GID, label=label))  # fmt: skip
        ax.plot(shape[:, 0], shape[:, 1], "o", ms=3.5, color="k", zorder=3)
        shapes.append(shape)
        texts.append(f"t = {result.time[k]:.0f} s\n$\\eta$ = {result.eta[b, k]:.2f}")
    # F* over the target where it is at the end (the target may move).
    target_path = result.target[b]
    slots = result.scenario.slots - np.asarray(result.scenario.target) + target_path[-1]
    name = formation_labels(result.scenario)["formation"]  # (F*, or the constrained design)
    ax.add_patch(Polygon(slots[outline_order(slots)], closed=True, fill=False, ec="C3",
                         ls="--", lw=1.0, label=name))  # fmt: skip
    moving = bool(np.ptp(target_path, axis=0).max() > 0)
    if moving:
        ax.plot(*target_path.T, color="k", lw=1.4, zorder=4.5, label="target path",
                path_effects=[withStroke(linewidth=3.2, foreground="white")])  # fmt: skip
        ax.plot(*target_path[0], marker="*", ms=11, mfc="white", mec="C3", ls="none",
                zorder=5, label="target at t = 0")  # fmt: skip
    if result.estimate is not None:
        ax.plot(*result.estimate[b].T, color="C6", lw=1.0, ls="--", zorder=4,
                label="UAVs' estimate of the target")  # fmt: skip
    ax.plot(*target_path[-1], marker="*", ms=12, color="C3", ls="none", zorder=5,
            label=f"target at t = {result.time[-1]:.0f} s" if moving else "target")  # fmt: skip
    ax.set_xlim(lo[0], hi[0], auto=None)  # (auto=None: the aspect may widen them, quietly)
    ax.set_ylim(lo[1], hi[1], auto=None)
    # The data limits, not the box, stretch to equal scales: no empty band in the figure.
    ax.set_aspect("equal", adjustable="datalim" if own else "box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(
        f"Formation evolution, scenario '{result.scenario.name}', seed {result.seeds[b]}",
        parse_math=False,
    )  # (the name is the user's text: a "$" is a dollar)
    ax.grid(True, alpha=0.3)
    handles, labels = _legend_entries(ax)
    if not own:
        ax.legend(handles, labels, fontsize=7, loc="best")
    else:  # outside the axes, off the data (constrained layout makes room)
        if legend_below:
            fig.legend(handles, labels, fontsize=7, ncol=4, loc="outside lower center")
        else:
            fig.legend(handles, labels, fontsize=7, loc="outside right upper")
    _label_snapshots(ax, shapes, texts)
    return fig


def _uav_names(uavs: Sequence[int] | None, n_uavs: int) -> list[int]:
    """The UAVs' indices in the swarm (``0 .. n_uavs-1`` by default), checked."""
    if uavs is None:
        return list(range(n_uavs))
    names = [int(u) for u in np.asarray(uavs, dtype=np.int64).reshape(-1)]
    if len(names) != n_uavs:
        raise FieldError("uavs", f"expected {n_uavs} indices (one per UAV), got {len(names)}")
    return names


def _pixels(points: ArrayLike, ax: Axes, join: bool) -> np.ndarray:
    """Display coordinates of data points; with ``join``, also points every 2 pixels
    along the segments between them (at most 2000 per segment)."""
    px = ax.transData.transform(np.asarray(points, dtype=float).reshape(-1, 2))
    px = px[np.all(np.isfinite(px), axis=1)]
    if not join or px.shape[0] < 2:
        return px
    seg = np.diff(px, axis=0)
    n = np.clip(np.ceil(np.hypot(seg[:, 0], seg[:, 1]) / 2.0), 1, 2000).astype(int)
    idx = np.repeat(np.arange(seg.shape[0]), n)
    frac = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return np.vstack([px[idx] + seg[idx] * frac[:, None], px[-1:]])


def _drawn_pixels(ax: Axes) -> tuple[np.ndarray, list[Any]]:
    """What a label must not cover: points along every line and polygon outline of
    ``ax`` (display coordinates), and the display boxes of the other patches."""
    points = [np.empty((0, 2))]
    boxes = []
    for line in ax.lines:
        joined = line.get_linestyle() not in ("None", "none", "", " ")
        points.append(_pixels(line.get_xydata(), ax, joined))
    for patch in ax.patches:
        if isinstance(patch, Polygon):
            xy = patch.get_xy()
            points.append(_pixels(np.vstack([xy, xy[:1]]), ax, True))
        else:
            boxes.append(patch.get_window_extent())
    legend = ax.get_legend()
    if legend is not None:
        boxes.append(legend.get_window_extent())
    return np.concatenate(points), boxes


def _candidates(box: np.ndarray, w: float, h: float, gaps: Sequence[float]) -> np.ndarray:
    """Centres of a w x h label around a display box ``[x0, y0, x1, y1]``, nearest first:
    beside each side (centred and flush with either end), then at the corners."""
    x0, y0, x1, y1 = box
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    out = []
    for g in gaps:
        east, west = x1 + g + w / 2, x0 - g - w / 2
        north, south = y1 + g + h / 2, y0 - g - h / 2
        for x in (east, west):
            out += [(x, cy), (x, y1 - h / 2), (x, y0 + h / 2)]
        for y in (north, south):
            out += [(cx, y), (x0 + w / 2, y), (x1 - w / 2, y)]
        out += [(east, north), (west, north), (east, south), (west, south)]
    return np.array(out)


def _overlap(a: np.ndarray, b: np.ndarray) -> float:
    """Area of the intersection of two boxes ``[x0, y0, x1, y1]``."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0)


def _label_snapshots(ax: Axes, shapes: list[np.ndarray], texts: list[str]) -> None:
    """Label each snapshot polygon at the free place nearest to it.

    The layout is computed first (so that the data limits and the axes' box are final);
    each label then goes to the candidate place beside its polygon that covers the fewest
    points of the tracks and outlines, and no obstacle, legend, other label or the outside
    of the axes.
    """
    if not shapes:
        return
    fig = _figure_of(ax)
    fig.draw_without_rendering()
    avoid, boxes = _drawn_pixels(ax)
    frame = ax.bbox.extents
    pt = fig.dpi / 72.0
    taken: list[np.ndarray] = []
    for shape, text in zip(shapes, texts, strict=True):
        centre = shape.mean(axis=0)
        ann = ax.annotate(
            text,
            xy=centre,
            xytext=(0, 0),
            textcoords="offset points",
            ha="center",
            va="center",
            fontsize=7,
            zorder=6,
            gid=f"{SNAPSHOT_GID}-label",
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.75},
        )
        ann.set_in_layout(False)
        extent = ann.get_window_extent()
        w, h = extent.width + 4 * pt, extent.height + 4 * pt
        px = ax.transData.transform(shape)
        box = np.r_[px.min(axis=0), px.max(axis=0)]
        best, best_score = None, np.inf
        for rank, (x, y) in enumerate(_candidates(box, w, h, (3 * pt, 12 * pt, 30 * pt))):
            cand = np.array([x - w / 2, y - h / 2, x + w / 2, y + h / 2])
            inside = (avoid[:, 0] >= cand[0]) & (avoid[:, 0] <= cand[2])
            inside &= (avoid[:, 1] >= cand[1]) & (avoid[:, 1] <= cand[3])
            score = 100.0 * np.count_nonzero(inside) + 0.01 * rank
            score += sum(1e3 * _overlap(cand, np.asarray(o.extents)) / (w * h) for o in boxes)
            score += sum(1e5 * (_overlap(cand, t) > 0) for t in taken)
            if (
                cand[0] < frame[0]
                or cand[1] < frame[1]
                or cand[2] > frame[2]
                or cand[3] > frame[3]
            ):
                score += 1e6
            if score < best_score:
                best, best_score = cand, score
        assert best is not None
        taken.append(best)
        anchor = ax.transData.transform(centre)
        offset = 0.5 * (best[:2] + best[2:]) - anchor
        ann.xyann = (float(offset[0] / pt), float(offset[1] / pt))


def plot_mission_timeseries(  # long: three panels and their legends
    result: MissionResult, run: int = 0, axes: Sequence[Axes] | None = None
) -> Figure:
    """Fig. 4: CRLB and control cost against time, with the bound and the passage shaded.

    A third panel shows the scaling factor eta (left axis) and the smallest obstacle
    clearance with the safety radius (right axis), under one legend for both axes; without
    obstacles it has no clearance axis and says "no obstacles". The bound's label names
    what it is (:func:`crlbswarm.design.formation_labels`: eq. (11), the dominant-UAV
    optimum, or the CRLB of the constrained design flown when F* is blocked). The cost
    :math:`\\mathcal L_{tot}` of eq. (15) adds squared distances (m^2) and squared speeds
    (m^2/s^2), as printed in the paper; its axis says so.

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
        fig = Figure(figsize=(6.4, 7.2), layout="constrained")
        axes = fig.subplots(3, 1, sharex=True, height_ratios=(3, 3, 2))
    if len(axes) != 3:
        raise FieldError("axes", f"expected three axes, got {len(axes)}")
    ax_crlb, ax_cost, ax_eta = axes
    fig = _figure_of(ax_crlb)
    t = result.time
    window = passage_interval(result, b)
    l_safe = result.scenario.control.safety_radius
    for axis in (ax_crlb, ax_cost, ax_eta):
        axis.grid(True, which="both", alpha=0.3)
        if window is not None:
            label = f"passage (a UAV within {l_safe:g} m of an obstacle)"
            axis.axvspan(*window, color="0.85", zorder=0, lw=0,
                         label=label if axis is ax_crlb else None)  # fmt: skip
    ax_crlb.plot(t, result.crlb[b], color="C0", label="CRLB at the UAV positions")
    bound = formation_labels(result.scenario)["bound"]
    if result.bound_steps is None:
        ax_crlb.axhline(result.bound, color="k", ls="--", lw=1.0,
                        label=f"{bound} = {result.bound:.3g} m²")  # fmt: skip
    else:  # (faults: the bound of the formation flown, re-planned when UAVs are lost)
        ax_crlb.step(t, result.bound_steps, where="post", color="k", ls="--", lw=1.0,
                     label=f"its formation's bound ({result.bound:.3g} m² last)")  # fmt: skip
    ax_crlb.set_yscale("log")
    ax_crlb.set_ylabel(r"CRLB (m$^2$)")
    ax_crlb.legend(fontsize=8)
    ax_cost.plot(t[:-1], result.cost[b], color="C1")  # (one curve: its axis label names it)
    ax_cost.set_yscale("log")
    ax_cost.set_ylabel(r"cost $\mathcal{L}_{tot}$, eq. (15) (m$^2$ + m$^2$/s$^2$)")
    obstacles = result.scenario.obstacle_set.count > 0
    ax_eta.plot(t, result.eta[b], color="C2",
                label=r"scaling $\eta$" + (" (left axis)" if obstacles else ""))  # fmt: skip
    ax_eta.set_ylim(0.0, 1.05)
    ax_eta.set_ylabel(r"scaling $\eta$ (-)")
    ax_eta.set_xlabel("time (s)")
    handles, labels = _legend_entries(ax_eta)
    if obstacles:
        ax_clear = ax_eta.twinx()
        ax_clear.plot(t, result.clearance[b], color="0.4", lw=0.8,
                      label="min obstacle clearance (right axis)")  # fmt: skip
        ax_clear.axhline(l_safe, color="0.4", ls=":", lw=0.8, label=f"safety radius "
                         f"$l_{{safe}}$ = {l_safe:g} m (right axis)")  # fmt: skip
        ax_clear.set_ylabel("min clearance (m)")
        more, more_labels = _legend_entries(ax_clear)
        ax_clear.legend(handles + more, labels + more_labels, fontsize=7, loc="center right")
    else:  # (no clearance to draw: it is infinite at every step)
        ax_eta.text(0.99, 0.04, "no obstacles: no clearance", transform=ax_eta.transAxes,
                    ha="right", va="bottom", fontsize=7, color="0.3")  # fmt: skip
        ax_eta.legend(handles, labels, fontsize=7, loc="center right")
    ax_crlb.set_title(
        "CRLB and control cost over time"
        + (f" (shaded: passage, {window[0]:.0f}-{window[1]:.0f} s)" if window else "")
    )
    return fig


def _altitude_list(h: np.ndarray, idx: np.ndarray) -> str:
    """The altitudes ``h[idx]`` in words: "H >= x m" for a run to the last, else a list."""
    if idx[-1] == h.shape[0] - 1 and np.all(np.diff(idx) == 1) and idx.shape[0] > 1:
        return f"H ≥ {h[idx[0]]:.0f} m"
    return "H = " + ", ".join(f"{x:.0f}" for x in h[idx]) + " m"


def plot_estimator_vs_altitude(  # long: two panels, a legend and the bias note
    sweep: EstimatorSweep, axes: Sequence[Axes] | None = None
) -> Figure:
    """MSE of the MLE (markers, 95 % intervals) beside each formation's CRLB (lines).

    The lower panel shows MSE / CRLB: 1 for an efficient estimator; above 1 where the
    likelihood is no longer locally Gaussian (low SNR, poor geometry); below 1 where the
    MLE is biased (the CRLB bounds unbiased estimators only). The legend sits below the
    panels, off the data; its title says so whenever a formation's whole 95 % interval lies
    below the CRLB, naming the formations and altitudes (and those within 20 % of it).

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
        fig = Figure(figsize=(6.4, 8.4), layout="constrained")
        axes = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    if len(axes) != 2:
        raise FieldError("axes", f"expected two axes, got {len(axes)}")
    ax, ratio_ax = axes
    fig = _figure_of(ax)
    h = sweep.altitude
    cols = sweep.columns()
    handles: list[Any] = []
    labels: list[str] = []
    below: list[str] = []  # formations whose MSE's 95 % interval lies below the CRLB
    for name in sweep.results:
        style = _STYLES.get(name, {})
        color, marker = style.get("color"), style.get("marker", "o")
        bound = cols[f"crlb_{name}_m2"]
        mse = cols[f"mse_{name}_m2"]
        err = np.abs(
            np.stack([mse - cols[f"mse_low_{name}_m2"], cols[f"mse_high_{name}_m2"] - mse])
        )
        label = FORMATION_LABELS.get(name, name).replace("(mean)", "(one draw)")
        (line,) = ax.plot(h, bound, color=color, lw=1.2, label=label)
        bars = ax.errorbar(h, mse, yerr=err, fmt=marker, color=color, ms=4, capsize=2, ls="none")
        ratio_ax.errorbar(h, mse / bound, yerr=err / bound, fmt=marker, color=color, ms=4,
                          capsize=2, ls="-", lw=0.8)  # fmt: skip
        handles.append((line, bars))
        labels.append(label)
        short = label.split(",")[0].split(" (")[0]
        low = cols[f"mse_high_{name}_m2"] < bound
        if low.any():
            slight = low & (mse >= 0.8 * bound)
            below.append(
                f"{short}: {_altitude_list(h, np.flatnonzero(low))}"
                + (
                    f" (by < 20 % at {_altitude_list(h, np.flatnonzero(slight))})"
                    if slight.any()
                    else ""
                )
            )
    handles += [
        Line2D([], [], color="0.3", lw=1.2),
        Line2D([], [], color="0.3", marker="o", ls="none"),
    ]
    labels += ["line: CRLB of the formation", "markers: MSE of the MLE (95 % interval)"]
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylabel(r"MSE or CRLB (m$^2$)")
    ax.set_title(f"MLE vs CRLB, {sweep.n_trials} trials per point")
    ax.grid(True, which="both", alpha=0.3)
    ratio_ax.axhline(1.0, color="k", ls="--", lw=1.0)
    ratio_ax.set_yscale("log")
    ratio_ax.set_ylabel("MSE / CRLB (-)")
    ratio_ax.set_xlabel("flight altitude H (m)")
    ratio_ax.grid(True, which="both", alpha=0.3)
    note = None
    if below:  # the legend's title: off the data whatever the data
        note = "\n".join(
            [
                "Below 1 the MSE beats the CRLB, which only a biased estimator can do (the CRLB",
                "bounds unbiased ones): the MLE is biased where the ranges hardly change as the",
                "target moves (docs/estimation.md, Sec. 4.5). 95 % interval below 1:",
                *below,
            ]
        )
    ratio_ax.legend(handles, labels, handler_map={tuple: HandlerTuple(ndivide=1)}, fontsize=7,
                    ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.24), borderaxespad=0.0,
                    title=note, title_fontsize=7, alignment="left")  # fmt: skip
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
    ax.set_title(f"Sensing in the loop, scenario '{result.scenario.name}'", parse_math=False)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax_c.plot(t, np.sqrt(np.mean(result.centroid_error**2, axis=0)), color="C2",
              label="RMS distance, formation centroid to true target")  # fmt: skip
    ax_c.axhline(CENTROID_TOL, color="0.4", ls=":", lw=0.8,
                 label=f"convergence tolerance, {CENTROID_TOL:g} m")  # fmt: skip
    ax_c.set_yscale("log")
    ax_c.set_ylabel("centroid to true target (m)")
    ax_c.legend(fontsize=8)
    ax_c.set_xlabel("time (s)")
    ax_c.grid(True, which="both", alpha=0.3)
    return fig


# -- any run of a saved result (``crlbswarm plot``) ------------------------------------------
__all__ += ["RUN_FIGURES", "plot_batch_metrics", "run_figure_names", "run_figures"]


def _finite_hist(
    ax: Axes,
    values: np.ndarray,
    xlabel: str,
    empty: str,
    color: str = "C0",
    marks: Sequence[float] = (),
) -> np.ndarray:
    """A histogram of the finite ``values`` (runs), or the text ``empty`` if there are none;
    its bins span the values and the reference values ``marks`` (drawn by the caller)."""
    from matplotlib.ticker import MaxNLocator

    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size:
        bins = int(np.clip(2 * np.sqrt(finite.size), 8, 40))
        # Values (nearly) all equal: bins at least 2 % of their size wide, so bars show.
        span = np.concatenate([finite, np.asarray(marks, dtype=float)])
        low, high = float(span.min()), float(span.max())
        pad = max(0.0, 0.02 * max(abs(low), abs(high), 1e-9) - (high - low)) / 2
        ax.hist(finite, bins=bins, range=(low - pad, high + pad), color=color, alpha=0.85,
                edgecolor="white", lw=0.5)  # fmt: skip
    else:
        ax.text(0.5, 0.5, empty, transform=ax.transAxes, ha="center", va="center", fontsize=9)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("runs (count)")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(True, alpha=0.3)
    return finite


def plot_batch_metrics(result: MissionResult, axes: Sequence[Axes] | None = None) -> Figure:
    """Distributions of the per-run metrics of a batch (``result.metrics``).

    Six panels: the count of each outcome (:data:`crlbswarm.results.OUTCOMES`), and
    histograms over the runs of the final CRLB / bound (with the convergence tolerance
    :data:`crlbswarm.results.CRLB_TOL`), the convergence time of the runs whose outcome is
    ``converged`` (a run that collided has none here, even if its CRLB settled), the
    smallest obstacle clearance (with the safety radius), the smallest separation between
    two UAVs (with ``safety.min_separation``), and the final distance from the centroid to
    its place over the target (or, with estimation, the final estimation error).

    Parameters
    ----------
    result : MissionResult
        Simulation result (one run or more).
    axes : sequence of six matplotlib.axes.Axes, optional
        Axes for the six panels, in the order above; a new figure is made if omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the panels.
    """
    from matplotlib.ticker import MaxNLocator

    from .results import CRLB_TOL, OUTCOMES

    if axes is None:
        fig = Figure(figsize=(10.0, 6.4), layout="constrained")
        axes = list(fig.subplots(2, 3).ravel())
    if len(axes) != 6:
        raise FieldError("axes", f"expected six axes, got {len(axes)}")
    fig = _figure_of(axes[0])
    m, sc, n = result.metrics, result.scenario, result.n_runs
    counts = result.outcome_counts
    ax = axes[0]
    bars = ax.bar(OUTCOMES, [counts.get(k, 0) for k in OUTCOMES],
                  color=["C3", "C2", "C1", "C7"])  # fmt: skip
    ax.bar_label(bars, fontsize=8)
    ax.set_xlabel("outcome")
    ax.set_ylabel("runs (count)")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.tick_params(axis="x", labelsize=8)
    ax.set_ylim(0, max(counts.values()) * 1.15 + 0.5)
    ax.set_title("outcomes", fontsize=9)
    ax = axes[1]
    _finite_hist(ax, m["final_crlb_ratio"], "final CRLB / bound (ratio, 1 = optimum)", "-",
                 marks=[1.0 + CRLB_TOL])  # fmt: skip
    ax.axvline(1.0 + CRLB_TOL, color="k", ls="--", lw=0.8, label=f"1 + {CRLB_TOL:g} (converged)")
    ax.legend(fontsize=7)
    ax.set_title("final CRLB relative to the bound", fontsize=9)
    ax = axes[2]
    converged = m["outcome"] == "converged"  # (a collided run may have settled all the same)
    conv = np.where(converged, m["convergence_time_s"], np.nan)
    _finite_hist(ax, conv, "convergence time, converged runs (s)", "no run converged")
    ax.set_title(f"convergence time ({np.count_nonzero(converged)} of {n} converged)",
                 fontsize=9)  # fmt: skip
    ax = axes[3]
    _finite_hist(ax, m["min_clearance_m"], "smallest clearance to an obstacle (m)",
                 "no obstacles", color="C5", marks=[0.0, sc.control.safety_radius])  # fmt: skip
    if np.isfinite(m["min_clearance_m"]).any():
        ax.axvline(sc.control.safety_radius, color="k", ls="--", lw=0.8,
                   label=f"safety radius {sc.control.safety_radius:g} m")  # fmt: skip
        ax.axvline(0.0, color="C3", lw=0.8, label="obstacle boundary")
        ax.legend(fontsize=7)
    ax.set_title("smallest clearance", fontsize=9)
    ax = axes[4]
    limit = sc.safety.min_separation
    _finite_hist(ax, m["min_separation_m"], "smallest separation between UAVs (m)", "-",
                 color="C4", marks=[limit])  # fmt: skip
    ax.axvline(limit, color="C3", ls="--", lw=0.8, label=f"{limit:g} m: collision below")
    ax.legend(fontsize=7)
    ax.set_title("smallest separation", fontsize=9)
    ax = axes[5]
    if "final_estimation_error_m" in m:
        _finite_hist(ax, m["final_estimation_error_m"], "final estimation error (m)", "-",
                     color="C9")  # fmt: skip
        ax.set_title("final error of the UAVs' estimate", fontsize=9)
    else:
        _finite_hist(ax, m["final_centroid_error_m"], "final centroid error (m)", "-",
                     color="C9")  # fmt: skip
        ax.set_title("final centroid error", fontsize=9)
    seeds = f"seed {result.seeds[0]}" if n == 1 else f"seeds {result.seeds[0]}..{result.seeds[-1]}"
    fig.suptitle(f"Metrics of {n} run{'s' * (n != 1)} of scenario '{sc.name}' ({seeds})",
                 parse_math=False)  # fmt: skip
    return fig


#: The figures of :func:`run_figures`, in order: name and what it shows.
RUN_FIGURES = {
    "trajectories": "Fig. 3 of the run: trajectories, obstacles, formation snapshots",
    "timeseries": "Fig. 4 of the run: CRLB and bound, cost, eta and clearance over time",
    "estimation": "with estimation: RMS estimation error over the runs and the PCRB",
    "metrics": "with two runs or more: distributions of the per-run metrics",
}


def run_figures(
    result: MissionResult, run: int = 0, *, uavs: Sequence[int] | None = None
) -> dict[str, Figure]:
    """The figures of one run of a result, and of its batch: what ``crlbswarm plot`` writes.

    Parameters
    ----------
    result : MissionResult
        Simulation result (for example :func:`crlbswarm.load_results` of a ``simulate``
        folder, or one group of a mission with several targets).
    run : int, default 0
        Index of the run in the batch.
    uavs : sequence of int, optional
        The UAVs' indices in the swarm, for the trajectories' legend (a group's members);
        by default ``0 .. M-1``.

    Returns
    -------
    dict of str to matplotlib.figure.Figure
        By name (:data:`RUN_FIGURES`, in that order): ``trajectories``
        (:func:`plot_mission_trajectories`; only if the trajectories were kept),
        ``timeseries``
        (:func:`plot_mission_timeseries`), ``estimation``
        (:func:`plot_estimation_timeseries`; only with estimation) and ``metrics``
        (:func:`plot_batch_metrics`; only for two runs or more).
    """
    b = result.run_index(run)
    draw = {
        "trajectories": lambda: plot_mission_trajectories(result, b, uavs=uavs),
        "timeseries": lambda: plot_mission_timeseries(result, b),
        "estimation": lambda: plot_estimation_timeseries(result),
        "metrics": lambda: plot_batch_metrics(result),
    }
    return {name: draw[name]() for name in run_figure_names(result)}


def run_figure_names(result: MissionResult) -> list[str]:
    """The names of the figures :func:`run_figures` draws for ``result``.

    Parameters
    ----------
    result : MissionResult
        Simulation result.

    Returns
    -------
    list of str
        Names of :data:`RUN_FIGURES`, in order: ``trajectories`` if the trajectories were
        kept, ``timeseries``, ``estimation`` with estimation, ``metrics`` for two runs or
        more.
    """
    kept = {
        "trajectories": result.positions is not None,
        "timeseries": True,
        "estimation": result.estimate is not None,
        "metrics": result.n_runs > 1,
    }
    return [name for name in RUN_FIGURES if kept[name]]
