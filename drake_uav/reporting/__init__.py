"""Identification reports (markdown, HTML, figures, JSON summary), written atomically.

``Report`` builds a report folder from sections; ``write_report`` writes the main job's report
of an :class:`~drake_uav.identification.main_job.IdentificationRun`; ``figures`` holds
the plots; ``write_tracking_plots`` the figures of a tracking run; ``export_replay_html``
and ``replay`` show a flight log in 3-D (Meshcat).
"""

from drake_uav.reporting import figures
from drake_uav.reporting.identification_report import write_report
from drake_uav.reporting.replay import export_replay_html, replay
from drake_uav.reporting.report import Report, format_value, json_ready
from drake_uav.reporting.tracking_figures import write_tracking_plots

__all__ = ["Report", "export_replay_html", "figures", "format_value", "json_ready", "replay",
           "write_report", "write_tracking_plots"]
