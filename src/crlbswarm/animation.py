"""Animation of one run of a mission: an MP4 or GIF file (``crlbswarm animate``).

Each frame shows the obstacles, every UAV's track so far, the UAVs (the leader in red), the
formation polygon (the UAVs in order of their angle around the centroid, so that it never
crosses itself), the CRLB-optimal formation F* over the target, the target and, with
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
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _validation as _v
from .errors import FieldError
from .output import atomic_path, check_output_file
from .results import MissionResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "ANIMATION_FORMATS",
    "DEFAULT_FPS",
    "DEFAULT_MAX_FRAMES",
    "animate_mission",
    "frame_steps",
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


def animate_mission(
    result: MissionResult,
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
    the options, the destination and, for an MP4, the ffmpeg of imageio-ffmpeg. The frames
    are :func:`frame_steps`; the file is written atomically.

    Parameters
    ----------
    result : MissionResult
        Simulation result with trajectories (``simulate(..., keep_trajectories=True)``, or
        :func:`crlbswarm.load_results` of a ``simulate`` folder).
    path : str or path-like
        Destination, ``.mp4`` or ``.gif``; its folder must exist.
    run : int, default 0
        Index of the run in the batch.
    fps : int, default 20
        Frames per second, 1 to 120 (a GIF stores each frame's duration in hundredths of a
        second: ``round(100 / fps)``).
    max_frames : int, default 300
        Most frames, 2 to 100 000.
    dpi : int, default 100
        Pixels per inch of the frames, 20 to 600: a frame is 8 inches wide (800 pixels at
        100 dpi), rounded to a multiple of 16 pixels, its height following the scene.
    overwrite : bool, default False
        Replace an existing file.

    Returns
    -------
    int
        The number of frames written.

    Raises
    ------
    FieldError
        If an argument is invalid (naming it), the result has no trajectories (field
        ``result``), or an MP4 is asked for without imageio-ffmpeg (field ``path``).
    """
    dest = Path(path)
    suffix = dest.suffix.lower()
    if suffix not in ANIMATION_FORMATS:
        raise FieldError("path", f"expected a file name ending in .mp4 or .gif, got {str(dest)!r}")
    b = result.run_index(run)
    if result.positions is None:
        raise FieldError(
            "result", "has no trajectories to animate (simulated with keep_trajectories=False)"
        )
    rate = _v.count(fps, "fps", 1, MAX_FPS)
    steps = frame_steps(result, max_frames)
    resolution = _v.count(dpi, "dpi", 20, 600)
    check_output_file(dest, "path", overwrite=overwrite)
    ffmpeg = _ffmpeg() if suffix == ".mp4" else None
    scene = _Scene(result, b, resolution)
    frames = (scene.frame(int(k)) for k in steps)
    with atomic_path(dest) as tmp:
        if ffmpeg is not None:
            _write_mp4(ffmpeg, tmp, frames, scene.size, rate)
        else:
            _write_gif(tmp, frames, rate)
    return int(steps.size)


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

    def __init__(self, result: MissionResult, run: int, dpi: int) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        self.result, self.run = result, run
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

    def _extent(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower-left and upper-right corners of what is drawn, with a margin, m."""
        r = self.result
        points = [self.q.reshape(-1, 2), r.target[self.run]]
        if r.estimate is not None:
            points.append(r.estimate[self.run])
        slots = r.scenario.slots - np.asarray(r.scenario.target)
        points.append(r.target[self.run, -1] + slots)
        allp = np.concatenate(points)
        low, high = allp.min(axis=0), allp.max(axis=0)
        pad = 0.06 * float(np.max(high - low)) + 3.0
        return low - pad, high + pad

    def _figure(self, dpi: int) -> tuple[Figure, tuple[int, int]]:
        from matplotlib.figure import Figure

        low, high = self._extent()
        span = high - low
        width = 16 * round(FRAME_WIDTH_IN * dpi / 16)
        # The map takes 70 % of the width (the legend the rest) and 80 % of the height.
        ratio = float(np.clip(span[1] / span[0], 0.35, 1.6))
        height = 16 * max(1, round(width * 0.70 * ratio / 0.80 / 16))
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
        from matplotlib.patches import Circle, Patch, Polygon, Rectangle

        r, ax = self.result, self.ax
        sc = r.scenario
        obstacles = sc.obstacle_set
        shapes: list[Patch] = [Circle((cx, cy), rad) for cx, cy, rad in obstacles.circles]
        rects = obstacles.rectangles
        shapes += [Rectangle((x0, y0), x1 - x0, y1 - y0) for x0, x1, y0, y1 in rects]
        for i, shape in enumerate(shapes):
            shape.set(color="0.55", alpha=0.8, lw=0, label="obstacle" if i == 0 else None)
            ax.add_patch(shape)
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
        self.optimum = Polygon(self.slots, closed=True, fill=False, ec="C3", ls="--", lw=0.9,
                               label="F* over the target")  # fmt: skip
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
        self.fig.text(0.08, 0.975, f"scenario '{sc.name}', run {self.run} (seed {seed})",
                      fontsize=9, va="top")  # fmt: skip
        self.caption = self.fig.text(0.08, 0.945, "", fontsize=9, va="top", family="monospace")

    def frame(self, step: int) -> np.ndarray:
        """The RGB pixels, shape (height, width, 3), of the scene at ``step``."""
        r, b = self.result, self.run
        row = self.rows[step]
        q = self.q[row]
        for m, track in enumerate(self.tracks):
            track.set_data(self.q[: row + 1, m, 0], self.q[: row + 1, m, 1])
        centroid = q.mean(axis=0)
        order = np.argsort(np.arctan2(q[:, 1] - centroid[1], q[:, 0] - centroid[0]))
        self.polygon.set_xy(q[order])
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
