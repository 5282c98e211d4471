"""Identification of model parameters: cost functions, least squares, diagnostics."""
