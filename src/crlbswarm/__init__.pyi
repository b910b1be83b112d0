"""crlbswarm's public names, each with the module that defines it.

The package imports them lazily (``lazy_loader.attach_stub`` reads this file), and type
checkers read them from here: this stub is the one list of the package's exports. Each name
is written ``name as name``, the explicit re-export of a stub.
"""

__version__: str

from .campaign import (
    CampaignSpec as CampaignSpec,
)
from .campaign import (
    run_campaign as run_campaign,
)
from .control import (
    ControlGains as ControlGains,
)
from .control import (
    EtaRule as EtaRule,
)
from .control import (
    consensus_step as consensus_step,
)
from .control import (
    eta_target as eta_target,
)
from .control import (
    eta_update as eta_update,
)
from .control import (
    formation_cost as formation_cost,
)
from .control import (
    formation_input as formation_input,
)
from .control import (
    leader_guidance as leader_guidance,
)
from .control import (
    repulsion as repulsion,
)
from .design import (
    crlb_bound as crlb_bound,
)
from .design import (
    design_report as design_report,
)
from .design import (
    information_weight as information_weight,
)
from .design import (
    optimal_elevation as optimal_elevation,
)
from .design import (
    optimal_formation as optimal_formation,
)
from .design import (
    optimal_radius as optimal_radius,
)
from .errors import (
    CampaignError as CampaignError,
)
from .errors import (
    ConfigError as ConfigError,
)
from .errors import (
    FieldError as FieldError,
)
from .errors import (
    ScenarioError as ScenarioError,
)
from .errors import (
    SimulationDivergedError as SimulationDivergedError,
)
from .estimation import (
    TargetEstimate as TargetEstimate,
)
from .estimation import (
    estimate_target as estimate_target,
)
from .estimation import (
    linearised_estimate as linearised_estimate,
)
from .estimation import (
    measure_ranges as measure_ranges,
)
from .estimation import (
    negative_log_likelihood as negative_log_likelihood,
)
from .experiments import (
    FORMATION_LABELS as FORMATION_LABELS,
)
from .experiments import (
    AltitudeSweep as AltitudeSweep,
)
from .experiments import (
    ElevationCurve as ElevationCurve,
)
from .experiments import (
    crlb_vs_altitude as crlb_vs_altitude,
)
from .experiments import (
    optimal_elevation_curve as optimal_elevation_curve,
)
from .fisher import (
    crlb as crlb,
)
from .fisher import (
    crlb_from_fim as crlb_from_fim,
)
from .fisher import (
    d_optimality as d_optimality,
)
from .fisher import (
    d_optimality_from_fim as d_optimality_from_fim,
)
from .fisher import (
    e_optimality as e_optimality,
)
from .fisher import (
    e_optimality_from_fim as e_optimality_from_fim,
)
from .fisher import (
    fisher_information as fisher_information,
)
from .fisher import (
    range_information as range_information,
)
from .formations import (
    arc_formation as arc_formation,
)
from .formations import (
    fixed_radius_polygon as fixed_radius_polygon,
)
from .formations import (
    line_formation as line_formation,
)
from .formations import (
    random_disc_formations as random_disc_formations,
)
from .geometry import (
    azimuth_angles as azimuth_angles,
)
from .geometry import (
    elevation_angles as elevation_angles,
)
from .geometry import (
    regular_polygon as regular_polygon,
)
from .geometry import (
    slant_ranges as slant_ranges,
)
from .graphs import (
    GRAPH_KINDS as GRAPH_KINDS,
)
from .graphs import (
    Adjacency as Adjacency,
)
from .graphs import (
    communication_graph as communication_graph,
)
from .graphs import (
    consensus_step_limit as consensus_step_limit,
)
from .graphs import (
    formation_step_limit as formation_step_limit,
)
from .montecarlo import (
    EstimatorSweep as EstimatorSweep,
)
from .montecarlo import (
    MonteCarloResult as MonteCarloResult,
)
from .montecarlo import (
    estimator_vs_altitude as estimator_vs_altitude,
)
from .montecarlo import (
    monte_carlo_mse as monte_carlo_mse,
)
from .obstacles import (
    Obstacles as Obstacles,
)
from .obstacles import (
    obstacle_clearance as obstacle_clearance,
)
from .paper import (
    reproduce as reproduce,
)
from .radar import (
    SPEED_OF_LIGHT as SPEED_OF_LIGHT,
)
from .radar import (
    Radar as Radar,
)
from .radar import (
    db_to_linear as db_to_linear,
)
from .radar import (
    dbm_to_watts as dbm_to_watts,
)
from .results import (
    MissionResult as MissionResult,
)
from .results import (
    load_results as load_results,
)
from .scenario import (
    BUILTIN_SCENARIOS as BUILTIN_SCENARIOS,
)
from .scenario import (
    Scenario as Scenario,
)
from .scenario import (
    load_scenario as load_scenario,
)
from .simulation import (
    simulate as simulate,
)
from .simulation import (
    start_positions as start_positions,
)
from .spatial import (
    smallest_separation as smallest_separation,
)
from .tracking import (
    motion_matrices as motion_matrices,
)
from .tracking import (
    posterior_crlb as posterior_crlb,
)
from .tracking import (
    summed_range_information as summed_range_information,
)
from .tracking import (
    target_trajectories as target_trajectories,
)
