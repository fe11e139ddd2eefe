"""Worlds robots move in: walls, corridors, and payloads held by compliant grasps.

Domain-neutral and vectorized over a leading ensemble axis; mode libraries build on it.
"""

from hybridteam.world.geometry import (
    Corridor,
    corridor_with_turn,
    point_segment_distance,
    point_segment_distances,
    points_in_polygon,
    segment_segment_distances,
    segments_intersect,
    segments_intersect_polygon,
)
from hybridteam.world.limits import longest_ladder
from hybridteam.world.payload import Equilibrium, bar, equilibrium, two_grasp_slack

__all__ = [
    "Corridor",
    "Equilibrium",
    "bar",
    "corridor_with_turn",
    "equilibrium",
    "longest_ladder",
    "point_segment_distance",
    "point_segment_distances",
    "points_in_polygon",
    "segment_segment_distances",
    "segments_intersect",
    "segments_intersect_polygon",
    "two_grasp_slack",
]
