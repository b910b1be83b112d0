"""The paper's figures, reproduced: :func:`reproduce` writes them with their data to a folder.

``crlbswarm figures --out DIR`` calls :func:`reproduce`. It writes Fig. 2 (CRLB against
altitude for :math:`F^*` and the benchmarks), the optimal elevation against altitude,
Figs. 3-4 (the paper mission's trajectories, CRLB and cost), and the figures beyond the
paper (the MLE's MSE against the CRLB, sensing in the loop, moving-target tracking), each
as an image and a CSV of the data behind it, plus ``manifest.json`` (crlbswarm version,
radar and benchmark parameters, seeds and summaries). Everything is computed before the
first file is written, so a failure leaves the folder untouched, and every file is written
atomically (:mod:`crlbswarm.output`).

Figs. 2-4 use the paper's scenario and laws as printed, with the corrections and the open
choices of ``docs/paper-defaults-and-errata.md`` (the leader's guidance and steering, the
eta rule); the estimator, sensing and tracking figures go beyond the paper.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from . import __version__, _validation as _v
from .errors import FieldError
from .output import check_output_folder, save_figure, staged_folder, write_csv, write_json

__all__ = ["FIGURE_FORMATS", "FIGURE_RUNS", "FIGURE_TRIALS", "reproduce"]

#: Monte Carlo trials per point of the estimator figure.
FIGURE_TRIALS = 2000

#: Runs of the sensing-in-the-loop and moving-target figures.
FIGURE_RUNS = 50

#: Image formats of the figures.
FIGURE_FORMATS = ("png", "pdf", "svg")

#: The file listing the figures; written last, its presence marks a complete folder.
MANIFEST = "manifest.json"


def reproduce(
    out_dir: str | os.PathLike[str],
    *,
    fmt: str = "png",
    n_uavs: int = 6,
    seed: int = 0,
    trials: int | None = None,
    runs: int | None = None,
    on_write: Callable[[Path], None] | None = None,
    overwrite: bool = False,
) -> list[Path]:
    """Write the paper's figures, and those beyond it, with their data, to ``out_dir``.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder: missing or empty (created if missing). The files are written in a
        hidden folder and moved into place at the end
        (:func:`crlbswarm.output.staged_folder`), ``manifest.json`` last: an interrupted
        run leaves a missing folder absent or complete.
    fmt : {"png", "pdf", "svg"}, default "png"
        Image format.
    n_uavs : int, default 6
        Number of UAVs of Fig. 2.
    seed : int, default 0
        Seed of the paper mission of Figs. 3-4 and of the Monte Carlo sweep, and the first
        of the seeds of the sensing figures.
    trials : int, optional
        Monte Carlo trials per point of the estimator figure (default
        :data:`FIGURE_TRIALS`).
    runs : int, optional
        Runs of the sensing and tracking figures, seeds ``seed .. seed + runs - 1``
        (default :data:`FIGURE_RUNS`).
    on_write : callable, optional
        Called with the path of each file once it is in place (for progress messages).
    overwrite : bool, default False
        Accept a folder that already holds files, replacing those of the same names.

    Returns
    -------
    list of pathlib.Path
        The files written, ``manifest.json`` last.

    Raises
    ------
    FieldError
        For an invalid argument (naming it) or an output folder that cannot be written
        (``out_dir``), before anything is computed or written.
    """
    if fmt not in FIGURE_FORMATS:
        raise FieldError("fmt", f"expected one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    n_trials = FIGURE_TRIALS if trials is None else _v.count(trials, "trials", 1)
    if runs is None:
        first, n_runs = _v.seed_range(seed, FIGURE_RUNS, "seed")
    else:
        first, n_runs = _v.seed_range(seed, runs, "seed", "runs")
    out = Path(out_dir)
    check_output_folder(out, "out_dir", new=True, overwrite=overwrite)
    figures, manifest = _compute(n_uavs, first, n_trials, n_runs)
    with staged_folder(out, "out_dir", overwrite=overwrite, marker=MANIFEST) as stage:
        for stem, (fig, columns) in figures.items():
            for path in (stage / f"{stem}.csv", stage / f"{stem}.{fmt}"):
                if path.suffix == ".csv":
                    write_csv(path, columns)
                else:
                    save_figure(fig, path)
                manifest["files"].append(path.name)
        write_json(stage / MANIFEST, manifest)
    written = [out / name for name in [*manifest["files"], MANIFEST]]
    if on_write is not None:
        for path in written:
            on_write(path)
    return written


def _compute(
    n_uavs: int, seed: int, trials: int, runs: int
) -> tuple[dict[str, tuple[Any, dict[str, Any]]], dict[str, Any]]:
    """Every figure (with the columns behind it) and the manifest, nothing written."""
    from .experiments import crlb_vs_altitude, optimal_elevation_curve
    from .montecarlo import estimator_vs_altitude
    from .plots import (
        plot_crlb_vs_altitude,
        plot_estimation_timeseries,
        plot_estimator_vs_altitude,
        plot_mission_timeseries,
        plot_mission_trajectories,
        plot_optimal_elevation,
    )
    from .radar import Radar
    from .scenario import load_scenario
    from .simulation import simulate

    sweep = crlb_vs_altitude(n_uavs=n_uavs)
    curve = optimal_elevation_curve()
    mission = simulate(load_scenario("paper"), seed=seed)
    mc = estimator_vs_altitude(n_trials=trials, seed=seed)
    seeds = range(seed, seed + runs)
    sensing = simulate(load_scenario("sensing"), seeds=seeds)
    moving = simulate(load_scenario("moving_target"), seeds=seeds)
    figures = {
        "fig2_crlb_vs_altitude": (plot_crlb_vs_altitude(sweep), sweep.columns()),
        "optimal_elevation": (plot_optimal_elevation(curve), curve.columns()),
        "fig3_formation_evolution": (
            plot_mission_trajectories(mission),
            mission.trajectory_columns(),
        ),
        "fig4_crlb_and_cost": (plot_mission_timeseries(mission), mission.timeseries_columns()),
        "estimator_mse_vs_crlb": (plot_estimator_vs_altitude(mc), mc.columns()),
        "sensing_in_the_loop": (plot_estimation_timeseries(sensing), sensing.estimation_columns()),
        "moving_target_tracking": (
            plot_estimation_timeseries(moving),
            moving.estimation_columns(),
        ),
        "moving_target_trajectories": (
            plot_mission_trajectories(moving),
            moving.trajectory_columns(),
        ),
    }
    manifest: dict[str, Any] = {
        "crlbswarm_version": __version__,
        "radar": Radar().to_dict(),
        "fig2_crlb_vs_altitude": {
            "what": "CRLB tr(J^-1) in m^2 vs altitude for F* and the benchmark formations",
            "n_uavs": sweep.n_uavs,
            "benchmark_parameters": sweep.parameters,
        },
        "optimal_elevation": {"what": "optimal elevation (deg) and radius (m) vs altitude"},
        "fig3_formation_evolution": {
            "what": "UAV trajectories and formation snapshots, built-in scenario 'paper'",
            "seed": seed,
        },
        "fig4_crlb_and_cost": {
            "what": "CRLB, bound, cost eq. (15), eta and clearance vs time, scenario 'paper'",
            "seed": seed,
            "metrics": {k: v[0].item() for k, v in mission.metrics.items()},
        },
        "estimator_mse_vs_crlb": {
            "what": "MSE of the MLE (95% CI) and CRLB vs altitude, F* and the benchmarks",
            "trials_per_point": trials,
            "seed": seed,
        },
        "sensing_in_the_loop": {
            "what": "RMS estimation error vs sqrt(PCRB) and sqrt(CRLB), scenario 'sensing'",
            "seeds": [seeds[0], seeds[-1]],
            "summary": sensing.summary(),
        },
        "moving_target_tracking": {
            "what": "tracking RMSE vs sqrt(PCRB), scenario 'moving_target'",
            "seeds": [seeds[0], seeds[-1]],
            "summary": moving.summary(),
        },
        "files": [],
    }
    return figures, manifest
