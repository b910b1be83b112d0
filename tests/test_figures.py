"""The figures of `crlbswarm figures` (crlbswarm.plots), read back from the drawn artists.

Checked independently of the drawing code: the passage is computed here from the obstacle
rectangles, the polygons' self-crossings with a segment-intersection test written here,
the units and legends from the axes' labels and legend texts, and the Fig. 2 benchmark at a
fixed geometry from formations rebuilt here.
"""

from __future__ import annotations

import copy
import itertools
import re

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.patches import Polygon

from crlbswarm import (
    BUILTIN_SCENARIOS,
    Scenario,
    crlb,
    crlb_bound,
    crlb_vs_altitude,
    estimator_vs_altitude,
    load_scenario,
    optimal_elevation_curve,
    random_disc_formations,
    simulate,
)
from crlbswarm.geometry import outline_order
from crlbswarm.plots import (
    SNAPSHOT_GID,
    mission_snapshot_steps,
    plot_crlb_vs_altitude,
    plot_estimation_timeseries,
    plot_estimator_vs_altitude,
    plot_mission_timeseries,
    plot_mission_trajectories,
    plot_optimal_elevation,
)

#: The unit that ends an axis label: "(...)" or "[...]", "(-)" for a dimensionless
#: quantity (at the end, so that "eq. (15)" inside a label does not count).
UNIT = re.compile(r"[(\[][^()\[\]]+[)\]]\s*$")


def gap_box(obstacles) -> tuple[float, float, float, float]:
    """The free rectangle between two axis-aligned rectangles that face each other across
    a gap (their extents overlap along one axis and are apart along the other):
    (x_min, x_max, y_min, y_max)."""
    (a, b) = sorted(obstacles, key=lambda r: (r[0], r[2]))
    x_lo, x_hi = max(a[0], b[0]), min(a[1], b[1])
    if x_lo < x_hi:  # one above the other
        low, high = sorted((a, b), key=lambda r: r[2])
        return x_lo, x_hi, low[3], high[2]
    y_lo, y_hi = max(a[2], b[2]), min(a[3], b[3])
    left, right = sorted((a, b), key=lambda r: r[0])
    return left[1], right[0], y_lo, y_hi


def mirrored_paper() -> Scenario:
    """The paper mission mirrored across y = x: the gap now runs from south to north."""
    data = copy.deepcopy(BUILTIN_SCENARIOS["paper"])
    data["target"] = data["target"][::-1]
    data["obstacles"] = [
        {"type": "rectangle", "x": o["y"], "y": o["x"]} for o in data["obstacles"]
    ]
    return Scenario.from_dict(data)


@pytest.fixture(scope="module")
def paper():
    return simulate(load_scenario("paper"), seed=0)


@pytest.fixture(scope="module")
def moving():
    """A short chase with sensing in the loop (two runs, 40 s)."""
    data = copy.deepcopy(BUILTIN_SCENARIOS["moving_target"])
    data["time"]["duration"] = 40.0
    return simulate(Scenario.from_dict(data), seeds=[0, 1])


@pytest.fixture(scope="module")
def all_figures(paper, moving):
    """Every figure function's figure, drawn once (small data, same code paths)."""
    sweep = crlb_vs_altitude([10.0, 50.0, 200.0], n_random=20)
    mc = estimator_vs_altitude([10.0, 3000.0], n_trials=20, seed=0)
    figures = {
        "fig2": plot_crlb_vs_altitude(sweep),
        "elevation": plot_optimal_elevation(optimal_elevation_curve()),
        "fig3": plot_mission_trajectories(paper),
        "fig4": plot_mission_timeseries(paper),
        "estimator": plot_estimator_vs_altitude(mc),
        "tracking": plot_estimation_timeseries(moving),
        "chase": plot_mission_trajectories(moving),
    }
    for name in ("fig3", "chase", "estimator"):  # (the tests of these read pixels)
        drawn(figures[name])
    return figures


def drawn(fig):
    """The figure after a real (Agg) draw: layout, limits and label boxes are final."""
    FigureCanvasAgg(fig).draw()
    return fig


def snapshots(fig):
    ax = fig.axes[0]
    polygons = [p for p in ax.patches if p.get_gid() == SNAPSHOT_GID]
    labels = [t for t in ax.texts if t.get_gid() == f"{SNAPSHOT_GID}-label"]
    return ax, polygons, labels


# -- Fig. 3: a snapshot inside the gap -------------------------------------------------------
@pytest.mark.parametrize("case", ["paper", "mirrored", "strided"])
def test_a_snapshot_falls_inside_the_gap(paper, case):
    """One snapshot step has the formation's centroid inside the free rectangle between
    the two obstacles (computed here from the rectangles), and the figure draws it (with
    positions kept every 10 steps only: at the nearest kept step)."""
    if case == "paper":
        result = paper
    elif case == "mirrored":
        result = simulate(mirrored_paper(), seed=0)
    else:
        result = simulate(load_scenario("paper"), seed=0, trajectory_stride=10)
    x0, x1, y0, y1 = gap_box(result.scenario.obstacle_set.rectangles)
    assert (x1 - x0) * (y1 - y0) > 0
    kept = list(result.trajectory_steps)
    steps = [min(kept, key=lambda k, s=s: abs(k - s)) for s in mission_snapshot_steps(result)]
    centroid = result.positions[0, [kept.index(k) for k in steps]].mean(axis=1)
    inside = (centroid[:, 0] > x0) & (centroid[:, 0] < x1)
    inside &= (centroid[:, 1] > y0) & (centroid[:, 1] < y1)
    assert inside.sum() == 1, (steps, centroid)
    assert result.eta[0, steps][inside][0] < 1.0  # shrunk there
    _, polygons, _ = snapshots(plot_mission_trajectories(result))
    assert len(polygons) == len(steps)
    centres = np.array([p.get_xy()[:-1].mean(axis=0) for p in polygons])
    np.testing.assert_allclose(centres, centroid, atol=1e-9)


# -- Fig. 3: polygons that do not cross themselves --------------------------------------------
def proper_crossings(vertices: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of non-adjacent edges of the closed polygon that intersect (touching
    included), by the orientation test."""

    def orient(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    def on_segment(p, q, r):  # r collinear with p-q: within its box?
        return min(p[0], q[0]) <= r[0] <= max(p[0], q[0]) and min(p[1], q[1]) <= r[1] <= max(
            p[1], q[1]
        )

    n = len(vertices)
    edges = [(vertices[i], vertices[(i + 1) % n]) for i in range(n)]
    out = []
    for i, j in itertools.combinations(range(n), 2):
        if j == i + 1 or (i == 0 and j == n - 1):
            continue  # adjacent edges share a vertex
        (p1, p2), (p3, p4) = edges[i], edges[j]
        o1, o2, o3, o4 = (
            orient(p1, p2, p3),
            orient(p1, p2, p4),
            orient(p3, p4, p1),
            orient(p3, p4, p2),
        )
        if (o1 * o2 < 0 and o3 * o4 < 0) or any(
            o == 0 and on_segment(a, b, c)
            for o, a, b, c in (
                (o1, p1, p2, p3),
                (o2, p1, p2, p4),
                (o3, p3, p4, p1),
                (o4, p3, p4, p2),
            )
        ):
            out.append((i, j))
    return out


def test_the_crossing_test_sees_a_bow_tie():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert proper_crossings(square) == []
    assert proper_crossings(square[[0, 2, 1, 3]]) != []


def test_snapshot_polygons_do_not_cross_themselves(paper, all_figures):
    """The paper's t = 0 snapshot in UAV-index order is a bow-tie; as drawn, no snapshot
    polygon (nor F*) crosses itself."""
    start = paper.positions[0, 0]
    assert proper_crossings(start) != []  # index order: the bow-tie of the issue
    for name in ("fig3", "chase"):
        ax, polygons, _ = snapshots(all_figures[name])
        assert polygons
        for patch in [p for p in ax.patches if isinstance(p, Polygon)]:
            assert proper_crossings(patch.get_xy()[:-1]) == []


@pytest.mark.parametrize("m", [3, 4, 6, 7, 12, 30])
def test_outline_order_never_crosses_for_any_layout(m):
    rng = np.random.default_rng(m)
    for layout in range(20):
        pts = rng.normal(size=(m, 2)) * rng.uniform(0.1, 100.0, size=2)
        if layout % 4 == 0:  # an arc, a cluster and a far outlier
            pts[: m // 2] = (
                50.0 * np.c_[np.cos(np.linspace(0, 2, m // 2)), np.sin(np.linspace(0, 2, m // 2))]
            )
            pts[-1] = (1e3, -5e2)
        order = outline_order(pts)
        assert sorted(order) == list(range(m))
        assert proper_crossings(pts[order]) == []


# -- Fig. 3: labels by their polygons, off the tracks -----------------------------------------
def test_snapshot_labels_sit_beside_their_polygon_off_the_tracks(paper, all_figures):
    fig = all_figures["fig3"]
    ax, polygons, labels = snapshots(fig)
    steps = mission_snapshot_steps(paper)
    assert len(labels) == len(polygons) == len(steps)
    renderer = fig.canvas.get_renderer()
    tracks = [ln for ln in ax.lines if ln.get_label().startswith("UAV")]
    assert len(tracks) == paper.scenario.uavs.count
    track_px = np.concatenate([ax.transData.transform(ln.get_xydata()) for ln in tracks])
    frame = ax.bbox
    pt = fig.dpi / 72.0
    for label, polygon, k in zip(labels, polygons, steps, strict=True):
        assert f"t = {paper.time[k]:.0f} s" in label.get_text()
        box = label.get_window_extent(renderer)
        inside = (track_px[:, 0] >= box.x0) & (track_px[:, 0] <= box.x1)
        inside &= (track_px[:, 1] >= box.y0) & (track_px[:, 1] <= box.y1)
        assert not inside.any(), label.get_text()
        assert frame.x0 <= box.x0
        assert box.x1 <= frame.x1
        assert frame.y0 <= box.y0
        assert box.y1 <= frame.y1
        poly = ax.transData.transform(polygon.get_xy())
        gap_x = max(poly[:, 0].min() - box.x1, box.x0 - poly[:, 0].max(), 0.0)
        gap_y = max(poly[:, 1].min() - box.y1, box.y0 - poly[:, 1].max(), 0.0)
        assert np.hypot(gap_x, gap_y) <= 40.0 * pt, label.get_text()  # beside it


def test_trajectory_figure_fills_its_canvas(all_figures):
    """No empty band: the axes (with the legend beside or below) span most of the figure
    in both directions, for the square paper scene and the long chase."""
    for name in ("fig3", "chase"):
        fig = all_figures[name]
        ax = fig.axes[0]
        box = ax.get_position()
        legend = fig.legends[0].get_window_extent().transformed(fig.transFigure.inverted())
        assert box.height + (legend.height if legend.y1 <= box.y0 else 0.0) > 0.72
        assert box.width + (legend.width if legend.x0 >= box.x1 else 0.0) > 0.8
        # the target's path is drawn above the tracks
        path = [ln for ln in ax.lines if ln.get_label() == "target path"]
        if name == "chase":
            assert path
            assert path[0].get_zorder() > max(
                ln.get_zorder() for ln in ax.lines if ln.get_label().startswith("UAV")
            )


# -- every figure: units on every axis, a legend for every labelled curve ---------------------


def legend_texts(fig) -> set[str]:
    legends = [ax.get_legend() for ax in fig.axes] + list(fig.legends)
    return {t.get_text() for lg in legends if lg is not None for t in lg.get_texts()}


@pytest.mark.parametrize(
    "name", ["fig2", "elevation", "fig3", "fig4", "estimator", "tracking", "chase"]
)
def test_every_axis_label_has_a_unit(all_figures, name):
    fig = all_figures[name]
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            shown = [t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            if not axis.get_visible() or not shown:
                continue  # a shared or hidden axis (its label is on the panel below)
            label = axis.get_label_text()
            assert UNIT.search(label), f"{name}: axis label {label!r} has no unit"


@pytest.mark.parametrize(
    "name", ["fig2", "elevation", "fig3", "fig4", "estimator", "tracking", "chase"]
)
def test_every_labelled_curve_is_in_a_legend(all_figures, name):
    """Every axes with labelled artists (twin axes included) has them in a legend of the
    figure; an axes with more than one has a legend on itself, its twin or the figure."""
    fig = all_figures[name]
    texts = legend_texts(fig)
    for ax in fig.axes:
        labels = set(ax.get_legend_handles_labels()[1])
        assert labels <= texts, f"{name}: {sorted(labels - texts)} not in any legend"
    assert texts or not any(ax.get_legend_handles_labels()[1] for ax in fig.axes)


def test_fig4_legend_covers_both_axes_and_the_dotted_line(all_figures, paper):
    fig = all_figures["fig4"]
    eta_ax = fig.axes[2]
    twin = [ax for ax in fig.axes if ax is not eta_ax and ax.bbox.bounds == eta_ax.bbox.bounds]
    assert len(twin) == 1
    clearance = [ln for ln in twin[0].lines if ln.get_linestyle() == "-"]
    np.testing.assert_array_equal(clearance[0].get_ydata(), paper.clearance[0])  # not clipped
    texts = legend_texts(fig)
    dotted = [ln for ln in twin[0].lines if ln.get_linestyle() == ":"]
    assert dotted
    assert all(ln.get_label() in texts for ln in dotted)
    assert all(ln.get_label() in texts for ln in eta_ax.lines)
    assert "m$^2$" in fig.axes[1].get_ylabel()  # the cost: squared distances (+ speeds)


def test_optimal_elevation_figure_shows_r_star(all_figures):
    """The README promises r*: a panel plots r* = H / tan(phi*) in metres."""
    curve = optimal_elevation_curve()
    expected = curve.altitude / np.tan(curve.elevation)
    lines = [
        ln
        for ax in all_figures["elevation"].axes
        for ln in ax.lines
        if ln.get_xydata().shape[0] == curve.altitude.shape[0]
        and np.allclose(ln.get_ydata(), expected, rtol=1e-12)
    ]
    assert len(lines) == 1
    assert "r^*" in lines[0].axes.get_ylabel()
    assert lines[0].axes.get_ylabel().endswith("(m)")


def test_estimator_figure_says_when_the_mse_is_below_the_crlb(all_figures):
    """At 3 km the 5 m polygon's MSE is far below its CRLB (a biased MLE): the figure says
    so in words (the title of the legend), and the legend is below the data panels."""
    fig = all_figures["estimator"]
    ratio_ax = fig.axes[1]
    notes = ratio_ax.get_legend().get_title().get_text()
    assert "biased" in notes
    assert "regular polygon" in notes
    legend = ratio_ax.get_legend().get_window_extent()
    for ax in fig.axes:
        assert legend.y1 <= ax.bbox.y0 + 1.0  # below every panel


# -- Fig. 2: the benchmark at a fixed geometry -------------------------------------------------
def test_fig2_has_a_fixed_geometry_benchmark_whose_gap_grows_with_altitude():
    altitudes = np.array([10.0, 20.0, 50.0, 100.0, 200.0])
    sweep = crlb_vs_altitude(altitudes, n_random=40, seed=2)
    assert "fixed_disc" in sweep.crlb
    assert "crlb_fixed_disc_m2" in sweep.columns()
    # The same 40 draws in a 10 m disc at every altitude (rebuilt here from the seed).
    draws = random_disc_formations(6, np.zeros(2), 10.0, 40, np.random.default_rng(2))
    assert np.all(np.hypot(draws[..., 0], draws[..., 1]) <= 10.0)
    per_draw = crlb(draws, np.zeros(2), altitudes[:, None])
    np.testing.assert_allclose(sweep.crlb["fixed_disc"], per_draw.mean(axis=-1), rtol=1e-12)
    gap = sweep.crlb["fixed_disc"] / crlb_bound(6, altitudes)
    assert np.all(gap > 1.0)
    assert np.all(np.diff(gap) > 0.0)
    assert gap[-1] > 50.0 * gap[0]
    flat = sweep.crlb["arc"] / sweep.bound  # scaled with r*: the same ratio
    np.testing.assert_allclose(flat, flat[0], rtol=1e-3)
    fig = plot_crlb_vs_altitude(sweep)
    assert any("fixed disc" in t for t in legend_texts(fig))
