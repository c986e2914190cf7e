"""Builders that wire systems into ready-to-simulate diagrams."""

from drake_uav.diagrams.identification_flight import (
    IdentificationFlight,
    build_identification_flight,
    default_excitation,
    fly,
)
from drake_uav.diagrams.tracking import (
    TrackingRun,
    build_terminal_set,
    fly_tracking,
    gust_force,
    solve_time_stats,
    tracking_reference,
)

__all__ = ["IdentificationFlight", "TrackingRun", "build_identification_flight",
           "build_terminal_set", "default_excitation", "fly", "fly_tracking", "gust_force",
           "solve_time_stats", "tracking_reference"]
