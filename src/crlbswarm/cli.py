"""Command-line interface: ``crlbswarm design | figures | scenario | simulate``.

Errors the user can cause (bad numbers, impossible parameters, an unwritable output folder)
are printed as one line ``crlbswarm: error: <argument>: <reason>`` on stderr, without a
traceback, and the command exits with status 2. Everything is computed before the first
file is written, and every file is written atomically (:mod:`crlbswarm.output`).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

import numpy as np

from . import __version__
from .design import crlb_bound, optimal_elevation, optimal_formation, optimal_radius
from .fisher import crlb
from .output import json_text
from .radar import Radar, db_to_linear, dbm_to_watts
from .simulation import MAX_SEED, SimulationDivergedError

__all__ = ["main"]

EXIT_USAGE = 2

#: Monte Carlo trials per point of the estimator figure, and runs of the sensing figures.
FIGURE_TRIALS = 2000
FIGURE_RUNS = 50


class UsageError(Exception):
    """An error the user can fix; printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr (no usage dump), exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _add_radar_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("radar (paper profile by default)")
    group.add_argument(
        "--power",
        type=float,
        default=0.1,
        metavar="W",
        help="transmit power per UAV p, W (default 0.1)",
    )
    group.add_argument(
        "--noise-dbm",
        type=float,
        default=-90.0,
        metavar="DBM",
        help="receiver noise power sigma0^2, dBm (default -90)",
    )
    group.add_argument(
        "--processing-gain-db",
        type=float,
        default=30.0,
        metavar="DB",
        help="processing gain G_p, dB (default 30)",
    )
    group.add_argument(
        "--rcs", type=float, default=1.0, metavar="M2", help="radar cross section, m^2 (default 1)"
    )
    group.add_argument(
        "--frequency",
        type=float,
        default=5.8e9,
        metavar="HZ",
        help="carrier frequency f_c, Hz (default 5.8e9)",
    )
    group.add_argument(
        "--kappa", type=float, default=1.0, help="range-estimation constant kappa (default 1)"
    )


def _radar_from_args(args: argparse.Namespace) -> Radar:
    return Radar(
        tx_power=args.power,
        noise_power=float(dbm_to_watts(args.noise_dbm)),
        processing_gain=float(db_to_linear(args.processing_gain_db)),
        rcs=args.rcs,
        carrier_frequency=args.frequency,
        kappa=args.kappa,
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``crlbswarm`` command."""
    parser = _Parser(
        prog="crlbswarm",
        description="CRLB-optimal UAV formations for cooperative range sensing "
        "(Wu et al., arXiv:2602.23990).",
    )
    parser.add_argument("--version", action="version", version=f"crlbswarm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    design = sub.add_parser(
        "design",
        help="print the CRLB-optimal formation F* for a scene",
        description="Closed-form CRLB-optimal formation (paper Sec. III): optimal elevation, "
        "radius, positions, CRLB and the bound 4/sum(w).",
    )
    design.add_argument("--uavs", type=int, default=6, help="number of UAVs M >= 3 (default 6)")
    design.add_argument(
        "--altitude",
        type=float,
        default=20.0,
        metavar="H",
        help="flight altitude H, m (default 20)",
    )
    design.add_argument(
        "--target",
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=("X", "Y"),
        help="target position, m (default 0 0)",
    )
    design.add_argument(
        "--rotation",
        type=float,
        default=0.0,
        metavar="DEG",
        help="azimuth of UAV 1 seen from the target, degrees (default 0)",
    )
    design.add_argument("--json", action="store_true", help="print JSON instead of a table")
    _add_radar_options(design)
    design.set_defaults(func=_cmd_design)

    figures = sub.add_parser(
        "figures",
        help="write the paper's figures and their data to a folder",
        description="Write Figs. 2-4 of the paper (CRLB vs altitude; the paper mission's "
        "trajectories, CRLB and cost), the optimal elevation vs altitude, the MLE's MSE vs "
        "the CRLB, sensing in the loop and moving-target tracking, with the data behind "
        "each figure as CSV.",
    )
    figures.add_argument(
        "--out", required=True, type=Path, metavar="DIR", help="output folder (created if missing)"
    )
    figures.add_argument(
        "--format", default="png", choices=("png", "pdf", "svg"), help="image format (default png)"
    )
    figures.add_argument(
        "--uavs", type=int, default=6, help="number of UAVs in Fig. 2 (default 6)"
    )
    figures.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the paper mission of Figs. 3-4, of the Monte Carlo sweep, and the first "
        "of the 50 seeds of the sensing figures (default 0)",
    )
    figures.set_defaults(func=_cmd_figures)

    scenario = sub.add_parser(
        "scenario",
        help="list the built-in scenarios or print one as TOML",
        description="Print a scenario as a TOML file to copy and edit (docs/scenarios.md).",
    )
    scenario_sub = scenario.add_subparsers(dest="action", required=True, metavar="ACTION")
    show = scenario_sub.add_parser("show", help="print a scenario (built-in or file) as TOML")
    show.add_argument(
        "scenario",
        metavar="SCENARIO",
        help="built-in name (paper, sensing, moving_target) or TOML file",
    )
    show.set_defaults(func=_cmd_scenario_show)
    listing = scenario_sub.add_parser("list", help="list the built-in scenarios")
    listing.set_defaults(func=_cmd_scenario_list)

    simulate = sub.add_parser(
        "simulate",
        help="run a mission for one seed or a batch of seeds",
        description="Simulate the distributed controller (paper Sec. IV) and write the "
        "trajectories (.npz), per-run metrics (CSV), a summary (JSON) and the scenario used.",
    )
    simulate.add_argument(
        "scenario",
        metavar="SCENARIO",
        help="built-in name (paper, sensing, moving_target) or TOML file",
    )
    simulate.add_argument("--seed", type=int, default=0, help="seed of the first run (default 0)")
    simulate.add_argument(
        "--runs", type=int, default=1, help="number of runs, seeds SEED..SEED+RUNS-1 (default 1)"
    )
    simulate.add_argument("--out", required=True, type=Path, metavar="DIR", help="output folder")
    simulate.add_argument(
        "--no-trajectories",
        action="store_true",
        help="do not keep positions and velocities (metrics and time series only)",
    )
    simulate.set_defaults(func=_cmd_simulate)

    sweep = sub.add_parser(
        "sweep",
        help="run a Monte Carlo campaign (variants x seeds) on Dask",
        description="Run or resume a campaign described by a TOML spec (docs/campaigns.md) on "
        "a local Dask cluster or an existing scheduler; one row of metrics per run in a "
        "Parquet dataset under DIR/runs. Re-running the same command resumes.",
    )
    sweep.add_argument("spec", metavar="SPEC", type=Path, help="campaign spec (TOML)")
    sweep.add_argument("--out", required=True, type=Path, metavar="DIR", help="output folder")
    sweep.add_argument(
        "--scheduler", metavar="ADDRESS", default=None,
        help="address of a running Dask scheduler (default: start a local cluster)",
    )  # fmt: skip
    sweep.add_argument(
        "--workers", type=int, default=None, help="workers of the local cluster (default: cores)"
    )
    sweep.set_defaults(func=_cmd_sweep)
    return parser


# -- design ------------------------------------------------------------------------------
def design_report(
    n_uavs: int, altitude: float, target_xy: Sequence[float], radar: Radar, rotation_deg: float
) -> dict:
    """The numbers printed by ``crlbswarm design``, as a JSON-ready dict.

    Keys: ``n_uavs``, ``altitude_m``, ``target_m`` ([x, y]), ``rotation_deg``,
    ``elevation_deg`` (phi*), ``radius_m`` (r*), ``positions_m`` (M x [x, y], UAV 1 first),
    ``crlb_m2`` (tr J^-1 of F*), ``bound_m2`` (4/sum w*), ``rmse_bound_m`` (sqrt of the
    CRLB), ``radar`` (the link parameters in linear SI units).
    """
    target = np.asarray(target_xy, dtype=float)
    positions = optimal_formation(n_uavs, target, altitude, radar, np.radians(rotation_deg))
    value = float(crlb(positions, target, altitude, radar))
    return {
        "n_uavs": n_uavs,
        "altitude_m": float(altitude),
        "target_m": target.tolist(),
        "rotation_deg": float(rotation_deg),
        "elevation_deg": float(np.degrees(optimal_elevation(altitude, radar))),
        "radius_m": float(optimal_radius(altitude, radar)),
        "positions_m": positions.tolist(),
        "crlb_m2": value,
        "bound_m2": float(crlb_bound(n_uavs, altitude, radar)),
        "rmse_bound_m": float(np.sqrt(value)),
        "radar": radar.to_dict(),
    }


def format_design(report: dict) -> str:
    """Render :func:`design_report` as a readable table."""
    x, y = report["target_m"]
    lines = [
        "CRLB-optimal formation F* (paper Sec. III)",
        f"  UAVs M               {report['n_uavs']}",
        f"  altitude H           {report['altitude_m']:g} m",
        f"  target s             ({x:g}, {y:g}) m",
        f"  optimal elevation    {report['elevation_deg']:.4f} deg",
        f"  radius r*            {report['radius_m']:.4f} m",
        f"  CRLB tr(J^-1)        {report['crlb_m2']:.6e} m^2"
        f"   (RMSE bound {100 * report['rmse_bound_m']:.3f} cm)",
        f"  bound 4/sum(w)       {report['bound_m2']:.6e} m^2   (eq. 11)",
        "  positions (m):",
        "     UAV           x           y",
    ]
    for i, (px, py) in enumerate(report["positions_m"], start=1):
        lines.append(f"    {i:4d}  {px:10.4f}  {py:10.4f}")
    return "\n".join(lines)


#: Library argument names and the CLI options that set them, for error messages.
_OPTION_NAMES = {
    "seeds": "--runs",
    "out": "--out",
    "n_uavs": "--uavs",
    "altitude": "--altitude",
    "target_xy": "--target",
    "rotation": "--rotation",
    "radar.tx_power": "--power",
    "radar.noise_power": "--noise-dbm",
    "radar.processing_gain": "--processing-gain-db",
    "radar.rcs": "--rcs",
    "radar.carrier_frequency": "--frequency",
    "radar.kappa": "--kappa",
}


def _as_option_error(exc: ValueError) -> UsageError:
    """Rename the library argument at the start of ``exc``'s message to its CLI option."""
    message = str(exc)
    name, sep, reason = message.partition(":")
    if sep and name in _OPTION_NAMES:
        message = f"{_OPTION_NAMES[name]}:{reason}"
    return UsageError(message)


def _cmd_design(args: argparse.Namespace) -> int:
    try:
        report = design_report(
            args.uavs, args.altitude, args.target, _radar_from_args(args), args.rotation
        )
    except ValueError as exc:
        raise _as_option_error(exc) from exc
    print(json_text(report) if args.json else format_design(report))
    return 0


# -- figures -----------------------------------------------------------------------------
def _check_out(out: Path) -> None:
    """Fail early, without creating anything, if ``out`` could not be created or written."""
    probe = out
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise UsageError(f"--out: {str(probe)!r} exists and is not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise UsageError(f"--out: cannot write in {str(probe)!r}")


def _make_out(out: Path) -> Path:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out: cannot create folder {str(out)!r}: {exc.strerror}") from exc
    return out


def _cmd_figures(args: argparse.Namespace) -> int:
    from .experiments import crlb_vs_altitude, optimal_elevation_curve
    from .montecarlo import estimator_vs_altitude
    from .output import save_figure, write_csv, write_json
    from .plots import (
        plot_crlb_vs_altitude,
        plot_estimation_timeseries,
        plot_estimator_vs_altitude,
        plot_mission_timeseries,
        plot_mission_trajectories,
        plot_optimal_elevation,
    )
    from .scenario import load_scenario
    from .simulation import simulate

    # Compute everything first: a failure leaves the output folder untouched.
    try:
        sweep = crlb_vs_altitude(n_uavs=args.uavs)
        _check_seed(args.seed)
        if args.seed + FIGURE_RUNS - 1 > MAX_SEED:
            raise UsageError(f"--seed: must be at most 2**63 - {FIGURE_RUNS}, got {args.seed}")
    except ValueError as exc:
        raise _as_option_error(exc) from exc
    curve = optimal_elevation_curve()
    mission = simulate(load_scenario("paper"), seed=args.seed)
    mc = estimator_vs_altitude(n_trials=FIGURE_TRIALS, seed=args.seed)
    seeds = range(args.seed, args.seed + FIGURE_RUNS)
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
        "sensing_in_the_loop": (
            plot_estimation_timeseries(sensing),
            sensing.estimation_columns(),
        ),
        "moving_target_tracking": (
            plot_estimation_timeseries(moving),
            moving.estimation_columns(),
        ),
        "moving_target_trajectories": (
            plot_mission_trajectories(moving),
            moving.trajectory_columns(),
        ),
    }
    manifest = {
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
            "seed": args.seed,
        },
        "fig4_crlb_and_cost": {
            "what": "CRLB, bound, cost eq. (15), eta and clearance vs time, scenario 'paper'",
            "seed": args.seed,
            "metrics": {k: v[0].item() for k, v in mission.metrics.items()},
        },
        "estimator_mse_vs_crlb": {
            "what": "MSE of the MLE (95% CI) and CRLB vs altitude, F* and the benchmarks",
            "trials_per_point": FIGURE_TRIALS,
            "seed": args.seed,
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
    out = _make_out(args.out)
    for stem, (fig, columns) in figures.items():
        for path in (out / f"{stem}.csv", out / f"{stem}.{args.format}"):
            if path.suffix == ".csv":
                write_csv(path, columns)
            else:
                save_figure(fig, path)
            manifest["files"].append(path.name)
            print(f"wrote {path}")
    write_json(out / "manifest.json", manifest)
    print(f"wrote {out / 'manifest.json'}")
    return 0


def _check_seed(seed: int) -> None:
    if seed < 0:
        raise UsageError(f"--seed: must be >= 0, got {seed}")


def _cmd_scenario_show(args: argparse.Namespace) -> int:
    from .scenario import load_scenario

    print(load_scenario(args.scenario).to_toml(), end="")
    return 0


def _cmd_scenario_list(args: argparse.Namespace) -> int:
    from .scenario import BUILTIN_SCENARIOS

    for name, data in sorted(BUILTIN_SCENARIOS.items()):
        print(f"{name:12s} {data.get('description', '')}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .output import atomic_path, write_csv, write_json, write_text
    from .scenario import load_scenario
    from .simulation import simulate

    # Validate everything before running anything; create the folder only after the run.
    scenario = load_scenario(args.scenario)
    _check_seed(args.seed)
    if args.seed > MAX_SEED:
        raise UsageError(f"--seed: must be below 2**63, got {args.seed}")
    if args.runs < 1:
        raise UsageError(f"--runs: must be >= 1, got {args.runs}")
    if args.seed + args.runs - 1 > MAX_SEED:
        raise UsageError(
            f"--runs: seeds must stay below 2**63, got up to {args.seed + args.runs - 1}"
        )
    _check_out(args.out)

    seeds = range(args.seed, args.seed + args.runs)
    with tqdm(total=args.runs, unit="run", disable=None, file=sys.stderr) as bar:
        try:
            result = simulate(
                scenario,
                seeds=seeds,
                keep_trajectories=not args.no_trajectories,
                progress=lambda done: bar.update(done - bar.n),
            )
        except ValueError as exc:
            raise _as_option_error(exc) from exc
    out = _make_out(args.out)
    arrays = {
        "time": result.time,
        "seeds": result.seeds,
        "centroid": result.centroid,
        "reference_velocity": result.reference_velocity,
        "eta": result.eta,
        "crlb": result.crlb,
        "cost": result.cost,
        "clearance": result.clearance,
        "separation": result.separation,
        "bound": np.array(result.bound),
        "target": result.target,
        "formation": scenario.formation,
    }
    if result.estimate is not None:
        arrays["estimate"] = result.estimate
        arrays["estimate_variance"] = result.estimate_variance
        arrays["pcrb"] = result.pcrb
    if result.positions is not None:
        arrays["positions"] = result.positions
        arrays["velocities"] = result.velocities
    # Each file is written atomically; summary.json comes last and marks a complete set.
    with atomic_path(out / "trajectories.npz") as tmp:
        np.savez(tmp, **arrays)
    write_csv(out / "metrics.csv", result.metrics)
    write_text(out / "scenario.toml", scenario.to_toml())
    summary = result.summary()
    summary["seeds"] = {"first": int(seeds[0]), "last": int(seeds[-1])}
    summary["crlbswarm_version"] = __version__
    write_json(out / "summary.json", summary)
    for name in ("trajectories.npz", "metrics.csv", "scenario.toml", "summary.json"):
        print(f"wrote {out / name}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .campaign import CampaignSpec, plan_tasks, run_campaign

    try:
        text = args.spec.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"SPEC: cannot read {str(args.spec)!r}: {exc}") from exc
    spec = CampaignSpec.from_toml(text, source=str(args.spec))
    if not Path(spec.base).is_absolute() and (args.spec.parent / spec.base).is_file():
        # A relative base scenario path is read relative to the spec file.
        spec = spec.model_copy(update={"base": str(args.spec.parent / spec.base)})
    plan_tasks(spec)  # every variant validated before anything runs or is written
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers: must be >= 1, got {args.workers}")
    _check_out(args.out)
    with tqdm(unit="task", disable=None, file=sys.stderr) as bar:

        def progress(done: int, total: int) -> None:
            if bar.total != total:  # first call: total known, finished tasks not timed
                bar.reset(total=total)
                bar.update(done)
                bar.refresh()
            else:
                bar.update(done - bar.n)

        try:
            counts = run_campaign(
                spec, args.out, scheduler=args.scheduler, n_workers=args.workers,
                spec_text=text, progress=progress,
            )  # fmt: skip
        except ValueError as exc:
            raise _as_option_error(exc) from exc
    print(
        f"{counts['tasks']} tasks over {counts['variants']} variants: ran {counts['ran']}, "
        f"skipped {counts['skipped']} already finished; results in {args.out / 'runs'}"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``crlbswarm`` console script.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; ``sys.argv[1:]`` if omitted.

    Returns
    -------
    int
        Exit status: 0 on success, 2 for an error the user can fix (printed as one line).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, UsageError, SimulationDivergedError) as exc:
        print(f"crlbswarm: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except RuntimeError as exc:  # a campaign task failed on a worker (CampaignError)
        print(f"crlbswarm: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("crlbswarm: interrupted (finished work is kept; re-run to resume)", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader (e.g. ``| head``) went away: not an error of ours; silence the flush.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        print(f"crlbswarm: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
