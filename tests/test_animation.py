"""``crlbswarm animate`` (issue 13): the frames drawn, an MP4 read back by ffmpeg (through
imageio-ffmpeg, an independent decoder), a GIF read back by Pillow, and the refusals."""

from __future__ import annotations

import copy
import gc
import sys
import warnings

import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

from crlbswarm import FieldError, load_results, load_scenario, simulate
from crlbswarm.animation import (
    DEFAULT_MAX_FRAMES,
    GIF_MAX_PIXELS,
    animate_mission,
    frame_size,
    frame_steps,
)
from crlbswarm.cli import main
from crlbswarm.scenario import Scenario

FAST = ["--dpi", "40", "--max-frames", "12", "--fps", "10"]  # 320 pixels wide, 1.2 s


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Two short runs with estimation, kept every 3 steps (68 of 201 steps), saved."""
    data = copy.deepcopy(load_scenario("sensing").model_dump())
    data["time"].update(duration=20.0, hold=2.0, stall=5.0)
    result = simulate(Scenario.from_dict(data), seeds=[3, 4], trajectory_stride=3)
    out = tmp_path_factory.mktemp("anim") / "runs"
    result.save(out)
    return out


def animate(capsys, *argv: str) -> tuple[int, list[str], list[str]]:
    capsys.readouterr()
    status = main(["animate", *argv])
    captured = capsys.readouterr()
    return status, captured.out.splitlines(), captured.err.splitlines()


def read_mp4(path) -> tuple[dict, list[bytes]]:
    """The stream's metadata and every decoded frame, by imageio-ffmpeg's reader (whose
    pipes to ffmpeg are left to the garbage collector: their ResourceWarning is not ours)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        reader = imageio_ffmpeg.read_frames(str(path))
        meta = next(reader)
        frames = list(reader)
        reader.close()
        del reader
        gc.collect()
    return meta, frames


def test_frame_steps_decimate_the_kept_steps_evenly_with_both_ends():
    data = copy.deepcopy(load_scenario("paper").model_dump())
    data["time"].update(duration=5.0, hold=1.0)
    result = simulate(
        Scenario.from_dict(data), seed=0, trajectory_stride=4, keep_trajectories=True
    )
    kept = [*range(0, 51, 4), 50]  # every 4th of 50 steps, and the last
    assert result.trajectory_steps.tolist() == kept
    assert frame_steps(result, 100).tolist() == kept  # fewer kept steps than frames: all
    for n in (2, 3, 7, 13, 14):
        steps = frame_steps(result, n).tolist()
        assert len(steps) == min(n, len(kept))
        assert steps[0] == 0
        assert steps[-1] == 50
        assert set(steps) <= set(kept)
        rows = np.diff([kept.index(s) for s in steps])
        assert rows.min() >= 1
        assert rows.max() - rows.min() <= 1
    with pytest.raises(FieldError, match="max_frames"):
        frame_steps(result, 1)


def test_mp4_has_the_frames_and_a_decodable_h264_stream(folder, tmp_path, capsys):
    path = tmp_path / "mission.mp4"
    status, out, err = animate(capsys, str(folder), "--run", "1", "-o", str(path), *FAST)
    assert status == 0, err
    assert out == [f"wrote {path} (12 frames, 1.2 s at 10 fps)"]
    assert imageio_ffmpeg.count_frames_and_secs(str(path)) == (12, 1.2)
    meta, frames = read_mp4(path)
    assert meta["codec"].startswith("h264")
    assert meta["fps"] == 10
    width, height = meta["size"]
    assert width == 320
    assert height % 16 == 0
    assert len(frames) == 12
    first, last = (np.frombuffer(f, np.uint8).reshape(height, width, 3).astype(int)
                   for f in (frames[0], frames[-1]))  # fmt: skip
    assert (last.min(axis=2) < 200).mean() > 0.02  # not blank: drawing covers the canvas
    # Red (the leader, the target, F*) is there; the frames change along the mission.
    assert (last[..., 0] - last[..., 1:].max(axis=2) > 60).sum() > 5
    assert (np.abs(first - last).max(axis=2) > 30).sum() > 100


def test_gif_has_the_frames_and_their_durations(folder, tmp_path, capsys):
    path = tmp_path / "mission.gif"
    status, _, err = animate(capsys, str(folder), "-o", str(path), *FAST)
    assert status == 0, err
    with Image.open(path) as gif:
        assert gif.format == "GIF"
        assert gif.n_frames == 12
        durations = []
        for i in range(gif.n_frames):
            gif.seek(i)
            durations.append(gif.info["duration"])
        frame = np.asarray(gif.convert("RGB")).astype(int)
    assert durations == [100] * 12
    assert (frame.min(axis=2) < 200).mean() > 0.02


def test_without_imageio_ffmpeg_an_mp4_is_one_error_line_and_a_gif_still_works(
    folder, tmp_path, capsys, monkeypatch
):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # as if not installed
    path = tmp_path / "mission.mp4"
    status, out, err = animate(capsys, str(folder), "-o", str(path), *FAST)
    assert status == 2
    assert out == []
    assert len(err) == 1
    assert err[0].startswith("crlbswarm: error: -o/--out: an .mp4 needs the optional package "
                             "imageio-ffmpeg")  # fmt: skip
    assert "pip install 'crlbswarm[video]'" in err[0]
    assert list(tmp_path.iterdir()) == []
    status, _, err = animate(capsys, str(folder), "-o", str(tmp_path / "m.gif"),
                             "--max-frames", "2", "--dpi", "20")  # fmt: skip
    assert status == 0, err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--run", "2"], "--run: must be an index in 0..1, got 2"),
        (["--fps", "0"], "--fps: must be at least 1, got 0"),
        (["--max-frames", "1"], "--max-frames: must be at least 2, got 1"),
        (["--dpi", "5"], "--dpi: must be at least 20, got 5"),
    ],
)
def test_bad_options_are_one_line_and_nothing_is_written(folder, tmp_path, capsys, argv,
                                                         message):  # fmt: skip
    status, _, err = animate(capsys, str(folder), "-o", str(tmp_path / "m.gif"), *argv)
    assert (status, err) == (2, [f"crlbswarm: error: {message}"])
    assert list(tmp_path.iterdir()) == []


def test_refusals_of_the_file_and_of_a_result_without_trajectories(folder, tmp_path, capsys):
    status, _, err = animate(capsys, str(folder), "-o", str(tmp_path / "m.avi"))
    assert status == 2
    assert "-o/--out: expected a file name ending in .mp4 or .gif" in err[0]
    existing = tmp_path / "m.gif"
    existing.write_bytes(b"keep")
    status, _, err = animate(capsys, str(folder), "-o", str(existing))
    assert status == 2
    assert "already exists" in err[0]
    assert "--force" in err[0]
    assert existing.read_bytes() == b"keep"
    data = copy.deepcopy(load_scenario("paper").model_dump())
    data["time"].update(duration=1.0, hold=0.5)
    bare = simulate(Scenario.from_dict(data), seed=0, keep_trajectories=False)
    with pytest.raises(FieldError, match="has no trajectories"):
        animate_mission(bare, tmp_path / "x.gif")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.gif"]


def test_a_gif_too_large_for_memory_is_refused_before_drawing(folder, tmp_path, capsys):
    """68 frames of 4800 pixels wide (600 dpi) are more pixels than a GIF may hold: one line
    naming --max-frames and --dpi, before anything is drawn or written."""
    status, _, err = animate(capsys, str(folder), "-o", str(tmp_path / "m.gif"), "--dpi", "600",
                             "--max-frames", "1000")  # fmt: skip
    assert status == 2
    assert len(err) == 1
    assert err[0].startswith("crlbswarm: error: --max-frames: a GIF of 68 frames of 4800 x ")
    assert "--dpi" in err[0]
    assert list(tmp_path.iterdir()) == []
    width, height = frame_size(load_results(folder), 0, 600)
    assert 68 * width * height > GIF_MAX_PIXELS
    # The defaults fit whatever the scene: 300 frames of at most 800 x 1120 pixels.
    assert DEFAULT_MAX_FRAMES * 800 * 1120 <= GIF_MAX_PIXELS


def test_a_gif_plays_at_most_50_fps_and_says_the_rate_it_plays(folder, tmp_path, capsys):
    path = tmp_path / "m.gif"
    status, _, err = animate(capsys, str(folder), "-o", str(path), "--fps", "60")
    assert status == 2
    assert err[0].startswith("crlbswarm: error: --fps: a GIF plays at most 50 frames per second")
    assert list(tmp_path.iterdir()) == []
    # 30 fps: delays of round(100 / 30) = 3 hundredths, so 33.3 fps, as the command says.
    status, out, err = animate(capsys, str(folder), "-o", str(path), "--fps", "30",
                               "--dpi", "20", "--max-frames", "3")  # fmt: skip
    assert status == 0, err
    assert out == [f"wrote {path} (3 frames, 0.1 s at 33.3 fps)"]
    with Image.open(path) as gif:
        gif.seek(1)
        assert gif.info["duration"] == 30
