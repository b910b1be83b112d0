"""Obstacle queries through the uniform grid (:func:`crlbswarm.obstacles.obstacle_field`)
against the loop over every obstacle (``clearance_at`` + ``repulsion_at``).

``--points`` points spread uniformly over a 1 km square, 10, 100, 1000 and 10 000 small
rectangles and circles (sides 2-5 m, radii 1-2.5 m, one per cell of a jittered lattice, so
they rarely overlap), the paper's repulsion (l_safe = 5 m). Prints a Markdown table of the
time per point and the ratio cost(1000 obstacles) / cost(10 obstacles) of the grid (the
project's target: at most 2 at 1000 points). Every result is checked bit for bit against
the loop over every obstacle. Up to 16 obstacles the index is skipped (direct mode).

Run: ``python benchmarks/bench_obstacles.py [--points 1000] [--repeat 20]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from numba import njit

from crlbswarm.obstacles import (
    clearance_at,
    clearance_grid,
    obstacle_field,
    obstacle_grid,
    repulsion_at,
)
from timing import best_of

SIDE = 1000.0  # m, the square of the points and the obstacles
L_SAFE = 5.0  # m, l_safe of the paper
GAIN = 2.0  # E_r (the paper scenario's)
MAX_STEP = 1.0  # m
COUNTS = (10, 100, 1000, 10_000)


def scene(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` small obstacles, half rectangles and half circles, one per lattice cell."""
    per_side = int(np.ceil(np.sqrt(n)))
    pitch = SIDE / per_side
    slots = rng.permutation(per_side * per_side)[:n]
    corner = np.column_stack([slots % per_side, slots // per_side]) * pitch
    centre = corner + rng.uniform(0.2, 0.8, (n, 2)) * pitch
    n_r = n // 2
    half = rng.uniform(1.0, 2.5, (n_r, 2))
    c = centre[:n_r]
    rects = np.column_stack([c[:, 0] - half[:, 0], c[:, 0] + half[:, 0],
                             c[:, 1] - half[:, 1], c[:, 1] + half[:, 1]])  # fmt: skip
    circles = np.column_stack([centre[n_r:], rng.uniform(1.0, 2.5, n - n_r)])
    return rects, circles


@njit
def field_grid(points, grid, out):
    for b in range(points.shape[0]):
        out[b, 0], out[b, 1], out[b, 2] = obstacle_field(
            points[b, 0], points[b, 1], grid, GAIN, L_SAFE, MAX_STEP
        )


@njit
def field_loop(points, rects, circles, out):
    for b in range(points.shape[0]):
        out[b, 0] = clearance_at(points[b, 0], points[b, 1], rects, circles)
        out[b, 1], out[b, 2] = repulsion_at(
            points[b, 0], points[b, 1], rects, circles, GAIN, L_SAFE, MAX_STEP
        )


@njit
def clearance_only(points, grid, out):
    for b in range(points.shape[0]):
        out[b, 0] = clearance_grid(points[b, 0], points[b, 1], grid)


def measure(n: int, points: np.ndarray, rng: np.random.Generator, repeat: int) -> dict:
    """Build time and time per point of the grid and of the loop for ``n`` obstacles;
    checks that both give the same bits."""
    rects, circles = scene(n, rng)
    t0 = time.perf_counter()
    grid = obstacle_grid(rects, circles, L_SAFE)
    build = time.perf_counter() - t0
    out, ref, clr = (np.empty((points.shape[0], 3)) for _ in range(3))
    per_point = {
        "grid": best_of(lambda: field_grid(points, grid, out), repeat),
        "clearance": best_of(lambda: clearance_only(points, grid, clr), repeat),
        "loop": best_of(lambda: field_loop(points, grid.rects, grid.circles, ref), repeat),
    }
    assert np.array_equal(out.view(np.int64), ref.view(np.int64)), n
    assert np.array_equal(clr[:, 0].view(np.int64), ref[:, 0].view(np.int64)), n
    return {"grid_index": grid, "build": build} | {
        k: v / points.shape[0] for k, v in per_point.items()
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    points = rng.uniform(0.0, SIDE, (args.points, 2))
    print(f"{args.points} points over a {SIDE:g} m square, l_safe {L_SAFE:g} m; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs\n")  # fmt: skip
    print("| obstacles | index | entries | build, ms | obstacle_field, ns/point | "
          "clearance_grid, ns/point | loop, ns/point | loop / obstacle_field |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    cost = {}
    for n in COUNTS:
        m = measure(n, points, rng, args.repeat)
        grid = m["grid_index"]
        cost[n] = m["grid"]
        index = "none (direct)" if grid.direct else (
            f"{grid.nx} x {grid.ny} cells of {grid.cell:.1f} m")  # fmt: skip
        print(f"| {n} | {index} | {grid.cell_items.size} | {m['build'] * 1e3:.2f} | "
              f"{m['grid'] * 1e9:.0f} | {m['clearance'] * 1e9:.0f} | {m['loop'] * 1e9:.0f} | "
              f"{m['loop'] / m['grid']:.1f} |")  # fmt: skip
    print(f"\nobstacle_field cost(1000 obstacles) / cost(10 obstacles) = "
          f"{cost[1000] / cost[10]:.2f} (target <= 2); 10 000 / 10: "
          f"{cost[10_000] / cost[10]:.2f}; 100 / 10: {cost[100] / cost[10]:.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
