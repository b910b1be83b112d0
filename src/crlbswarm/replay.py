"""The interactive replay: one self-contained HTML page of a batch of missions.

:func:`replay_html` turns a :class:`~crlbswarm.results.MissionResult` (or a
:class:`~crlbswarm.results.GroupMissionResult`, several targets) into one HTML file that
works offline: the data (decimated in time, :func:`frame_rows`: the map's frames among the
kept steps of the trajectories, the time plots' points among every step), the script and
the style are inline, nothing is fetched. The page draws the obstacles, the UAVs' tracks, the
formation polygon, the target and the UAVs' estimate on a canvas (zoom with the wheel, pan
by dragging), with play, pause, speed, a time slider, a run selector and linked time plots
of the CRLB and its bound, the cost, eta, the clearance and the separation. Its state is
scriptable through ``window.crlbReplay`` (``docs/replay.md``).

The page's script and style are package files (``web/replay.js``, ``web/replay.css``,
``web/replay.html``), assembled by :mod:`crlbswarm.webpage`.

:func:`load_mission_folder` reads any ``crlbswarm simulate`` folder (one target or
several): ``crlbswarm replay``, ``plot`` and ``animate`` all load through it.
"""

from __future__ import annotations

import base64
import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from ._validation import count, positive_scalar
from .design import formation_labels
from .errors import FieldError
from .output import check_output_file, write_text
from .results import GroupMissionResult, MissionResult, load_results
from .webpage import check_page_path, html_page, json_script, package_text

__all__ = [
    "MAX_FRAMES",
    "MAX_MB",
    "MIN_FRAMES",
    "float32_base64",
    "frame_rows",
    "frames_per_run",
    "interval_minima",
    "load_mission_folder",
    "replay_data",
    "replay_html",
    "write_replay",
]

#: Default cap on the frames of one run (each a kept step of the trajectories), and on the
#: points of each of its time series (each a step).
MAX_FRAMES = 600
#: Default cap on the size of the page's data, megabytes (10^6 bytes).
MAX_MB = 10.0
#: The fewest frames a run may have (or all its kept steps, if fewer); a batch that does
#: not fit at this rate is refused.
MIN_FRAMES = 20

#: The per-step series drawn in the time plots, in the page's order.
SERIES = ("crlb", "cost", "eta", "clearance", "separation")

#: The per-run metrics shown in the page's run panel.
RUN_METRICS = (
    "outcome",
    "convergence_time_s",
    "final_crlb_ratio",
    "min_clearance_m",
    "min_separation_m",
)


# -- arrays in the page ------------------------------------------------------------------
def float32_base64(values: Any) -> str:
    """An array as base64 of its little-endian float32 bytes, in C order (NaN and
    infinities kept; JavaScript reads it into a ``Float32Array``).

    Parameters
    ----------
    values : array_like
        Numbers.

    Returns
    -------
    str
        The base64 text (4/3 byte per byte of float32).
    """
    raw = np.ascontiguousarray(values, dtype="<f4").tobytes()
    return base64.b64encode(raw).decode("ascii")


# -- decimation -------------------------------------------------------------------------
def frame_rows(n_rows: int, max_frames: int) -> np.ndarray:
    """The kept rows a page shows: a uniform stride over ``0 .. n_rows - 1`` and the last.

    The stride is the smallest that gives at most ``max_frames`` rows:
    ``ceil((n_rows - 1) / (max_frames - 1))``; the last row is always kept (the end of the
    mission), so the last interval may be shorter than the others.

    Parameters
    ----------
    n_rows : int
        Rows available (the kept steps of the trajectories), at least 1.
    max_frames : int
        Most rows to keep, at least 2.

    Returns
    -------
    ndarray of int64
        The rows, increasing, from 0 to ``n_rows - 1``.
    """
    if n_rows <= 1:
        return np.zeros(min(n_rows, 1), dtype=np.int64)
    stride = max(1, math.ceil((n_rows - 1) / (max(max_frames, 2) - 1)))
    rows = np.arange(0, n_rows, stride, dtype=np.int64)
    return rows if rows[-1] == n_rows - 1 else np.append(rows, n_rows - 1)


def frames_per_run(
    n_runs: int,
    values_per_frame: int,
    max_frames: int = MAX_FRAMES,
    max_mb: float = MAX_MB,
    min_frames: int = MIN_FRAMES,
) -> int:
    """The most frames each run may have for the page's data to fit in ``max_mb``.

    A frame of a run holds ``values_per_frame`` float32 numbers, 16/3 bytes each in
    base64 (the map's positions at a frame, and the time series at as many points); the
    result is ``min(max_frames, floor(max_mb * 1e6 / (n_runs * values_per_frame * 16/3)))``.

    Parameters
    ----------
    n_runs : int
        Runs in the page.
    values_per_frame : int
        Numbers per frame and run (positions, series, moving target, estimate).
    max_frames : int, default MAX_FRAMES
        Cap per run.
    max_mb : float, default MAX_MB
        Cap on the data, 10^6 bytes.
    min_frames : int, default MIN_FRAMES
        The fewest frames a run may have (``min(MIN_FRAMES, R)`` for R kept steps).

    Returns
    -------
    int
        Frames per run.

    Raises
    ------
    FieldError
        If fewer than ``min_frames`` frames per run would fit: field ``runs`` (naming how
        many runs would fit), or ``max_mb`` if not even one run fits.
    """
    per_frame = n_runs * values_per_frame * 16 / 3
    fit = int(max_mb * 1e6 // per_frame)
    if fit < min_frames:
        one_run = min_frames * values_per_frame * 16 / 3
        most = int(max_mb * 1e6 // one_run)
        if most < 1:
            raise FieldError(
                "max_mb", f"no run fits in a page of {max_mb:g} MB: one run at {min_frames} "
                f"frames takes {one_run / 1e6:.3g} MB; give a larger size limit",
            )  # fmt: skip
        raise FieldError(
            "runs",
            f"{n_runs} runs do not fit in a page of {max_mb:g} MB at {min_frames} frames per "
            f"run; choose at most {most} runs, or a larger size limit",
        )
    return min(max_frames, fit)


# -- the page's data ----------------------------------------------------------------------
def load_mission_folder(folder: str | os.PathLike[str]) -> MissionResult | GroupMissionResult:
    """The result in a ``crlbswarm simulate`` folder: one target
    (:func:`~crlbswarm.results.load_results`), or several (the ``group<g>/`` folders and
    the whole scenario). ``crlbswarm replay``, ``plot`` and ``animate`` read their
    ``RUNS_DIR`` with it.

    Parameters
    ----------
    folder : str or path-like
        The folder.

    Returns
    -------
    MissionResult or GroupMissionResult
        The result.

    Raises
    ------
    FieldError
        If the folder does not exist, is not a folder or holds no complete result (field
        ``folder``).
    """
    path = Path(folder)
    if not path.exists():
        raise FieldError("folder", f"{str(path)!r} does not exist")
    if not path.is_dir():
        raise FieldError("folder", f"{str(path)!r} is not a folder")
    if (path / "trajectories.npz").is_file() or not (path / "group0").is_dir():
        return load_results(path)
    from .scenario import load_scenario

    if not (path / "scenario.toml").is_file():
        raise FieldError("folder", f"{str(path)!r} holds groups but no scenario.toml")
    scenario = load_scenario(path / "scenario.toml")
    plan = scenario.group_plan
    if plan is None:
        raise FieldError("folder", f"{str(path)!r} holds groups but its scenario has one target")
    groups = tuple(load_results(path / f"group{g}") for g in range(len(plan.members)))
    return GroupMissionResult(scenario=scenario, plan=plan, groups=groups)


def _groups(result: MissionResult | GroupMissionResult) -> list[tuple[MissionResult, list[int]]]:
    """Each group's result and its UAVs' indices in the swarm (one group for one target)."""
    if isinstance(result, MissionResult):
        return [(result, list(range(result.scenario.uavs.count)))]
    if isinstance(result, GroupMissionResult):
        out = [
            (g, [int(i) for i in members])
            for g, members in zip(result.groups, result.plan.members, strict=True)
        ]
        steps = out[0][0].trajectory_steps
        for group, _ in out[1:]:
            if not np.array_equal(group.trajectory_steps, steps):
                raise FieldError("result", "its groups keep their trajectories at other steps")
        return out
    raise FieldError(
        "result", f"must be a MissionResult or a GroupMissionResult, got {type(result).__name__}"
    )


def _run_indices(runs: Iterable[int] | None, first: MissionResult) -> list[int]:
    """The runs to show, checked (all of them by default)."""
    if runs is None:
        return list(range(first.n_runs))
    if isinstance(runs, str | bytes):
        raise FieldError("runs", f"must be run indices, got {runs!r}")
    chosen = []
    for run in runs:
        try:
            chosen.append(first.run_index(run))
        except FieldError as exc:
            raise FieldError("runs", exc.reason) from None
    if not chosen:
        raise FieldError("runs", "must name at least one run")
    if len(set(chosen)) != len(chosen):
        raise FieldError("runs", "names a run twice")
    return chosen


def _values_per_frame(groups: list[tuple[MissionResult, list[int]]]) -> int:
    """Float32 numbers per frame and run: each group's positions, its series, its moving
    target and its estimate."""
    total = 0
    for group, members in groups:
        total += 2 * len(members) + len(SERIES)
        total += 2 * int(_moving(group)) + 2 * int(group.estimate is not None)
    return total


def _moving(group: MissionResult) -> bool:
    """Whether the target moves in some run."""
    return bool(np.any(group.target != group.target[:, :1]))


def _finite(values: Any) -> list[Any]:
    """A list for JSON: numbers (None where not finite) or strings."""
    out: list[Any] = []
    for v in np.asarray(values).tolist():
        out.append(v if isinstance(v, str) or (v is not None and math.isfinite(v)) else None)
    return out


def _series(group: MissionResult, runs: list[int], steps: np.ndarray) -> dict[str, np.ndarray]:
    """The time series at their points (``steps``, among every step), shape (runs, points):
    the CRLB, cost and eta at those steps (the cost, defined at steps 0..K-1, is NaN at the
    last step); the clearance and separation the smallest since the previous point (at
    point 0, its step), so that no near miss between two points is lost."""
    cost = np.concatenate([group.cost, np.full((group.n_runs, 1), np.nan)], axis=1)
    out = {
        "crlb": group.crlb[runs][:, steps],
        "cost": cost[runs][:, steps],
        "eta": group.eta[runs][:, steps],
    }
    for name in ("clearance", "separation"):
        values = np.asarray(getattr(group, name))[runs]
        out[name] = values[:, steps] if steps.shape[0] < 2 else interval_minima(values, steps)
    return {name: out[name] for name in SERIES}


def interval_minima(values: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """The smallest value over the steps since the previous frame, at each frame.

    Parameters
    ----------
    values : ndarray, shape (B, K+1)
        A series at every step.
    steps : ndarray of int, shape (F,)
        The frames' steps, increasing, from 0 to K (F >= 2).

    Returns
    -------
    ndarray, shape (B, F)
        At frame 0 the value at step 0; at frame i the minimum over the steps
        ``steps[i-1] + 1 .. steps[i]``.
    """
    tail = np.minimum.reduceat(values[:, 1:], steps[:-1], axis=1)
    return np.concatenate([values[:, :1], tail], axis=1)


def _group_data(
    group: MissionResult,
    members: list[int],
    runs: list[int],
    rows: np.ndarray,
    points: np.ndarray,
) -> dict[str, Any]:
    """One group's part of the page data (arrays as base64 float32): positions, target and
    estimate at the frames (``rows`` of the kept steps), the series at their ``points``
    (steps)."""
    assert group.positions is not None
    steps = group.trajectory_steps[rows]
    series = _series(group, runs, points)
    sc = group.scenario
    slots = np.asarray(sc.slots) - np.asarray(sc.target, dtype=float)
    moving = _moving(group)
    target = group.target[runs][:, steps] if moving else group.target[runs][:, 0]
    estimate = None if group.estimate is None else group.estimate[runs][:, steps]
    envelope = None
    if len(runs) > 1:  # the band of the batch: min and max over the runs at each frame
        envelope = {
            name: float32_base64(np.stack([np.fmin.reduce(v, axis=0), np.fmax.reduce(v, axis=0)]))
            for name, v in series.items()
        }
    metrics = {name: group.metrics[name][runs] for name in RUN_METRICS}
    converged = metrics["outcome"] == "converged"  # (a time only for the converged runs)
    metrics["convergence_time_s"] = np.where(converged, metrics["convergence_time_s"], np.nan)
    return {
        "uavs": members,
        "leader": members[int(sc.uavs.leader)],
        "bound": float(group.bound),
        **{f"{key}Label": text for key, text in formation_labels(sc).items()},
        "target0": [float(v) for v in sc.target],
        "slotOffsets": np.round(slots, 6).tolist(),
        "targetMoving": moving,
        "target": float32_base64(target),
        "estimate": None if estimate is None else float32_base64(estimate),
        "positions": float32_base64(group.positions[np.asarray(runs)[:, None], rows]),
        "series": {name: float32_base64(v) for name, v in series.items()},
        "envelope": envelope,
        "metrics": {name: _finite(values) for name, values in metrics.items()},
    }


def replay_data(
    result: MissionResult | GroupMissionResult,
    *,
    runs: Iterable[int] | None = None,
    max_frames: int = MAX_FRAMES,
    max_mb: float = MAX_MB,
    title: str | None = None,
) -> dict[str, Any]:
    """The data of the replay page, JSON-ready (arrays as base64 float32).

    Each run keeps the same frames: :func:`frame_rows` over the kept steps of the
    trajectories (``result.trajectory_steps``), at most ``max_frames`` and at most what
    fits in ``max_mb`` over all the runs (:func:`frames_per_run`); positions, target and
    estimate are taken at those steps. The time series have their own points, as many at
    most, chosen by :func:`frame_rows` among *every* step (so that trajectories kept every
    few steps still get detailed time plots).

    Parameters
    ----------
    result : MissionResult or GroupMissionResult
        The missions, with their trajectories.
    runs : iterable of int, optional
        Indices of the runs to show, in the order of the run selector (default all).
    max_frames : int, default MAX_FRAMES
        Most frames per run (at least :data:`MIN_FRAMES`).
    max_mb : float, default MAX_MB
        Most megabytes (10^6 bytes) of data in the page.
    title : str, optional
        Title of the page (default: the scenario's name and the number of runs).

    Returns
    -------
    dict
        The page's data (``docs/replay.md``).

    Raises
    ------
    FieldError
        If the result has no trajectories (field ``result``), a run index is invalid or
        the runs do not fit (``runs``), or a limit is out of range (``max_frames``,
        ``max_mb``).
    """
    from . import __version__

    groups = _groups(result)
    first = groups[0][0]
    if any(group.positions is None for group, _ in groups):
        raise FieldError(
            "result",
            "has no trajectories (simulated with keep_trajectories=False or "
            "--no-trajectories): nothing to replay",
        )
    chosen = _run_indices(runs, first)
    cap = count(max_frames, "max_frames", MIN_FRAMES, 10**7)
    limit = positive_scalar(max_mb, "max_mb")
    kept = first.trajectory_steps
    fewest = min(MIN_FRAMES, kept.shape[0])
    per_run = frames_per_run(len(chosen), _values_per_frame(groups), cap, limit, fewest)
    rows = frame_rows(kept.shape[0], per_run)
    points = frame_rows(first.time.shape[0], per_run)  # the series' steps (every step there)
    sc = result.scenario
    obstacles = sc.obstacle_set
    name = sc.name
    return {
        "format": 1,
        "generator": f"crlbswarm {__version__}",
        "title": title or f"{name}: {len(chosen)} run{'s' if len(chosen) > 1 else ''}",
        "scenario": name,
        "description": sc.description,
        "step": float(sc.time.step),
        "steps": int(first.time.shape[0] - 1),
        "decimation": {
            "trajectoryStride": int(first.trajectory_stride),
            "keptSteps": int(kept.shape[0]),
            "frameStride": int(rows[1] - rows[0]) if rows.shape[0] > 1 else 1,
            "frames": int(rows.shape[0]),
            "seriesStride": int(points[1] - points[0]) if points.shape[0] > 1 else 1,
            "seriesPoints": int(points.shape[0]),
            "maxFrames": cap,
            "maxMB": limit,
        },
        "frameStep": kept[rows].tolist(),
        "frameTime": np.round(first.time[kept[rows]], 9).tolist(),
        "seriesStep": points.tolist(),
        "seriesTime": np.round(first.time[points], 9).tolist(),
        "runIndex": chosen,
        "seed": [int(s) for s in first.seeds[chosen]],
        "obstacles": {
            "rectangles": np.asarray(obstacles.rectangles, dtype=float).tolist(),
            "circles": np.asarray(obstacles.circles, dtype=float).tolist(),
        },
        "safetyRadius": float(sc.control.safety_radius),
        "minSeparation": float(sc.safety.min_separation),
        "groups": [_group_data(g, members, chosen, rows, points) for g, members in groups],
    }


def replay_html(
    result: MissionResult | GroupMissionResult,
    *,
    runs: Iterable[int] | None = None,
    max_frames: int = MAX_FRAMES,
    max_mb: float = MAX_MB,
    title: str | None = None,
) -> str:
    """The replay page of a result: one self-contained HTML document (works offline).

    Parameters
    ----------
    result : MissionResult or GroupMissionResult
        The missions, with their trajectories (``crlbswarm.load_results(folder)`` reads a
        ``crlbswarm simulate`` folder).
    runs : iterable of int, optional
        Indices of the runs to show (default all).
    max_frames : int, default MAX_FRAMES
        Most frames per run.
    max_mb : float, default MAX_MB
        Most megabytes of data in the page: a large batch gets fewer frames per run.
    title : str, optional
        Title of the page.

    Returns
    -------
    str
        The HTML.

    Raises
    ------
    FieldError
        As :func:`replay_data`.

    Examples
    --------
    >>> import crlbswarm
    >>> from crlbswarm.replay import replay_html
    >>> data = crlbswarm.BUILTIN_SCENARIOS["paper"]
    >>> data["time"].update(duration=5.0, hold=2.0)
    >>> result = crlbswarm.simulate(crlbswarm.Scenario.from_dict(data), seeds=[0, 1])
    >>> page = replay_html(result)
    >>> page.startswith("<!DOCTYPE html>") and "crlbReplay" in page
    True
    """
    data = replay_data(result, runs=runs, max_frames=max_frames, max_mb=max_mb, title=title)
    return html_page(
        data["title"],
        package_text("replay.css"),
        package_text("replay.html"),
        [
            json_script(data, "crlb-replay-data"),
            f"<script>\n{package_text('replay.js')}\n</script>",
        ],
    )


def write_replay(
    result: MissionResult | GroupMissionResult,
    path: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    runs: Iterable[int] | None = None,
    max_frames: int = MAX_FRAMES,
    max_mb: float = MAX_MB,
    title: str | None = None,
) -> Path:
    """Write the replay page of a result (:func:`replay_html`) to ``path``, atomically.

    Parameters
    ----------
    result : MissionResult or GroupMissionResult
        The missions, with their trajectories.
    path : str or path-like
        The HTML file (``.html`` or ``.htm``); its folder must exist.
    overwrite : bool, default False
        Replace an existing file.
    runs : iterable of int, optional
        Indices of the runs to show (default all).
    max_frames : int, default MAX_FRAMES
        Most frames per run.
    max_mb : float, default MAX_MB
        Most megabytes of data in the page.
    title : str, optional
        Title of the page.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    FieldError
        If the file does not end in ``.html`` or ``.htm``, exists (and not ``overwrite``)
        or cannot be written (field ``path``), or as :func:`replay_data`; nothing is
        written then.
    """
    dest = check_output_file(check_page_path(path, "path"), "path", overwrite=overwrite)
    page = replay_html(result, runs=runs, max_frames=max_frames, max_mb=max_mb, title=title)
    write_text(dest, page)
    return dest
