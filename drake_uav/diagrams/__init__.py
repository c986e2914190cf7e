"""Builders that wire systems into ready-to-simulate diagrams."""

from drake_uav.diagrams.identification_flight import build_identification_flight, fly

__all__ = ["build_identification_flight", "fly"]
