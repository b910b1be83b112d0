"""Input checks shared by the public functions.

Every check raises :class:`~crlbswarm.errors.FieldError` (a :class:`ValueError`) carrying the
name of the offending argument and the reason, whose message is one line; the CLI maps the
name to its option. The checks never modify the caller's array: they return it as a float
array (the caller's own array when it already is one, so callers copy before writing).
"""

from __future__ import annotations

import numbers

import numpy as np

from .errors import FieldError

__all__: list[str] = []

#: Largest seed (seeds are stored as int64).
MAX_SEED = 2**63 - 1

#: Fewest UAVs of a formation: the design and the benchmarks need three (with two, the
#: formation and the target are collinear in the horizontal plane for some geometries and
#: the regular polygon degenerates).
MIN_UAVS = 3


def as_float_array(value: object, name: str) -> np.ndarray:
    """Convert ``value`` to a float64 array or raise a ``ValueError`` naming ``name``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise FieldError(name, f"expected numbers, got {value!r}") from exc
    return arr


def check_finite(arr: np.ndarray, name: str) -> np.ndarray:
    """Raise if ``arr`` holds NaN or infinity."""
    if not np.all(np.isfinite(arr)):
        raise FieldError(name, "must be finite (found NaN or inf)")
    return arr


def positions(value: object, name: str) -> np.ndarray:
    """Check an array of planar positions of shape ``(..., M, 2)``."""
    arr = as_float_array(value, name)
    if arr.ndim < 2 or arr.shape[-1] != 2:
        raise FieldError(name, f"expected shape (..., M, 2), got {arr.shape}")
    if arr.shape[-2] < 1:
        raise FieldError(name, f"needs at least one UAV, got shape {arr.shape}")
    return check_finite(arr, name)


def point(value: object, name: str) -> np.ndarray:
    """Check a planar point (or batch of points) of shape ``(..., 2)``."""
    arr = as_float_array(value, name)
    if arr.ndim < 1 or arr.shape[-1] != 2:
        raise FieldError(name, f"expected shape (..., 2), got {arr.shape}")
    return check_finite(arr, name)


def positive(value: object, name: str) -> np.ndarray:
    """Check a strictly positive, finite number or array of them."""
    arr = as_float_array(value, name)
    check_finite(arr, name)
    if not np.all(arr > 0):
        raise FieldError(name, f"must be > 0, got {value!r}")
    return arr


def finite(value: object, name: str) -> np.ndarray:
    """Check a finite number or array of them."""
    return check_finite(as_float_array(value, name), name)


def count(value: object, name: str, minimum: int) -> int:
    """Check an integer count of at least ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise FieldError(name, f"expected an integer, got {value!r}")
    if value < minimum:
        raise FieldError(name, f"must be at least {minimum}, got {value}")
    return int(value)


def broadcast(name: str, *shapes: tuple[int, ...]) -> tuple[int, ...]:
    """Broadcast shapes or raise a ``ValueError`` naming the argument ``name``."""
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError as exc:
        raise FieldError(
            f"{name}", f"shapes {', '.join(str(s) for s in shapes)} do not broadcast"
        ) from exc


def scalar(value: object, name: str) -> float:
    """Check a single finite number."""
    arr = finite(value, name)
    if arr.ndim != 0:
        raise FieldError(name, f"expected a single number, got shape {arr.shape}")
    return float(arr)


def positive_scalar(value: object, name: str) -> float:
    """Check a single finite number > 0."""
    number = scalar(value, name)
    if not number > 0:
        raise FieldError(name, f"must be > 0, got {value!r}")
    return number


def seed(value: object, name: str) -> int:
    """Check a seed: an integer in ``0 .. MAX_SEED``."""
    s = count(value, name, 0)
    if s > MAX_SEED:
        raise FieldError(name, f"must be at most 2**63 - 1, got {s}")
    return s


def uav_count(value: object, name: str) -> int:
    """Check a number of UAVs of a formation: an integer of at least :data:`MIN_UAVS`."""
    return count(value, name, MIN_UAVS)


def seed_range(
    first: object, n: object, first_name: str, n_name: str | None = None
) -> tuple[int, int]:
    """Check the seeds ``first .. first + n - 1``: ``first`` a seed, ``n >= 1``, and the last
    seed at most :data:`MAX_SEED`. The error names ``n_name``, or ``first_name`` when the
    number of seeds is not the caller's choice (``n_name`` None)."""
    start = seed(first, first_name)
    runs = count(n, n_name or "n", 1)
    if start + runs - 1 > MAX_SEED:
        raise FieldError(
            n_name or first_name,
            f"the seeds {start}..{start + runs - 1} go beyond the largest, 2**63 - 1",
        )
    return start, runs


# -- the model's physical range ------------------------------------------------------------
# Inputs outside these ranges are refused (FieldError) instead of overflowing: squares of
# coordinates, fourth powers of ranges and the Fisher information stay far from the limits
# of double precision inside them (docs/scenarios.md, "Ranges").

#: Largest horizontal coordinate (positions, targets, obstacles), m: 1000 km.
MAX_COORDINATE = 1e6

#: Smallest and largest flight altitude H, m.
MIN_ALTITUDE = 0.1
MAX_ALTITUDE = 1e5

#: Largest number of UAVs of a formation or a scenario (the largest swarm of the scaling
#: benchmark; a mission of that size already takes minutes).
MAX_UAVS = 100_000

#: Share of the memory this process may still take that one request may ask for.
MEMORY_SHARE = 0.5


def _meminfo_available() -> int | None:
    """MemAvailable of /proc/meminfo (Linux), or the physical memory elsewhere."""
    import os

    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # pragma: no cover - not POSIX
        return None


def _status_bytes(key: str) -> int | None:
    """A ``kB`` entry of /proc/self/status (``VmSize``, ``VmData``) in bytes (Linux)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_room() -> int | None:
    """Memory left under the cgroup v2 limit of this process (containers), if any."""
    try:
        with open("/sys/fs/cgroup/memory.max", encoding="ascii") as f:
            text = f.read().strip()
        if text == "max":
            return None
        with open("/sys/fs/cgroup/memory.current", encoding="ascii") as f:
            return int(text) - int(f.read().strip())
    except (OSError, ValueError):
        return None


def memory_room() -> int | None:
    """Bytes this process may still allocate: the smallest of the memory available on the
    machine, the room under the process's address-space and data limits (``ulimit -v``,
    ``ulimit -d``) and the room under its container's limit; None if none is known."""
    rooms = [_meminfo_available(), _cgroup_room()]
    try:
        import resource

        for limit, used in (
            (resource.RLIMIT_AS, _status_bytes("VmSize")),
            (resource.RLIMIT_DATA, _status_bytes("VmData")),
        ):
            soft = resource.getrlimit(limit)[0]
            if soft != resource.RLIM_INFINITY:
                rooms.append(soft - (used or 0))
    except (ImportError, OSError, ValueError):  # pragma: no cover - not POSIX
        pass
    known = [max(r, 0) for r in rooms if r is not None]
    return min(known) if known else None


def _size_text(nbytes: float) -> str:
    for unit, scale in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes:.0f} bytes"


def check_memory(nbytes: float, name: str, what: str, hint: str = "") -> None:
    """Refuse, before allocating, a request of ``nbytes`` that would not fit: more than
    :data:`MEMORY_SHARE` of :func:`memory_room`. ``what`` says what needs the memory
    (``"400 runs of 6000 steps"``), ``hint`` what to change; the error names ``name`` and
    gives both sizes."""
    room = memory_room()
    if room is not None and nbytes > MEMORY_SHARE * room:
        raise FieldError(
            name,
            f"{what} need about {_size_text(nbytes)}, more than this process may take "
            f"(half of the {_size_text(room)} it can still allocate)"
            + (f"; {hint}" if hint else ""),
        )
