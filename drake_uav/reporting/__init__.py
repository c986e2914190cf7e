"""Identification reports (markdown, HTML, figures, JSON summary), written atomically.

``Report`` builds a report folder from sections; ``write_report`` writes the main job's report
of an :class:`~drake_uav.identification.pipeline.IdentificationRun`; ``figures`` holds
the plots; ``write_tracking_plots`` the figures of a tracking run; ``export_replay_html``
and ``replay`` show a flight log in 3-D (Meshcat).
"""

import importlib

_HOMES = {
    "Report": "drake_uav.reporting.report",
    "export_replay_html": "drake_uav.reporting.replay",
    "figures": None,
    "format_value": "drake_uav.reporting.report",
    "json_ready": "drake_uav.reporting.report",
    "replay": "drake_uav.reporting.replay",
    "write_report": "drake_uav.reporting.identification_report",
    "write_tracking_plots": "drake_uav.reporting.tracking_figures",
}
"""Where each exported name lives: submodules load on first use, so that writing an
identification report does not import the simulation diagrams (tracking figures) or Meshcat
(replay). ``figures`` is the submodule itself."""

__all__ = ["Report", "export_replay_html", "figures", "format_value", "json_ready", "replay",
           "write_report", "write_tracking_plots"]


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'drake_uav.reporting' has no attribute {name!r}")
    if _HOMES[name] is None:
        return importlib.import_module(f"drake_uav.reporting.{name}")
    value = getattr(importlib.import_module(_HOMES[name]), name)
    globals()[name] = value  # the submodule import bound its module to the same name
    return value
