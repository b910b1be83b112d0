"""The fuzzing of ``tests/fuzzing.py``, a short fixed-seed run: scenario files, campaign
specs, command lines and public functions, under a memory cap. Here a case may take up to
60 s (a hang guard, not a speed test: the first case of a kind may compile the simulator
on a cold cache, on a loaded machine); the on-demand fuzzer's limit is 10 s.

``CRLBSWARM_FUZZ_CASES`` sets the number of cases (default 320, about a minute);
``CRLBSWARM_FUZZ_SEED`` the seed. For a long search run ``python tests/fuzzing.py --cases
2000 --seed N`` directly.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent


@pytest.mark.parametrize("family", ["scenario", "campaign", "cli", "api"])
def test_fuzz_family(family: str, tmp_path: Path) -> None:
    cases = int(os.environ.get("CRLBSWARM_FUZZ_CASES", "320")) // 4
    seed = os.environ.get("CRLBSWARM_FUZZ_SEED", "2026")
    proc = subprocess.run(
        [sys.executable, str(HERE / "fuzzing.py"), "--cases", str(cases), "--seed", seed,
         "--family", family],
        capture_output=True, text=True, cwd=tmp_path, timeout=600,
        env={**os.environ, "CRLBSWARM_FUZZ_CASE_SECONDS": "60"},
    )  # fmt: skip
    lines = proc.stdout.strip().splitlines()
    failures = [json.loads(line) for line in lines[:-1]]
    assert not failures, "\n".join(json.dumps(f, default=str)[:600] for f in failures)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(lines[-1]) == {"cases": cases, "failures": 0}
