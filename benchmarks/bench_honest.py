"""Honest benchmarks (issue 12): crlbswarm against baselines, peers and the machine floor.

Run: ``python benchmarks/bench_honest.py [--batch 1000] [--plain-runs 20] [--quick]``.
One run measures, side by side on the same machine state, and prints a Markdown table of
ratios (times are best of a few repeats after a warm-up; only the ratios within one run
mean anything, as the absolute times follow the machine's load):

1. the paper mission (built-in ``paper`` scenario) against (a) a plain Python
   transcription of the paper's laws and (b) a NumPy implementation vectorised over runs
   and UAVs (``honest_baselines.py``; both are first checked against crlbswarm on the same
   seeds: same draws, so the trajectories must agree to 1e-6 m, and every run must end over
   F* with its CRLB within 1 % of the bound). The plain batch is timed on ``--plain-runs``
   runs and scaled linearly to ``--batch``;
2. the peers (``peers.py``): ewgeo, scipy, filterpy, Stone Soup, each "not installed" if
   it is not importable;
3. the machine floor (``machine_floor.py``): measured SIMD flop rate and memory
   bandwidth, the work of one UAV-step counted from the laws, and crlbswarm's time per
   UAV-step over that floor, for the paper mission and for the large-swarm step of
   ``bench_scaling.py``;
4. one large mission on all threads against one thread (blocks of UAVs), 1000 UAVs among
   1000 obstacles against 10 (the obstacle grid), and the peak memory of one 10^5-UAV
   mission without trajectories for 150 and 1500 steps (``bench_memory.py``, each in a
   fresh process; ``--memory-uavs 0`` skips it).

No assertion on time anywhere: a failed agreement check is reported, not raised.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import time

import numba
import numpy as np

import bench_memory
import crlbswarm as cs
import honest_baselines as hb
import machine_floor as mf
import peers
from bench_scaling import obstacle_field_scenario, swarm_scenario
from timing import best_of

try:
    from importlib.metadata import PackageNotFoundError, version
except ImportError:  # pragma: no cover
    version = None


def once(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _version(name: str) -> str:
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


def agreement(sc, mi, n_runs: int, n_plain: int) -> list[str]:
    """Same seeds through crlbswarm, (a) and (b): the largest differences, and whether every
    run ends over F* with its CRLB within 1 % of the bound."""
    ref = cs.simulate(sc, seeds=range(n_runs))
    vec = hb.numpy_missions(mi, range(n_runs), keep_trajectories=True)
    plain = [hb.plain_mission(mi, *hb.draw(mi, s)) for s in range(n_plain)]
    slots = np.asarray(sc.slots)
    bound = float(ref.bound)
    lines = []
    d_pos_b = float(np.abs(vec["positions"] - ref.positions).max())
    d_pos_a = max(
        float(np.abs(p["final"] - ref.positions[i, -1]).max()) for i, p in enumerate(plain)
    )
    d_crlb_a = max(float(np.abs(p["crlb"] / ref.crlb[i] - 1).max()) for i, p in enumerate(plain))
    d_crlb_b = float(np.abs(vec["crlb"] / ref.crlb - 1).max())
    ok = d_pos_a < 1e-6 and d_pos_b < 1e-6
    lines.append(
        f"same seeds, same draws: (a) vs crlbswarm final positions differ by at most "
        f"{d_pos_a:.1e} m, CRLB by {d_crlb_a:.1e} (relative), over {n_plain} runs; (b) vs "
        f"crlbswarm whole trajectories by {d_pos_b:.1e} m, CRLB by {d_crlb_b:.1e}, over "
        f"{n_runs} runs: {'agree to 1e-6 m' if ok else 'DO NOT AGREE to 1e-6 m'}"
    )
    for name, finals, crlb_end in (
        ("crlbswarm", ref.positions[:, -1], ref.crlb[:, -1]),
        (
            "(a) plain",
            np.array([p["final"] for p in plain]),
            np.array([p["crlb"][-1] for p in plain]),
        ),
        ("(b) NumPy", vec["final"], vec["crlb"][:, -1]),
    ):
        off = float(np.hypot(*(finals - slots).transpose(2, 0, 1)).max())
        ratio = crlb_end / bound
        lines.append(
            f"{name}: every run ends within {off:.3f} m of its slot of F*; final CRLB / bound "
            f"{ratio.min():.4f} to {ratio.max():.4f} "
            f"({'within 1 %' if np.all(np.abs(ratio - 1) < 0.01) else 'NOT within 1 %'})"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=1000, help="missions per batch")
    parser.add_argument("--plain-runs", type=int, default=20, help="plain runs timed")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--swarm", type=int, default=10_000, help="UAVs of the large swarm")
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke test)")
    parser.add_argument(
        "--memory-uavs", type=int, default=100_000,
        help="UAVs of the peak-memory missions (150 and 1500 steps; 0: skip)",
    )  # fmt: skip
    args = parser.parse_args()
    if args.quick:
        args.batch, args.plain_runs, args.repeat, args.swarm = 50, 2, 1, 1000
        args.memory_uavs = 0
    rows: list[tuple[str, str, str, str]] = []
    notes: list[str] = []

    sc = cs.load_scenario("paper")
    mi = hb.Mission.from_scenario(sc)
    t0 = time.perf_counter()
    cs.simulate(sc, seed=0)  # loads or compiles the kernels
    notes.append(
        f"first crlbswarm call (loads or compiles the kernels): {time.perf_counter() - t0:.2f} s"
    )

    # -- 0. agreement ---------------------------------------------------------------------
    notes += agreement(sc, mi, n_runs=min(16, args.batch), n_plain=min(4, args.plain_runs))

    # -- 1. the paper mission ------------------------------------------------------------
    n = args.batch
    steps, m_uavs = mi.steps, mi.m
    t_cs1 = best_of(lambda: cs.simulate(sc, seed=0, keep_trajectories=False), 3 * args.repeat)
    t_a1 = best_of(lambda: hb.plain_missions(mi, [0]), args.repeat)
    t_b1 = best_of(lambda: hb.numpy_missions(mi, [0]), args.repeat)
    t_cs = best_of(lambda: cs.simulate(sc, seeds=range(n), keep_trajectories=False), args.repeat)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        t_cs_1t = best_of(lambda: cs.simulate(sc, seeds=range(n), keep_trajectories=False), 1)
    finally:
        numba.set_num_threads(threads)
    t_a = once(lambda: hb.plain_missions(mi, range(args.plain_runs))) * n / args.plain_runs
    t_b = once(lambda: hb.numpy_missions(mi, range(n)))
    paper = "paper mission (6 UAVs, 1500 steps, CRLB every step)"
    rows += [
        (
            f"one {paper} vs (a) plain Python",
            f"{t_cs1 * 1e3:.2f} ms",
            f"{t_a1 * 1e3:.0f} ms",
            f"{t_a1 / t_cs1:.0f}x",
        ),
        (
            f"one {paper} vs (b) NumPy",
            f"{t_cs1 * 1e3:.2f} ms",
            f"{t_b1 * 1e3:.0f} ms",
            f"{t_b1 / t_cs1:.0f}x",
        ),
        (
            f"{n} paper missions, one batch, vs (a) plain Python "
            f"(timed on {args.plain_runs}, scaled)",
            f"{t_cs:.2f} s",
            f"{t_a:.1f} s",
            f"{t_a / t_cs:.0f}x",
        ),
        (
            f"{n} paper missions, one batch, vs (b) NumPy over runs and UAVs",
            f"{t_cs:.2f} s",
            f"{t_b:.1f} s",
            f"{t_b / t_cs:.1f}x",
        ),
        (
            "the same batch, crlbswarm on 1 thread, vs (b) NumPy (1 core)",
            f"{t_cs_1t:.2f} s",
            f"{t_b:.1f} s",
            f"{t_b / t_cs_1t:.1f}x",
        ),
    ]

    # -- 2. peers ------------------------------------------------------------------------
    t_crlb = peers.crlb_batch_time(repeat=args.repeat)
    try:
        peers.crlb_vs_ewgeo()
    except peers.NotInstalled as exc:
        rows.append(
            (
                "CRLB of a formation (M = 6) vs ewgeo `compute_crlb_gaussian`",
                f"{t_crlb * 1e9:.0f} ns",
                f"{exc}",
                "-",
            )
        )
    mle = peers.mle_vs_scipy(
        n_batch=2_000 if args.quick else 20_000,
        n_scipy=20 if args.quick else 300,
        repeat=args.repeat,
    )
    rows += [
        (
            "range-only ML localisation, per trial, vs ewgeo least squares",
            f"{mle['crlbswarm'] * 1e6:.1f} µs",
            "not installed (ewgeo requires Python >= 3.12)",
            "-",
        ),
        (
            "range-only ML localisation, per trial, vs scipy `least_squares` "
            "(LM, analytic Jacobian)",
            f"{mle['crlbswarm'] * 1e6:.1f} µs",
            f"{mle['least_squares'] * 1e6:.0f} µs",
            f"{mle['least_squares'] / mle['crlbswarm']:.0f}x",
        ),
        (
            "range-only ML localisation, per trial, vs scipy BFGS (exact likelihood)",
            f"{mle['crlbswarm'] * 1e6:.1f} µs",
            f"{mle['bfgs'] * 1e6:.0f} µs",
            f"{mle['bfgs'] / mle['crlbswarm']:.0f}x",
        ),
    ]
    notes.append(
        f"ML agreement: scipy BFGS on the exact likelihood matches crlbswarm's MLE to "
        f"{mle['diff_bfgs']:.1e} m; least_squares (weights at the measured ranges, no "
        f"variance term: a slightly different estimator) to {mle['diff_ls']:.1e} m"
    )
    ekf = peers.ekf_vs_peers(n_calls=200 if args.quick else 2000, repeat=args.repeat)
    t_ekf = ekf.get("crlbswarm")
    for key, label in (
        ("filterpy", "filterpy `ExtendedKalmanFilter.update`"),
        ("stonesoup", "Stone Soup `ExtendedKalmanUpdater.update`"),
    ):
        peer = ekf.get(key)
        if t_ekf is None:
            rows.append((f"range-only EKF update vs {label}", "API changed", "-", "-"))
        elif peer is None:
            rows.append(
                (
                    f"range-only EKF update vs {label}",
                    f"{t_ekf * 1e6:.2f} µs",
                    "not installed",
                    "-",
                )
            )
        else:
            rows.append(
                (
                    f"range-only EKF update (6 ranges) vs {label}",
                    f"{t_ekf * 1e6:.2f} µs",
                    f"{peer * 1e6:.0f} µs",
                    f"{peer / t_ekf:.0f}x",
                )
            )
            notes.append(
                f"EKF agreement with {key}: updated state within {ekf[key + '_diff']:.1e} m"
            )

    # -- 3. machine floor ----------------------------------------------------------------
    rates = mf.measure_rates(repeat=args.repeat)
    counts = hb.count_paper_work(mi)
    n_rect, n_circ = len(mi.rects), len(mi.circles)
    work = mf.step_work(
        m_uavs,
        2.0,
        n_rect,
        n_circ,
        counts["evaluations"],
        counts["samples"],
        counts["repulsion_terms"],
        extra_flops=2.0 * (m_uavs - 1),
        segment_tests=counts["segment_tests"],
    )
    floor1 = mf.floor_time(work, rates["flops_1"], rates["bw_1"])
    floor_all = mf.floor_time(work, rates["flops_all"], rates["bw_all"])
    per1 = t_cs1 / (steps * m_uavs)
    per_batch = t_cs / (n * steps * m_uavs)
    rows += [
        (
            "paper mission, one run (1 thread): time per UAV-step vs floor",
            f"{per1 * 1e9:.0f} ns",
            f"{floor1 * 1e9:.1f} ns",
            f"{per1 / floor1:.0f}x",
        ),
        (
            f"paper mission, batch of {n} ({threads} threads): time per UAV-step vs floor",
            f"{per_batch * 1e9:.0f} ns",
            f"{floor_all * 1e9:.1f} ns",
            f"{per_batch / floor_all:.0f}x",
        ),
    ]
    swarm_steps = 10 if args.quick else 50
    big = swarm_scenario(args.swarm, swarm_steps)
    cs.simulate(big, seed=0, keep_trajectories=False)
    numba.set_num_threads(1)
    try:  # (one thread: the serial kernel, against the one-thread floor)
        cs.simulate(big, seed=0, keep_trajectories=False)
        t_big = best_of(lambda: cs.simulate(big, seed=1, keep_trajectories=False), 2)
    finally:
        numba.set_num_threads(threads)
    t_big_all = best_of(lambda: cs.simulate(big, seed=1, keep_trajectories=False), 2)
    per_big = t_big / (swarm_steps * args.swarm)
    big_mi = hb.Mission.from_scenario(big)
    eta_count = hb._Counter()
    start, _ = hb.draw(big_mi, 1)
    hb._eta_goal(*start.mean(axis=0), big_mi, eta_count)  # the eta rule at the start
    n_obs = len(big_mi.rects) + len(big_mi.circles)
    evals = 2.0 * args.swarm * n_obs + n_obs + eta_count.evaluations
    work_big = mf.step_work(
        args.swarm,
        2.0,
        len(big_mi.rects),
        len(big_mi.circles),
        evals,
        eta_count.samples,
        0.0,
        extra_flops=mf.FLOPS_SEPARATION,
        large_graph=True,
    )
    floor_big = mf.floor_time(work_big, rates["flops_1"], rates["bw_1"])
    rows.append(
        (
            f"large-swarm step ({args.swarm} UAVs, ring, {n_obs} circles, 1 thread): "
            "time per UAV-step vs floor",
            f"{per_big * 1e9:.0f} ns",
            f"{floor_big * 1e9:.1f} ns",
            f"{per_big / floor_big:.0f}x",
        )
    )

    rows.append(
        (
            f"one {args.swarm}-UAV mission ({swarm_steps} steps): {threads} threads vs 1 "
            "(blocks of UAVs on all threads)",
            f"{t_big_all:.3f} s",
            f"{t_big:.3f} s",
            f"{t_big / t_big_all:.2f}x",
        )
    )

    # -- 4. obstacles: 10 against 1000 at M = 1000 ------------------------------------------
    field_steps = 10 if args.quick else 50
    per_step = {}
    for n_obs in (10, 1000):
        field = obstacle_field_scenario(1000, n_obs, field_steps)
        cs.simulate(field, seed=0, keep_trajectories=False)
        t_field = best_of(lambda f=field: cs.simulate(f, seed=1, keep_trajectories=False),
                          args.repeat)  # fmt: skip
        per_step[n_obs] = t_field / field_steps
    rows.append(
        (
            "1000 UAVs among 1000 obstacles vs among 10: time per step (obstacle grid)",
            f"{per_step[1000] * 1e3:.2f} ms",
            f"{per_step[10] * 1e3:.2f} ms",
            f"{per_step[1000] / per_step[10]:.2f}x as long",
        )
    )

    # -- 5. memory of one large mission without trajectories --------------------------------
    if args.memory_uavs:
        mem = {n_steps: bench_memory.measure(args.memory_uavs, n_steps) for n_steps in (150, 1500)}
        for n_steps, m in mem.items():
            notes.append(
                f"peak memory, one {args.memory_uavs}-UAV mission of {n_steps} steps without "
                f"trajectories: {m['peak_kib'] / 1024:.0f} MiB (process; "
                f"{(m['peak_kib'] - m['before_kib']) / 1024:.0f} MiB after import and "
                f"scenario), {m['seconds']:.1f} s"
            )
        ratio = mem[1500]["peak_kib"] / mem[150]["peak_kib"]
        notes.append(f"peak memory, 1500 steps / 150 steps: {ratio:.3f}")

    # -- report --------------------------------------------------------------------------
    print(
        f"date: {datetime.date.today().isoformat()}; machine: {platform.machine()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}, NumPy {np.__version__}, "
        f"Numba {numba.__version__} ({threads} threads), crlbswarm {cs.__version__}; "
        f"peers: scipy {_version('scipy')}, filterpy {_version('filterpy')}, "
        f"stonesoup {_version('stonesoup')}, ewgeo {_version('ewgeo')}"
    )
    print()
    print("| comparison | crlbswarm | other | crlbswarm faster by |")
    print("|---|---:|---:|---:|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    print()
    print(
        f"machine probe: {rates['flops_1'] / 1e9:.1f} GFLOP/s on 1 thread, "
        f"{rates['flops_all'] / 1e9:.1f} GFLOP/s on {threads} (FMA chains, L1); triad "
        f"{rates['bw_1'] / 1e9:.1f} GB/s on 1 thread, {rates['bw_all'] / 1e9:.1f} GB/s on "
        f"{threads}"
    )
    share = counts["eta_evaluations"] / counts["evaluations"]
    print(
        f"paper step: {counts['evaluations']:.1f} obstacle-distance evaluations per step "
        f"({share:.0%} from the eta rule's path samples, {counts['samples']:.1f} sample "
        f"points), {counts['repulsion_terms']:.2f} repulsion terms; per UAV-step "
        f"{work['flops']:.0f} flops and {work['bytes']:.0f} bytes"
    )
    print(
        f"large-swarm step: {evals / args.swarm:.1f} obstacle-distance evaluations per "
        f"UAV-step ({eta_count.evaluations} of the eta rule per step); per UAV-step "
        f"{work_big['flops']:.0f} flops and {work_big['bytes']:.0f} bytes"
    )
    for line in notes:
        print(f"- {line}")


if __name__ == "__main__":
    main()
