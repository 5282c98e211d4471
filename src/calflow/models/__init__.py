"""Calibration models: the five XYΘ models (Ch. 4) and the nanopositioning models (Ch. 5)."""
