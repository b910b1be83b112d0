"""crlbswarm: CRLB-optimal UAV formations for cooperative range sensing.

Implements and extends Wu, Jin, Su, Li, Pan, Chan, "Formation Control for CRLB-Optimal
Cooperative Sensing in Low-Altitude Wireless Networks", arXiv:2602.23990 (2026).

Positions are horizontal coordinates in metres, shape ``(..., M, 2)`` (UAVs are rows);
every function accepts any leading batch shape. Angles are radians inside the library.

The public names (listed, with their modules, in ``__init__.pyi``) are imported on first
use, so ``import crlbswarm`` is instant and loads none of the heavy libraries (Numba, SciPy,
Matplotlib, Dask) until something that needs them is used.
"""

import os
import sys

import lazy_loader

__version__ = "0.1.0"

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)


def _writable(path: str) -> bool:
    """Whether ``path``, or the nearest folder above it that exists, can be written."""
    while not os.path.exists(path):
        parent = os.path.dirname(path)
        if parent == path:
            return False
        path = parent
    return os.path.isdir(path) and os.access(path, os.W_OK | os.X_OK)


def _numba_cache_fallback() -> None:
    """Give Numba a cache folder in the temp folder when it would have none.

    Numba caches the compiled code (``cache=True``) in ``__pycache__`` next to the source or,
    when that cannot be written (a read-only install), in the user's cache folder
    (``$XDG_CACHE_HOME`` or ``~/.cache``, then ``numba/``). When neither can be written (a
    read-only install run by an account whose home is read-only) Numba refuses to compile
    (``RuntimeError: cannot cache function ...: no locator available``); this sets
    ``NUMBA_CACHE_DIR`` to ``crlbswarm-numba-<uid>`` in the temp folder instead, made private
    (mode 700, owned by the user: the cache holds code that is loaded and run). Nothing is
    changed when ``NUMBA_CACHE_DIR`` is set or when either folder can be written.
    """
    numba = sys.modules.get("numba")
    if os.environ.get("NUMBA_CACHE_DIR") or getattr(
        getattr(numba, "config", None), "CACHE_DIR", ""
    ):
        return
    here = os.path.dirname(os.path.abspath(__file__))
    if _writable(os.path.join(here, "__pycache__")) or not hasattr(os, "getuid"):
        return
    home = os.path.expanduser("~")
    if sys.platform == "darwin":
        user = os.path.join(home, "Library", "Caches")
    else:
        user = os.environ.get("XDG_CACHE_HOME", os.path.join(home, ".cache"))
    if _writable(os.path.join(user, "numba")):
        return
    import stat
    import tempfile

    path = os.path.join(tempfile.gettempdir(), f"crlbswarm-numba-{os.getuid()}")
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    except OSError:
        return
    info = os.lstat(path)
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
        return  # not a private folder of this user: not trusted with code to run
    os.environ["NUMBA_CACHE_DIR"] = path
    if numba is not None:  # (already imported: it read the environment then)
        numba.config.CACHE_DIR = path


_numba_cache_fallback()
