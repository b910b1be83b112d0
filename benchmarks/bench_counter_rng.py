"""Counter-based normals: nanoseconds per pair of ``normal_pair`` against NumPy.

Times, per pair of standard normals, (a) :func:`crlbswarm.counter_rng.normal_pair` called
in a compiled loop over (step, UAV) counters, the way the mission kernel draws them, summed
so the compiler cannot drop the work, (b) the same Box-Muller with the C library's sine and
cosine instead of ``normal_pair``'s own, (c) the loop writing the pairs to an array (what
:func:`~crlbswarm.counter_rng.standard_normals` does), and (d)
``numpy.random.Generator.standard_normal(out=...)`` (PCG64, ziggurat) filling an array of
the same shape, what the driver pre-draws today. Prints a Markdown table with the ratios
to NumPy.

Run: ``python benchmarks/bench_counter_rng.py [--steps 2000] [--uavs 500] [--repeat 15]``.
"""

from __future__ import annotations

import argparse
import math
import platform

import numpy as np
from numba import njit

from crlbswarm.counter_rng import DISTURBANCE, normal_pair, stream_key, uniform_pair
from timing import best_of


@njit(cache=True)
def summed_pairs(k0, k1, steps, uavs):
    """Sum of the disturbance pairs of ``steps`` x ``uavs`` counters (nothing stored)."""
    total = 0.0
    for k in range(steps):
        for m in range(uavs):
            z0, z1 = normal_pair(k0, k1, k, m, DISTURBANCE, 0)
            total += z0 + z1
    return total


@njit(cache=True)
def summed_libm_pairs(k0, k1, steps, uavs):
    """As :func:`summed_pairs`, with the sine and cosine of the C library (``sincos``)."""
    total = 0.0
    for k in range(steps):
        for m in range(uavs):
            u1, u2 = uniform_pair(k0, k1, k, m, DISTURBANCE, 0)
            r = math.sqrt(-2.0 * math.log(u1))
            total += r * math.cos(2.0 * math.pi * u2) + r * math.sin(2.0 * math.pi * u2)
    return total


@njit(cache=True)
def stored_pairs(k0, k1, out):
    """The disturbance pairs written to ``out`` (steps, uavs, 2)."""
    for k in range(out.shape[0]):
        for m in range(out.shape[1]):
            z0, z1 = normal_pair(k0, k1, k, m, DISTURBANCE, 0)
            out[k, m, 0] = z0
            out[k, m, 1] = z1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--uavs", type=int, default=500)
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    pairs = args.steps * args.uavs
    k0, k1 = stream_key(0, DISTURBANCE)
    out = np.empty((args.steps, args.uavs, 2))
    rng = np.random.default_rng(0)
    times = {
        "normal_pair, compiled loop (summed)": best_of(
            lambda: summed_pairs(k0, k1, args.steps, args.uavs), args.repeat
        ),
        "Box-Muller with libm sin/cos, compiled loop (summed)": best_of(
            lambda: summed_libm_pairs(k0, k1, args.steps, args.uavs), args.repeat
        ),
        "normal_pair, compiled loop (stored)": best_of(
            lambda: stored_pairs(k0, k1, out), args.repeat
        ),
        "numpy Generator.standard_normal(out=)": best_of(
            lambda: rng.standard_normal(out=out), args.repeat
        ),
    }
    numpy_ns = times["numpy Generator.standard_normal(out=)"] / pairs * 1e9
    print(f"{pairs} pairs ({args.steps} steps x {args.uavs} UAVs), best of {args.repeat}; "
          f"{platform.processor() or platform.machine()}, NumPy {np.__version__}\n")  # fmt: skip
    print("| method | ns per pair | ratio to NumPy |")
    print("|---|---|---|")
    for name, seconds in times.items():
        ns = seconds / pairs * 1e9
        print(f"| {name} | {ns:.1f} | {ns / numpy_ns:.2f} |")


if __name__ == "__main__":
    main()
