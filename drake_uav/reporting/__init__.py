"""Identification reports (markdown, HTML, figures, JSON summary)."""
