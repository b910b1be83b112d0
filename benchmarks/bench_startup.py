"""Start-up: the import, the first ``simulate`` after install, and the later ones (issue 12).

Run: ``python benchmarks/bench_startup.py [--repeat 3]``.

Each figure is a new Python process (wall time, best of ``--repeat``):

* ``python -c "import numpy"`` and ``python -c "import crlbswarm"``;
* the first ``simulate`` of the ``paper`` scenario "after a fresh install": a copy of
  ``src/crlbswarm`` in a scratch folder with no compiled cache (Numba caches next to the
  source, so the copy starts cold), ``simulate(load_scenario("paper"), seed=0)``;
* the same in a second process on that copy: the kernels are loaded from its cache.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "crlbswarm"

SIMULATE = "import crlbswarm as c; c.simulate(c.load_scenario('paper'), seed=0)"


def wall(code: str, env: dict[str, str] | None = None) -> float:
    """Wall time of ``python -c code`` in a new process, s."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    numpy_s = min(wall("import numpy") for _ in range(args.repeat))
    import_s = min(wall("import crlbswarm") for _ in range(args.repeat))
    cold, warm = [], []
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory() as tmp:
            shutil.copytree(SRC, Path(tmp) / "crlbswarm",
                            ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
            env = {**os.environ, "PYTHONPATH": tmp}
            env.pop("NUMBA_CACHE_DIR", None)
            cold.append(wall(SIMULATE, env))
            warm.append(wall(SIMULATE, env))
    print("| what (a new process each) | time |")
    print("|---|---:|")
    print(f"| `import numpy` | {numpy_s:.3f} s |")
    print(f"| `import crlbswarm` | {import_s:.3f} s ({import_s / numpy_s:.2f}x numpy) |")
    print(f"| first `simulate` of `paper` after install (no cache) | {min(cold):.1f} s |")
    print(f"| a later `simulate` of `paper` (cache loaded) | {min(warm):.2f} s |")


if __name__ == "__main__":
    main()
