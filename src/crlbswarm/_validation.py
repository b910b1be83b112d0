"""Input checks shared by the public functions.

Every check raises :class:`~crlbswarm.errors.FieldError` (a :class:`ValueError`) carrying the
name of the offending argument and the reason, whose message is one line; the CLI maps the
name to its option. The checks never modify the caller's array: they return it as a float
array (the caller's own array when it already is one, so callers copy before writing).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .errors import FieldError, one_line

__all__: list[str] = []

#: Largest seed (seeds are stored as int64).
MAX_SEED = 2**63 - 1

#: Fewest UAVs of a formation: the design and the benchmarks need three (with two, the
#: formation and the target are collinear in the horizontal plane for some geometries and
#: the regular polygon degenerates).
MIN_UAVS = 3


def as_float_array(value: object, name: str) -> np.ndarray:
    """Convert ``value`` to a float64 array or raise a ``ValueError`` naming ``name``.

    Real numbers (Python or NumPy, integer or float, any shape) are accepted; complex numbers
    (even with a zero imaginary part: the conversion would drop it), booleans, strings,
    dates and objects that are not numbers are refused, in one line.
    """
    if isinstance(value, str | bytes | bool | np.bool_):
        raise FieldError(name, f"expected numbers, got {short(value)}")
    try:
        raw = value if isinstance(value, np.ndarray) else np.asarray(value)
    except Exception as exc:  # ragged nesting, a failing __array__, ...
        raise FieldError(name, f"expected numbers, got {short(value)}") from exc
    kind = raw.dtype.kind
    if kind == "c":
        raise FieldError(name, f"expected real numbers, got complex {short(value)}")
    if kind == "b":
        raise FieldError(name, f"expected numbers, got booleans {short(value)}")
    if kind not in "iufO":
        raise FieldError(name, f"expected numbers, got {short(value)}")
    if raw.dtype == np.float64:  # nothing to convert (the hot path)
        return np.asarray(raw)
    if kind == "O" and any(
        isinstance(x, str | bytes | bool | np.bool_ | complex | np.complexfloating)
        for x in raw.flat
    ):
        raise FieldError(name, f"expected real numbers, got {short(value)}")
    try:
        with np.errstate(over="raise"):  # (a long double beyond double precision)
            return np.asarray(raw, dtype=float)
    except FloatingPointError as exc:
        raise FieldError(name, "beyond the range of double precision") from exc
    except (TypeError, ValueError, OverflowError) as exc:
        raise FieldError(name, f"expected numbers, got {short(value)}") from exc


def short(value: object, limit: int = 60) -> str:
    """``repr(value)`` on one line and at most ``limit`` characters (for error messages)."""
    return one_line(repr(value), limit)


def check_finite(arr: np.ndarray, name: str) -> np.ndarray:
    """Raise if ``arr`` holds NaN or infinity."""
    if not np.isfinite(arr).all():
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
        raise FieldError(name, f"must be > 0, got {short(value)}")
    return arr


def finite(value: object, name: str) -> np.ndarray:
    """Check a finite number or array of them."""
    return check_finite(as_float_array(value, name), name)


def count(value: object, name: str, minimum: int, maximum: int | None = None) -> int:
    """Check an integer count of at least ``minimum`` (and at most ``maximum``).

    Python and NumPy integers (and 0-d integer arrays) are accepted; floats, booleans and
    anything else are refused."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        value = value.item()
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        raise FieldError(name, f"expected an integer, got {short(value)}")
    value = int(value)
    if value < minimum:
        raise FieldError(name, f"must be at least {minimum}, got {short(value)}")
    limit = MAX_SEED if maximum is None else maximum  # every count fits in an int64
    if value > limit:
        shown = "2**63 - 1" if limit == MAX_SEED else str(limit)
        raise FieldError(name, f"must be at most {shown}, got {short(value)}")
    return value


def broadcast(name: str, *shapes: tuple[int, ...]) -> tuple[int, ...]:
    """Broadcast shapes or raise a ``ValueError`` naming the argument ``name``."""
    given = [tuple(s) for s in shapes if len(s)]
    if all(s == given[0] for s in given[1:]):  # equal or scalar shapes (the hot path)
        return given[0] if given else ()
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError as exc:
        raise FieldError(
            f"{name}", f"shapes {', '.join(str(s) for s in shapes)} do not broadcast"
        ) from exc


def scalar(value: object, name: str) -> float:
    """Check a single finite number: a Python or NumPy number or a 0-d array (an array of
    any other shape, even of one element, is refused)."""
    arr = as_float_array(value, name)
    if arr.ndim != 0:
        raise FieldError(name, f"expected a single number, got an array of shape {arr.shape}")
    check_finite(arr, name)
    return float(arr)


def positive_scalar(value: object, name: str) -> float:
    """Check a single finite number > 0."""
    number = scalar(value, name)
    if not number > 0:
        raise FieldError(name, f"must be > 0, got {short(value)}")
    return number


def seed(value: object, name: str) -> int:
    """Check a seed: an integer in ``0 .. MAX_SEED``."""
    s = count(value, name, 0)
    if s > MAX_SEED:
        raise FieldError(name, f"must be at most 2**63 - 1, got {s}")
    return s


def uav_count(value: object, name: str) -> int:
    """Check a number of UAVs of a formation: an integer from :data:`MIN_UAVS` to
    :data:`MAX_UAVS`."""
    return count(value, name, MIN_UAVS, MAX_UAVS)


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
# of double precision inside them (docs/sensing-model.md, "Ranges of the model").

#: Largest horizontal coordinate (positions, targets, obstacles), m: 10 000 km, so that
#: projected coordinates (UTM eastings and northings, up to 1e7 m) are accepted.
MAX_COORDINATE = 1e7

#: Smallest and largest flight altitude H, m.
MIN_ALTITUDE = 0.1
MAX_ALTITUDE = 1e5

#: Largest number of UAVs of a formation or a scenario (the largest swarm of the scaling
#: benchmark; a mission of that size already takes minutes).
MAX_UAVS = 100_000

#: Largest number of UAVs of a constrained (numerical) design: its dense SQP costs about
#: M^3 per iteration (M = 100 takes seconds per start, docs/constrained-design.md).
MAX_DESIGN_UAVS = 500

#: Largest slant range, m: the farthest two points of the coordinate range, at the largest
#: altitude (2 sqrt(2) 1e7 m, rounded up).
MAX_DISTANCE = 3.0 * MAX_COORDINATE

#: Smallest size of a formation (a radius, an offset, a length, a separation), m: a
#: micrometre. Smaller formations are all but a single point, whose CRLB (about 1/r^2)
#: would overflow.
MIN_LENGTH = 1e-6

#: Largest magnitude of an angle (a rotation or heading, in rad or deg): beyond it the
#: spacing of a formation's azimuths (2 pi / M) is lost to rounding.
MAX_ANGLE = 1e6

#: Largest speed or velocity component, m/s (UAVs, targets, reference velocities).
MAX_SPEED = 1e6

#: Largest time step, s (of the target motion models and the control laws' time step).
MAX_TIME_STEP = 1e4

#: Largest standard deviation of a target's white acceleration, m/s^2.
MAX_ACCELERATION = 1e4

#: Largest turn rate of the turning target model, rad/s.
MAX_TURN_RATE = 1e3

#: Range of the radar's constant A = p G_p beta0 / (kappa sigma0^2), m^4: the range standard
#: deviation at 1 m, 1/sqrt(A), lies between 1e-15 m and 1e15 m. With slant ranges in
#: [MIN_ALTITUDE, MAX_DISTANCE] and up to MAX_UAVS UAVs, the variances d^4/A, the Fisher
#: information, its determinant and the CRLB then stay finite and non-zero in double
#: precision (docs/sensing-model.md, "Ranges of the model").
MIN_SNR_CONSTANT = 1e-30
MAX_SNR_CONSTANT = 1e30

#: Largest magnitude of a measured range, m: beyond what the model can produce (a range of
#: MAX_DISTANCE with the smallest A has a standard deviation of about 1e28 m), small enough
#: that the likelihood and its derivatives stay finite.
MAX_MEASURED_RANGE = 1e30

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
            used = int(f.read().strip())
        with open("/sys/fs/cgroup/memory.stat", encoding="ascii") as f:  # reclaimable cache
            for line in f:
                if line.startswith("inactive_file "):
                    used -= int(line.split()[1])
        return int(text) - used
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
            f"{what} would need about {_size_text(nbytes)}, more than this process may take "
            f"(half of the {_size_text(room)} it can still allocate)"
            + (f"; {hint}" if hint else ""),
        )


# -- checks against the model's range ------------------------------------------------------
def bounded(arr: np.ndarray, name: str, low: float, high: float, unit: str) -> np.ndarray:
    """Refuse entries of ``arr`` outside ``[low, high]`` (after the finiteness check)."""
    if arr.size:  # the hot path: one pass for the extremes (NaN propagates into them)
        lo, hi = arr.min(), arr.max()
        if low <= lo and hi <= high and math.isfinite(lo) and math.isfinite(hi):
            return arr
    check_finite(arr, name)
    if arr.size and not (np.all(arr >= low) and np.all(arr <= high)):
        bad = arr[(arr < low) | (arr > high)].flat[0]
        raise FieldError(
            name, f"must be between {low:g} and {high:g}{unit} (the model's range), got {bad:g}"
        )
    return arr


def coordinates(value: object, name: str) -> np.ndarray:
    """Check planar positions ``(..., M, 2)`` within +-:data:`MAX_COORDINATE` m."""
    arr = positions(value, name)
    return bounded(arr, name, -MAX_COORDINATE, MAX_COORDINATE, " m")


def location(value: object, name: str) -> np.ndarray:
    """Check a planar point (or batch of points) ``(..., 2)`` within
    +-:data:`MAX_COORDINATE` m."""
    arr = point(value, name)
    return bounded(arr, name, -MAX_COORDINATE, MAX_COORDINATE, " m")


def velocity(value: object, name: str) -> np.ndarray:
    """Check a planar velocity (or batch of them) ``(..., 2)`` with components within
    +-:data:`MAX_SPEED` m/s."""
    arr = point(value, name)
    return bounded(arr, name, -MAX_SPEED, MAX_SPEED, " m/s")


def altitude(value: object, name: str) -> np.ndarray:
    """Check a flight altitude (or array of them) in [:data:`MIN_ALTITUDE`,
    :data:`MAX_ALTITUDE`] m."""
    arr = as_float_array(value, name)
    return bounded(arr, name, MIN_ALTITUDE, MAX_ALTITUDE, " m")


def length(value: object, name: str) -> np.ndarray:
    """Check a length (or array of them) in [:data:`MIN_LENGTH`, :data:`MAX_DISTANCE`] m."""
    arr = as_float_array(value, name)
    check_finite(arr, name)
    if not np.all(arr > 0):
        raise FieldError(name, f"must be > 0, got {short(value)}")
    return bounded(arr, name, MIN_LENGTH, MAX_DISTANCE, " m")


def in_range(value: object, name: str, low: float, high: float, unit: str = "") -> float:
    """Check a single number in ``[low, high]``."""
    number = scalar(value, name)
    if not low <= number <= high:
        raise FieldError(
            name, f"must be between {low:g} and {high:g}{unit} (the model's range), got {number:g}"
        )
    return number


def finite_result(result: np.ndarray, name: str, reason: str) -> np.ndarray:
    """Refuse a computed result that is not finite: the input ``name`` is out of range.

    The safety net of the public functions: inside the model's ranges their results are
    finite; an argument whose range is not declared (a gain) may still make them overflow,
    and the error then names that argument, with ``reason``."""
    if not np.isfinite(result).all():
        raise FieldError(name, reason)
    return result


def check_elements(n_elements: float, name: str, what: str, copies: int = 4) -> None:
    """Refuse, before allocating, arrays of ``n_elements`` float64 values, counted ``copies``
    times for the temporaries (:func:`check_memory`). Requests below
    :data:`SMALL_REQUEST` bytes pass without reading the system's memory (the hot paths)."""
    nbytes = 8.0 * copies * float(n_elements)
    if nbytes >= SMALL_REQUEST:
        check_memory(nbytes, name, what)


#: Requests smaller than this (64 MiB) are not checked against the memory left.
SMALL_REQUEST = 2**26


def angle(value: object, name: str, unit: str = " rad") -> float:
    """Check a single angle of magnitude at most :data:`MAX_ANGLE`."""
    return in_range(value, name, -MAX_ANGLE, MAX_ANGLE, unit)
