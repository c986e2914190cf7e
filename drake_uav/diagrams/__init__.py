"""Builders that wire systems into ready-to-simulate diagrams."""

from drake_uav.diagrams.identification_flight import (
    IdentificationFlight,
    build_identification_flight,
    default_excitation,
    fly,
)

__all__ = ["IdentificationFlight", "build_identification_flight", "default_excitation", "fly"]
