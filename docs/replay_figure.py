"""Draw docs/replay.png: the replay page of the paper mission, inside the passage.

A batch of 20 runs of the built-in ``paper`` scenario, written by ``crlbswarm.write_replay``,
opened in headless Chromium (as the tests do, tests/browser.py) at 1280x800; run 0 is shown
at the middle of its passage through the gap. The screenshot is saved with a palette of 256
colours (a small PNG).

Run from the repository root: ``PYTHONPATH=src python docs/replay_figure.py``.
"""

from __future__ import annotations

import io
import sys
import tempfile
from pathlib import Path

from PIL import Image

from crlbswarm import load_scenario, simulate, write_replay
from crlbswarm.plots import passage_interval

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from browser import open_page  # noqa: E402


def main() -> None:
    result = simulate(load_scenario("paper"), seeds=range(20))
    start, end = passage_interval(result, 0) or (0.0, 0.0)
    with tempfile.TemporaryDirectory() as tmp:
        page_path = write_replay(result, Path(tmp) / "paper.html")
        with open_page(page_path, width=1280, height=800) as page:
            page.wait_for_function("window.crlbReplay !== undefined")
            page.evaluate(f"crlbReplay.setTime({(start + end) / 2})")
            png = page.screenshot()
            assert page.console_errors == [], page.console_errors
    image = Image.open(io.BytesIO(png)).convert("RGB").quantize(256)
    out = ROOT / "docs" / "replay.png"
    image.save(out, optimize=True)
    print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB), t = {(start + end) / 2:.1f} s")


if __name__ == "__main__":
    main()
