"""The machine floor: a small SIMD and bandwidth probe, and the work of a mission step.

Two measured rates (Numba, double precision), single-threaded and on all threads:

* ``flop rate``: each element of an 8 KiB array (fits in L1) goes through a chain of
  ``FMA_CHAIN`` fused multiply-adds ``y = y * a + b`` (2 flops each) before it is stored;
  LLVM vectorises the loop over the elements (AVX2/AVX-512), so the rate is the sustained
  SIMD FMA throughput of a compiled loop, not a datasheet peak.
* ``bandwidth``: the STREAM triad ``a[i] = b[i] + s * c[i]`` on three arrays of 32 MiB
  each (far beyond L2), counted as 24 bytes per element (STREAM's convention: the
  write-allocate read is not counted, so the figure is on the high side).

The work of one UAV-step of a mission (:func:`step_work`) is counted in flops and bytes
from the laws and the algorithm of crlbswarm's kernel (docs/performance.md, "Honest
baselines and the machine floor"): the control laws, the obstacle distances, the eta rule
(its segment test every step, its samples only where the test fails), the CRLB's Fisher
terms and the disturbance drawn in the kernel (a Philox4x32-10 block and Box-Muller per
UAV-step); the floor time is the roofline ``max(flops / flop rate, bytes / bandwidth)``.
Every division, comparison, square root, logarithm, min and max counts as one flop, like a
multiply-add's half, and so does each 32-bit integer operation of the generator, although
most cost more: the floor is optimistic, a lower bound.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from timing import best_of

#: Fused multiply-adds applied to each element per pass of the flop probe.
FMA_CHAIN = 16

#: Elements of the flop probe's array (8 KiB of float64: in L1).
FLOP_ELEMENTS = 1024

#: Elements of each array of the triad (32 MiB each).
TRIAD_ELEMENTS = 4 * 2**20


@njit(fastmath=True, cache=True)
def _fma_pass(y, a, b, passes):
    for _ in range(passes):
        for i in range(y.shape[0]):
            v = y[i]
            for _ in range(FMA_CHAIN):
                v = v * a + b
            y[i] = v


@njit(fastmath=True, cache=True, parallel=True)
def _fma_parallel(ys, a, b, passes):
    for t in prange(ys.shape[0]):
        _fma_pass(ys[t], a, b, passes)


@njit(cache=True)
def _triad(a, b, c, s):
    for i in range(a.shape[0]):
        a[i] = b[i] + s * c[i]


@njit(cache=True, parallel=True)
def _triad_parallel(a, b, c, s):
    for i in prange(a.shape[0]):
        a[i] = b[i] + s * c[i]


def measure_rates(repeat: int = 5) -> dict[str, float]:
    """Measured flop rate (flop/s) and triad bandwidth (B/s), on one thread and on all
    Numba threads (keys ``flops_1``, ``flops_all``, ``bw_1``, ``bw_all``, ``threads``)."""
    threads = numba.get_num_threads()
    passes = 20_000
    # a * y + b with |a| < 1 keeps the values finite and normal.
    y = np.full(FLOP_ELEMENTS, 0.5)
    t = best_of(lambda: _fma_pass(y, 0.999, 1e-3, passes), repeat)
    work = 2.0 * FMA_CHAIN * FLOP_ELEMENTS * passes
    ys = np.full((threads, FLOP_ELEMENTS), 0.5)
    t_all = best_of(lambda: _fma_parallel(ys, 0.999, 1e-3, passes), repeat)
    a = np.zeros(TRIAD_ELEMENTS)
    b = np.ones(TRIAD_ELEMENTS)
    c = np.ones(TRIAD_ELEMENTS)
    tb = best_of(lambda: _triad(a, b, c, 0.5), repeat)
    tb_all = best_of(lambda: _triad_parallel(a, b, c, 0.5), repeat)
    nbytes = 24.0 * TRIAD_ELEMENTS
    return {
        "threads": float(threads),
        "flops_1": work / t,
        "flops_all": threads * work / t_all,
        "bw_1": nbytes / tb,
        "bw_all": nbytes / tb_all,
    }


# ---------------------------------------------------------------------------------------
# Work per UAV-step, counted from the laws
# ---------------------------------------------------------------------------------------
#: Flops of one obstacle-distance evaluation: a rectangle's clamp (4 min/max), the offset
#: (2), its squared length (3), the square root (1) and the running minimum (1).
FLOPS_RECT_DISTANCE = 11
#: A circle's: the offset (2), squared length (3), square root (1), minus the radius (1)
#: and the running minimum (1).
FLOPS_CIRCLE_DISTANCE = 8
#: Extra flops of the repulsion for an obstacle within l_safe (unit vector 2 divisions,
#: 1/l - 1/l_safe and the gain 5, accumulation 4); only counted where it applies.
FLOPS_REPULSION_TERM = 11
#: Per neighbour: formation input (eq. (19): 2 x (sub, sub, fma, fma), 8), consensus
#: (eq. (14): 2 x (sub, add), 4) and cost (eq. (15): 2 x (sub, sub, sub, fma), 8).
FLOPS_PER_NEIGHBOUR = 20
#: Per UAV, once: motion model (eq. (3): 2 x 4), the gains (eq. (19) eps, eq. (14) gamma: 4),
#: the cap of the repulsion (norm and compare: 4), the cost's velocity term (8), the centroid
#: (2), the clearance minimum (1) and the CRLB's FIM terms (eq. (10): offset 2, squared range 3,
#: g_m = (A/d^2 + 8)/d^4 with 5, three products 3 and three sums 3, 16).
FLOPS_PER_UAV = 43
#: Per formation and step: the 2x2 inverse trace (5), the leader's guidance and saturation
#: (about 15), the eta rule's bookkeeping (about 30); spread over the UAVs.
FLOPS_PER_FORMATION = 50
#: Per sample point of the eta rule: its position on the path or across it (4).
FLOPS_PER_SAMPLE = 4

#: The eta rule's segment test (its whole sampled path against each obstacle, every step),
#: once per step: the two endpoints (8), the direction and its squared length (5), the
#: padded and rounded threshold and its square (4) and its sign test (1).
FLOPS_SEGMENT_SETUP = 18
#: Flops of one squared point-to-segment distance and its test: the offset (2), the dot
#: product (3), the degenerate-segment test (1), the division (1), the clamp to [0, 1] (2),
#: the nearest point's offset (6), its squared length (3) and the comparison (1).
FLOPS_POINT_SEGMENT = 19
#: Per rectangle: two endpoint-to-box distances and tests (2 x (clamp 4, offset 2, squared
#: length 3, comparison 1), 20), the Liang-Barsky clip (4 sides x (offset 1, two sign tests
#: 2, division 1, min or max 1, the t0 > t1 test 1), 24; all four sides, although it often
#: stops earlier) and the four corners' distances to the segment (4 x 19): 120. The test
#: stops at the first too close; the usual case (the segment clears) runs all of it.
FLOPS_SEGMENT_RECT = 20 + 24 + 4 * FLOPS_POINT_SEGMENT
#: Per circle: the centre's distance to the segment (19) and the threshold radius +
#: keep, squared (2).
FLOPS_SEGMENT_CIRCLE = FLOPS_POINT_SEGMENT + 2

#: Rounds of the Philox4x32-10 block the kernel draws per UAV-step (its motion disturbance).
PHILOX_ROUNDS = 10
#: Per round: two 32x32 -> 64-bit multiplies and about six xor, shift, mask and key-bump
#: integer operations, each counted as one flop-equivalent.
FLOPS_PHILOX_ROUND = 8
#: Box-Muller on the block: the logarithm, the square root and the sine-cosine pair (one
#: flop each, although the kernel's pair is two Taylor polynomials of about 30 flops), and
#: about six multiplies and adds (the uniform's scale, -2 ln u, r cos, r sin and the two
#: products by sigma). Not counted: the shifts and ors that make the 53-bit uniforms.
FLOPS_BOX_MULLER = 9
#: The in-kernel draw of one UAV-step: one Philox4x32-10 block and Box-Muller (89).
FLOPS_RANDOM_DRAW = PHILOX_ROUNDS * FLOPS_PHILOX_ROUND + FLOPS_BOX_MULLER

#: The smallest separation (a metric of every step): all pairs for a small swarm, 4 flops a
#: pair, 2 (M - 1) per UAV (pass as ``extra_flops``); for a large swarm a cell list of about
#: one UAV per cell: bounding box (4), cell index (6), about 4.5 pair distances (18).
FLOPS_SEPARATION = 28
#: Its bytes per UAV in a large swarm: cell key, count, order and fill arrays (8 each, each
#: written and read once: 64), counted only with ``large_graph``.
BYTES_SEPARATION = 64

#: Bytes per UAV-step: the kernel reads q_k (16) and v_k (16) and writes q_{k+1} (16) and
#: v_{k+1} (16). The disturbance is drawn in the kernel (no array written by the driver and
#: read back) and the CRLB's Fisher terms are summed there too (no pass reading the positions
#: back). Graph (CSR) and obstacles are a few hundred bytes per step, in cache. Not counted:
#: the metrics per step (a few per formation).
BYTES_PER_UAV_STEP = 64
#: Per neighbour, for a graph that does not fit in cache (large swarms): one CSR index (8)
#: and the neighbour's position and velocity (32, mostly cache hits along a ring: 0 here).
BYTES_PER_NEIGHBOUR = 8


def step_work(
    m_uavs: int,
    neighbours: float,
    n_rects: int,
    n_circles: int,
    evaluations: float,
    samples: float,
    repulsion_terms: float,
    extra_flops: float = 0.0,
    large_graph: bool = False,
    segment_tests: float | None = None,
) -> dict[str, float]:
    """Flops and bytes of one UAV-step of a mission.

    Parameters
    ----------
    m_uavs : int
        UAVs of the formation.
    neighbours : float
        Neighbours per UAV (a ring: 2).
    n_rects, n_circles : int
        Rectangles and circles of the scenario.
    evaluations : float
        Point-to-obstacle distance evaluations per step, all UAVs and all purposes
        (repulsion, clearance, the eta rule's samples where its segment test fails).
    samples : float
        The eta rule's sample points per step.
    repulsion_terms : float
        Obstacles within ``l_safe`` per step (each adds a repulsion term).
    extra_flops : float, optional
        Further flops per UAV-step (the smallest separation, :data:`FLOPS_SEPARATION`).
    large_graph : bool, optional
        Whether the graph and the separation's cell list fall out of cache (large swarms:
        :data:`BYTES_PER_NEIGHBOUR` and :data:`BYTES_SEPARATION` per UAV-step).
    segment_tests : float or None, optional
        The eta rule's segment-to-obstacle tests per step (``count_paper_work``'s
        ``segment_tests``); None: one per obstacle and step, the usual case of a segment
        that clears (0 when the eta rule is off).

    Returns
    -------
    dict of str to float
        ``evaluations_per_uav_step``; ``flops`` and ``bytes`` per UAV-step.

    Notes
    -----
    Per UAV-step, every UAV: :data:`FLOPS_PER_UAV`, :data:`FLOPS_PER_NEIGHBOUR` per
    neighbour and the draw of its disturbance, :data:`FLOPS_RANDOM_DRAW`; per step, spread
    over the UAVs: the evaluations, samples, repulsion terms and segment tests (with
    :data:`FLOPS_SEGMENT_SETUP` once if any) and :data:`FLOPS_PER_FORMATION`.
    """
    n_obs = n_rects + n_circles
    per_eval = (n_rects * FLOPS_RECT_DISTANCE + n_circles * FLOPS_CIRCLE_DISTANCE) / n_obs
    per_test = (n_rects * FLOPS_SEGMENT_RECT + n_circles * FLOPS_SEGMENT_CIRCLE) / n_obs
    if segment_tests is None:
        segment_tests = float(n_obs)
    segment_flops = segment_tests * per_test + (FLOPS_SEGMENT_SETUP if segment_tests else 0)
    flops = (
        (
            evaluations * per_eval
            + samples * FLOPS_PER_SAMPLE
            + repulsion_terms * FLOPS_REPULSION_TERM
            + segment_flops
            + FLOPS_PER_FORMATION
        )
        / m_uavs
        + neighbours * FLOPS_PER_NEIGHBOUR
        + FLOPS_PER_UAV
        + FLOPS_RANDOM_DRAW
        + extra_flops
    )
    nbytes = BYTES_PER_UAV_STEP
    if large_graph:
        nbytes += neighbours * BYTES_PER_NEIGHBOUR + BYTES_SEPARATION
    return {
        "evaluations_per_uav_step": evaluations / m_uavs,
        "flops": flops,
        "bytes": nbytes,
    }


def floor_time(work: dict[str, float], flop_rate: float, bandwidth: float) -> float:
    """Roofline floor of one UAV-step, s: the larger of the compute and the memory time."""
    return max(work["flops"] / flop_rate, work["bytes"] / bandwidth)
