"""Lookup tables of the XYΘ micro-robot: XY position errors, the angle table, characterisation."""
