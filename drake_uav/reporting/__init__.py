"""Identification reports (markdown, HTML, figures, JSON summary), written atomically.

``Report`` builds a report folder from sections; ``write_report`` writes the main job's report
of an :class:`~drake_uav.identification.main_job.IdentificationRun`; ``figures`` holds
the plots.
"""

from drake_uav.reporting import figures
from drake_uav.reporting.identification_report import write_report
from drake_uav.reporting.report import Report, format_value, json_ready

__all__ = ["Report", "figures", "format_value", "json_ready", "write_report"]
