"""The interactive replay: one self-contained HTML page of a batch of missions.

:func:`replay_html` turns a :class:`~crlbswarm.results.MissionResult` (or a
:class:`~crlbswarm.results.GroupMissionResult`, several targets) into one HTML file that
works offline: the data (decimated in time, :func:`frame_rows`), the script and the style
are inline, nothing is fetched. The page draws the obstacles, the UAVs' tracks, the
formation polygon, the target and the UAVs' estimate on a canvas (zoom with the wheel, pan
by dragging), with play, pause, speed, a time slider, a run selector and linked time plots
of the CRLB and its bound, the cost, eta, the clearance and the separation. Its state is
scriptable through ``window.crlbReplay`` (``docs/replay.md``).

The page's script and style are package files (``web/replay.js``, ``web/replay.css``,
``web/replay.html``); the generic pieces (:func:`package_text`, :func:`json_script`,
:func:`float32_base64`, :func:`html_page`) serve any self-contained page.
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
from .errors import FieldError
from .output import check_output_file, write_text
from .results import GroupMissionResult, MissionResult, load_results
from .webpage import html_page, json_script, package_text

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

#: Default cap on the frames of one run (each a kept step of the trajectories).
MAX_FRAMES = 600
#: Default cap on the size of the page's data, megabytes (10^6 bytes).
MAX_MB = 10.0
#: The fewest frames a run may have; a batch that does not fit at this rate is refused.
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


# -- generic pieces of a self-contained page ----------------------------------------------
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
    n_runs: int, values_per_frame: int, max_frames: int = MAX_FRAMES, max_mb: float = MAX_MB
) -> int:
    """The most frames each run may have for the page's data to fit in ``max_mb``.

    A frame of a run holds ``values_per_frame`` float32 numbers, 16/3 bytes each in
    base64; the result is ``min(max_frames, floor(max_mb * 1e6 / (n_runs *
    values_per_frame * 16/3)))``.

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

    Returns
    -------
    int
        Frames per run.

    Raises
    ------
    FieldError
        If fewer than :data:`MIN_FRAMES` frames per run would fit (field ``runs``).
    """
    per_frame = n_runs * values_per_frame * 16 / 3
    fit = int(max_mb * 1e6 // per_frame)
    if fit < MIN_FRAMES:
        most = max(1, int(max_mb * 1e6 // (MIN_FRAMES * values_per_frame * 16 / 3)))
        raise FieldError(
            "runs",
            f"{n_runs} runs do not fit in a page of {max_mb:g} MB at {MIN_FRAMES} frames per "
            f"run; choose at most {most} runs, or a larger size limit",
        )
    return min(max_frames, fit)


# -- the page's data ----------------------------------------------------------------------
def load_mission_folder(folder: str | os.PathLike[str]) -> MissionResult | GroupMissionResult:
    """The result in a ``crlbswarm simulate`` folder: one target
    (:func:`~crlbswarm.results.load_results`), or several (the ``group<g>/`` folders and
    the whole scenario).

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
        If the folder holds no complete result (field ``folder``).
    """
    path = Path(folder)
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
    """The time series at the frames, shape (runs, frames): the CRLB, cost and eta at the
    frames' steps (the cost, defined at steps 0..K-1, is NaN at the last step); the
    clearance and separation the smallest since the previous frame (at frame 0, its step),
    so that no near miss between two frames is lost."""
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
    group: MissionResult, members: list[int], runs: list[int], rows: np.ndarray
) -> dict[str, Any]:
    """One group's part of the page data (arrays as base64 float32)."""
    if group.positions is None:
        raise FieldError(
            "result",
            "has no trajectories (simulated with keep_trajectories=False or "
            "--no-trajectories): nothing to replay",
        )
    steps = group.trajectory_steps[rows]
    series = _series(group, runs, steps)
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
    return {
        "uavs": members,
        "leader": members[int(sc.uavs.leader)],
        "bound": float(group.bound),
        "target0": [float(v) for v in sc.target],
        "slotOffsets": np.round(slots, 6).tolist(),
        "targetMoving": moving,
        "target": float32_base64(target),
        "estimate": None if estimate is None else float32_base64(estimate),
        "positions": float32_base64(group.positions[np.asarray(runs)[:, None], rows]),
        "series": {name: float32_base64(v) for name, v in series.items()},
        "envelope": envelope,
        "metrics": {name: _finite(group.metrics[name][runs]) for name in RUN_METRICS},
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
    fits in ``max_mb`` over all the runs (:func:`frames_per_run`). Positions, target,
    estimate and the time series are taken at those steps.

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
    chosen = _run_indices(runs, first)
    cap = count(max_frames, "max_frames", MIN_FRAMES, 10**7)
    limit = positive_scalar(max_mb, "max_mb")
    kept = first.trajectory_steps
    per_run = frames_per_run(len(chosen), _values_per_frame(groups), cap, limit)
    rows = frame_rows(kept.shape[0], per_run)
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
            "maxFrames": cap,
            "maxMB": limit,
        },
        "frameStep": kept[rows].tolist(),
        "frameTime": np.round(first.time[kept[rows]], 9).tolist(),
        "runIndex": chosen,
        "seed": [int(s) for s in first.seeds[chosen]],
        "obstacles": {
            "rectangles": np.asarray(obstacles.rectangles, dtype=float).tolist(),
            "circles": np.asarray(obstacles.circles, dtype=float).tolist(),
        },
        "safetyRadius": float(sc.control.safety_radius),
        "minSeparation": float(sc.safety.min_separation),
        "groups": [_group_data(g, members, chosen, rows) for g, members in groups],
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
        The HTML file; its folder must exist.
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
        If the file exists (and not ``overwrite``) or cannot be written (field ``path``),
        or as :func:`replay_data`; nothing is written then.
    """
    dest = check_output_file(path, "path", overwrite=overwrite)
    page = replay_html(result, runs=runs, max_frames=max_frames, max_mb=max_mb, title=title)
    write_text(dest, page)
    return dest
