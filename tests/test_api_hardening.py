"""Every bad input a one-line error (issue 10): a seeded fuzzer over the public API.

Each public function (except the file, scenario, simulation and campaign layers, tested
elsewhere) is called with one argument (sometimes two) replaced by a value from the classes
below: huge and tiny finite numbers, NaN and infinities, complex numbers, booleans, 0-d
arrays, arrays where a number is expected, wrong shapes, empty arrays, absurd sizes, wrong
types. The contract: either a :class:`crlbswarm.FieldError` (a ValueError) whose ``field``
names one of the function's parameters (or a dotted sub-field of one), in one line, or a
result whose every float is finite, and never a warning (pytest turns warnings into errors;
the calls also run under ``warnings.simplefilter("error")``). The documented exceptions:
the CRLB figures of a singular geometry are +inf, as are the clearance with no obstacle and
the separation of a single UAV.

``CRLBSWARM_FUZZ_CASES`` sets the number of mutated calls per function (default 40; the
whole file then runs in well under 30 s).
"""

# ruff: noqa: E501, PT017, PT018, RUF005 (a table of calls; checks inside the harness)
from __future__ import annotations

import dataclasses
import math
import os
import re
import warnings
from collections.abc import Callable
from typing import Any

import networkx as nx
import numpy as np
import pytest

import crlbswarm as cs
from crlbswarm import FieldError
from crlbswarm._validation import MAX_UAVS

CASES = int(os.environ.get("CRLBSWARM_FUZZ_CASES", "40"))

# -- the scene every call starts from ------------------------------------------------------
TARGET = np.array([80.0, 90.0])
F6 = cs.optimal_formation(6, TARGET, 20.0)
DELTA = F6 - F6.mean(axis=0)
RANGES = cs.slant_ranges(F6, TARGET, 20.0)
ADJ = cs.Adjacency.from_graph(cs.communication_graph("ring", 6))
WALLS = cs.Obstacles(rectangles=[[30.0, 45.0, 0.0, 34.0], [30.0, 45.0, 54.0, 80.0]])
RULE = cs.EtaRule()
GAINS = cs.ControlGains(epsilon=0.2, gamma=0.2)
FIM = cs.fisher_information(F6, TARGET, 20.0)
F_CV, Q_CV, _ = cs.motion_matrices("constant_velocity", 0.1, 0.0, 0.5)
TARGET3 = np.array([80.0, 90.0, 2.0])
F3D = np.column_stack([F6, [20.0, 22.0, 25.0, 21.0, 30.0, 24.0]])
RANGES3 = np.linalg.norm(F3D - TARGET3, axis=-1)


class Rng:
    """A fresh seeded Generator at every call (the mutated calls are independent)."""


def _fresh(value: Any) -> Any:
    if value is Rng:
        return np.random.default_rng(0)
    if isinstance(value, list) and value and value[0] is Rng:
        return [np.random.default_rng(i) for i in range(len(value))]
    return value


# (name, callable, base keyword arguments, extra accepted field roots, +inf allowed)
SPECS: list[tuple[str, Callable[..., Any], dict[str, Any], set[str], bool]] = [
    ("slant_ranges", cs.slant_ranges, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0), set(), False),
    ("elevation_angles", cs.elevation_angles, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0), set(), False),
    ("azimuth_angles", cs.azimuth_angles, dict(uav_xy=F6, target_xy=TARGET), set(), False),
    ("regular_polygon", cs.regular_polygon, dict(n_uavs=6, center_xy=TARGET, radius=14.0, rotation=0.3), set(), False),
    ("range_information", cs.range_information, dict(distance=RANGES, radar=cs.Radar()), set(), False),
    ("fisher_information", cs.fisher_information, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0, radar=cs.Radar()), set(), False),
    ("crlb", cs.crlb, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0, radar=cs.Radar()), set(), True),
    ("d_optimality", cs.d_optimality, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0, radar=cs.Radar()), set(), True),
    ("e_optimality", cs.e_optimality, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0, radar=cs.Radar()), set(), True),
    ("crlb_from_fim", cs.crlb_from_fim, dict(fim=FIM), set(), True),
    ("d_optimality_from_fim", cs.d_optimality_from_fim, dict(fim=FIM), set(), True),
    ("e_optimality_from_fim", cs.e_optimality_from_fim, dict(fim=FIM), set(), True),
    ("information_weight", cs.information_weight, dict(elevation=0.9, altitude=20.0, radar=cs.Radar()), set(), False),
    ("optimal_elevation", cs.optimal_elevation, dict(altitude=20.0, radar=cs.Radar()), set(), False),
    ("optimal_radius", cs.optimal_radius, dict(altitude=20.0, radar=cs.Radar()), set(), False),
    ("crlb_bound", cs.crlb_bound, dict(n_uavs=6, altitude=20.0, radar=cs.Radar()), set(), False),
    ("optimal_formation", cs.optimal_formation, dict(n_uavs=6, target_xy=TARGET, altitude=20.0, radar=cs.Radar(), rotation=0.0), set(), False),
    ("design_report", cs.design_report, dict(n_uavs=6, altitude=20.0, target_xy=TARGET, radar=cs.Radar(), rotation_deg=10.0), set(), False),
    ("fixed_radius_polygon", cs.fixed_radius_polygon, dict(n_uavs=6, target_xy=TARGET, radius=5.0, rotation=0.0), set(), False),
    ("arc_formation", cs.arc_formation, dict(n_uavs=6, target_xy=TARGET, radius=14.0, span=1.5, heading=0.0), set(), False),
    ("line_formation", cs.line_formation, dict(n_uavs=6, target_xy=TARGET, offset=14.0, length=28.0, heading=0.0), set(), False),
    ("random_disc_formations", cs.random_disc_formations, dict(n_uavs=6, target_xy=TARGET, radius=28.0, n_draws=4, rng=Rng), set(), False),
    ("measure_ranges", cs.measure_ranges, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0, radar=cs.Radar(), rng=Rng), set(), False),
    ("negative_log_likelihood", cs.negative_log_likelihood, dict(target_xy=TARGET, uav_xy=F6, measured_ranges=RANGES, altitude=20.0, radar=cs.Radar()), set(), False),
    ("linearised_estimate", cs.linearised_estimate, dict(uav_xy=F6, measured_ranges=RANGES, altitude=20.0), set(), False),
    ("estimate_target", cs.estimate_target, dict(uav_xy=F6, measured_ranges=RANGES, altitude=20.0, radar=cs.Radar(), init=TARGET + 1.0, max_iter=30, tol=1e-10), set(), False),
    ("ControlGains", cs.ControlGains, dict(epsilon=0.2, gamma=0.2, guidance_gain=0.5, cruise_speed=2.0, safety_radius=5.0, repulsion_gain=2.0, repulsion_max_step=1.0), set(), False),
    ("EtaRule", cs.EtaRule, dict(minimum=0.3, rate=0.1, lookahead=40.0, margin=5.0, samples=32), set(), False),
    ("consensus_step", cs.consensus_step, dict(velocities=np.ones((6, 2)), v_ref=[1.0, 0.5], adjacency=ADJ, leader=0, gains=GAINS), set(), False),
    ("formation_input", cs.formation_input, dict(positions=F6, delta=DELTA, eta=0.8, adjacency=ADJ, gains=GAINS), set(), False),
    ("leader_guidance", cs.leader_guidance, dict(leader_xy=[0.0, 0.0], goal_xy=TARGET, gains=GAINS, center_xy=[1.0, 1.0], goal_velocity=[0.1, 0.0], footprint=3.0, obstacles=WALLS, dt=0.1), set(), False),
    ("repulsion", cs.repulsion, dict(positions=[[29.0, 10.0], [50.0, 60.0]], obstacles=WALLS, gains=GAINS), set(), False),
    ("eta_target", cs.eta_target, dict(center_xy=[0.0, 40.0], target_xy=TARGET, obstacles=WALLS, radius=14.0, rule=RULE, gains=GAINS), set(), False),
    ("eta_update", cs.eta_update, dict(eta=0.7, goal=0.4, rule=RULE, dt=0.1), set(), False),
    ("formation_cost", cs.formation_cost, dict(positions=F6, next_positions=F6 + 0.1, delta=DELTA, v_ref=[1.0, 0.0], adjacency=ADJ, dt=0.1), set(), False),
    ("communication_graph", cs.communication_graph, dict(kind="random_geometric", n_uavs=6, radius=0.9, seed=1), {"graph"}, False),
    ("Adjacency", cs.Adjacency, dict(indptr=ADJ.indptr, indices=ADJ.indices), set(), False),
    ("formation_step_limit", cs.formation_step_limit, dict(adjacency=ADJ), set(), False),
    ("consensus_step_limit", cs.consensus_step_limit, dict(adjacency=ADJ, leader=0), set(), False),
    ("Obstacles", cs.Obstacles, dict(rectangles=[[30.0, 45.0, 0.0, 34.0]], circles=[[0.0, 0.0, 3.0]]), set(), False),
    ("obstacle_clearance", cs.obstacle_clearance, dict(positions=[[0.0, 0.0], [40.0, 40.0]], obstacles=WALLS), set(), True),
    ("assign_slots", cs.assign_slots, dict(start_xy=F6[::-1], slots_xy=F6, leader=0), set(), False),
    ("plan_route", cs.plan_route, dict(start_xy=[0.0, 0.0], goal_xy=TARGET, obstacles=WALLS, inflation=3.0), {"guidance"}, False),
    ("safety_filter", cs.safety_filter, dict(positions=F6, displacements=np.full((6, 2), 0.1), obstacles=WALLS, min_separation=1.0, max_speed=5.0, dt=0.1, sensing_radius=30.0, decay=0.5, sigma=0.01), set(), False),
    ("smallest_separation", cs.smallest_separation, dict(positions=F6), set(), True),
    ("Radar", cs.Radar, dict(tx_power=0.1, noise_power=1e-12, processing_gain=1000.0, carrier_frequency=5.8e9, kappa=1.0), {"radar"}, False),
    ("Radar.from_db", cs.Radar.from_db, dict(tx_power_dbm=20.0, noise_power_dbm=-90.0, rcs_dbsm=0.0), {"radar"}, False),
    ("db_to_linear", cs.db_to_linear, dict(value_db=3.0), set(), False),
    ("dbm_to_watts", cs.dbm_to_watts, dict(value_dbm=20.0), set(), False),
    ("motion_matrices", cs.motion_matrices, dict(model="turning", dt=0.1, turn_rate=0.05, acceleration_noise=0.5), set(), False),
    ("target_trajectories", cs.target_trajectories, dict(start_xy=TARGET, velocity=[1.0, 0.0], model="constant_velocity", dt=0.1, n_steps=20, rngs=[Rng, Rng], turn_rate=0.0, acceleration_noise=0.2), set(), False),
    ("summed_range_information", cs.summed_range_information, dict(uav_xy=np.broadcast_to(F6, (2, 3, 6, 2)), target_xy=np.broadcast_to(TARGET, (2, 3, 2)), altitude=20.0, radar=cs.Radar()), set(), False),
    ("posterior_crlb", cs.posterior_crlb, dict(mean_fim=np.broadcast_to(FIM, (5, 2, 2)), f=F_CV, q=Q_CV, p0=np.eye(4) * 4.0, n_state=4, measure_every=1), set(), False),
    ("crlb_vs_altitude", cs.crlb_vs_altitude, dict(altitudes=[10.0, 50.0], n_uavs=4, radar=cs.Radar(), fixed_radius=5.0, arc_span=1.5, disc_factor=2.0, n_random=3, seed=0), set(), False),
    ("optimal_elevation_curve", cs.optimal_elevation_curve, dict(altitudes=[1.0, 10.0, 100.0], radar=cs.Radar()), set(), False),
    ("monte_carlo_mse", cs.monte_carlo_mse, dict(uav_xy=F6, target_xy=TARGET, altitude=20.0, radar=cs.Radar(), n_trials=8, rng=Rng, prior_std=1.0), set(), True),
    ("optimal_weights", cs.optimal_weights, dict(n_uavs=4, altitude=20.0, radar=cs.Radar(tx_power=[0.1, 0.2, 0.1, 0.3])), set(), False),
    ("attainable_crlb", cs.attainable_crlb, dict(weights=[1.0, 2.0, 0.5]), set(), False),
    ("isotropic_azimuths", cs.isotropic_azimuths, dict(weights=[1.0, 2.0, 0.5, 0.7], rotation=0.2), set(), False),
    ("Radar.take", cs.Radar(tx_power=[0.1, 0.2, 0.3]).take, dict(indices=[0, 2]), set(), False),
    ("allocate_targets", cs.allocate_targets, dict(targets_xy=[[0.0, 0.0], [200.0, 0.0]], n_uavs=6, altitude=20.0, radar=cs.Radar(), objective="sum", method="auto"), set(), False),
    ("constrained_design", cs.constrained_design, dict(n_uavs=4, target_xy=TARGET, altitude=20.0, radar=cs.Radar(), criterion="A", max_radius=12.0, min_separation=1.0, starts=2, seed=0), set(), False),
    ("fisher_information_3d", cs.fisher_information_3d, dict(uav_xyz=F3D, target_xyz=TARGET3, radar=cs.Radar(), target_height="unknown"), set(), False),
    ("crlb_3d", cs.crlb_3d, dict(uav_xyz=F3D, target_xyz=TARGET3, radar=cs.Radar(), target_height="known"), set(), True),
    ("optimal_elevation_3d", cs.optimal_elevation_3d, dict(altitude=20.0, radar=cs.Radar()), set(), False),
    ("design_3d", cs.design_3d, dict(altitudes=[20.0, 20.5, 21.0, 20.0, 22.0], target_xyz=TARGET3, radar=cs.Radar(), target_height="unknown", rotation=0.1, starts=2, seed=0), set(), False),
    ("optimal_formation_3d", cs.optimal_formation_3d, dict(altitudes=[20.0] * 6, target_xyz=TARGET3, radar=cs.Radar(), target_height="known", rotation=0.1, starts=2, seed=0), set(), False),
    ("measure_ranges_3d", cs.measure_ranges_3d, dict(uav_xyz=F3D, target_xyz=TARGET3, radar=cs.Radar(), rng=Rng), set(), False),
    ("estimate_target_3d", cs.estimate_target_3d, dict(uav_xyz=F3D, measured_ranges=RANGES3, radar=cs.Radar(), init=TARGET3 + 1.0, max_iter=30, tol=1e-10), set(), False),
    ("monte_carlo_mse_3d", cs.monte_carlo_mse_3d, dict(uav_xyz=F3D, target_xyz=TARGET3, radar=cs.Radar(), n_trials=8, rng=Rng), set(), True),
    ("constrained_design bands", cs.constrained_design, dict(n_uavs=4, target_xy=TARGET, altitude=20.0, radar=cs.Radar(), criterion="E", max_radius=12.0, altitude_bands=[[10.0, 30.0], [15.0, 15.0], [20.0, 40.0], [5.0, 8.0]], starts=2, seed=0), set(), False),
    ("criterion_value per_uav", cs.criterion_value, dict(positions=F6, target_xy=TARGET, altitude=np.array([10.0, 20.0, 30.0, 15.0, 25.0, 20.0]), radar=cs.Radar(), criterion="D", per_uav=True), set(), True),
    ("optimal_value per_uav", cs.optimal_value, dict(n_uavs=6, altitude=np.array([10.0, 20.0, 30.0, 15.0, 25.0, 20.0]), radar=cs.Radar(), criterion="E", per_uav=True), set(), False),
    ("constrained_report", cs.constrained_report, dict(n_uavs=4, target_xy=TARGET, altitude=20.0, radar=cs.Radar(), max_radius=12.0, altitude_bands=[10.0, 30.0], starts=1, seed=0, rotation_deg=10.0), set(), False),
    ("allocation_report", cs.allocation_report, dict(targets_xy=[[0.0, 0.0], [200.0, 0.0]], n_uavs=6, altitude=20.0, radar=cs.Radar(), objective="max", method="auto"), set(), False),
    ("estimator_vs_altitude", cs.estimator_vs_altitude, dict(altitudes=[20.0], n_uavs=4, radar=cs.Radar(), n_trials=3, seed=0, fixed_radius=5.0, arc_span=1.5, disc_factor=2.0), set(), False),
]  # fmt: skip

# -- the classes of bad values -------------------------------------------------------------
SCALARS: list[Any] = [
    1e308, -1e308, 1e200, -1e300, 5e-324, -5e-324, 1e-300, 0.0, -0.0, -1.0, math.nan, math.inf,
    -math.inf, 1 + 2j, complex(3.0, 0.0), np.complex128(1.0), True, False, np.bool_(True),
    np.array(2.5), np.array([2.5]), np.ones(3), np.array([[1.0]]), np.float32(1e38),
    np.float16(1.0), 10**400, -(10**400), 7, np.int64(3), "1.0", b"1", None, object(), [],
    [1.0, "a"], {"a": 1}, np.datetime64("2024-01-01"),
]  # fmt: skip
COUNTS: list[Any] = [
    0, -1, 1, 2, 10**9, 10**7, MAX_UAVS + 1, 2**70, 3.0, 6.5, True, np.int64(4), np.uint8(5),
    np.array(4), np.array([4]), "6", None, math.nan,
]  # fmt: skip
OBJECTS: list[Any] = [None, 1.0, "ring", np.zeros(3), object(), [1, 2]]


def _array_mutations(base: np.ndarray, rng: np.random.Generator) -> list[Any]:
    a = np.array(base, dtype=float)
    idx = tuple(rng.integers(0, s) for s in a.shape) if a.size else ()
    out: list[Any] = []
    for bad in (math.nan, math.inf, -math.inf, 1e308, -1e300, 1e200, 5e-324, 1e7, -2e6):
        b = a.copy()
        if b.size:
            b[idx] = bad
        out.append(b)
    out += [
        a * 1e300,
        a * 1e-300,
        a.astype(complex),
        a + 1j,
        a.astype(bool),
        a.astype(int),
        a.astype(np.float32),
        np.array(1.0),
        a[..., None],
        a.T,
        a.reshape(-1),
        np.empty((0, *a.shape[1:])),
        np.empty((0,)),
        np.zeros((*a.shape[:-1], 3)),
        np.broadcast_to(a, (3, *a.shape)),
        a.astype(object),
        a.astype(str),
        a.tolist(),
        [[1.0, 2.0], [3.0]],
        np.full(a.shape, -1.0),
        np.zeros(a.shape),
    ]
    return out


def _mutations(value: Any, rng: np.random.Generator) -> list[Any]:
    if isinstance(value, bool):
        return [None, 1, 0.5, "yes", np.bool_(True), np.array([True])]
    if isinstance(value, int | np.integer):
        return COUNTS + SCALARS[:8]
    if isinstance(value, float):
        return SCALARS + [value * 1e300, value * 1e-300, np.full(4, value)]
    if isinstance(value, str):
        return [None, "", "nope", 1.0, b"ring", np.array(["ring"]), value.upper()]
    if value is Rng:
        return OBJECTS + [np.random.RandomState(0), np.random.default_rng]
    if isinstance(value, list) and value and value[0] is Rng:
        return [[], None, Rng, [None], "rngs", [1, 2]]
    if isinstance(value, np.ndarray | list | tuple):
        arr = np.asarray(value)
        if arr.dtype.kind in "iu":  # integer arrays (CSR)
            return [arr[::-1], arr + 10, arr - 3, arr.astype(float), arr[:-1], np.empty(0),
                    arr.astype(bool), np.array(1), arr.reshape(-1, 1), arr * 10**6]  # fmt: skip
        return _array_mutations(arr, rng) + SCALARS[:12]
    return OBJECTS + [cs.Radar(), ADJ, WALLS, RULE, GAINS]


def _param_roots(field: str) -> set[str]:
    return {p for p in re.split(r"[.\[\]]", field) if p and not p.isdigit()}


def _floats(result: Any, out: list[np.ndarray]) -> None:
    """Collect every float of a result (arrays, numbers, containers, dataclasses)."""
    if isinstance(result, np.ndarray):
        if result.dtype.kind in "fc":
            out.append(np.asarray(result, dtype=float))
    elif isinstance(result, float | np.floating):
        out.append(np.asarray(float(result)))
    elif isinstance(result, dict):
        for v in result.values():
            _floats(v, out)
    elif isinstance(result, list | tuple):
        for v in result:
            _floats(v, out)
    elif dataclasses.is_dataclass(result) and not isinstance(result, type):
        if isinstance(result, cs.Radar | cs.Obstacles | cs.Adjacency):
            _floats(result.__dict__, out)
        else:
            for f in dataclasses.fields(result):
                _floats(getattr(result, f.name), out)
    elif isinstance(result, cs.ControlGains | cs.EtaRule):
        _floats(result.model_dump(), out)
    elif isinstance(result, nx.Graph):
        pass


def check_call(name: str, func: Callable[..., Any], kwargs: dict[str, Any], extra: set[str],
               inf_ok: bool, label: str) -> str:  # fmt: skip
    """Call and check the contract; return "error" or "result" (fail the test otherwise)."""
    kwargs = {k: _fresh(v) for k, v in kwargs.items()}
    allowed = set(kwargs) | extra
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            result = func(**kwargs)
    except FieldError as exc:
        assert isinstance(exc, ValueError)
        assert "\n" not in str(exc), f"{name}({label}): message on several lines: {exc!s:.300}"
        assert _param_roots(exc.field) & allowed, (
            f"{name}({label}): the error names {exc.field!r}, not a parameter: {exc}"
        )
        return "error"
    except Exception as exc:
        pytest.fail(f"{name}({label}) raised {type(exc).__name__}: {exc!s:.300}")
    floats: list[np.ndarray] = []
    _floats(result, floats)
    for arr in floats:
        bad = np.isnan(arr) | (np.isinf(arr) & ((arr < 0) | (not inf_ok)))
        assert not np.any(bad), f"{name}({label}) returned NaN or inf: {arr!r:.300}"
    return "result"


def _label(key: str, value: Any) -> str:
    text = " ".join(repr(value).split())
    return f"{key}={text[:60]}"


@pytest.mark.parametrize(
    ("name", "func", "base", "extra", "inf_ok"), SPECS, ids=[s[0] for s in SPECS]
)
def test_fuzz_public_function(name, func, base, extra, inf_ok):
    """Mutated calls: a FieldError naming a parameter, in one line, or finite results."""
    # The base call itself is valid and finite.
    assert check_call(name, func, base, extra, inf_ok, "base") == "result"
    rng = np.random.default_rng(abs(hash(name)) % 2**32 if False else sum(map(ord, name)))
    keys = list(base)
    pools = {k: _mutations(base[k], rng) for k in keys}
    # Every mutation of every argument once, then random (one or two arguments) up to CASES.
    plan = [(k, i) for k in keys for i in range(len(pools[k]))]
    if len(plan) > CASES:
        plan = [plan[i] for i in rng.choice(len(plan), CASES, replace=False)]
    for key, i in plan:
        kwargs = dict(base)
        kwargs[key] = pools[key][i]
        label = _label(key, pools[key][i])
        if len(keys) > 1 and rng.random() < 0.25:
            other = keys[int(rng.integers(len(keys)))]
            if other != key:
                j = int(rng.integers(len(pools[other])))
                kwargs[other] = pools[other][j]
                label += ", " + _label(other, pools[other][j])
        check_call(name, func, kwargs, extra, inf_ok, label)


# -- the examples of the fuzzing report ----------------------------------------------------
def _error(call: Callable[[], Any], field: str) -> FieldError:
    with pytest.raises(FieldError) as info:
        call()
    assert info.value.field == field, str(info.value)
    assert "\n" not in str(info.value)
    return info.value


def test_crlb_at_an_absurd_altitude_is_refused_with_the_range():
    err = _error(lambda: cs.crlb(F6, TARGET, 1e308), "altitude")
    assert str(err) == (
        "altitude: must be between 0.1 and 100000 m (the model's range), got 1e+308"
    )


@pytest.mark.parametrize("altitude", [0.1, 1e5])
@pytest.mark.parametrize("where", [0.0, 1e7, -1e7])
def test_crlb_at_the_corners_of_the_ranges_is_finite(altitude, where):
    """An extreme but valid scene never overflows: the optimal formation (clipped into the
    coordinate range) at the lowest and highest altitude, near the edge of the coordinates."""
    target = np.array([where, -where]) * 0.9
    f = cs.optimal_formation(6, target, altitude)
    for figure in (cs.crlb, cs.d_optimality, cs.e_optimality):
        value = figure(f, target, altitude)
        assert np.isfinite(value) and value > 0


@pytest.mark.parametrize("a_std", [1.001e-15, 0.999e15])
@pytest.mark.parametrize("altitude", [0.1, 1e5])
@pytest.mark.parametrize("n_uavs", [3, 2000])
def test_extreme_radars_keep_every_figure_finite_and_non_zero(a_std, altitude, n_uavs):
    """The radar's range of A (a range standard deviation at 1 m from 1e-15 m to 1e15 m)
    checked at the corners: slant ranges from MIN_ALTITUDE to MAX_DISTANCE."""
    radar = cs.Radar(noise_power=1e-12 * (a_std / cs.Radar().snr_constant ** -0.5) ** 2)
    assert radar.snr_constant == pytest.approx(a_std**-2, rel=1e-9)
    for target, spread in (((0.0, 0.0), 1e-6), ((0.0, 0.0), 2.0), ((-9.9e6, -9.9e6), 1.9e7)):
        uavs = cs.regular_polygon(n_uavs, target, spread)
        uavs = np.clip(uavs, -1e7, 1e7)
        for figure in (cs.crlb, cs.d_optimality, cs.e_optimality):
            value = figure(uavs, target, altitude, radar)
            assert np.isfinite(value) and value > 0, (figure.__name__, target, spread)
        w = cs.information_weight(cs.optimal_elevation(altitude, radar), altitude, radar)
        assert np.isfinite(w) and w > 0
        assert np.isfinite(cs.crlb_bound(n_uavs, altitude, radar))
        variance = radar.range_variance(np.array([0.1, 3e7]))
        assert np.all(np.isfinite(variance) & (variance > 0))


@pytest.mark.parametrize("a_std", [0.99e-15, 1.01e15])
def test_radar_beyond_the_range_of_a_is_refused(a_std):
    noise = 1e-12 * (a_std / cs.Radar().snr_constant ** -0.5) ** 2
    err = _error(lambda: cs.Radar(noise_power=noise), "radar")
    assert "1e-15 and 1e+15 m" in err.reason


def test_measure_ranges_extremes():
    rng = np.random.default_rng(0)
    _error(lambda: cs.measure_ranges(F6 * 1e300, TARGET, 20.0, rng=rng), "uav_xy")
    _error(lambda: cs.measure_ranges(F6, TARGET, 1e308, rng=rng), "altitude")
    _error(lambda: cs.measure_ranges(F6, TARGET, 5e-324, rng=rng), "altitude")
    weak = cs.Radar(noise_power=1e-12 * (0.999e15 / cs.Radar().snr_constant ** -0.5) ** 2)
    far = np.clip(cs.regular_polygon(6, (0.0, 0.0), 1.4e7), -1e7, 1e7)
    d = cs.measure_ranges(far, (-1e7, 1e7), 1e5, weak, rng=rng)
    assert np.all(np.isfinite(d))


def test_leader_guidance_with_an_enormous_gain_saturates_or_is_refused():
    """A gain of 1e300 is a valid (absurd) gain: the speed saturates at the cruise speed in
    the goal's direction; a gain that overflows the velocity is refused naming gains."""
    huge = cs.ControlGains(guidance_gain=1e300, cruise_speed=2.0)
    v = cs.leader_guidance([0.0, 0.0], [3.0, 4.0], huge)
    np.testing.assert_allclose(v, [1.2, 1.6], rtol=1e-12)
    worse = cs.ControlGains(guidance_gain=1e308)
    _error(lambda: cs.leader_guidance([-1e7, -1e7], [1e7, 1e7], worse), "gains")


def test_target_trajectories_with_an_enormous_dt_is_refused():
    rngs = [np.random.default_rng(0)]
    err = _error(
        lambda: cs.target_trajectories(TARGET, [1.0, 0.0], "constant_velocity", 1e300, 5, rngs),
        "dt",
    )
    assert "model's range" in err.reason


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 1e4, -1e4])
def test_db_to_linear_refuses_non_finite_and_overflowing_values(value):
    _error(lambda: cs.db_to_linear(value), "value_db")
    _error(lambda: cs.dbm_to_watts(value), "value_dbm")


def test_db_to_linear_keeps_its_values():
    assert cs.db_to_linear(30.0) == pytest.approx(1000.0)
    assert cs.dbm_to_watts(20.0) == pytest.approx(0.1)
    np.testing.assert_allclose(cs.db_to_linear([0.0, 10.0]), [1.0, 10.0])


@pytest.mark.parametrize(
    "bad", [F6.astype(complex), F6 + 0j, F6.astype(bool), np.array(1.0), F6.astype(object)]
)
def test_complex_bool_and_0d_positions_are_refused(bad):
    if bad.dtype == object:  # an object array of floats is numbers: accepted
        assert np.isfinite(cs.crlb(bad, TARGET, 20.0))
        return
    err = _error(lambda: cs.crlb(bad, TARGET, 20.0), "uav_xy")
    if bad.dtype.kind == "c":
        assert "real numbers" in err.reason


@pytest.mark.parametrize("altitude", [np.array([20.0]), np.ones(3)])
def test_array_where_a_number_is_expected(altitude):
    _error(lambda: cs.design_report(6, altitude), "altitude")
    _error(lambda: cs.eta_update(0.5, 0.5, RULE, altitude), "dt")


def test_regular_polygon_of_a_billion_vertices_is_refused_before_allocating():
    err = _error(lambda: cs.regular_polygon(10**9, TARGET, 10.0), "n_uavs")
    assert f"at most {MAX_UAVS}" in err.reason
    err = _error(lambda: cs.regular_polygon(MAX_UAVS, np.zeros((10**6, 2)), 10.0), "n_uavs")
    assert "need about" in err.reason and "can still allocate" in err.reason
    err = _error(
        lambda: cs.random_disc_formations(6, TARGET, 10.0, 10**9, np.random.default_rng(0)),
        "n_draws",
    )
    assert "need about" in err.reason


def test_uav_counts_accept_numpy_integers_and_refuse_the_rest():
    assert cs.optimal_formation(np.int64(4), TARGET, 20.0).shape == (4, 2)
    assert cs.optimal_formation(np.array(4), TARGET, 20.0).shape == (4, 2)
    for bad in (4.0, True, np.bool_(True), "4", 10**7):
        _error(lambda bad=bad: cs.optimal_formation(bad, TARGET, 20.0), "n_uavs")
