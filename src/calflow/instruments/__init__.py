"""Instruments: sensors that serve any robot family (a camera over a coded pattern, …)."""
