"""Atomic file writing: nothing half written, CSV round-trips exactly."""

from __future__ import annotations

import numpy as np
import pytest

from crlbswarm.output import atomic_path, write_csv, write_json


def test_failed_write_leaves_old_content_and_no_temporary(tmp_path):
    dest = tmp_path / "result.csv"
    dest.write_text("old")

    def interrupted_write():
        with atomic_path(dest) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError):
        interrupted_write()
    assert dest.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.csv"]


def test_csv_round_trips_floats_exactly(tmp_path):
    rng = np.random.default_rng(3)
    x = rng.normal(size=17) * 10.0 ** rng.integers(-12, 12, size=17)
    write_csv(tmp_path / "x.csv", {"a": x, "b": np.arange(17)})
    back = np.genfromtxt(tmp_path / "x.csv", delimiter=",", names=True)
    assert np.array_equal(back["a"], x)
    assert (tmp_path / "x.csv").read_text().startswith("a,b\n")


def test_csv_rejects_ragged_columns(tmp_path):
    with pytest.raises(ValueError, match=r"^columns"):
        write_csv(tmp_path / "x.csv", {"a": [1.0, 2.0], "b": [1.0]})
    assert not list(tmp_path.iterdir())


def test_json(tmp_path):
    write_json(tmp_path / "x.json", {"a": 1})
    assert (tmp_path / "x.json").read_text() == '{\n  "a": 1\n}\n'
