"""The interactive replay page (crlbswarm.replay, `crlbswarm replay`): its decimation, its
command line, and the page itself in a real headless Chromium (tests/browser.py)."""

from __future__ import annotations

import copy
import dataclasses
import io
import json
import re
from contextlib import nullcontext

import numpy as np
import pytest

from browser import open_page
from crlbswarm import (
    BUILTIN_SCENARIOS,
    FieldError,
    Scenario,
    load_results,
    replay_html,
    simulate,
    simulate_groups,
    write_replay,
)
from crlbswarm.cli import main
from crlbswarm.replay import MIN_FRAMES, frame_rows, interval_minima, replay_data

#: Runs of the paper batch, and the cap on frames that makes its page decimate.
RUNS = 3
FRAMES = 60


def _scenario(name: str, duration: float) -> Scenario:
    data = copy.deepcopy(BUILTIN_SCENARIOS[name])
    data["time"].update(duration=duration, hold=min(10.0, duration / 2))
    return Scenario.from_dict(data)


@pytest.fixture(scope="module")
def paper_dir(tmp_path_factory):
    """A short paper batch (through the gap), trajectories kept every 2 steps, saved."""
    folder = tmp_path_factory.mktemp("paper") / "runs"
    simulate(_scenario("paper", 40.0), seeds=range(RUNS), trajectory_stride=2).save(folder)
    return folder


@pytest.fixture(scope="module")
def paper(paper_dir):
    return load_results(paper_dir)


@pytest.fixture(scope="module")
def paper_page(paper, tmp_path_factory):
    return write_replay(paper, tmp_path_factory.mktemp("page") / "p.html", max_frames=FRAMES)


def page_data(html: str) -> dict:
    """The JSON data inlined in a page."""
    found = re.search(r'<script type="application/json" id="crlb-replay-data">(.*?)</script>',
                      html, re.S)  # fmt: skip
    assert found is not None
    return json.loads(found.group(1))


def tiled(result, n_runs: int):
    """The batch's runs repeated to ``n_runs`` runs (a large batch without simulating it)."""
    take = np.arange(n_runs) % result.n_runs
    per_run = {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if (
            f.init
            and isinstance(value, np.ndarray)
            and value.ndim
            and f.name not in ("time", "pcrb")
        ):
            per_run[f.name] = value[take]
    per_run["seeds"] = np.arange(n_runs)
    return dataclasses.replace(result, **per_run)


# -- decimation --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("n_rows", "cap"),
    [(1, 5), (2, 2), (10, 20), (1501, 600), (1501, 109), (201, 60), (100, 99), (7, 3)],
)
def test_frame_rows_are_a_uniform_stride_ending_at_the_last_row(n_rows, cap):
    rows = frame_rows(n_rows, cap)
    assert rows[0] == 0
    assert rows[-1] == n_rows - 1
    assert len(rows) <= max(cap, 1)
    gaps = np.diff(rows)
    if gaps.size:
        stride = gaps[0]
        assert np.all(gaps[:-1] == stride)
        assert 0 < gaps[-1] <= stride
        # The smallest stride that fits: one less would give too many rows.
        assert stride == 1 or len(range(0, n_rows - 1, stride - 1)) + 1 > cap


def test_interval_minima_is_the_smallest_since_the_previous_frame():
    rng = np.random.default_rng(3)
    values = rng.normal(size=(4, 31))
    steps = np.array([0, 4, 8, 12, 16, 20, 24, 28, 30])
    got = interval_minima(values, steps)
    for b in range(4):
        assert got[b, 0] == values[b, 0]
        for i in range(1, len(steps)):
            assert got[b, i] == min(values[b, k] for k in range(steps[i - 1] + 1, steps[i] + 1))


def test_page_data_keeps_the_last_step_and_the_kept_steps(paper):
    data = replay_data(paper, max_frames=FRAMES)
    steps = np.array(data["frameStep"])
    assert steps[-1] == paper.time.shape[0] - 1  # the end of the mission
    assert set(steps) <= set(paper.trajectory_steps)  # positions exist there
    assert len(steps) <= FRAMES
    assert data["decimation"]["trajectoryStride"] == 2
    assert data["frameTime"] == pytest.approx(paper.time[steps])


def test_a_thousand_runs_fit_the_size_limit(paper):
    big = tiled(paper, 1000)
    limit = 3.0  # MB: about 30 frames per run
    html = replay_html(big, max_mb=limit)
    data = page_data(html)
    per_run = [
        v for g in data["groups"] for v in (g["positions"], g["target"], *g["series"].values())
    ]
    assert sum(len(b) for b in per_run) <= limit * 1e6  # base64 text of every run's frames
    assert MIN_FRAMES <= len(data["frameStep"]) < len(paper.trajectory_steps)
    assert data["frameStep"][-1] == paper.time.shape[0] - 1
    assert len(data["runIndex"]) == 1000
    assert len(html.encode()) < limit * 1e6 + 200e3  # the code, the per-run metadata, the band


def coarse(paper, stride: int):
    """The batch as if its trajectories were kept every ``stride`` steps (a multiple of 2)."""
    return dataclasses.replace(paper, positions=paper.positions[:, :: stride // 2],
                               velocities=paper.velocities[:, :: stride // 2],
                               trajectory_stride=stride)  # fmt: skip


def decoded(text: str, shape: tuple[int, ...]) -> np.ndarray:
    import base64

    return np.frombuffer(base64.b64decode(text), dtype="<f4").reshape(shape)


def test_time_plots_have_their_own_points_whatever_the_trajectory_stride(paper):
    """Kept every 100 steps, the trajectories give 5 frames; the time series still have a
    point at every step (401 <= max_frames), the clearance the smallest since the last."""
    sparse = coarse(paper, 100)
    data = replay_data(sparse)
    assert data["frameStep"] == [0, 100, 200, 300, 400]
    assert data["seriesStep"] == list(range(401))
    assert data["seriesTime"] == pytest.approx(paper.time)
    assert data["decimation"]["seriesPoints"] == 401
    series = data["groups"][0]["series"]
    np.testing.assert_array_equal(decoded(series["crlb"], (RUNS, 401)),
                                  paper.crlb.astype("<f4"))  # fmt: skip
    # Capped: the points are a stride over every step, the minima over each interval.
    data = replay_data(sparse, max_frames=50)
    steps = np.array(data["seriesStep"])
    assert steps.tolist() == [*range(0, 400, 9), 400]  # ceil(400 / 49) = 9: 46 points
    got = decoded(data["groups"][0]["series"]["separation"], (RUNS, 46))
    np.testing.assert_array_equal(got, interval_minima(paper.separation, steps).astype("<f4"))


def test_few_kept_steps_need_few_frames_and_no_fit_says_so(paper):
    """5 kept steps need 5 frames of the size limit, not 20; a limit below one run's worth
    names --max-mb and says that no run fits."""
    sparse = coarse(paper, 100)
    one_run = 5 * (2 * 6 + 5) * 16 / 3  # bytes of 5 frames of 6 UAVs and 5 series
    data = replay_data(sparse, runs=[0], max_mb=1.01 * one_run / 1e6)
    assert len(data["frameStep"]) == 5
    with pytest.raises(FieldError, match="no run fits in a page of") as info:
        replay_data(sparse, runs=[0], max_mb=0.9 * one_run / 1e6)
    assert info.value.field == "max_mb"


@pytest.mark.parametrize("command", ["replay", "report"])
def test_a_page_must_be_an_html_file(paper_dir, tmp_path, capsys, command):
    out = tmp_path / "page.txt"
    status, _, err = run(capsys, command, str(paper_dir), "-o", str(out))
    assert status == 2
    assert err == (f"crlbswarm: error: -o/--out: expected a file name ending in .html or .htm, "
                   f"got {str(out)!r}\n")  # fmt: skip
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(FieldError, match=r"\.html or \.htm") as info:
        write_replay(load_results(paper_dir), tmp_path / "page.HTML5")
    assert info.value.field == "path"
    assert run(capsys, "replay", str(paper_dir), "-o", str(tmp_path / "p.HTM"))[0] == 0


def test_too_many_runs_for_the_limit_are_refused(paper):
    with pytest.raises(FieldError, match="choose at most") as info:
        replay_html(tiled(paper, 1000), max_mb=0.05)
    assert info.value.field == "runs"


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"runs": [3]}, "runs"), ({"runs": []}, "runs"), ({"runs": [0, 0]}, "runs"),
     ({"max_frames": 2}, "max_frames"), ({"max_mb": 0.0}, "max_mb")],
)  # fmt: skip
def test_bad_arguments_name_their_field(paper, kwargs, field):
    with pytest.raises(FieldError) as info:
        replay_html(paper, **kwargs)
    assert info.value.field == field


def test_a_result_without_trajectories_is_refused():
    result = simulate(_scenario("paper", 2.0), seed=0, keep_trajectories=False)
    with pytest.raises(FieldError, match="no trajectories") as info:
        replay_html(result)
    assert info.value.field == "result"
    with pytest.raises(FieldError, match="MissionResult"):
        replay_html("runs/")  # type: ignore[arg-type]


def test_page_is_self_contained(paper_page):
    html = paper_page.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>")
    assert not re.search(r"(src|href)\s*=\s*[\"'](?!data:)", html)  # nothing loaded
    assert "http://" not in html
    assert "https://" not in html
    assert "Content-Security-Policy" in html


# -- command line ------------------------------------------------------------------------
def run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_writes_the_page(paper_dir, tmp_path, capsys):
    out = tmp_path / "mission.html"
    status, stdout, err = run(capsys, "replay", str(paper_dir), "-o", str(out), "--runs", "0,2")
    assert status == 0, err
    assert f"wrote {out}" in stdout
    data = page_data(out.read_text(encoding="utf-8"))
    assert data["runIndex"] == [0, 2]
    assert data["seed"] == [0, 2]


@pytest.mark.parametrize(
    ("argv", "option"),
    [(["--runs", "0:9"], "--runs"), (["--runs", "x"], "--runs"),
     (["--runs", "0:1000000000000"], "--runs"), (["--runs", "2:1"], "--runs"),
     (["--runs=-1"], "--runs"),
     (["--max-frames", "1"], "--max-frames"), (["--max-mb", "-2"], "--max-mb")],
)  # fmt: skip
def test_cli_errors_are_one_line_and_write_nothing(paper_dir, tmp_path, capsys, argv, option):
    out = tmp_path / "mission.html"
    status, _, err = run(capsys, "replay", str(paper_dir), "-o", str(out), *argv)
    assert status == 2
    assert err.count("\n") == 1
    assert err.startswith(f"crlbswarm: error: {option}: ")
    assert list(tmp_path.iterdir()) == []


def test_cli_refuses_a_folder_without_a_result_or_trajectories(tmp_path, capsys):
    status, _, err = run(capsys, "replay", str(tmp_path / "none"), "-o", str(tmp_path / "a.html"))
    assert status == 2
    assert err.startswith("crlbswarm: error: RUNS_DIR: ")
    bare = tmp_path / "bare"
    simulate(_scenario("paper", 2.0), seed=0, keep_trajectories=False).save(bare)
    status, _, err = run(capsys, "replay", str(bare), "-o", str(tmp_path / "a.html"))
    assert status == 2
    assert err.count("\n") == 1
    assert "no trajectories" in err
    assert not (tmp_path / "a.html").exists()


def test_cli_refuses_an_existing_file_unless_forced(paper_dir, tmp_path, capsys):
    out = tmp_path / "mission.html"
    out.write_text("mine")
    status, _, err = run(capsys, "replay", str(paper_dir), "-o", str(out))
    assert status == 2
    assert err.count("\n") == 1
    assert "--force" in err
    assert out.read_text() == "mine"
    status, _, err = run(capsys, "replay", str(paper_dir), "-o", str(tmp_path / "no" / "a.html"))
    assert status == 2
    assert "does not exist" in err
    status, _, _ = run(capsys, "replay", str(paper_dir), "-o", str(out), "--force")
    assert status == 0
    assert out.read_text().startswith("<!DOCTYPE html>")


# -- in the browser ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def browser(paper_page):
    """One headless Chromium for the module's pages (a launch takes seconds)."""
    with open_page(paper_page) as page:
        yield page


def show(page, path):
    """Load the page at ``path`` in the browser, its error and request lists emptied."""
    page.console_errors.clear()
    page.external_requests.clear()
    page.goto(path.resolve().as_uri())
    page.wait_for_function("window.crlbReplay !== undefined")
    return page


def rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[k : k + 2], 16) for k in (1, 3, 5)])


def kept_row(result, t: float) -> tuple[int, int]:
    """The step at time ``t`` and its row in the kept trajectories."""
    step = round(t / result.scenario.time.step)
    row = int(np.searchsorted(result.trajectory_steps, step))
    assert result.trajectory_steps[row] == step
    return step, row


def map_pixels(page) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.locator("#map").screenshot())).convert("RGB"))


def check_uav_pixels(page, positions: np.ndarray) -> int:
    """Each UAV's colour at its projected position (UAVs drawn apart from the others)."""
    img = map_pixels(page).astype(int)
    colours = page.evaluate("crlbReplay.uavColours()")
    pixels = np.array([page.evaluate(f"crlbReplay.worldToCanvas({x}, {y})") for x, y in positions])
    checked = 0
    for m, (px, py) in enumerate(pixels):
        others = np.delete(pixels, m, axis=0)
        if np.min(np.hypot(*(others - (px, py)).T)) < 16:
            continue  # another UAV's marker may cover this one
        assert 0 <= px < img.shape[1]
        assert 0 <= py < img.shape[0]
        assert np.abs(img[int(py), int(px)] - rgb(colours[m])).max() <= 10, m
        checked += 1
    return checked


def test_page_in_the_browser(paper, paper_page, browser):
    with nullcontext(show(browser, paper_page)) as page:
        api = page.evaluate("({n: crlbReplay.nRuns, f: crlbReplay.nFrames, t: crlbReplay.time()})")
        assert api["n"] == RUNS
        assert 2 < api["f"] <= FRAMES
        assert api["t"] == 0

        # Play advances time; pause stops it.
        page.click("#play")
        page.wait_for_function("crlbReplay.time() > 0.5")
        assert page.evaluate("crlbReplay.playing()")
        page.click("#play")
        stopped = page.evaluate("crlbReplay.time()")
        page.wait_for_timeout(150)
        assert page.evaluate("crlbReplay.time()") == stopped
        assert not page.evaluate("crlbReplay.playing()")

        # The slider (the DOM input) to frame i: the UAVs where the data says, in the page's
        # state and in the pixels of the map.
        times = page.evaluate("crlbReplay.frameTimes()")
        i = int(np.argmin(np.abs(np.array(times) - 25.0)))  # in the gap
        page.locator("#slider").fill(str(i))
        t = page.evaluate("crlbReplay.time()")
        assert t == pytest.approx(times[i])
        _, row = kept_row(paper, t)
        expected = paper.positions[0, row]
        got = np.array(page.evaluate("crlbReplay.uavPositions()"))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-4)
        assert check_uav_pixels(page, expected) >= 3
        assert page.locator("#time-label").inner_text().startswith(f"t = {t:.1f} s")
        # The time plots have their own points (among every step): at one, the data's values.
        point_times = page.evaluate("crlbReplay.seriesTimes()")
        j = int(np.argmin(np.abs(np.array(point_times) - 25.0)))
        page.evaluate(f"crlbReplay.setTime({point_times[j]})")
        k = round(point_times[j] / paper.scenario.time.step)
        values = page.evaluate("crlbReplay.seriesValues()")
        assert values["crlb"][0] == pytest.approx(paper.crlb[0, k], rel=1e-6)
        assert values["eta"][0] == pytest.approx(paper.eta[0, k], rel=1e-6)
        page.locator("#slider").fill(str(i))

        # The footer says how the time plots are sampled; the legend names F*; the run panel
        # gives a convergence time only to a converged run.
        assert "Time plots: " in page.locator("#note").inner_text()
        assert "F* (CRLB-optimal)" in page.locator("#legend").inner_text()
        cells = page.locator("#info span").all_inner_texts()
        outcome, conv = (
            cells[cells.index("outcome") + 1],
            cells[cells.index("convergence time") + 1],
        )
        assert outcome != "converged"  # (40 s of the 150 s mission)
        assert conv == "– (not converged)"

        # The run selector switches to that run's data at the same time.
        page.select_option("#run", "2")
        assert page.evaluate("crlbReplay.run()") == 2
        got = np.array(page.evaluate("crlbReplay.uavPositions()"))
        np.testing.assert_allclose(got, paper.positions[2, row], rtol=0, atol=1e-4)
        assert np.abs(paper.positions[2, row] - paper.positions[0, row]).max() > 0.1
        assert check_uav_pixels(page, paper.positions[2, row]) >= 3

        # A click on a time plot seeks; later on the plot is later in time.
        box = page.locator("#plot-eta").bounding_box()
        page.mouse.click(box["x"] + 0.4 * box["width"], box["y"] + box["height"] / 2)
        early = page.evaluate("crlbReplay.time()")
        page.mouse.click(box["x"] + 0.8 * box["width"], box["y"] + box["height"] / 2)
        late = page.evaluate("crlbReplay.time()")
        assert 0 < early < late < times[-1]
        assert int(page.locator("#slider").input_value()) == page.evaluate("crlbReplay.frame()")

        # Zoom (wheel), pan (drag), reset view.
        start = page.evaluate("crlbReplay.view()")
        mbox = page.locator("#map").bounding_box()
        cx, cy = mbox["x"] + mbox["width"] / 2, mbox["y"] + mbox["height"] / 2
        page.mouse.move(cx, cy)
        page.mouse.wheel(0, -300)
        zoomed = page.evaluate("crlbReplay.view()")
        assert zoomed["scale"] > 1.2 * start["scale"]
        page.mouse.down()
        page.mouse.move(cx + 80, cy, steps=4)
        page.mouse.up()
        assert page.evaluate("crlbReplay.view()")["cx"] < zoomed["cx"]
        page.click("#reset-view")
        assert page.evaluate("crlbReplay.view()") == pytest.approx(start)

        # Not blank: many colours, much drawn.
        from PIL import Image

        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
        assert len(np.unique(shot.reshape(-1, 3), axis=0)) > 200
        assert np.mean(np.any(shot < 200, axis=2)) > 0.03
        assert page.console_errors == []
        assert page.external_requests == []


def test_moving_target_and_estimate_in_the_browser(tmp_path, browser):
    result = simulate(_scenario("moving_target", 20.0), seeds=[0, 1])
    path = write_replay(result, tmp_path / "m.html")
    with nullcontext(show(browser, path)) as page:
        page.select_option("#run", "1")
        times = page.evaluate("crlbReplay.frameTimes()")
        page.locator("#slider").fill(str(len(times) // 2))
        step, row = kept_row(result, page.evaluate("crlbReplay.time()"))
        np.testing.assert_allclose(page.evaluate("crlbReplay.targetPositions()"),
                                   result.target[1, step][None], atol=1e-4)  # fmt: skip
        np.testing.assert_allclose(page.evaluate("crlbReplay.estimatePositions()"),
                                   result.estimate[1, step][None], atol=1e-4)  # fmt: skip
        np.testing.assert_allclose(page.evaluate("crlbReplay.uavPositions()"),
                                   result.positions[1, row], atol=1e-4)  # fmt: skip
        assert page.console_errors == []
        assert page.external_requests == []


def test_several_targets_from_the_cli_in_the_browser(tmp_path, capsys, browser):
    data = {"name": "two", "altitude": 20.0, "target": [60.0, 70.0],
            "extra_targets": [[100.0, -20.0]],
            "uavs": {"count": 7, "start_region": [[-15.0, 15.0], [-15.0, 15.0]]},
            "time": {"step": 0.1, "duration": 20.0}}  # fmt: skip
    grouped = simulate_groups(Scenario.from_dict(data), seeds=[0, 1])
    grouped.save(tmp_path / "runs")
    out = tmp_path / "groups.html"
    status, _, err = run(capsys, "replay", str(tmp_path / "runs"), "-o", str(out))
    assert status == 0, err
    positions = grouped.positions
    with nullcontext(show(browser, out)) as page:
        assert page.evaluate("crlbReplay.nUavs") == 7
        assert page.evaluate("crlbReplay.leaders()") == grouped.plan.leaders.tolist()
        page.select_option("#run", "1")
        times = page.evaluate("crlbReplay.frameTimes()")
        page.locator("#slider").fill(str(len(times) - 1))
        step, row = kept_row(grouped.groups[0], page.evaluate("crlbReplay.time()"))
        assert step == 200
        np.testing.assert_allclose(page.evaluate("crlbReplay.uavPositions()"),
                                   positions[1, row], atol=1e-4)  # fmt: skip
        assert len(page.evaluate("crlbReplay.targetPositions()")) == 2
        assert page.console_errors == []
        assert page.external_requests == []


def test_a_page_refuses_code_that_would_end_its_element_early():
    from crlbswarm.webpage import html_page, json_script

    data = json_script({"text": "</script><b>&"}, "d")
    assert data.count("</script") == 1  # its own end: the data's are escaped
    assert "<b>" not in data
    html_page("t", "a{}", "", [data, "<script>1</script>"])
    with pytest.raises(ValueError, match="style"):
        html_page("t", "a{}</style>", "", [])
    with pytest.raises(ValueError, match="scripts"):
        html_page("t", "", "", ["<script>'</script>'</script>"])
