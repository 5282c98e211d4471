"""Nano campaign summaries (ISO 9283, stabilisation, ordering), figures and templates."""
