"""crlbswarm: CRLB-optimal UAV formations for cooperative range sensing.

Implements and extends Wu, Jin, Su, Li, Pan, Chan, "Formation Control for CRLB-Optimal
Cooperative Sensing in Low-Altitude Wireless Networks", arXiv:2602.23990 (2026).

Positions are horizontal coordinates in metres, shape ``(..., M, 2)`` (UAVs are rows);
every function accepts any leading batch shape. Angles are radians inside the library.
"""

from .design import (
    crlb_bound,
    information_weight,
    optimal_elevation,
    optimal_formation,
    optimal_radius,
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
from .radar import SPEED_OF_LIGHT, Radar, db_to_linear, dbm_to_watts

__version__ = "0.1.0"

__all__ = [
    "FORMATION_LABELS",
    "SPEED_OF_LIGHT",
    "AltitudeSweep",
    "ElevationCurve",
    "Radar",
    "arc_formation",
    "azimuth_angles",
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
    "fisher_information",
    "fixed_radius_polygon",
    "information_weight",
    "line_formation",
    "optimal_elevation",
    "optimal_elevation_curve",
    "optimal_formation",
    "optimal_radius",
    "random_disc_formations",
    "range_information",
    "regular_polygon",
    "slant_ranges",
]
