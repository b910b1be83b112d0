"""A read-only install: the compiled code is cached outside the package.

Installed where the user cannot write (a system ``site-packages``), the package cannot cache
its compiled kernels (Numba, ``cache=True``) in ``__pycache__`` next to the source; Numba
then writes them in the user's cache folder, ``$XDG_CACHE_HOME/numba`` (or
``~/.cache/numba``), and when that cannot be written either, the package gives it a private
folder in the temp folder (``crlbswarm.__init__``). These tests copy the package, make the
copy read-only and run a small computation through compiled code of two modules in new
processes with their own home, cache and temp folders: it must succeed without a warning,
write the cache where expected (nothing in the copy), and a second process must load the
compiled code from that cache instead of compiling it again.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "crlbswarm"

pytestmark = pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX permissions")

#: Compiled code of two modules: the range ufunc and the closed-form estimate
#: (estimation), the filter's prediction (tracking); every warning is recorded.
SCRIPT = textwrap.dedent(
    """
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import numpy as np
        import crlbswarm as cs
        from crlbswarm import tracking

        q = cs.optimal_formation(6, (0.0, 0.0), 20.0)
        d = cs.measure_ranges(q, (1.0, 2.0), 20.0, rng=np.random.default_rng(0))
        s = cs.linearised_estimate(q, d, 20.0)
        f, qn, _ = tracking.motion_matrices("constant_velocity", 0.1, acceleration_noise=0.3)
        x, _ = tracking.predict(np.array([1.0, 2.0, 0.5, 0.0]), np.eye(4), f, qn)
    print("package", cs.__file__)
    print("result", repr(float(s[0])), repr(float(s[1])), repr(float(x[0])))
    for w in caught:
        print("warning", w.category.__name__, str(w.message).replace(chr(10), " "))
    """
)


def _chmod_tree(root: Path, writable: bool) -> None:
    """``chmod -R a-w`` (or ``u+w``) on ``root``."""
    for path in [root, *root.rglob("*")]:
        mode = stat.S_IMODE(path.stat().st_mode)
        path.chmod(mode | stat.S_IWUSR if writable else mode & ~0o222)


@pytest.fixture
def install(tmp_path):
    """A read-only copy of the package (without its ``__pycache__``) in ``tmp_path /
    "install"``, and empty home, cache and temp folders beside it; skipped where write
    permissions are not enforced (root)."""
    shutil.copytree(PACKAGE, tmp_path / "install" / "crlbswarm",
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    for name in ("home", "cache", "tmp"):
        (tmp_path / name).mkdir()
    _chmod_tree(tmp_path / "install", writable=False)
    try:
        if os.access(tmp_path / "install" / "crlbswarm", os.W_OK):
            pytest.skip(
                "write permissions are not enforced for this user (root, or the capability "
                "CAP_DAC_OVERRIDE): a read-only install cannot be simulated with chmod"
            )
        yield tmp_path
    finally:
        _chmod_tree(tmp_path / "install", writable=True)


def _run(root: Path, *, debug: bool = False) -> dict[str, list[str]]:
    """The script in a new process: the read-only copy first on the path, ``root`` holding
    its home, cache and temp folders, no ``NUMBA_*`` setting (but ``NUMBA_DEBUG_CACHE=1``,
    Numba's log of the cache, if ``debug``). Its output lines by first word."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(
        HOME=str(root / "home"),
        XDG_CACHE_HOME=str(root / "cache"),
        TMPDIR=str(root / "tmp"),
        PYTHONPATH=str(root / "install"),
    )
    if debug:
        env["NUMBA_DEBUG_CACHE"] = "1"
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, cwd=root,
                          capture_output=True, text=True, timeout=300, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    lines: dict[str, list[str]] = {}
    for line in done.stdout.splitlines():
        key, _, rest = line.partition(" ")
        lines.setdefault(key, []).append(rest)
    assert Path(lines["package"][0]).is_relative_to(root / "install")
    assert lines.get("warning", []) == []
    assert "Warning" not in done.stderr, done.stderr[-3000:]
    return lines


def _cache_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.suffix in (".nbi", ".nbc"))


def _loads_from_cache(root: Path, first: dict[str, list[str]], folder: Path) -> None:
    """A second process gets the same results from the compiled code in ``folder``, which it
    loads, compiling (saving) nothing."""
    second = _run(root, debug=True)
    assert second["result"] == first["result"]
    log = second.get("[cache]", [])
    loaded = [line for line in log if line.startswith("data loaded from")]
    assert loaded, log
    assert all(str(folder) in line for line in loaded), loaded
    assert not [line for line in log if line.startswith("data saved")], log


def test_readonly_install_caches_in_the_user_cache_folder(install):
    first = _run(install)
    cache = install / "cache" / "numba"
    files = _cache_files(cache)
    assert any(p.suffix == ".nbi" for p in files)
    assert any(p.suffix == ".nbc" for p in files)
    assert {p.name.split(".")[0] for p in files} >= {"estimation", "tracking"}
    assert _cache_files(install / "install") == []
    assert _cache_files(install / "home") == []
    assert _cache_files(install / "tmp") == []
    _loads_from_cache(install, first, cache)


def test_readonly_install_and_home_cache_in_a_private_temp_folder(install):
    """Neither the install nor the user's cache folder can be written: the package gives
    Numba a folder of its own in the temp folder (Numba alone would refuse to compile)."""
    _chmod_tree(install / "home", writable=False)
    _chmod_tree(install / "cache", writable=False)
    try:
        first = _run(install)
        folder = install / "tmp" / f"crlbswarm-numba-{os.getuid()}"
        assert stat.S_IMODE(folder.stat().st_mode) == 0o700
        assert _cache_files(folder)
        assert _cache_files(install / "install") == []
        assert _cache_files(install / "cache") == []
        _loads_from_cache(install, first, folder)
    finally:
        _chmod_tree(install / "home", writable=True)
        _chmod_tree(install / "cache", writable=True)
