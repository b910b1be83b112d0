"""crlbswarm: CRLB-optimal UAV formations for cooperative range sensing.

Implements and extends Wu, Jin, Su, Li, Pan, Chan, "Formation Control for CRLB-Optimal
Cooperative Sensing in Low-Altitude Wireless Networks", arXiv:2602.23990 (2026).

Positions are horizontal coordinates in metres, shape ``(..., M, 2)`` (UAVs are rows);
every function accepts any leading batch shape. Angles are radians inside the library.
"""

__version__ = "0.1.0"  # defined first: submodules import it


from .campaign import CampaignSpec, run_campaign
from .control import (
    Obstacles,
    consensus_step,
    eta_target,
    eta_update,
    formation_cost,
    formation_input,
    leader_guidance,
    obstacle_clearance,
    repulsion,
)
from .design import (
    crlb_bound,
    information_weight,
    optimal_elevation,
    optimal_formation,
    optimal_radius,
)
from .estimation import (
    TargetEstimate,
    estimate_target,
    linearised_estimate,
    measure_ranges,
    negative_log_likelihood,
)
from .experiments import (
    FORMATION_LABELS,
    AltitudeSweep,
    ElevationCurve,
    crlb_vs_altitude,
    optimal_elevation_curve,
)
from .fisher import (
    crlb,
    crlb_from_fim,
    d_optimality,
    d_optimality_from_fim,
    e_optimality,
    e_optimality_from_fim,
    fisher_information,
    range_information,
)
from .formations import (
    arc_formation,
    fixed_radius_polygon,
    line_formation,
    random_disc_formations,
)
from .geometry import azimuth_angles, elevation_angles, regular_polygon, slant_ranges
from .graphs import (
    GRAPH_KINDS,
    Adjacency,
    communication_graph,
    consensus_step_limit,
    formation_step_limit,
)
from .montecarlo import (
    EstimatorSweep,
    MonteCarloResult,
    estimator_vs_altitude,
    monte_carlo_mse,
)
from .radar import SPEED_OF_LIGHT, Radar, db_to_linear, dbm_to_watts
from .scenario import BUILTIN_SCENARIOS, Scenario, ScenarioError, load_scenario
from .simulation import MissionResult, SimulationDivergedError, simulate, start_positions
from .tracking import (
    motion_matrices,
    posterior_crlb,
    summed_range_information,
    target_trajectories,
)

__all__ = [
    "BUILTIN_SCENARIOS",
    "FORMATION_LABELS",
    "GRAPH_KINDS",
    "SPEED_OF_LIGHT",
    "Adjacency",
    "AltitudeSweep",
    "CampaignSpec",
    "ElevationCurve",
    "EstimatorSweep",
    "MissionResult",
    "MonteCarloResult",
    "Obstacles",
    "Radar",
    "Scenario",
    "ScenarioError",
    "SimulationDivergedError",
    "TargetEstimate",
    "arc_formation",
    "azimuth_angles",
    "communication_graph",
    "consensus_step",
    "consensus_step_limit",
    "crlb",
    "crlb_bound",
    "crlb_from_fim",
    "crlb_vs_altitude",
    "d_optimality",
    "d_optimality_from_fim",
    "db_to_linear",
    "dbm_to_watts",
    "e_optimality",
    "e_optimality_from_fim",
    "elevation_angles",
    "estimate_target",
    "estimator_vs_altitude",
    "eta_target",
    "eta_update",
    "fisher_information",
    "fixed_radius_polygon",
    "formation_cost",
    "formation_input",
    "formation_step_limit",
    "information_weight",
    "leader_guidance",
    "line_formation",
    "linearised_estimate",
    "load_scenario",
    "measure_ranges",
    "monte_carlo_mse",
    "motion_matrices",
    "negative_log_likelihood",
    "obstacle_clearance",
    "optimal_elevation",
    "optimal_elevation_curve",
    "optimal_formation",
    "optimal_radius",
    "posterior_crlb",
    "random_disc_formations",
    "range_information",
    "regular_polygon",
    "repulsion",
    "run_campaign",
    "simulate",
    "slant_ranges",
    "start_positions",
    "summed_range_information",
    "target_trajectories",
]
