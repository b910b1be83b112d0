"""The views of a result agree with it (issue 13's review): the name of the bound follows
the formation flown, a convergence time counts only for a converged run, user text in a
title is text, a scene without obstacles draws no clearance, and a damaged folder's bound
and stride are refused on reload."""

from __future__ import annotations

import copy
import dataclasses
import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from crlbswarm import BUILTIN_SCENARIOS, FieldError, Scenario, load_results, simulate
from crlbswarm.animation import _Scene
from crlbswarm.design import formation_labels
from crlbswarm.plots import plot_batch_metrics, plot_mission_timeseries, run_figures
from crlbswarm.replay import replay_data
from crlbswarm.report import report_data

#: A scenario name that Matplotlib would read as (invalid) math.
MATH_NAME = r"dollar $\nocmd{x}$ name"


@pytest.fixture(scope="module")
def constrained():
    """Two runs, 3 s, of a scene whose F* exceeds formation.max_radius (no obstacles): the
    constrained design is flown."""
    data = copy.deepcopy(BUILTIN_SCENARIOS["paper_safe"])
    data.update(name=MATH_NAME, obstacles=[])
    data["formation"].update(max_radius=10.0, starts=2)
    data["guidance"]["planner"] = False
    data["time"].update(duration=3.0, hold=1.0)
    return simulate(Scenario.from_dict(data), seeds=[0, 1])


def legend_texts(fig) -> list[str]:
    legends = [ax.get_legend() for ax in fig.axes] + list(fig.legends)
    return [t.get_text() for lg in legends if lg is not None for t in lg.get_texts()]


# -- the bound's name -------------------------------------------------------------------
def test_the_bound_is_named_after_the_formation_flown(constrained):
    assert constrained.scenario.formation_design.method == "constrained"
    words = formation_labels(constrained.scenario)
    assert words["formation"].startswith("constrained design")
    assert "constrained design" in words["bound"]
    figures = run_figures(constrained)
    assert words["formation"] in legend_texts(figures["trajectories"])
    assert not any("F* (CRLB-optimal)" in t for t in legend_texts(figures["trajectories"]))
    bound = [t for t in legend_texts(figures["timeseries"]) if t.startswith("bound")]
    assert bound == [f"{words['bound']} = {constrained.bound:.3g} m²"]
    assert "4/Σ" not in bound[0]
    group = replay_data(constrained)["groups"][0]
    assert (group["boundLabel"], group["formationLabel"]) == (words["bound"], words["formation"])
    scene = _Scene(constrained, 0, 20)
    assert scene.optimum.get_label() == words["formation"]


def test_the_three_kinds_of_bound_have_their_own_words():
    data = copy.deepcopy(BUILTIN_SCENARIOS["paper"])
    assert formation_labels(Scenario.from_dict(data)) == {
        "formation": "F* (CRLB-optimal)", "bound": "bound 4/Σw* (eq. 11)"}  # fmt: skip
    # One UAV much stronger than the two others together: 1/w_max + 1/(W - w_max).
    data.update(obstacles=[])
    data["uavs"]["count"] = 3
    data["radar"]["tx_power"] = [3.0, 0.05, 0.4]
    words = formation_labels(Scenario.from_dict(data))
    assert "one UAV dominates" in words["formation"]
    assert words["bound"].startswith("bound 1/w*max + 1/(Σw* − w*max)")


# -- user text in titles ----------------------------------------------------------------
def test_a_dollar_in_the_scenario_name_is_text(constrained, tmp_path):
    for fig in run_figures(constrained).values():
        FigureCanvasAgg(fig).draw()  # (math parsing would fail on \nocmd)
        titles = [ax.get_title() for ax in fig.axes] + [fig.get_suptitle()]
        assert any(MATH_NAME in t for t in titles) or fig.axes[0].get_title().startswith("CRLB")
    scene = _Scene(constrained, 1, 20)
    assert scene.frame(int(constrained.trajectory_steps[-1])).shape[2] == 3
    assert any(MATH_NAME in t.get_text() for t in scene.fig.texts)


# -- without obstacles: no clearance axis -----------------------------------------------
def test_the_time_series_of_a_scene_without_obstacles_have_no_clearance_axis(constrained):
    fig = plot_mission_timeseries(constrained)
    assert len(fig.axes) == 3  # (no twin axis for a clearance)
    texts = [t.get_text() for t in fig.axes[2].texts]
    assert any(t.startswith("no obstacles") for t in texts)
    assert not any("clearance" in ln.get_label() for ax in fig.axes for ln in ax.lines)


# -- convergence time: converged runs only ----------------------------------------------
@pytest.fixture(scope="module")
def settled(constrained):
    """Run 0 settled at once and collided; run 1 settled at once, no collision."""
    separation = constrained.separation.copy()
    separation[0] = 0.0
    return dataclasses.replace(
        constrained,
        crlb=np.full_like(constrained.crlb, constrained.bound),
        centroid_error=np.zeros_like(constrained.crlb),
        separation=separation,
    )


def test_the_views_count_a_convergence_time_for_converged_runs_only(settled):
    metrics = settled.metrics
    assert metrics["outcome"].tolist() == ["collision", "converged"]
    assert np.isfinite(metrics["convergence_time_s"]).all()  # (the column: settled or not)
    assert settled.summary()["converged_runs"] == settled.outcome_counts["converged"] == 1
    fig = plot_batch_metrics(settled)
    panel = fig.axes[2]
    assert panel.get_title() == "convergence time (1 of 2 converged)"
    assert sum(p.get_height() for p in panel.patches) == 1
    assert "converged runs" in panel.get_xlabel()
    shown = replay_data(settled)["groups"][0]["metrics"]["convergence_time_s"]
    assert shown == [None, 0.0]


def test_the_report_counts_a_convergence_time_for_converged_runs_only(tmp_path):
    """A campaign folder written here: of three runs, one collided after settling at 5 s."""
    (tmp_path / "spec.json").write_text(json.dumps({"spec": {"seeds": {"count": 3}}}))
    pq.write_table(pa.table({"variant": [0]}), tmp_path / "variants.parquet")
    part = tmp_path / "runs" / "variant=0"
    part.mkdir(parents=True)
    pq.write_table(pa.table({
        "seed": [0, 1, 2], "outcome": ["collision", "converged", "converged"],
        "final_crlb_ratio": [1.0, 1.0, 1.0], "convergence_time_s": [5.0, 40.0, 60.0],
        "min_clearance_m": [1.0, 2.0, 3.0], "min_separation_m": [0.0, 2.0, 2.0],
    }), part / "part-0-2.parquet")  # fmt: skip
    data = report_data(tmp_path)
    stats = data["variants"][0]["stats"]["convergence_time_s"]
    assert (stats["n"], stats["missing"], stats["median"], stats["min"]) == (2, 1, 50.0, 40.0)
    assert data["variants"][0]["rows"]["convergence_time_s"] == [None, 40.0, 60.0]
    meta = next(d for d in data["distributions"] if d["key"] == "convergence_time_s")
    assert "converged" in meta["label"]
    assert "collided" in meta["missing"]


# -- reload: the bound and the stride ---------------------------------------------------
@pytest.mark.parametrize(
    ("name", "value", "message"),
    [("bound", math.nan, "bound is nan"), ("bound", -1.0, "bound is -1.0"),
     ("bound", math.inf, "bound is inf"), ("trajectory_stride", 0, "trajectory_stride is 0"),
     ("trajectory_stride", -3, "trajectory_stride is -3")],
)  # fmt: skip
def test_a_saved_bound_or_stride_out_of_range_is_refused(constrained, tmp_path, name, value,
                                                          message):  # fmt: skip
    constrained.save(tmp_path / "run")
    npz = tmp_path / "run" / "trajectories.npz"
    with np.load(npz) as data:
        arrays = dict(data)
    arrays[name] = np.asarray(value)
    np.savez(npz, **arrays)
    with pytest.raises(FieldError, match=message) as info:
        load_results(tmp_path / "run")
    assert info.value.field == "folder"
