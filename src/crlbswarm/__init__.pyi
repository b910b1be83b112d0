"""crlbswarm's public names, each with the module that defines it.

The package imports them lazily (``lazy_loader.attach_stub`` reads this file), and type
checkers read them from here: this stub is the one list of the package's exports. Each name
is written ``name as name``, the explicit re-export of a stub.
"""

__version__: str

# Modules that draw (Matplotlib, imported on first use): crlbswarm.plots, crlbswarm.animation.
from . import (
    animation as animation,
    plots as plots,
)
from .campaign import (
    CampaignSpec as CampaignSpec,
    run_campaign as run_campaign,
)
from .constrained import (
    ConstrainedDesign as ConstrainedDesign,
    constrained_design as constrained_design,
    constrained_report as constrained_report,
    criterion_value as criterion_value,
    optimal_value as optimal_value,
)
from .control import (
    ControlGains as ControlGains,
    EtaRule as EtaRule,
    consensus_step as consensus_step,
    eta_target as eta_target,
    eta_update as eta_update,
    formation_cost as formation_cost,
    formation_input as formation_input,
    leader_guidance as leader_guidance,
    repulsion as repulsion,
)
from .design import (
    attainable_crlb as attainable_crlb,
    best_eigenvalues as best_eigenvalues,
    crlb_bound as crlb_bound,
    design_report as design_report,
    information_weight as information_weight,
    isotropic_azimuths as isotropic_azimuths,
    optimal_elevation as optimal_elevation,
    optimal_formation as optimal_formation,
    optimal_radius as optimal_radius,
    optimal_weights as optimal_weights,
)
from .errors import (
    CampaignError as CampaignError,
    ConfigError as ConfigError,
    FieldError as FieldError,
    ScenarioError as ScenarioError,
    SimulationDivergedError as SimulationDivergedError,
)
from .estimation import (
    TargetEstimate as TargetEstimate,
    estimate_target as estimate_target,
    linearised_estimate as linearised_estimate,
    measure_ranges as measure_ranges,
    negative_log_likelihood as negative_log_likelihood,
)
from .experiments import (
    FORMATION_LABELS as FORMATION_LABELS,
    AltitudeSweep as AltitudeSweep,
    ElevationCurve as ElevationCurve,
    crlb_vs_altitude as crlb_vs_altitude,
    optimal_elevation_curve as optimal_elevation_curve,
)
from .fisher import (
    crlb as crlb,
    crlb_from_fim as crlb_from_fim,
    d_optimality as d_optimality,
    d_optimality_from_fim as d_optimality_from_fim,
    e_optimality as e_optimality,
    e_optimality_from_fim as e_optimality_from_fim,
    fisher_information as fisher_information,
    range_information as range_information,
)
from .formations import (
    arc_formation as arc_formation,
    fixed_radius_polygon as fixed_radius_polygon,
    line_formation as line_formation,
    random_disc_formations as random_disc_formations,
)
from .geometry import (
    azimuth_angles as azimuth_angles,
    elevation_angles as elevation_angles,
    regular_polygon as regular_polygon,
    slant_ranges as slant_ranges,
)
from .graphs import (
    GRAPH_KINDS as GRAPH_KINDS,
    Adjacency as Adjacency,
    communication_graph as communication_graph,
    consensus_step_limit as consensus_step_limit,
    formation_step_limit as formation_step_limit,
)
from .links import (
    LinksConfig as LinksConfig,
    message_fates as message_fates,
)
from .montecarlo import (
    EstimatorSweep as EstimatorSweep,
    MonteCarloResult as MonteCarloResult,
    estimator_vs_altitude as estimator_vs_altitude,
    monte_carlo_mse as monte_carlo_mse,
)
from .multitarget import (
    TargetAllocation as TargetAllocation,
    allocate_targets as allocate_targets,
    allocation_report as allocation_report,
)
from .obstacles import (
    Obstacles as Obstacles,
    obstacle_clearance as obstacle_clearance,
)
from .paper import (
    reproduce as reproduce,
)
from .planning import (
    assign_slots as assign_slots,
    plan_route as plan_route,
)
from .radar import (
    SPEED_OF_LIGHT as SPEED_OF_LIGHT,
    Radar as Radar,
    db_to_linear as db_to_linear,
    dbm_to_watts as dbm_to_watts,
)
from .replay import (
    replay_html as replay_html,
    write_replay as write_replay,
)
from .report import (
    report_html as report_html,
    write_report as write_report,
)
from .results import (
    GroupMissionResult as GroupMissionResult,
    MissionResult as MissionResult,
    load_results as load_results,
)
from .safety import (
    safety_filter as safety_filter,
)
from .scenario import (
    BUILTIN_SCENARIOS as BUILTIN_SCENARIOS,
    Scenario as Scenario,
    load_scenario as load_scenario,
)
from .scenario_checks import (
    convergence_estimate as convergence_estimate,
    preflight as preflight,
)
from .simulation import (
    simulate as simulate,
    simulate_groups as simulate_groups,
    start_positions as start_positions,
)
from .spatial import (
    smallest_separation as smallest_separation,
)
from .three_d import (
    TARGET_HEIGHTS as TARGET_HEIGHTS,
    Design3D as Design3D,
    crlb_3d as crlb_3d,
    design_3d as design_3d,
    estimate_target_3d as estimate_target_3d,
    fisher_information_3d as fisher_information_3d,
    measure_ranges_3d as measure_ranges_3d,
    monte_carlo_mse_3d as monte_carlo_mse_3d,
    optimal_elevation_3d as optimal_elevation_3d,
    optimal_formation_3d as optimal_formation_3d,
)
from .tracking import (
    motion_matrices as motion_matrices,
    posterior_crlb as posterior_crlb,
    summed_range_information as summed_range_information,
    target_trajectories as target_trajectories,
)
