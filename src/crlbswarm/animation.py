"""Animation of one run of a mission: an MP4 or GIF file (``crlbswarm animate``).

Each frame shows the obstacles, every UAV's track so far, the UAVs (the leader in red), the
formation polygon (:func:`crlbswarm.geometry.outline_order`, so that it never crosses
itself), the formation flown over the target (F*, or the constrained design when F* is
blocked; named by :func:`crlbswarm.design.formation_labels`), the target and, with
estimation on, the UAVs' estimate of it; a caption gives the time, the scaling factor eta,
the CRLB and its ratio to the bound.

**Frames.** One frame per kept step of the run
(:attr:`crlbswarm.MissionResult.trajectory_steps`: every step, or every
``trajectory_stride``-th and the last), decimated evenly to at most ``max_frames``
(:func:`frame_steps`: the first and the last step always drawn), played at ``fps`` frames
per second. The tracks are drawn through every kept step, whatever the decimation.

**Files.** An ``.mp4`` (H.264, ``yuv420p``, playable everywhere) is encoded by the ffmpeg
binary of the optional package ``imageio-ffmpeg`` (``pip install 'crlbswarm[video]'``); a
``.gif`` needs only Pillow, which comes with Matplotlib. Either is written to a temporary
file beside the destination and renamed when complete
(:func:`crlbswarm.output.atomic_path`). Matplotlib, Pillow and imageio-ffmpeg are imported
only when an animation is made.

**GIF limits.** Pillow holds every frame of a GIF in memory until the file is written
(about 1.2 bytes per pixel): a GIF of more than :data:`GIF_MAX_PIXELS` pixels in all
(frames x width x height) is refused before anything is drawn; the defaults (300 frames of
at most 800 x 1120 pixels) always fit. A GIF stores each frame's delay in hundredths of a
second and browsers stretch delays under 2 to 10, so a GIF plays at most
:data:`GIF_MAX_FPS` frames per second, and at ``100 / round(100 / fps)`` exactly
(:func:`written_fps`).

**Several targets.** A :class:`~crlbswarm.results.GroupMissionResult` is animated one
group per file (:func:`animation_paths`), each titled with its UAVs' indices in the swarm.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _validation as _v
from .design import formation_labels
from .errors import FieldError
from .geometry import outline_order
from .output import atomic_path, check_output_file
from .results import GroupMissionResult, MissionResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "ANIMATION_FORMATS",
    "DEFAULT_FPS",
    "DEFAULT_MAX_FRAMES",
    "GIF_MAX_FPS",
    "GIF_MAX_PIXELS",
    "animate_mission",
    "animation_paths",
    "frame_size",
    "frame_steps",
    "written_fps",
]

#: The file suffixes :func:`animate_mission` writes.
ANIMATION_FORMATS = (".mp4", ".gif")

#: Frames per second by default.
DEFAULT_FPS = 20

#: Most frames by default (15 s at the default frame rate).
DEFAULT_MAX_FRAMES = 300

#: Largest frame rate, frames per second.
MAX_FPS = 120

#: Most frames (about 14 minutes at 120 frames per second).
MAX_FRAMES = 100_000

#: Largest frame rate of a GIF, frames per second (delays of 2 hundredths of a second).
GIF_MAX_FPS = 50

#: Most pixels of a GIF, all frames together (Pillow keeps every frame in memory).
GIF_MAX_PIXELS = 300_000_000

#: Width of a frame in inches (its pixels: this times ``dpi``, rounded to a multiple of 16).
FRAME_WIDTH_IN = 8.0

#: How to install what an MP4 needs.
VIDEO_HINT = "pip install 'crlbswarm[video]' (or pip install imageio-ffmpeg), or write a .gif"


def frame_steps(result: MissionResult, max_frames: int = DEFAULT_MAX_FRAMES) -> np.ndarray:
    """The steps an animation draws, one per frame.

    The kept steps (:attr:`crlbswarm.MissionResult.trajectory_steps`) if there are at most
    ``max_frames``, else ``max_frames`` of them evenly spaced: the kept step nearest to
    ``i (R - 1) / (max_frames - 1)`` (rounding half up) for ``i = 0 .. max_frames - 1``,
    which are distinct and include the first and the last step.

    Parameters
    ----------
    result : MissionResult
        Simulation result with trajectories.
    max_frames : int, default 300
        Most frames, at least 2.

    Returns
    -------
    ndarray of int64
        Steps (indices into ``result.time``), increasing; ``min(R, max_frames)`` of them for
        R kept steps.
    """
    limit = _v.count(max_frames, "max_frames", 2, MAX_FRAMES)
    kept = result.trajectory_steps
    if kept.size <= limit:
        return kept
    rows = np.floor(np.linspace(0.0, kept.size - 1, limit) + 0.5).astype(np.int64)
    return kept[rows]


def _ffmpeg() -> Any:
    """The module imageio_ffmpeg, with its ffmpeg binary found, or a FieldError saying how
    to install it."""
    try:
        import imageio_ffmpeg  # type: ignore[import-untyped]
    except ImportError:
        raise FieldError(
            "path", f"an .mp4 needs the optional package imageio-ffmpeg: {VIDEO_HINT}"
        ) from None
    try:
        imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as exc:
        raise FieldError(
            "path", f"an .mp4 needs an ffmpeg binary, and imageio-ffmpeg has none ({exc}); "
            f"{VIDEO_HINT}",
        ) from None  # fmt: skip
    return imageio_ffmpeg


def written_fps(path: str | os.PathLike[str], fps: int) -> float:
    """The frame rate an animation file plays at: ``fps`` for an MP4; for a GIF, whose
    delays are whole hundredths of a second, ``100 / round(100 / fps)``.

    Parameters
    ----------
    path : str or path-like
        The file (its suffix decides).
    fps : int
        The frame rate asked for, frames per second.

    Returns
    -------
    float
        Frames per second.

    Examples
    --------
    >>> from crlbswarm.animation import written_fps
    >>> written_fps("a.mp4", 30), round(written_fps("a.gif", 30), 2)
    (30.0, 33.33)
    """
    if Path(path).suffix.lower() == ".gif":
        return 100.0 / max(1, round(100 / fps))
    return float(fps)


def animation_paths(
    result: MissionResult | GroupMissionResult, path: str | os.PathLike[str]
) -> list[Path]:
    """The files :func:`animate_mission` writes: ``path`` for one target; for several
    targets one per group, ``<stem>_group<g><suffix>`` beside ``path``.

    Parameters
    ----------
    result : MissionResult or GroupMissionResult
        The result to animate.
    path : str or path-like
        The destination asked for.

    Returns
    -------
    list of pathlib.Path
        The files, in the order of the groups.
    """
    dest = Path(path)
    if isinstance(result, GroupMissionResult):
        return [dest.with_name(f"{dest.stem}_group{g}{dest.suffix}")
                for g in range(len(result.groups))]  # fmt: skip
    return [dest]


def _parts(result: MissionResult | GroupMissionResult) -> list[tuple[MissionResult, str]]:
    """Each result to draw and the words of its title that name its UAVs ("" for one
    target)."""
    if isinstance(result, GroupMissionResult):
        steps = result.groups[0].trajectory_steps
        if any(not np.array_equal(g.trajectory_steps, steps) for g in result.groups):
            raise FieldError("result", "its groups keep their trajectories at other steps")
        return [
            (group, f"group {g}: UAVs {', '.join(str(int(u) + 1) for u in members)} of "
             f"{result.scenario.uavs.count}, ")
            for g, (group, members) in enumerate(zip(result.groups, result.plan.members,
                                                     strict=True))
        ]  # fmt: skip
    if isinstance(result, MissionResult):
        return [(result, "")]
    raise FieldError(
        "result", f"must be a MissionResult or a GroupMissionResult, got {type(result).__name__}"
    )


def animate_mission(
    result: MissionResult | GroupMissionResult,
    path: str | os.PathLike[str],
    run: int = 0,
    *,
    fps: int = DEFAULT_FPS,
    max_frames: int = DEFAULT_MAX_FRAMES,
    dpi: int = 100,
    overwrite: bool = False,
) -> int:
    """Write an animation of one run: an MP4 or a GIF, by the suffix of ``path``.

    Everything is checked before anything is drawn or written: the run, the trajectories,
    the options, the size of a GIF, the destination and, for an MP4, the ffmpeg of
    imageio-ffmpeg. The frames are :func:`frame_steps`; the file is written atomically.

    Parameters
    ----------
    result : MissionResult or GroupMissionResult
        Simulation result with trajectories (``simulate(..., keep_trajectories=True)``, or
        :func:`crlbswarm.load_results` of a ``simulate`` folder); with several targets,
        one file per group (:func:`animation_paths`).
    path : str or path-like
        Destination, ``.mp4`` or ``.gif``; its folder must exist.
    run : int, default 0
        Index of the run in the batch.
    fps : int, default 20
        Frames per second, 1 to 120; for a GIF at most 50, played at
        ``100 / round(100 / fps)`` (:func:`written_fps`: its delays are hundredths of a
        second).
    max_frames : int, default 300
        Most frames, 2 to 100 000; a GIF has at most :data:`GIF_MAX_PIXELS` pixels in all.
    dpi : int, default 100
        Pixels per inch of the frames, 20 to 600: a frame is 8 inches wide (800 pixels at
        100 dpi), rounded to a multiple of 16 pixels, its height following the scene.
    overwrite : bool, default False
        Replace an existing file.

    Returns
    -------
    int
        The number of frames written (in each file).

    Raises
    ------
    FieldError
        If an argument is invalid (naming it; a GIF too large names ``max_frames``), the
        result has no trajectories (field ``result``), or an MP4 is asked for without
        imageio-ffmpeg (field ``path``).
    """
    dest = Path(path)
    suffix = dest.suffix.lower()
    if suffix not in ANIMATION_FORMATS:
        raise FieldError("path", f"expected a file name ending in .mp4 or .gif, got {str(dest)!r}")
    parts = _parts(result)
    b = parts[0][0].run_index(run)
    if any(part.positions is None for part, _ in parts):
        raise FieldError("result", "has no trajectories to animate (simulated with "
                         "keep_trajectories=False or --no-trajectories)")  # fmt: skip
    rate = _v.count(fps, "fps", 1, MAX_FPS)
    if suffix == ".gif" and rate > GIF_MAX_FPS:
        raise FieldError("fps", f"a GIF plays at most {GIF_MAX_FPS} frames per second (its "
                         "delays are hundredths of a second, and browsers stretch shorter "
                         f"ones), got {rate}; write an .mp4 for more")  # fmt: skip
    steps = frame_steps(parts[0][0], max_frames)
    resolution = _v.count(dpi, "dpi", 20, 600)
    if suffix == ".gif":
        _check_gif_size(steps.size, [frame_size(part, b, resolution) for part, _ in parts])
    dests = animation_paths(result, dest)
    for each in dests:
        check_output_file(each, "path", overwrite=overwrite)
    ffmpeg = _ffmpeg() if suffix == ".mp4" else None
    for (part, words), each in zip(parts, dests, strict=True):
        scene = _Scene(part, b, resolution, words)
        frames = (scene.frame(int(k)) for k in steps)
        with atomic_path(each) as tmp:
            if ffmpeg is not None:
                _write_mp4(ffmpeg, tmp, frames, scene.size, rate)
            else:
                _write_gif(tmp, frames, rate)
    return int(steps.size)


def _check_gif_size(n_frames: int, sizes: list[tuple[int, int]]) -> None:
    """Refuse a GIF whose frames hold more than :data:`GIF_MAX_PIXELS` pixels in all."""
    width, height = max(sizes, key=lambda wh: wh[0] * wh[1])
    pixels = n_frames * width * height
    if pixels > GIF_MAX_PIXELS:
        raise FieldError(
            "max_frames", f"a GIF of {n_frames} frames of {width} x {height} pixels holds "
            f"{pixels:.3g} pixels in memory, more than its limit of {GIF_MAX_PIXELS:.0e}: "
            "give fewer frames (--max-frames) or a lower dpi (--dpi), or write an .mp4",
        )  # fmt: skip


def frame_size(result: MissionResult, run: int = 0, dpi: int = 100) -> tuple[int, int]:
    """The width and height in pixels of the frames of a run's animation.

    The width is 8 inches at ``dpi``, rounded to a multiple of 16 pixels; the map takes 70 %
    of it (the legend the rest) and 80 % of the height, which follows the scene's aspect
    ratio (clipped to 0.35 .. 1.6), rounded to a multiple of 16 pixels.

    Parameters
    ----------
    result : MissionResult
        Simulation result with trajectories.
    run : int, default 0
        Index of the run in the batch.
    dpi : int, default 100
        Pixels per inch, 20 to 600.

    Returns
    -------
    (int, int)
        Width and height, pixels.
    """
    b = result.run_index(run)
    resolution = _v.count(dpi, "dpi", 20, 600)
    low, high = _extent(result, b)
    span = high - low
    width = 16 * round(FRAME_WIDTH_IN * resolution / 16)
    ratio = float(np.clip(span[1] / span[0], 0.35, 1.6))
    return width, 16 * max(1, round(width * 0.70 * ratio / 0.80 / 16))


def _extent(result: MissionResult, run: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corners of what is drawn of a run, with a margin, m."""
    if result.positions is None:
        raise FieldError("result", "has no trajectories to animate")
    points = [result.positions[run].reshape(-1, 2), result.target[run]]
    if result.estimate is not None:
        points.append(result.estimate[run])
    slots = result.scenario.slots - np.asarray(result.scenario.target)
    points.append(result.target[run, -1] + slots)
    allp = np.concatenate(points)
    low, high = allp.min(axis=0), allp.max(axis=0)
    pad = 0.06 * float(np.max(high - low)) + 3.0
    return low - pad, high + pad


def _write_mp4(
    ffmpeg: Any, path: Path, frames: Iterator[np.ndarray], size: tuple[int, int], fps: int
) -> None:
    """Pipe RGB frames to ffmpeg (H.264, yuv420p)."""
    writer = ffmpeg.write_frames(str(path), size, fps=fps, quality=7, macro_block_size=16,
                                 ffmpeg_log_level="error")  # fmt: skip
    writer.send(None)  # start ffmpeg
    try:
        for frame in frames:
            writer.send(frame.tobytes())
    finally:
        writer.close()


def _write_gif(path: Path, frames: Iterator[np.ndarray], fps: int) -> None:
    """Write RGB frames as a looping GIF (each with its own palette of 64 colours)."""
    from PIL import Image

    fast = Image.Quantize.FASTOCTREE
    images = (Image.fromarray(frame).quantize(colors=64, method=fast) for frame in frames)
    first = next(images)
    duration = 10 * max(1, round(100 / fps))  # GIF delays are hundredths of a second
    first.save(path, format="GIF", save_all=True, append_images=images, duration=duration,
               loop=0, optimize=False)  # fmt: skip


class _Scene:
    """The figure of one run, drawn once; :meth:`frame` moves its artists to a step."""

    def __init__(self, result: MissionResult, run: int, dpi: int, words: str = "") -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        self.result, self.run, self.words = result, run, words
        self.rows = {int(k): i for i, k in enumerate(result.trajectory_steps)}
        if result.positions is None:
            raise FieldError("result", "has no trajectories to animate")
        self.q: np.ndarray = result.positions[run]
        self.fig, self.size = self._figure(dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self._draw_static()
        # Blitting: the still parts are drawn once; each frame restores them and draws the
        # moving artists over them (made animated after the legend copied their styles).
        estimate = [] if self.estimate is None else [self.estimate]
        self.moving = [self.optimum, self.polygon, *self.tracks, self.uavs, self.target,
                       *estimate, self.caption]  # fmt: skip
        for artist in self.moving:
            artist.set_animated(True)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)

    def _figure(self, dpi: int) -> tuple[Figure, tuple[int, int]]:
        from matplotlib.figure import Figure

        low, high = _extent(self.result, self.run)
        span = high - low
        width, height = frame_size(self.result, self.run, dpi)
        fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        box = (0.08, 0.08, 0.70, 0.80)
        self.ax = fig.add_axes(box)
        # Limits that fill the axes at equal scales: the shorter side widened about its middle.
        scale = max(span[0] / (box[2] * width), span[1] / (box[3] * height))
        middle, half = (low + high) / 2, scale * np.array([box[2] * width, box[3] * height]) / 2
        self.ax.set_xlim(middle[0] - half[0], middle[0] + half[0])
        self.ax.set_ylim(middle[1] - half[1], middle[1] + half[1])
        self.ax.set_aspect("equal", adjustable="box")
        return fig, (width, height)

    def _draw_static(self) -> None:
        from matplotlib.patches import Polygon

        from .plots import draw_obstacles  # (Matplotlib is loaded by now)

        r, ax = self.result, self.ax
        sc = r.scenario
        draw_obstacles(ax, sc.obstacle_set)
        leader, m_uavs = sc.uavs.leader, self.q.shape[1]
        colours = [f"C{m % 10}" if m % 10 != 3 else "C9" for m in range(m_uavs)]
        colours[leader] = "C3"
        self.tracks = [
            ax.plot([], [], lw=1.4 if m == leader else 0.7, color=colours[m], alpha=0.8,
                    label="leader's track" if m == leader else None)[0]
            for m in range(m_uavs)
        ]  # fmt: skip
        self.tracks[(leader + 1) % m_uavs].set_label("followers' tracks")
        self.slots = np.asarray(sc.slots) - np.asarray(sc.target)
        self.slots = self.slots[outline_order(self.slots)]
        self.optimum = Polygon(self.slots, closed=True, fill=False, ec="C3", ls="--", lw=0.9,
                               label=formation_labels(sc)["formation"])  # fmt: skip
        ax.add_patch(self.optimum)
        self.polygon = Polygon(self.q[0], closed=True, fc="C0", alpha=0.12, ec="k", lw=1.0,
                               label="formation")  # fmt: skip
        ax.add_patch(self.polygon)
        self.uavs = ax.scatter(self.q[0, :, 0], self.q[0, :, 1], s=22, c=colours, zorder=5,
                               edgecolors="k", linewidths=0.5, label="UAVs")  # fmt: skip
        (self.target,) = ax.plot([], [], "*", ms=13, color="C3", mec="k", mew=0.5, zorder=6,
                                 label="target")  # fmt: skip
        self.estimate = None
        if r.estimate is not None:
            (self.estimate,) = ax.plot([], [], "X", ms=8, color="k", zorder=6,
                                       label="UAVs' estimate")  # fmt: skip
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
        seed = int(r.seeds[self.run])
        self.fig.text(0.08, 0.975, f"scenario '{sc.name}', {self.words}run {self.run} "
                      f"(seed {seed})", fontsize=9, va="top", parse_math=False)  # fmt: skip
        self.caption = self.fig.text(0.08, 0.945, "", fontsize=9, va="top", family="monospace")

    def frame(self, step: int) -> np.ndarray:
        """The RGB pixels, shape (height, width, 3), of the scene at ``step``."""
        r, b = self.result, self.run
        row = self.rows[step]
        q = self.q[row]
        for m, track in enumerate(self.tracks):
            track.set_data(self.q[: row + 1, m, 0], self.q[: row + 1, m, 1])
        self.polygon.set_xy(q[outline_order(q)])
        self.uavs.set_offsets(q)
        target = r.target[b, step]
        self.target.set_data([target[0]], [target[1]])
        self.optimum.set_xy(self.slots + target)
        crlb = r.crlb[b, step]
        text = (
            f"t = {r.time[step]:6.1f} s   η = {r.eta[b, step]:.3f}   "
            f"CRLB = {crlb:.3g} m² = {crlb / r.bound:{'.3f' if crlb < 100 * r.bound else '.3g'}}"
            " × bound"
        )
        if self.estimate is not None and r.estimate is not None:
            estimate = r.estimate[b, step]
            self.estimate.set_data([estimate[0]], [estimate[1]])
            text += f"\nestimate {np.hypot(*(estimate - target)):.2f} m from the target"
        self.caption.set_text(text)
        self.canvas.restore_region(self.background)
        for artist in self.moving:
            self.fig.draw_artist(artist)
        return np.ascontiguousarray(np.asarray(self.canvas.buffer_rgba())[..., :3])
