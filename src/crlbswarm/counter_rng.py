r"""Counter-based random numbers: Philox4x32-10, keyed by the seed, counted by the draw.

A counter-based generator has no state: a draw is a pure function of a *key* and a
*counter*, so a compiled kernel computes each random number where it needs it, from the
run's seed and the draw's coordinates (step, UAV, stream), instead of reading it from an
array drawn beforehand. The memory then does not grow with the mission's length, and a
run's draws do not depend on the batch it is in, the chunk, the thread or the order in
which they are drawn.

The generator is Philox4x32-10 (Salmon, Moraes, Dror, Shaw, "Parallel random numbers: as
easy as 1, 2, 3", SC'11; the Random123 library): ten rounds of a Feistel-like network of
32x32 -> 64-bit products turn a 128-bit counter and a 64-bit key into 128 random bits. For
a fixed key it is a bijection of the counters (distinct counters give distinct blocks), it
passes TestU01's BigCrush, and :func:`philox4x32` reproduces the published known-answer
vectors of Random123 bit for bit (``tests/test_counter_rng.py``).

Key
    :func:`stream_key` ``(seed, stream)`` is the 64-bit key, two 32-bit words ``(k0, k1)``
    from ``numpy.random.SeedSequence(seed, spawn_key=(KEY_DOMAIN, stream))
    .generate_state(2, numpy.uint32)``: SeedSequence hashes the seed (any integer in
    ``0 .. 2**63 - 1``) so that neighbouring seeds give unrelated keys, and the spawn key
    (whose first word :data:`KEY_DOMAIN` no ``SeedSequence.spawn`` child of the seed
    reaches) keeps these keys apart from the NumPy streams the driver spawns from the
    same seed.

Counter
    Four 32-bit words ``(c0, c1, c2, c3)`` name the draw:

    ======  ==========================================================================
    word    meaning
    ======  ==========================================================================
    ``c0``  the step ``k`` (``0 <= k < 2**32``)
    ``c1``  the UAV ``m`` (``0 <= m < 2**32``)
    ``c2``  the stream: :data:`DISTURBANCE` (0) or :data:`RANGE_NOISE` (1)
    ``c3``  the block of the (step, UAV, stream) cell: 0 (each block gives two normals;
            a draw needing more takes blocks 1, 2, ...)
    ======  ==========================================================================

    The stream :data:`LINKS` (2) of the communication links (:mod:`crlbswarm.links`)
    counts the messages between UAVs ``a < b`` by (step, a, ``LINKS``, 4 b + kind): the
    two directions of a link share a block, each kind of draw (loss, delay, channel) has
    its own.

    The stream enters the key and the counter: two streams of one run never share a
    Philox block, even if their keys collided.

Normals
    :func:`normal_pair` turns one block into two independent standard normals by the
    Box-Muller transform: words ``(x0, x1)`` and ``(x2, x3)`` make two 53-bit uniforms
    :math:`u_1, u_2 \in (0, 1]` (:func:`uniform53`; never 0, so the logarithm is finite),
    and :math:`z_0 = r\cos 2\pi u_2`, :math:`z_1 = r\sin 2\pi u_2` with
    :math:`r = \sqrt{-2\ln u_1}`. Box-Muller takes a fixed number of words per pair (the
    polar method and the ziggurat reject, so a pair would take a variable number of
    blocks); its radius is at most :math:`\sqrt{2 \cdot 53 \ln 2} \approx 8.57`, a
    truncation of probability :math:`2^{-53} \approx 10^{-16}`. The sine and cosine are
    computed from the 53 bits of :math:`u_2` (a turn), whose reduction to
    :math:`[-\pi/4, \pi/4)` is exact integer arithmetic, by two Taylor polynomials:
    within :math:`3 \cdot 10^{-16}` of the exact values, and cheaper than the C library's
    ``sincos`` (a pair in 19 ns instead of 34, ``benchmarks/bench_counter_rng.py``). The
    motion disturbance of UAV ``m`` at step
    ``k`` is the pair of counter ``(k, m, DISTURBANCE, 0)``; its range noise is the first
    value of the pair of ``(k, m, RANGE_NOISE, 0)``.

:func:`standard_normals` returns, as an array, exactly the values a kernel draws, for the
tests and for the reference implementations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from . import _validation as _v
from .errors import FieldError

__all__ = [
    "DISTURBANCE",
    "KEY_DOMAIN",
    "LINKS",
    "PHASE_STREAMS",
    "RANGE_NOISE",
    "normal_pair",
    "philox4x32",
    "standard_normals",
    "stream_key",
    "uniform32",
    "uniform53",
    "uniform_pair",
    "uniform_quad",
]

#: Stream of the motion disturbance (counter word ``c2``): a pair of normals per UAV and step.
DISTURBANCE = 0

#: Stream of the range noise (counter word ``c2``): one normal per UAV and step.
RANGE_NOISE = 1

#: Stream of the communication links (counter word ``c2``; :mod:`crlbswarm.links`): the
#: loss, delay and channel state of the messages between UAVs a < b sent at the sending
#: turns 2 j and 2 j + 1, counted by (j, a, LINKS, 4 b + kind).
LINKS = 2

#: Streams per phase of a mission with faults (:mod:`crlbswarm.faults`): phase ``p`` draws
#: stream ``s`` from the key of (seed, ``s + p * PHASE_STREAMS``); phase 0 is the mission.
PHASE_STREAMS = 16

#: First word of the spawn key of :func:`stream_key` ("PHLX" in ASCII): far above the
#: children ``SeedSequence(seed).spawn(n)`` gives, so the keys share no entropy with them.
KEY_DOMAIN = 0x50484C58

# Philox4x32 multipliers and Weyl key increments (Random123, philox.h).
_M0 = np.uint64(0xD2511F53)
_M1 = np.uint64(0xCD9E8D57)
_W0 = np.uint64(0x9E3779B9)
_W1 = np.uint64(0xBB67AE85)
_MASK = np.uint64(0xFFFFFFFF)
_SHIFT = np.uint64(32)
_HI_SHIFT = np.uint64(21)  # uniform53: 32 bits of hi above the top 21 bits of lo
_LO_SHIFT = np.uint64(11)
_ROUNDS = 10
_WORD = 2**32
_INV_2_53 = 2.0**-53  # 53-bit integer -> double
_INV_2_32 = 2.0**-32  # 32-bit integer -> double

# sin and cos of a turn fraction n / 2**53 (normal_pair): the quarter turn from the top two
# bits of n + 2**50 (an eighth of a turn), the remaining angle in [-pi/4, pi/4), where the
# Taylor series to x**15 (sin) and x**16 (cos) are exact to below 1e-16.
_EIGHTH_TURN = np.uint64(2**50)
_TURN_MASK = np.uint64(2**53 - 1)
_QUARTER_MASK = np.uint64(2**51 - 1)
_QUARTER_SHIFT = np.uint64(51)
_QUARTER_ANGLE = (math.pi / 2) * 2.0**-51  # radians per unit of the quarter's 51 bits
_S1, _S3, _S5, _S7, _S9, _S11, _S13, _S15 = (
    (-1) ** i / math.factorial(2 * i + 1) for i in range(8)
)
_C0, _C2, _C4, _C6, _C8, _C10, _C12, _C14, _C16 = (
    (-1) ** i / math.factorial(2 * i) for i in range(9)
)


@njit(cache=True, inline="always")
def philox4x32(c0, c1, c2, c3, k0, k1):
    """Philox4x32-10 of the counter ``(c0, c1, c2, c3)`` under the key ``(k0, k1)``.

    Parameters
    ----------
    c0, c1, c2, c3 : int
        The counter's 32-bit words (integers; only the low 32 bits are used).
    k0, k1 : int
        The key's 32-bit words.

    Returns
    -------
    tuple of 4 numpy.uint64
        The four 32-bit output words (each below ``2**32``), in Random123's order.

    Notes
    -----
    Compiled kernel (inlined into its callers); the products are 64-bit, their high and
    low halves the two 32-bit words of Random123's ``mulhilo``.

    Examples
    --------
    >>> [f"{int(x):08x}" for x in philox4x32(0, 0, 0, 0, 0, 0)]
    ['6627e8d5', 'e169c58d', 'bc57ac4c', '9b00dbd8']
    """
    x0 = np.uint64(c0) & _MASK
    x1 = np.uint64(c1) & _MASK
    x2 = np.uint64(c2) & _MASK
    x3 = np.uint64(c3) & _MASK
    key0 = np.uint64(k0) & _MASK
    key1 = np.uint64(k1) & _MASK
    for r in range(_ROUNDS):
        if r > 0:
            key0 = (key0 + _W0) & _MASK
            key1 = (key1 + _W1) & _MASK
        p0 = _M0 * x0
        p1 = _M1 * x2
        x0, x1, x2, x3 = (
            (p1 >> _SHIFT) ^ x1 ^ key0,
            p1 & _MASK,
            (p0 >> _SHIFT) ^ x3 ^ key1,
            p0 & _MASK,
        )
    return x0, x1, x2, x3


@njit(cache=True, inline="always")
def uniform53(hi, lo):
    """The uniform in ``(0, 1]`` of two 32-bit words.

    The 53-bit integer of the 32 bits of ``hi`` and the top 21 bits of ``lo``, plus one,
    times ``2**-53`` (exact in double precision).

    Parameters
    ----------
    hi, lo : int
        Two 32-bit words (outputs of :func:`philox4x32`).

    Returns
    -------
    float
        A multiple of ``2**-53`` in ``[2**-53, 1]``: never 0, so its logarithm is finite.

    Examples
    --------
    >>> uniform53(0, 0) == 2.0**-53
    True
    >>> uniform53(2**32 - 1, 2**32 - 1)
    1.0
    """
    return _bits53(hi, lo) * _INV_2_53


@njit(cache=True, inline="always")
def uniform32(word):
    """The uniform in ``(0, 1]`` of one 32-bit word: ``(word + 1) 2**-32`` (exact).

    Parameters
    ----------
    word : int
        A 32-bit word (an output of :func:`philox4x32`).

    Returns
    -------
    float
        A multiple of ``2**-32`` in ``[2**-32, 1]``.

    Notes
    -----
    Compiled kernel, no checks (only the word's low 32 bits count).

    Examples
    --------
    >>> uniform32(0) == 2.0**-32, uniform32(2**32 - 1)
    (True, 1.0)
    """
    return np.float64((np.uint64(word) & _MASK) + np.uint64(1)) * _INV_2_32


@njit(cache=True, inline="always")
def _bits53(hi, lo):
    """The 53-bit integer of ``hi``'s 32 bits above ``lo``'s top 21, plus one (int64 in
    ``1 .. 2**53``)."""
    bits = ((np.uint64(hi) & _MASK) << _HI_SHIFT) | ((np.uint64(lo) & _MASK) >> _LO_SHIFT)
    return np.int64(bits) + 1


@njit(cache=True, inline="always")
def _sincos_turn(n):
    """``(sin, cos)`` of the angle ``2 pi n / 2**53`` for an integer ``0 <= n <= 2**53``,
    to within 3e-16: the argument reduction is exact integer arithmetic (the quarter turn
    from the top bits, no rounded multiple of pi), the rest two short Taylor series."""
    w = (np.uint64(n) + _EIGHTH_TURN) & _TURN_MASK
    quarter = np.int64(w >> _QUARTER_SHIFT)
    a = (np.int64(w & _QUARTER_MASK) - 2**50) * _QUARTER_ANGLE  # in [-pi/4, pi/4)
    z = a * a
    s = _S13 + z * _S15
    s = a * (_S1 + z * (_S3 + z * (_S5 + z * (_S7 + z * (_S9 + z * (_S11 + z * s))))))
    c = _C12 + z * (_C14 + z * _C16)
    c = _C0 + z * (_C2 + z * (_C4 + z * (_C6 + z * (_C8 + z * (_C10 + z * c)))))
    if quarter & 1:  # a quarter turn: (cos, sin) -> (-sin, cos)
        c, s = -s, c
    if quarter & 2:  # a half turn
        c, s = -c, -s
    return s, c


@njit(cache=True, inline="always")
def uniform_pair(k0, k1, c0, c1, c2, c3):
    """Two independent uniforms in ``(0, 1]`` from one Philox block.

    Parameters
    ----------
    k0, k1 : int
        The key (:func:`stream_key`).
    c0, c1, c2, c3 : int
        The counter: step, UAV, stream, block (the module's counter layout).

    Returns
    -------
    tuple of 2 float
        :func:`uniform53` of the words ``(x0, x1)`` and of ``(x2, x3)``.
    """
    x0, x1, x2, x3 = philox4x32(c0, c1, c2, c3, k0, k1)
    return uniform53(x0, x1), uniform53(x2, x3)


@njit(cache=True, inline="always")
def uniform_quad(k0, k1, c0, c1, c2, c3):
    """Four independent uniforms in ``(0, 1]`` from one Philox block, 32 bits each.

    Parameters
    ----------
    k0, k1 : int
        The key (:func:`stream_key`).
    c0, c1, c2, c3 : int
        The counter.

    Returns
    -------
    tuple of 4 float
        :func:`uniform32` of the words ``x0 .. x3``: twice the uniforms of
        :func:`uniform_pair` per block, at a resolution of ``2**-32`` (the link layer's
        message draws, :func:`crlbswarm.links.pair_block`).

    Notes
    -----
    Compiled kernel, no checks: each word's low 32 bits count (a
    negative word wraps), and an argument that is not an integer below ``2**64`` is a
    typing or overflow error of the compiler.
    """
    x0, x1, x2, x3 = philox4x32(c0, c1, c2, c3, k0, k1)
    return uniform32(x0), uniform32(x1), uniform32(x2), uniform32(x3)


@njit(cache=True, inline="always")
def normal_pair(k0, k1, c0, c1, c2, c3):
    r"""Two independent standard normals from one Philox block (Box-Muller).

    Parameters
    ----------
    k0, k1 : int
        The key (:func:`stream_key`).
    c0, c1, c2, c3 : int
        The counter: step, UAV, stream, block (the module's counter layout).

    Returns
    -------
    tuple of 2 float
        :math:`r\cos 2\pi u_2` and :math:`r\sin 2\pi u_2`,
        :math:`r = \sqrt{-2\ln u_1}`, for the uniforms :math:`(u_1, u_2)` of
        :func:`uniform_pair` (the sine and cosine to within :math:`3 \cdot 10^{-16}`).

    Notes
    -----
    Compiled kernel, no checks; inlined into its callers (``inline="always"``: about 12 %
    faster in a loop than a call). The mission's disturbance of UAV ``m`` at step ``k`` is
    ``normal_pair(k0, k1, k, m, DISTURBANCE, 0)`` with ``(k0, k1) = stream_key(seed,
    DISTURBANCE)``.

    Examples
    --------
    >>> z0, z1 = normal_pair(*stream_key(7, DISTURBANCE), 0, 0, DISTURBANCE, 0)
    >>> bool(abs(z0) < 9 and abs(z1) < 9)
    True
    """
    x0, x1, x2, x3 = philox4x32(c0, c1, c2, c3, k0, k1)
    r = math.sqrt(-2.0 * math.log(_bits53(x0, x1) * _INV_2_53))
    s, c = _sincos_turn(_bits53(x2, x3))
    return r * c, r * s


def stream_key(seed: int, stream: int) -> tuple[int, int]:
    """The Philox key of a seed's stream.

    Parameters
    ----------
    seed : int
        The run's seed, ``0 .. 2**63 - 1``.
    stream : int
        The stream, ``0 .. 2**32 - 1`` (:data:`DISTURBANCE`, :data:`RANGE_NOISE`).

    Returns
    -------
    tuple of 2 int
        The key's words ``(k0, k1)``, each below ``2**32``:
        ``SeedSequence(seed, spawn_key=(KEY_DOMAIN, stream)).generate_state(2, uint32)``.

    Raises
    ------
    FieldError
        If ``seed`` or ``stream`` is not an integer in its range.

    Examples
    --------
    >>> k0, k1 = stream_key(0, DISTURBANCE)
    >>> (k0, k1) != stream_key(1, DISTURBANCE) and (k0, k1) != stream_key(0, RANGE_NOISE)
    True
    """
    seed = _v.seed(seed, "seed")
    stream = _v.count(stream, "stream", 0, _WORD - 1)
    sequence = np.random.SeedSequence(seed, spawn_key=(KEY_DOMAIN, stream))
    k0, k1 = sequence.generate_state(2, np.uint32)
    return int(k0), int(k1)


def _indices(value: ArrayLike, name: str) -> np.ndarray:
    """A count ``n`` as the indices ``0 .. n-1``, or a 1-D array of indices, each a 32-bit
    counter word."""
    if np.ndim(value) == 0:
        return np.arange(_v.count(value, name, 0, _WORD), dtype=np.int64)
    arr = np.asarray(value)
    if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iu"):
        raise FieldError(
            name, f"expected a count or a 1-D array of integers, got {_v.short(value)}"
        )
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < 0 or arr.max() >= _WORD):
        raise FieldError(name, "indices must be in 0 .. 2**32 - 1")
    return arr


@njit(cache=True)
def _fill_normals(k0, k1, stream, steps, uavs, out):
    """``out[i, j]`` = the pair (or its first value) of counter (steps[i], uavs[j], stream, 0)."""
    dims = out.shape[2]
    for i in range(steps.shape[0]):
        for j in range(uavs.shape[0]):
            z0, z1 = normal_pair(k0, k1, steps[i], uavs[j], stream, 0)
            out[i, j, 0] = z0
            if dims == 2:
                out[i, j, 1] = z1


def standard_normals(
    seed: int, stream: int, steps: ArrayLike, uavs: ArrayLike, dims: int = 2
) -> np.ndarray:
    """The standard normals a kernel draws for a seed's stream, as an array.

    Parameters
    ----------
    seed : int
        The run's seed, ``0 .. 2**63 - 1``.
    stream : int
        The stream (:data:`DISTURBANCE`, :data:`RANGE_NOISE`), ``0 .. 2**32 - 1``.
    steps : int or array_like of int
        The steps: a count ``K`` (the steps ``0 .. K-1``) or a 1-D array of steps, each in
        ``0 .. 2**32 - 1``.
    uavs : int or array_like of int
        The UAVs: a count ``M`` (``0 .. M-1``) or a 1-D array of UAV indices.
    dims : {2, 1}, default 2
        2: the pair of :func:`normal_pair` (the disturbance's two axes); 1: its first value
        (the range noise).

    Returns
    -------
    ndarray, shape (len(steps), len(uavs), dims)
        ``out[i, j]`` is :func:`normal_pair` of the key :func:`stream_key` ``(seed,
        stream)`` and the counter ``(steps[i], uavs[j], stream, 0)`` (its first ``dims``
        values): the same bits whatever steps and UAVs are asked for, in any order.

    Raises
    ------
    FieldError
        If an argument is out of its range, or the array would not fit in memory.

    Examples
    --------
    >>> z = standard_normals(3, DISTURBANCE, 100, 4)
    >>> z.shape
    (100, 4, 2)
    >>> bool((standard_normals(3, DISTURBANCE, [99], [2]) == z[99, 2]).all())
    True
    """
    k0, k1 = stream_key(seed, stream)
    dims = _v.count(dims, "dims", 1, 2)
    step_index = _indices(steps, "steps")
    uav_index = _indices(uavs, "uavs")
    shape = (step_index.size, uav_index.size, dims)
    _v.check_elements(float(np.prod(shape, dtype=float)), "steps", "the normals", copies=1)
    out = np.empty(shape)
    _fill_normals(k0, k1, stream, step_index, uav_index, out)
    return out
