"""Nano campaign summaries (ISO 9283, stabilisation, ordering, extrapolation), figures and templates."""
