"""Command-line interface: ``crlbswarm COMMAND`` (animate, design, figures, fly, plot,
replay, report, scenario, simulate, sweep).

The CLI only parses, calls the library and prints. Errors the user can cause (bad numbers,
impossible parameters, an unwritable output folder) are :class:`~crlbswarm.errors.FieldError`
from the library; each carries the library's name of the offending argument, which the CLI
maps to its option (``n_uavs`` to ``--uavs``), and prints as one line
``crlbswarm: error: <option>: <reason>`` on stderr, without a traceback, with exit status 2.
Everything is validated before the first file is written, and every file is written
atomically (:mod:`crlbswarm.output`). Nothing heavy is imported before it is needed, so
``--help``, ``--version`` and input errors print at once.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from . import __version__
from ._validation import MIN_UAVS
from .errors import CampaignError, ConfigError, FieldError, SimulationDivergedError, one_line
from .paper import FIGURE_FORMATS, FIGURE_RUNS
from .radar import Radar, radar_parameters

__all__ = ["build_parser", "format_allocation", "format_constrained", "format_design", "main"]

EXIT_USAGE = 2

#: Results larger than this (bytes) are announced before a run starts.
LARGE_OUTPUT = 10**9

#: Help text of a SCENARIO argument.
_BUILTIN_HELP = "built-in name (see `crlbswarm scenario list`) or TOML file"


def _path(text: str) -> Path:
    """A path argument; an empty one (which would silently mean the working folder) is
    refused."""
    if not text:
        raise argparse.ArgumentTypeError("empty path")
    return Path(text)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr (no usage dump), exit 2."""

    def error(self, message: str) -> NoReturn:
        if "arguments are required" in message:  # e.g. no command: say how to call it
            usage = " ".join(self.format_usage().split())
            message = f"{message} ({usage}; see --help)"
        self.exit(EXIT_USAGE, f"crlbswarm: error: {one_line(message, 1000)}\n")


def _option(target: Any, fields: dict[str, str], *flags: str, field: str, **kwargs: Any) -> None:
    """Add the option ``flags`` to ``target`` (a parser or a group of it) and record in
    ``fields`` that it sets the library argument ``field`` (for error messages)."""
    target.add_argument(*flags, **kwargs)
    fields[field] = "/".join(flags)  # as argparse names an option with aliases


def _add_radar_options(parser: argparse.ArgumentParser, fields: dict[str, str]) -> None:
    """One option per field of :class:`crlbswarm.Radar` in linear units, and one for its
    decibel form where it has one (mutually exclusive), all derived from its declaration."""
    group = parser.add_argument_group("radar (paper profile by default)")
    for p in radar_parameters():
        alternatives = group.add_mutually_exclusive_group()
        dashed = p.name.replace("_", "-")
        flags = [f"--{dashed}"] + ([f"--{p.short}"] if p.short else [])
        unit = p.unit or "linear"
        _option(
            alternatives,
            fields,
            *flags,
            field=f"radar.{p.name}",
            dest=p.name,
            type=float,
            nargs="+",
            metavar=(p.unit or "X").upper().replace("^", ""),
            help=f"{p.label}, {unit}; one value, or one per UAV (default {p.default:g})",
        )
        if p.db_unit:
            db_flags = [f"--{p.db_name.replace('_', '-')}"]
            if p.short:
                db_flags.append(f"--{p.short}-{p.db_unit.lower()}")
            _option(
                alternatives,
                fields,
                *db_flags,
                field=f"radar.{p.db_name}",
                dest=p.db_name,
                type=float,
                nargs="+",
                metavar=p.db_unit.upper(),
                help=f"{p.label}, {p.db_unit} (default {p.db_default:g})",
            )


def _given_radar(args: argparse.Namespace) -> dict[str, Any]:
    """The radar options given, by field name (linear or decibel)."""
    given = {}
    for p in radar_parameters():
        for dest in (p.name, p.db_name):
            value = getattr(args, dest, None) if dest else None
            if value is not None:  # one value for every UAV, or one per UAV
                given[dest] = value[0] if len(value) == 1 else value
    return given


def _radar_from_args(args: argparse.Namespace, base: Radar | None = None) -> Radar:
    """The radar of the options, over the paper profile or over ``base`` (a scenario's):
    a field given (in linear or decibel form) replaces the base's."""
    given = _given_radar(args)
    if base is None:
        return Radar.from_db(**given)
    kept = {
        p.name: getattr(base, p.name)
        for p in radar_parameters()
        if p.name not in given and not (p.db_name and p.db_name in given)
    }
    return Radar.from_db(**kept, **given)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``crlbswarm`` command.

    Returns
    -------
    argparse.ArgumentParser
        The parser, with one sub-parser per command.
    """
    parser = _Parser(
        prog="crlbswarm",
        description="CRLB-optimal UAV formations for cooperative range sensing "
        "(Wu et al., arXiv:2602.23990).",
    )
    parser.add_argument("--version", action="version", version=f"crlbswarm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_design(sub)
    _add_figures(sub)
    _add_scenario(sub)
    _add_simulate(sub)
    _add_sweep(sub)
    _add_replay(sub)
    _add_report(sub)
    _add_plot(sub)
    _add_animate(sub)
    _add_fly(sub)
    return parser


def _command(
    sub: Any, name: str, func: Callable[[argparse.Namespace], int], **kwargs: Any
) -> tuple[Any, dict[str, str]]:
    """A sub-command parser that runs ``func``, and its map from library field to option."""
    command = sub.add_parser(name, **kwargs)
    fields: dict[str, str] = {}
    command.set_defaults(func=func, fields=fields)
    return command, fields


def _add_design(sub: Any) -> None:
    design, fields = _command(
        sub,
        "design",
        _cmd_design,
        help="print the CRLB-optimal formation for a scene (with constraints or targets)",
        description="The CRLB-optimal formation of a scene. Without constraints, the closed "
        "form F* (paper Sec. III): optimal elevation, radius, positions, CRLB and the bound "
        "4/sum(w). With any constraint option (or --scenario), the numerical constrained "
        "design (criterion value, unconstrained optimum, ratio, active constraints). With "
        "--target given two or more times, the allocation of the UAVs to the targets.",
    )
    scene = design.add_argument_group("scene")
    _option(scene, fields, "--uavs", field="n_uavs", type=int, default=None,
            help=f"number of UAVs M >= {MIN_UAVS} (default 6, or the scenario's)")  # fmt: skip
    _option(scene, fields, "--altitude", field="altitude", type=float, default=None,
            metavar="H", help="flight altitude H, m (default 20, or the scenario's)")  # fmt: skip
    _option(scene, fields, "--target", field="target_xy", action="append", nargs="+",
            default=None, metavar="X,Y",
            help="target position, m, as X,Y (or X Y); give it again for several targets, "
            "allocated with allocate_targets (default 0,0, or the scenario's; a negative "
            "X: --target=-5,3)")  # fmt: skip
    fields["targets_xy"] = fields["target_xy"]
    _option(scene, fields, "--rotation", field="rotation_deg", type=float, default=None,
            metavar="DEG",
            help="azimuth of UAV 1 seen from the target, degrees (default 0)")  # fmt: skip
    fields["rotation"] = fields["rotation_deg"]
    _option(scene, fields, "--scenario", field="scenario", default=None,
            metavar="SCENARIO",
            help=f"design what a scenario flies ({_BUILTIN_HELP}): its M, altitude, "
            "target(s), radar, obstacles and the constraints of its design when F* is "
            "blocked (clearance 1.05 control.safety_radius, separation twice the start "
            "separation, formation.criterion, max_radius, starts, seed); options given "
            "override them")  # fmt: skip
    _add_constraint_options(design, fields)
    out = design.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="print JSON instead of a table")
    _option(out, fields, "-o", "--out", field="out", type=_path, default=None,
            metavar="FILE",
            help="also write the JSON to FILE (atomically; an existing file is refused "
            "unless --force)")  # fmt: skip
    out.add_argument("--force", action="store_true", help="replace FILE if it exists")
    _add_radar_options(design, fields)


def _add_constraint_options(design: Any, fields: dict[str, str]) -> None:
    """The options of the constrained design and of the allocation."""
    group = design.add_argument_group(
        "constrained design (any of these selects constrained_design)"
    )
    _option(group, fields, "--criterion", field="criterion", default=None,
            metavar="A|D|E",
            help="A: tr(J^-1) (the CRLB), D: det(J^-1), E: lambda_max(J^-1) "
            "(default A)")  # fmt: skip
    _option(group, fields, "--obstacle", field="obstacles", action="append", default=None,
            metavar="SHAPE",
            help="an obstacle, rect:X0,X1,Y0,Y1 or circle:X,Y,R (m); repeat for more")  # fmt: skip
    fields["rectangles"] = fields["circles"] = fields["obstacles"]
    _option(group, fields, "--no-fly", field="no_fly", action="append", default=None,
            metavar="SHAPE",
            help="a no-fly zone, circle:X,Y,R or poly:X1,Y1,X2,Y2,X3,Y3,... (m, vertices "
            "in order); repeat for more")  # fmt: skip
    for flag, field, what in (
        ("--clearance", "clearance", "smallest distance from each UAV to every obstacle "
         "and no-fly zone, m (default 0, or the scenario's design clearance)"),
        ("--min-separation", "min_separation", "smallest distance between two UAVs, m "
         "(default 0, or the scenario's design separation)"),
        ("--max-radius", "max_radius", "largest distance from the target to a UAV, m"),
    ):  # fmt: skip
        _option(group, fields, flag, field=field, type=float, default=None, metavar="M",
                help=what)  # fmt: skip
    _option(group, fields, "--altitude-band", field="altitude_bands", action="append",
            default=None, metavar="LOW:HIGH",
            help="altitude band, m: once for every UAV, or once per UAV in order; each "
            "UAV's altitude is then designed in its band")  # fmt: skip
    _option(group, fields, "--starts", field="starts", type=int, default=None,
            help="starts of the search (default: 64 up to 16 UAVs, then fewer)")  # fmt: skip
    _option(group, fields, "--seed", field="seed", type=int, default=None,
            help="seed of the random starts (default 0)")  # fmt: skip
    _option(group, fields, "--objective", field="objective", default=None,
            metavar="sum|max",
            help="with several targets: minimise the sum or the largest of their CRLBs "
            "(default sum)")  # fmt: skip


def _add_figures(sub: Any) -> None:
    figures, fields = _command(
        sub,
        "figures",
        _cmd_figures,
        help="write the paper's figures and their data to a folder",
        description="Write Figs. 2-4 of the paper (CRLB vs altitude; the paper mission's "
        "trajectories, CRLB and cost), the optimal elevation vs altitude, the MLE's MSE vs "
        "the CRLB, sensing in the loop and moving-target tracking, with the data behind "
        "each figure as CSV (crlbswarm.reproduce).",
    )
    _option(
        figures,
        fields,
        "--out",
        field="out_dir",
        required=True,
        type=_path,
        metavar="DIR",
        help="output folder (created if missing; refused if it holds files, unless --force)",
    )
    figures.add_argument(
        "--force",
        action="store_true",
        help="write into DIR even if it holds files (those of the same names are replaced)",
    )
    _option(
        figures,
        fields,
        "--format",
        field="fmt",
        default="png",
        choices=FIGURE_FORMATS,
        help="image format (default %(default)s)",
    )
    _option(
        figures,
        fields,
        "--uavs",
        field="n_uavs",
        type=int,
        default=6,
        help="number of UAVs in Fig. 2 (default %(default)s)",
    )
    _option(
        figures,
        fields,
        "--seed",
        field="seed",
        type=int,
        default=0,
        help="seed of the paper mission of Figs. 3-4, of the Monte Carlo sweep, and the "
        f"first of the {FIGURE_RUNS} seeds of the sensing figures (default %(default)s)",
    )


def _add_scenario(sub: Any) -> None:
    scenario = sub.add_parser(
        "scenario",
        help="list the built-in scenarios or print one as TOML",
        description="Print a scenario as a TOML file to copy and edit (docs/scenarios.md).",
    )
    actions = scenario.add_subparsers(dest="action", required=True, metavar="ACTION")
    show, _ = _command(
        actions, "show", _cmd_scenario_show, help="print a scenario (built-in or file) as TOML"
    )
    show.add_argument("scenario", metavar="SCENARIO", help=_BUILTIN_HELP)
    _command(actions, "list", _cmd_scenario_list, help="list the built-in scenarios")


def _add_simulate(sub: Any) -> None:
    simulate, fields = _command(
        sub,
        "simulate",
        _cmd_simulate,
        help="run a mission for one seed or a batch of seeds",
        description="Simulate the distributed controller (paper Sec. IV) and write the "
        "trajectories (.npz), per-run metrics (CSV), a summary (JSON) and the scenario used "
        "(read back with crlbswarm.load_results).",
    )
    simulate.add_argument("scenario", metavar="SCENARIO", help=_BUILTIN_HELP)
    _option(
        simulate,
        fields,
        "--seed",
        field="seed",
        type=int,
        default=0,
        help="seed of the first run (default %(default)s)",
    )
    _option(
        simulate,
        fields,
        "--runs",
        field="seeds",
        type=int,
        default=1,
        help="number of runs, seeds SEED..SEED+RUNS-1 (default 1)",
    )
    _option(
        simulate,
        fields,
        "--out",
        field="folder",
        required=True,
        type=_path,
        metavar="DIR",
        help="output folder (missing or empty, unless --force)",
    )
    simulate.add_argument(
        "--no-trajectories",
        action="store_true",
        help="do not keep positions and velocities (metrics and time series only)",
    )
    _option(
        simulate,
        fields,
        "--trajectory-stride",
        field="trajectory_stride",
        type=int,
        default=1,
        metavar="N",
        help="keep positions and velocities every N steps and at the last (default 1)",
    )
    simulate.add_argument(
        "--force",
        action="store_true",
        help="write into DIR even if it holds files (those of the same names are replaced)",
    )
    simulate.add_argument(
        "--strict",
        action="store_true",
        help="exit with status 1 when a run does not end converged (the files are written)",
    )


def _add_sweep(sub: Any) -> None:
    sweep, fields = _command(
        sub,
        "sweep",
        _cmd_sweep,
        help="run a Monte Carlo campaign (variants x seeds) on Dask",
        description="Run or resume a campaign described by a TOML spec (docs/campaigns.md) on "
        "a local Dask cluster or an existing scheduler; one row of metrics per run in a "
        "Parquet dataset under DIR/runs. Re-running the same command resumes.",
    )
    sweep.add_argument("spec", metavar="SPEC", type=_path, help="campaign spec (TOML)")
    _option(
        sweep,
        fields,
        "--out",
        field="out",
        required=True,
        type=_path,
        metavar="DIR",
        help="output folder",
    )
    _option(
        sweep,
        fields,
        "--scheduler",
        field="scheduler",
        metavar="ADDRESS",
        default=None,
        help="address of a running Dask scheduler (default: start a local cluster)",
    )
    _option(
        sweep,
        fields,
        "--workers",
        field="n_workers",
        type=int,
        default=None,
        help="workers of the local cluster (default: cores)",
    )
    for flag, field, what in (
        ("--tls-ca-file", "tls_ca_file", "certificate authority of the scheduler (PEM)"),
        ("--tls-cert", "tls_cert", "this client's certificate (PEM)"),
        ("--tls-key", "tls_key", "this client's private key (PEM)"),
    ):
        _option(sweep, fields, flag, field=field, type=_path, metavar="FILE", default=None,
                help=f"with a tls:// scheduler: {what}")  # fmt: skip
    _option(
        sweep,
        fields,
        "--connect-timeout",
        field="connect_timeout",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="how long to wait for the scheduler (default %(default)s)",
    )


# -- plot and animate a saved result -------------------------------------------------------
def _runs_dir_argument(command: Any, fields: dict[str, str]) -> None:
    """RUNS_DIR and --run of ``plot`` and ``animate``."""
    command.add_argument("runs_dir", metavar="RUNS_DIR", type=_path,
                         help="a folder written by crlbswarm simulate (with several "
                         "targets, each group is drawn, in files named for it), or a "
                         "campaign's trajectories/variant=<id> folder or one of its part "
                         "folders")  # fmt: skip
    fields["folder"] = fields["result"] = "RUNS_DIR"
    _option(command, fields, "--run", field="run", type=int, default=0, metavar="I",
            help="index of the run in the batch, from 0 (default 0)")  # fmt: skip


def _add_plot(sub: Any) -> None:
    from .paper import FIGURE_FORMATS

    plot, fields = _command(
        sub,
        "plot",
        _cmd_plot,
        help="draw a run of a simulate folder: trajectories, time series, batch metrics",
        description="Draw one run of a saved result (crlbswarm.load_results): its "
        "trajectories with formation snapshots (runI_trajectories, as Fig. 3), its CRLB, cost "
        "and eta over time (runI_timeseries, as Fig. 4), and for the whole batch the "
        "estimation error against the PCRB (estimation, with estimation on) and the "
        "distributions of the per-run metrics (metrics, with two runs or more). With several "
        "targets, the figures of each group, their files starting with groupG_.",
    )
    _runs_dir_argument(plot, fields)
    _option(plot, fields, "--out", field="out_dir", type=_path, default=None, metavar="DIR",
            help="output folder, created if missing (default RUNS_DIR/plots)")  # fmt: skip
    _option(plot, fields, "--format", field="fmt", default="png", choices=FIGURE_FORMATS,
            help="image format (default %(default)s)")  # fmt: skip
    _option(plot, fields, "--dpi", field="dpi", type=int, default=150,
            help="resolution of a png, pixels per inch, 20 to 600 "
            "(default %(default)s)")  # fmt: skip
    plot.add_argument("--force", action="store_true",
                      help="replace files of the same names in DIR")  # fmt: skip


def _add_animate(sub: Any) -> None:
    from .animation import DEFAULT_FPS, DEFAULT_MAX_FRAMES

    animate, fields = _command(
        sub,
        "animate",
        _cmd_animate,
        help="write an animation (MP4 or GIF) of a run of a simulate folder",
        description="Animate one run of a saved result: UAVs, their tracks, the formation "
        "polygon, obstacles, the target and the UAVs' estimate, with time, eta and the CRLB "
        "as a caption. One frame per kept step, evenly decimated to at most --max-frames "
        "(first and last step included). An .mp4 needs the optional package imageio-ffmpeg "
        "(pip install 'crlbswarm[video]'); a .gif does not, but plays at most 50 fps and "
        "holds at most 3e8 pixels (frames x width x height). With several targets, one file "
        "per group, FILE_groupG.mp4.",
    )
    _runs_dir_argument(animate, fields)
    _option(animate, fields, "-o", "--out", field="path", type=_path, required=True,
            metavar="FILE", help="the animation, FILE.mp4 or FILE.gif (an existing file is "
            "refused unless --force)")  # fmt: skip
    _option(animate, fields, "--fps", field="fps", type=int, default=DEFAULT_FPS,
            help="frames per second, 1 to 120 (a .gif: to 50) (default %(default)s)")  # fmt: skip
    _option(animate, fields, "--max-frames", field="max_frames", type=int, metavar="N",
            default=DEFAULT_MAX_FRAMES, help="most frames (default %(default)s)")  # fmt: skip
    _option(animate, fields, "--dpi", field="dpi", type=int, default=100,
            help="pixels per inch of the 8-inch-wide frames (default %(default)s)")  # fmt: skip
    animate.add_argument("--force", action="store_true", help="replace FILE if it exists")


def _cmd_plot(args: argparse.Namespace) -> int:
    from ._validation import count
    from .output import check_output_file, check_output_folder
    from .replay import load_mission_folder

    count(args.dpi, "dpi", 20, 600)  # (before any folder is made)
    parts = _result_parts(load_mission_folder(args.runs_dir))
    b = parts[0][1].run_index(args.run)
    out = args.out if args.out is not None else args.runs_dir / "plots"
    check_output_folder(out, "out_dir")
    from .plots import run_figure_names  # (Matplotlib: after the checks of the input)

    per_run = ("trajectories", "timeseries")  # (the figures of the run; the others: the batch)
    paths = {(prefix, n): out / f"{prefix}{f'run{b}_' if n in per_run else ''}{n}.{args.format}"
             for prefix, part, _ in parts for n in run_figure_names(part)}  # fmt: skip
    if out.is_dir():  # nothing is replaced unasked, and nothing is written on a refusal
        for path in paths.values():
            check_output_file(path, "out_dir", overwrite=args.force)
    from .output import make_output_folder, save_figure
    from .plots import run_figures

    figures = {(prefix, name): fig for prefix, part, uavs in parts
               for name, fig in run_figures(part, b, uavs=uavs).items()}  # fmt: skip
    make_output_folder(out, "out_dir")
    for key, fig in figures.items():
        save_figure(fig, paths[key], dpi=args.dpi)
        print(f"wrote {paths[key]}")
    if parts[0][1].positions is None:
        print("note: no trajectories in RUNS_DIR (simulated with --no-trajectories): "
              "runI_trajectories left out")  # fmt: skip
    return 0


def _result_parts(result: Any) -> list[tuple[str, Any, list[int] | None]]:
    """What ``plot`` draws of a result: its file prefix, the result and its UAVs' indices
    in the swarm (None: all of one target's); a group's for each group of several targets."""
    from .results import GroupMissionResult

    if isinstance(result, GroupMissionResult):
        return [(f"group{g}_", group, [int(u) for u in members])
                for g, (group, members) in enumerate(zip(result.groups, result.plan.members,
                                                         strict=True))]  # fmt: skip
    return [("", result, None)]


def _cmd_animate(args: argparse.Namespace) -> int:
    from .animation import animate_mission, animation_paths, written_fps
    from .replay import load_mission_folder

    result = load_mission_folder(args.runs_dir)
    frames = animate_mission(result, args.out, args.run, fps=args.fps,
                             max_frames=args.max_frames, dpi=args.dpi,
                             overwrite=args.force)  # fmt: skip
    rate = written_fps(args.out, args.fps)
    for path in animation_paths(result, args.out):
        print(f"wrote {path} ({frames} frames, {frames / rate:.1f} s at {rate:.3g} fps)")
    return 0


# -- fly: one process per UAV over Zenoh ---------------------------------------------------
def _add_fly(sub: Any) -> None:
    from .flynet import DEFAULT_TIMEOUT, MODES

    fly, fields = _command(
        sub,
        "fly",
        _cmd_fly,
        help="fly a scenario as one process per UAV over Zenoh, with a recorder",
        description="Start one process per UAV and a recorder, talking over Zenoh (peer mode, "
        "endpoints on 127.0.0.1, no multicast); each UAV runs the mission kernel's laws on "
        "the states it receives. The recorder writes the same folder as simulate, plus "
        "fly.json. With --uav I or --recorder, run only that member in this process (start "
        "them by hand, on different machines, with --connect and --listen). Needs the "
        "optional package eclipse-zenoh: pip install 'crlbswarm[fly]' (docs/fly.md).",
    )
    fly.add_argument("scenario", metavar="SCENARIO", help=_BUILTIN_HELP)
    _option(fly, fields, "--out", field="out", type=_path, default=None, metavar="DIR",
            help="the recorder's output folder (missing or empty, unless --force)")  # fmt: skip
    _option(fly, fields, "--seed", field="seed", type=int, default=0,
            help="seed of the run: the starts and draws of simulate --seed "
            "(default 0)")  # fmt: skip
    _option(fly, fields, "--mode", field="mode", default="stepped", choices=MODES,
            help="stepped: a UAV takes the next step when it has its neighbours' states "
            "(reproducible); realtime: steps on the wall clock (default %(default)s)")  # fmt: skip
    _option(fly, fields, "--timeout", field="timeout", type=float, default=DEFAULT_TIMEOUT,
            metavar="SEC", help="stepped mode: longest wait for a state before a UAV goes on "
            "with the last it holds (default %(default)s)")  # fmt: skip
    _option(fly, fields, "--loss", field="loss", type=float, default=0.0, metavar="P",
            help="probability that a swarm message is lost, injected at the sender "
            "(default 0)")  # fmt: skip
    _option(fly, fields, "--delay", field="delay", type=int, default=0, metavar="STEPS",
            help="steps a swarm message is held back at the sender (default 0)")  # fmt: skip
    fly.add_argument("--force", action="store_true",
                     help="write into DIR even if it holds files")  # fmt: skip
    role = fly.add_argument_group("one member by hand").add_mutually_exclusive_group()
    _option(role, fields, "--uav", field="uav", type=int, default=None, metavar="I",
            help="run only UAV I in this process")  # fmt: skip
    role.add_argument("--recorder", action="store_true",
                      help="run only the recorder in this process (needs --out)")  # fmt: skip
    _option(fly, fields, "--listen", field="listen", action="append", default=None,
            metavar="ENDPOINT", help="Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 "
            "(a member: default any free port of 127.0.0.1; the launcher: once per member, "
            "the recorder's first, default free ports of 127.0.0.1)")  # fmt: skip
    _option(fly, fields, "--connect", field="connect", action="append", default=None,
            metavar="ENDPOINT", help="Zenoh endpoint of another member to connect to "
            "(repeat for more)")  # fmt: skip
    _option(fly, fields, "--key", field="key", default=None, metavar="PREFIX",
            help="the flight's key prefix, the same for every member (by hand: default "
            "crlbswarm/fly; the launcher: one per flight)")  # fmt: skip
    _option(fly, fields, "--kill", field="kill", default=None,
            metavar="UAV@TIME", help="UAV's process kills itself (SIGKILL) when the mission "
            "reaches TIME s: a UAV lost, the others re-form (e.g. 2@100)")  # fmt: skip
    fly.add_argument("--parent", type=int, default=None, help=argparse.SUPPRESS)


def _kill_spec(text: str | None) -> tuple[int, float] | None:
    """``UAV@TIME`` of ``fly --kill`` (None: none)."""
    if text is None:
        return None
    uav, sep, at = text.partition("@")
    try:
        value = (int(uav), float(at))
    except ValueError:
        value = None
    if not sep or value is None or not math.isfinite(value[1]):
        raise FieldError("kill", f"expected UAV@TIME (e.g. 2@100), got {text!r}")
    return value


def _interrupt(signum: int, frame: Any) -> None:
    """SIGTERM: stop as Ctrl-C does (a member of a flight writes or closes, then exits)."""
    raise KeyboardInterrupt


def _cmd_fly(args: argparse.Namespace) -> int:
    import signal

    from .flynet import DEFAULT_KEY, FlightError, FlightOptions, ParentGone, import_zenoh
    from .scenario import load_scenario

    import_zenoh()
    scenario = load_scenario(args.scenario)
    args.kill = _kill_spec(args.kill)
    if args.uav is not None and args.out is not None:
        raise FieldError("out", "is the recorder's: not used with --uav")
    if args.uav is None and args.out is None:
        raise FieldError("out", "is required (the recorder's output folder)")
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        if args.uav is None and not args.recorder:
            return _fly_launcher(args, scenario)
        from .fly import check_kill, run_recorder
        from .uav_node import fly_run, run_uav

        options = FlightOptions(
            key=args.key or DEFAULT_KEY, listen=tuple(args.listen or ["tcp/127.0.0.1:0"]),
            connect=tuple(args.connect or ()), mode=args.mode, timeout=args.timeout,
            loss=args.loss, delay=args.delay, parent=args.parent, kill=args.kill,
        )  # fmt: skip
        run = fly_run(scenario, args.seed, args.delay)
        check_kill(args.kill, run)
        if args.recorder:
            report = run_recorder(run, args.out, options, args.force)
            return 130 if report.interrupted else 0 if report.complete else 1
        run_uav(run, args.uav, options)
        return 0
    except FlightError as exc:
        return _fail(str(exc), 1)
    except ParentGone:
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)


def _fly_launcher(args: argparse.Namespace, scenario: Any) -> int:
    """``crlbswarm fly SCENARIO --out DIR``: every member, then their statuses."""
    import json
    import time

    from .fly import fly

    began = time.monotonic()
    try:
        statuses = fly(scenario, args.out, seed=args.seed, mode=args.mode, timeout=args.timeout,
                       loss=args.loss, delay=args.delay, force=args.force, key=args.key,
                       listen=args.listen, connect=args.connect or (),
                       kill=args.kill)  # fmt: skip
    except KeyboardInterrupt:
        print("crlbswarm: interrupted: every process stopped; the recorder kept the steps "
              f"recorded ({args.out / 'fly.json'})", file=sys.stderr)  # fmt: skip
        return 130
    failed = ", ".join(f"{name} {code}" for name, code in statuses.items() if code != 0)
    print(f"fly: {len(statuses) - 1} UAVs and the recorder, {time.monotonic() - began:.1f} s"
          + (f"; exit status {failed}" if failed else ""))  # fmt: skip
    record = args.out / "fly.json"
    if record.is_file():
        note = json.loads(record.read_text(encoding="utf-8")).get("note")
        if note:
            print(f"note: {note}")
    return 1 if failed else 0


# -- commands ------------------------------------------------------------------------------
def format_design(report: dict[str, Any]) -> str:
    """Render :func:`crlbswarm.design.design_report` as a readable table.

    Parameters
    ----------
    report : dict
        The report.

    Returns
    -------
    str
        The table, one line per quantity and per UAV.
    """
    x, y = report["target_m"]
    per_uav = isinstance(report["elevation_deg"], list)
    lines = [
        "CRLB-optimal formation F* (paper Sec. III)",
        f"  UAVs M               {report['n_uavs']}",
        f"  altitude H           {report['altitude_m']:g} m",
        f"  target s             ({x:g}, {y:g}) m",
    ]
    if not per_uav:
        lines += [
            f"  optimal elevation    {report['elevation_deg']:.4f} deg",
            f"  radius r*            {report['radius_m']:.4f} m",
        ]
    bound = "eq. 11" if report["isotropic"] else "one UAV dominates: 1/w_max + 1/(W - w_max)"
    lines += [
        f"  CRLB tr(J^-1)        {report['crlb_m2']:.6e} m^2"
        f"   (RMSE bound {100 * report['rmse_bound_m']:.3f} cm)",
        f"  attainable optimum   {report['bound_m2']:.6e} m^2   ({bound})",
        "  positions (m):",
        "     UAV           x           y"
        + ("   elevation (deg)   radius (m)" if per_uav else ""),
    ]
    for i, (px, py) in enumerate(report["positions_m"], start=1):
        row = f"    {i:4d}  {px:10.4f}  {py:10.4f}"
        if per_uav:
            elev, rad = report["elevation_deg"][i - 1], report["radius_m"][i - 1]
            row += f"   {elev:15.4f}   {rad:10.4f}"
        lines.append(row)
    return "\n".join(lines)


def format_constrained(report: dict[str, Any]) -> str:
    """Render :func:`crlbswarm.constrained.constrained_report` as a readable table.

    Parameters
    ----------
    report : dict
        The report.

    Returns
    -------
    str
        The table, one line per quantity and per UAV.
    """
    x, y = report["target_m"]
    unit, c = report["unit"], report["constraints"]
    obs = c["obstacles"]
    bands = report["altitude_bands_m"]
    altitude = (f"{report['altitude_m']:g} m" if bands is None
                else "per UAV, in its band (table)")  # fmt: skip
    limits = [
        f"obstacles {len(obs['rectangles']) + len(obs['circles'])}",
        f"no-fly zones {len(c['no_fly'])}",
        f"clearance {c['clearance_m']:g} m",
        f"min separation {c['min_separation_m']:g} m",
        "max radius " + ("none" if c["max_radius_m"] is None else f"{c['max_radius_m']:g} m"),
    ]
    reference = "closed form" + (", each UAV at its band's low end" if bands else "")
    lines = [
        f"Constrained design, criterion {report['criterion']}",
        f"  UAVs M               {report['n_uavs']}",
        f"  altitude H           {altitude}",
        f"  target s             ({x:g}, {y:g}) m",
        f"  constraints          {', '.join(limits)}",
        f"  criterion value      {report['value']:.6e} {unit}",
        f"  unconstrained        {report['unconstrained']:.6e} {unit}   ({reference})",
        f"  ratio                {report['ratio']:.9f}",
        f"  CRLB tr(J^-1)        {report['crlb_m2']:.6e} m^2"
        f"   (RMSE bound {100 * report['rmse_bound_m']:.3f} cm)",
        f"  starts               {report['starts']} ({report['feasible_starts']} feasible), "
        f"seed {report['seed']}",
        "  active constraints   " + (", ".join(report["active"]) or "none"),
        "  positions (m):",
        "     UAV           x           y" + ("   altitude (m)        band (m)" if bands else ""),
    ]
    for i, (px, py) in enumerate(report["positions_m"]):
        row = f"    {i + 1:4d}  {px:10.4f}  {py:10.4f}"
        if bands:
            low, high = bands[i]
            row += f"   {report['altitudes_m'][i]:12.4f}   {low:g} to {high:g}"
        lines.append(row)
    return "\n".join(lines)


def format_allocation(report: dict[str, Any]) -> str:
    """Render :func:`crlbswarm.multitarget.allocation_report` as a readable table.

    Parameters
    ----------
    report : dict
        The report.

    Returns
    -------
    str
        The table: the allocation, then each target's group and formation.
    """
    how = (f"exhaustive: all {report['evaluated']} assignments evaluated (the optimum)"
           if report["exhaustive"] else
           f"heuristic: local search, {report['evaluated']} assignments evaluated "
           "(a local optimum)")  # fmt: skip
    lines = [
        f"Allocation of {report['n_uavs']} UAVs to {len(report['targets_m'])} targets",
        f"  altitude H           {report['altitude_m']:g} m",
        f"  objective            {report['objective']} of the CRLBs = "
        f"{report['value_m2']:.6e} m^2",
        f"  search               {how}",
    ]
    for group in report["groups"]:
        x, y = group["target_m"]
        uavs = ", ".join(str(u) for u in group["uavs"])
        lines += [
            f"  target {group['target']} at ({x:g}, {y:g}) m: UAVs {uavs}",
            f"    CRLB tr(J^-1)      {group['crlb_m2']:.6e} m^2"
            f"   (RMSE bound {100 * group['rmse_bound_m']:.3f} cm)",
            "     UAV           x           y",
        ]
        for u, (px, py) in zip(group["uavs"], group["positions_m"], strict=True):
            lines.append(f"    {u:4d}  {px:10.4f}  {py:10.4f}")
    return "\n".join(lines)


#: The options that select the constrained design (argparse destinations).
_CONSTRAINED = ("criterion", "obstacle", "no_fly", "clearance", "min_separation", "max_radius",
                "altitude_band", "starts", "seed")  # fmt: skip

#: The library field each of them sets (to name it in an error).
_FIELD = {"obstacle": "obstacles", "altitude_band": "altitude_bands"}


def _numbers(text: str, field: str, form: str, count: int | None = None) -> list[float]:
    """The comma-separated numbers of ``text`` (``count`` of them, if given)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or (count is not None and len(values) != count):
        raise FieldError(field, f"expected {form}, got {text!r}")
    return values


def _targets(given: list[list[str]] | None) -> list[list[float]] | None:
    """``--target X,Y`` (or ``X Y``), once or more."""
    if given is None:
        return None
    targets = []
    for values in given:
        text = values[0] if len(values) == 1 else ",".join(values)
        targets.append(_numbers(text, "target_xy", "X,Y (or X Y)", 2))
    return targets


def _obstacles(given: list[str]) -> Any:
    from .obstacles import Obstacles

    rects, circles = [], []
    form = "rect:X0,X1,Y0,Y1 or circle:X,Y,R"
    for item in given:
        kind, _, rest = item.partition(":")
        if kind.strip().lower() in ("rect", "rectangle"):
            rects.append(_numbers(rest, "obstacles", form, 4))
        elif kind.strip().lower() == "circle":
            circles.append(_numbers(rest, "obstacles", form, 3))
        else:
            raise FieldError("obstacles", f"expected {form}, got {item!r}")
    return Obstacles(rectangles=rects or (), circles=circles or ())


def _no_fly(given: list[str]) -> list[Any]:
    zones: list[Any] = []
    form = "circle:X,Y,R or poly:X1,Y1,X2,Y2,X3,Y3,..."
    for item in given:
        kind, _, rest = item.partition(":")
        if kind.strip().lower() == "circle":
            zones.append(tuple(_numbers(rest, "no_fly", form, 3)))
        elif kind.strip().lower() in ("poly", "polygon"):
            values = _numbers(rest, "no_fly", form)
            if len(values) % 2 or len(values) < 6:
                raise FieldError("no_fly", f"a polygon needs 3 or more X,Y pairs, got {item!r}")
            zones.append([values[k : k + 2] for k in range(0, len(values), 2)])
        else:
            raise FieldError("no_fly", f"expected {form}, got {item!r}")
    return zones


def _bands(given: list[str], n_uavs: int) -> list[float] | list[list[float]]:
    bands = [_numbers(b.replace(":", ",", 1), "altitude_bands", "LOW:HIGH", 2) for b in given]
    if len(bands) not in (1, n_uavs):
        raise FieldError(
            "altitude_bands",
            f"give one band for every UAV or one per UAV ({n_uavs}), got {len(bands)}",
        )
    return bands[0] if len(bands) == 1 else bands


def _scene(args: argparse.Namespace) -> dict[str, Any]:
    """The scene of ``crlbswarm design``: the scenario's (if any), the options over it."""
    sc = None
    if args.scenario is not None:
        from .scenario import load_scenario

        try:
            sc = load_scenario(args.scenario)
        except ConfigError as exc:  # a file's own field: the message names it
            raise FieldError("scenario", str(exc)) from None

    def pick(value: Any, from_scenario: Any, default: Any) -> Any:
        return value if value is not None else (from_scenario if sc is not None else default)

    n = pick(args.uavs, sc and sc.uavs.count, 6)
    # The scenario's own design arguments (what it flies when F* is blocked), if any.
    given: dict[str, Any] = {}
    if sc is not None and not sc.extra_targets:
        from .scenario import design_arguments

        given = design_arguments(sc)
    obstacles = given.get("obstacles")
    if args.obstacle is not None:
        obstacles = _obstacles(args.obstacle)
    scenario_targets = [list(sc.target), *map(list, sc.extra_targets)] if sc else [[0.0, 0.0]]
    return {
        "scenario": sc,
        "n_uavs": n,
        "altitude": pick(args.altitude, sc and sc.altitude, 20.0),
        "targets": _targets(args.target) or scenario_targets,
        "rotation_deg": pick(args.rotation, sc and sc.uavs.rotation_deg, 0.0),
        "radar": _radar_from_args(args, sc.radar_model if sc else None),
        "obstacles": obstacles,
        "no_fly": _no_fly(args.no_fly) if args.no_fly is not None else None,
        "clearance": pick(args.clearance, given.get("clearance"), 0.0),
        "min_separation": pick(args.min_separation, given.get("min_separation"), 0.0),
        "max_radius": pick(args.max_radius, given.get("max_radius"), None),
        "criterion": pick(args.criterion, given.get("criterion"), "A"),
        "starts": pick(args.starts, given.get("starts"), None),
        "seed": pick(args.seed, given.get("seed"), 0),
        "objective": pick(args.objective, sc and sc.formation.objective, "sum"),
        "altitude_bands": None if args.altitude_band is None else _bands(args.altitude_band, n),
    }


def _design_report(args: argparse.Namespace) -> dict[str, Any]:
    """The report ``crlbswarm design`` prints: closed form, constrained or allocation."""
    from .design import design_report

    scene = _scene(args)
    targets = scene["targets"]
    if len(targets) > 1:
        from .multitarget import allocation_report

        given = [k for k in (*_CONSTRAINED, "rotation") if getattr(args, k) is not None]
        if given:
            raise FieldError(
                _FIELD.get(given[0], given[0]), "applies to one target: several targets are "
                "allocated (each group in its closed-form formation) without constraints or "
                "rotation",
            )  # fmt: skip
        return allocation_report(targets, scene["n_uavs"], scene["altitude"], scene["radar"],
                                 objective=scene["objective"])  # fmt: skip
    if args.objective is not None:
        raise FieldError("objective", "applies to several targets (--target given twice or more)")
    if scene["scenario"] is None and all(getattr(args, k) is None for k in _CONSTRAINED):
        return design_report(scene["n_uavs"], scene["altitude"], targets[0], scene["radar"],
                             scene["rotation_deg"])  # fmt: skip
    from .constrained import constrained_report

    return constrained_report(
        scene["n_uavs"], targets[0], scene["altitude"], scene["radar"],
        criterion=scene["criterion"], obstacles=scene["obstacles"], no_fly=scene["no_fly"],
        clearance=scene["clearance"], min_separation=scene["min_separation"],
        max_radius=scene["max_radius"], altitude_bands=scene["altitude_bands"],
        starts=scene["starts"], seed=scene["seed"], rotation_deg=scene["rotation_deg"],
    )  # fmt: skip


def _cmd_design(args: argparse.Namespace) -> int:
    from .output import check_output_file, json_text, write_text

    if args.force and args.out is None:
        raise FieldError("out", "--force replaces the file of -o/--out: give it")
    if args.out is not None:  # before any work, and nothing written on an error
        check_output_file(args.out, "out", overwrite=args.force)
    report = _design_report(args)
    text = json_text(report)
    if args.out is not None:
        write_text(args.out, text)
    formats = {"constrained": format_constrained, "allocation": format_allocation}
    print(text if args.json else formats.get(report.get("design", ""), format_design)(report))
    if args.out is not None and not args.json:
        print(f"wrote {args.out}")
    return 0


def _cmd_figures(args: argparse.Namespace) -> int:
    from .paper import reproduce

    reproduce(
        args.out,
        overwrite=args.force,
        fmt=args.format,
        n_uavs=args.uavs,
        seed=args.seed,
        on_write=lambda path: print(f"wrote {path}"),
    )
    return 0


def _cmd_scenario_show(args: argparse.Namespace) -> int:
    from .scenario import BUILTIN_SCENARIOS, builtin_scenario_text, load_scenario

    if args.scenario in BUILTIN_SCENARIOS:
        print(builtin_scenario_text(args.scenario), end="")
    else:
        print(load_scenario(args.scenario).to_toml(), end="")
    return 0


def _cmd_scenario_list(args: argparse.Namespace) -> int:
    from .scenario import BUILTIN_SCENARIOS

    for name, data in BUILTIN_SCENARIOS.items():
        print(f"{name:12s} {data.get('description', '')}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from . import _validation as _v
    from .output import check_output_folder
    from .results import result_nbytes
    from .scenario import load_scenario
    from .scenario_checks import preflight
    from .simulation import check_memory

    # Validate everything before running anything; create the folder only after the run.
    scenario = load_scenario(args.scenario)
    first, runs = _v.seed_range(args.seed, args.runs, "seed", "seeds")
    check_output_folder(args.out, "folder", new=True, overwrite=args.force)
    keep = not args.no_trajectories
    steps, count = scenario.time.steps, scenario.uavs.count
    stride = _v.count(args.trajectory_stride, "trajectory_stride", 1, max(steps, 1))
    check_memory(runs, steps, count, keep, stride)
    size = result_nbytes(runs, steps, count, keep, stride)
    if size > LARGE_OUTPUT:  # said before the run (stdout: stderr is kept for one error line)
        print(
            f"note: the results will take about {size / 1e9:.1f} GB before compression"
            + (" (--no-trajectories keeps much less)" if keep else ""),
            flush=True,
        )

    from tqdm import tqdm

    from .results import outcome_report
    from .simulation import simulate, simulate_groups

    if scenario.extra_targets:  # several targets: one result per group
        grouped = simulate_groups(scenario, seeds=range(first, first + runs),
                                  keep_trajectories=keep)  # fmt: skip
        for path in grouped.save(args.out, overwrite=args.force):
            print(f"wrote {path}")
        warned = False
        for g, group in enumerate(grouped.groups):
            uavs, leader = grouped.plan.members[g].tolist(), grouped.plan.leaders[g]
            print(f"group {g}: UAV indices {uavs} (leader {leader}) -> target "
                  f"{list(group.scenario.target)}")  # fmt: skip
            lines = outcome_report(group)
            if lines[-1].startswith("warning:"):
                lines.pop()
                warned = True
            print("\n".join("  " + line for line in lines))
        for group in grouped.groups:
            for line in preflight(group.scenario):
                print(f"crlbswarm: warning: {group.scenario.name}: {line}", file=sys.stderr)
        if warned:
            print("crlbswarm: warning: some runs of some groups did not end converged; see "
                  "metrics.csv", file=sys.stderr)  # fmt: skip
            return 1 if args.strict else 0
        return 0
    with tqdm(total=runs, unit="run", disable=None, file=sys.stderr) as bar:
        result = simulate(
            scenario,
            seeds=range(first, first + runs),
            keep_trajectories=keep,
            trajectory_stride=stride,
            progress=lambda done: bar.update(done - bar.n),
        )
    for path in result.save(args.out, overwrite=args.force):
        print(f"wrote {path}")
    lines = outcome_report(result)
    warning = lines.pop() if lines[-1].startswith("warning:") else None
    print("\n".join(lines))
    # The scenario's warnings come with the outcome (an error line, if any, stays alone).
    for line in preflight(scenario):
        print(f"crlbswarm: warning: {line}", file=sys.stderr)
    if warning is not None:
        print(f"crlbswarm: {warning}", file=sys.stderr)
        return 1 if args.strict else 0
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .campaign import CampaignSpec
    from .output import check_output_folder

    spec, text = CampaignSpec.from_file(args.spec)
    check_output_folder(args.out, "out")

    from tqdm import tqdm

    from .campaign import run_campaign

    bars: list[Any] = []  # the bar appears with the first progress report, not before

    def progress(done: int, total: int) -> None:
        if not bars:  # first call: total known, finished tasks not timed
            bars.append(
                tqdm(total=total, initial=done, unit="task", disable=None, file=sys.stderr)
            )
        bars[0].update(done - bars[0].n)

    try:
        counts = run_campaign(
            spec,
            args.out,
            scheduler=args.scheduler,
            n_workers=args.workers,
            spec_text=text,
            progress=progress,
            tls_ca_file=args.tls_ca_file,
            tls_cert=args.tls_cert,
            tls_key=args.tls_key,
            connect_timeout=args.connect_timeout,
        )
    finally:
        for bar in bars:
            bar.close()
    print(
        f"{counts['tasks']} tasks over {counts['variants']} variants: ran {counts['ran']}, "
        f"skipped {counts['skipped']} already finished; results in {args.out / 'runs'}"
    )
    return 0


# -- crlbswarm replay ------------------------------------------------------------------------
def _add_replay(sub: Any) -> None:
    replay, fields = _command(
        sub,
        "replay",
        _cmd_replay,
        help="write an interactive replay of a simulate folder (one offline HTML file)",
        description="Write one self-contained HTML page (works offline: data and code "
        "inline) replaying the missions of a `crlbswarm simulate` folder: obstacles, "
        "tracks, formation, target and estimate on a map (wheel: zoom, drag: pan); play, "
        "speed, a time slider, a run selector; time plots of the CRLB and its bound, cost, "
        "eta, clearance and separation (docs/replay.md). A large batch gets fewer frames "
        "per run so that the page stays under --max-mb.",
    )
    replay.add_argument("runs_dir", metavar="RUNS_DIR", type=_path,
                        help="folder written by `crlbswarm simulate --out`")  # fmt: skip
    fields["folder"] = fields["result"] = "RUNS_DIR"
    _option(replay, fields, "-o", "--out", field="out", required=True, type=_path,
            metavar="FILE", help="the HTML file to write, .html or .htm (refused if it "
            "exists, unless --force)")  # fmt: skip
    fields["path"] = fields["out"]
    replay.add_argument("--force", action="store_true", help="replace FILE if it exists")
    _option(replay, fields, "--runs", field="runs", default=None, metavar="LIST",
            help="runs to show, by index: comma-separated indices and ranges A:B (B not "
            "included), e.g. 0:10,42 (default all)")  # fmt: skip
    _option(replay, fields, "--max-frames", field="max_frames", type=int, default=None,
            metavar="N", help="most frames per run (default 600)")  # fmt: skip
    _option(replay, fields, "--max-mb", field="max_mb", type=float, default=None,
            metavar="MB", help="most megabytes of data in the page; a large batch gets fewer "
            "frames per run (default 10)")  # fmt: skip
    _option(replay, fields, "--title", field="title", default=None,
            help="title of the page (default: scenario name and number of runs)")  # fmt: skip


def _run_list(text: str, n_runs: int) -> list[int]:
    """The run indices of ``--runs``: ``I``, ``A:B`` (B excluded), comma-separated, each in
    ``0 .. n_runs - 1`` (checked before a range is expanded)."""
    runs: list[int] = []
    for item in text.split(","):
        first, colon, last = item.strip().partition(":")
        try:
            lo, hi = (int(first), int(last)) if colon else (int(first), int(first) + 1)
        except ValueError:
            raise FieldError("runs", f"expected indices I or ranges A:B, got {item!r}") from None
        if not 0 <= lo < hi <= n_runs:
            raise FieldError(
                "runs", f"{item.strip()!r} is not a non-empty range of runs in 0..{n_runs - 1}"
            )
        runs.extend(range(lo, hi))
    return runs


def _cmd_replay(args: argparse.Namespace) -> int:
    from .output import check_output_file
    from .replay import MAX_FRAMES, MAX_MB, load_mission_folder, write_replay
    from .results import GroupMissionResult
    from .webpage import check_page_path

    check_output_file(check_page_path(args.out, "out"), "out", overwrite=args.force)
    result = load_mission_folder(args.runs_dir)
    first = result.groups[0] if isinstance(result, GroupMissionResult) else result
    runs = None if args.runs is None else _run_list(args.runs, first.n_runs)
    path = write_replay(
        result,
        args.out,
        overwrite=args.force,
        runs=runs,
        max_frames=MAX_FRAMES if args.max_frames is None else args.max_frames,
        max_mb=MAX_MB if args.max_mb is None else args.max_mb,
        title=args.title,
    )
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0


# -- crlbswarm report ------------------------------------------------------------------------
def _add_report(sub: Any) -> None:
    report, fields = _command(
        sub,
        "report",
        _cmd_report,
        help="write the HTML report of a campaign (outcomes, distributions, sortable tables)",
        description="Write one self-contained HTML page (works offline: data, script and "
        "style inline) from the Parquet dataset of a campaign written by crlbswarm sweep: "
        "per variant, the outcome counts, the distributions of the final CRLB / bound, the "
        "convergence time, the clearance and the separation, the sweep parameters, and "
        "tables sortable by column (docs/report.md).",
    )
    _option(report, fields, "campaign_dir", field="campaign_dir", type=_path,
            metavar="CAMPAIGN_DIR", help="the --out folder of crlbswarm sweep")  # fmt: skip
    fields["campaign_dir"] = "CAMPAIGN_DIR"
    _option(report, fields, "-o", "--out", field="out", required=True, type=_path,
            metavar="FILE", help="the HTML file to write, .html or .htm (its folder must "
            "exist; an existing file is refused unless --force)")  # fmt: skip
    report.add_argument("--force", action="store_true", help="replace FILE if it exists")
    _option(report, fields, "--max-run-rows", field="max_run_rows", type=int,
            default=None, metavar="N",
            help="embed the per-run rows when the campaign has at most N runs (0: never; "
            "default 100000)")  # fmt: skip


def _cmd_report(args: argparse.Namespace) -> int:
    from .report import MAX_RUN_ROWS, write_report

    rows = MAX_RUN_ROWS if args.max_run_rows is None else args.max_run_rows
    path = write_report(args.campaign_dir, args.out, overwrite=args.force, max_run_rows=rows)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0


def _message(exc: FieldError, fields: dict[str, str]) -> str:
    """The error's line, its library argument replaced by the option that set it (a field
    of a file, a ``ConfigError``, keeps the file's name and its own dotted field)."""
    option = None if isinstance(exc, ConfigError) else fields.get(exc.field)
    return str(exc) if option is None else f"{option}: {exc.reason}"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``crlbswarm`` console script.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; ``sys.argv[1:]`` if omitted.

    Returns
    -------
    int
        Exit status: 0 on success, 2 for an error the user can fix (printed as one line; a
        campaign task failing because of its input is a ``ValueError``, so it is one), 1 for
        a campaign that failed on its cluster (a worker lost), 130 when interrupted.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    # Warnings (numerical or from a library) are held back: printed as one line each after
    # a success, dropped when an error line is printed.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        status = _run(args)
    succeeded = status == 0 or (status == 1 and args.command == "simulate")  # (--strict)
    if succeeded:
        for text in dict.fromkeys(
            one_line(str(w.message)) for w in caught if not issubclass(w.category, _QUIET)
        ):
            print(f"crlbswarm: warning: {text}", file=sys.stderr)
    return status


#: Warnings meant for developers, not for the user of the command (libraries' deprecations).
_QUIET = (DeprecationWarning, PendingDeprecationWarning, ResourceWarning, ImportWarning)


def _run(args: argparse.Namespace) -> int:
    """Run the command; every failure becomes one line on stderr and an exit status."""
    try:
        return int(args.func(args))
    except FieldError as exc:
        return _fail(_message(exc, args.fields), EXIT_USAGE)
    except (ValueError, SimulationDivergedError) as exc:
        return _fail(str(exc), EXIT_USAGE)
    except CampaignError as exc:  # the cluster failed (input errors are ValueErrors, above)
        return _fail(str(exc), 1)
    except KeyboardInterrupt:
        kept = (
            "finished tasks are kept; run the same command again to resume"
            if args.command == "sweep"
            else "results are kept only as a complete set; none was left half-written"
        )
        print(f"crlbswarm: interrupted ({kept})", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader (e.g. ``| head``) went away: not an error of ours; silence the flush.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        return _fail(str(exc), EXIT_USAGE)
    except (MemoryError, RecursionError) as exc:  # a size or a depth beyond the checks
        what = "memory" if isinstance(exc, MemoryError) else "recursion depth"
        return _fail(f"not enough {what} for this input; use smaller sizes", EXIT_USAGE)
    except Exception as exc:  # a bug: one line, the traceback on demand
        if os.environ.get("CRLBSWARM_DEBUG"):
            raise
        return _fail(
            f"internal error ({type(exc).__name__}: {exc}); please report it "
            "(CRLBSWARM_DEBUG=1 shows the traceback)",
            1,
        )


def _fail(message: str, status: int) -> int:
    print(f"crlbswarm: error: {one_line(message)}", file=sys.stderr)
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
