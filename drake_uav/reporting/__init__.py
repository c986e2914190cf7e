"""Identification reports (markdown, HTML, figures, JSON summary), written atomically."""

from drake_uav.reporting import figures
from drake_uav.reporting.report import Report, format_value, json_ready, markdown_to_html

__all__ = ["Report", "figures", "format_value", "json_ready", "markdown_to_html"]
