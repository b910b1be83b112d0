"""Large swarms: simulator time per step against the number of UAVs (issue 5).

Run: ``python benchmarks/bench_scaling.py [--sizes 1000 3000 10000 30000 100000]
[--steps 50] [--plot FILE.png]``. Each size is a ring-graph swarm flying from a square start
region to F* over the target, through a field of 40 circular obstacles, with every metric
computed (CRLB, cost, obstacle clearance, smallest separation, eta). Times are per step,
best of two missions after a warm-up mission; trajectories are not kept. The "plain loop"
row times one control step written as a per-UAV Python loop (formation input, consensus,
repulsion, motion) for the comparison, at the smallest size.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np

import crlbswarm as cs


def swarm_scenario(n: int, steps: int) -> cs.Scenario:
    """n UAVs 2 m apart on F*, starting in a square of about 1 UAV per 4 m^2."""
    radius = 2.0 * n / (2.0 * math.pi)
    altitude = radius * math.tan(float(cs.optimal_elevation(1000.0)))
    side = 2.0 * math.sqrt(n)
    rng = np.random.default_rng(0)
    angles = rng.uniform(0.0, 2.0 * math.pi, 40)
    centres = 0.5 * radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1) + [0, side]
    return cs.Scenario.from_dict(
        {
            "altitude": altitude,
            "target": [0.0, 0.0],
            "uavs": {"count": n, "start_region": [[-side / 2, side / 2], [-side / 2, side / 2]]},
            # (hold: the convergence window must be shorter than these short missions)
            "time": {"step": 0.1, "duration": 0.1 * steps, "hold": 0.05 * steps},
            "graph": {"kind": "ring"},
            # The paper's controller (new scenarios fly with the safety layers on).
            "safety": {"enabled": False},
            "guidance": {"planner": False},
            "formation": {"assignment": "index", "design": "closed_form"},
            "obstacles": [
                {"type": "circle", "center": c.tolist(), "radius": 3.0} for c in centres
            ],
        }
    )


def obstacle_field_scenario(n: int, n_obstacles: int, steps: int, seed: int = 0) -> cs.Scenario:
    """The swarm of :func:`swarm_scenario` flying through a field of ``n_obstacles`` discs
    (radius 2 m) spread uniformly over a square of side 4 r* around the target, none
    within 12 m of the start region or of F*'s ring of slots: the obstacles near a UAV are
    a few whatever their number."""
    base = swarm_scenario(n, steps)
    radius = 2.0 * n / (2.0 * math.pi)
    side = 2.0 * math.sqrt(n)
    rng = np.random.default_rng(seed)
    half = 2.0 * radius
    centres = []
    while len(centres) < n_obstacles:
        x, y = rng.uniform(-half, half, 2)
        if abs(math.hypot(x, y) - radius) < 12.0:
            continue  # off the ring of slots
        if abs(x) < side / 2 + 12.0 and abs(y) < side / 2 + 12.0:
            continue  # off the start region
        centres.append((float(x), float(y)))
    data = base.model_dump()
    data["obstacles"] = [{"type": "circle", "center": list(c), "radius": 2.0} for c in centres]
    return cs.Scenario.from_dict(data)


def plain_loop_step(q, v, delta, nbrs, leader, v_ref, eps, gamma, dt, circles, l_safe, e_r, cap):
    """One step of the control laws, one UAV at a time, in plain Python (for comparison)."""
    n = len(q)
    q_new, v_new = [None] * n, [None] * n
    for m in range(n):
        ux = uy = 0.0
        for p in nbrs[m]:
            ux -= eps * (q[m][0] - q[p][0] - (delta[m][0] - delta[p][0]))
            uy -= eps * (q[m][1] - q[p][1] - (delta[m][1] - delta[p][1]))
        rx = ry = 0.0
        for cx, cy, r in circles:
            dx, dy = q[m][0] - cx, q[m][1] - cy
            rho = math.hypot(dx, dy)
            ell = rho - r
            if 0.0 < ell < l_safe:
                mag = e_r * (1.0 / ell - 1.0 / l_safe) / ell**2
                rx += mag * dx / rho
                ry += mag * dy / rho
        norm = math.hypot(rx, ry)
        if norm > cap:
            rx, ry = rx * cap / norm, ry * cap / norm
        q_new[m] = (q[m][0] + ux + rx + v[m][0] * dt, q[m][1] + uy + ry + v[m][1] * dt)
        if m == leader:
            v_new[m] = v_ref
        else:
            sx = sum(v[m][0] - (v_ref[0] if p == leader else v[p][0]) for p in nbrs[m])
            sy = sum(v[m][1] - (v_ref[1] if p == leader else v[p][1]) for p in nbrs[m])
            v_new[m] = (v[m][0] - gamma * sx, v[m][1] - gamma * sy)
    return q_new, v_new


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 3000, 10000, 30000, 100000])
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--plot", default=None, help="write a log-log plot to this PNG file")
    args = parser.parse_args()

    rows = []
    for n in args.sizes:
        sc = swarm_scenario(n, args.steps)
        cs.simulate(sc, seed=0, keep_trajectories=False)  # warm-up (and compilation)
        best = math.inf
        for seed in (1, 2):
            t0 = time.perf_counter()
            cs.simulate(sc, seed=seed, keep_trajectories=False)
            best = min(best, time.perf_counter() - t0)
        rows.append((n, best / args.steps))

    n0 = args.sizes[0]
    sc = swarm_scenario(n0, 1)
    rng = np.random.default_rng(0)
    q = [tuple(p) for p in rng.uniform(-20, 20, (n0, 2))]
    v = [(0.0, 0.0)] * n0
    delta = [tuple(p) for p in sc.slots]
    adj = sc.adjacency
    nbrs = [adj.indices[adj.indptr[m] : adj.indptr[m + 1]].tolist() for m in range(n0)]
    circles = sc.obstacle_set.circles.tolist()
    t0 = time.perf_counter()
    plain_loop_step(q, v, delta, nbrs, 0, (1.0, 0.0), 0.01, 0.25, 0.1, circles, 5.0, 2.0, 1.0)
    t_plain = time.perf_counter() - t0

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, NumPy {np.__version__}")  # fmt: skip
    print()
    print("| UAVs M | time per step (ms) | steps per second | per UAV-step (ns) |")
    print("|---:|---:|---:|---:|")
    for n, t in rows:
        print(f"| {n} | {1e3 * t:.3f} | {1 / t:.0f} | {1e9 * t / n:.0f} |")
    print(f"| {n0}, plain per-UAV Python loop (control laws only) | {1e3 * t_plain:.1f} | "
          f"{1 / t_plain:.0f} | {1e9 * t_plain / n0:.0f} |")  # fmt: skip
    sizes = np.array([n for n, _ in rows], dtype=float)
    times = np.array([t for _, t in rows])
    slope = np.polyfit(np.log(sizes), np.log(times), 1)[0]
    print()
    print(f"log-log slope of time per step against M: {slope:.2f} (1 = linear)")
    if args.plot:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(5.5, 4.0), layout="constrained")
        ax = fig.add_subplot()
        ax.loglog(sizes, 1e3 * times, "o-", label="crlbswarm.simulate")
        ax.loglog(sizes, 1e3 * times[0] * sizes / sizes[0], "k--", lw=1, label="linear in M")
        ax.set_xlabel("number of UAVs M")
        ax.set_ylabel("time per step (ms)")
        ax.set_title("Large swarms: ring graph, 40 obstacles, all metrics")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.savefig(args.plot, dpi=150)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
