"""Thesis-style HTML and PDF reports rendered from campaign summaries."""

from calflow.report.render import render_campaign, render_index, write_pdf

__all__ = ["render_campaign", "render_index", "write_pdf"]
