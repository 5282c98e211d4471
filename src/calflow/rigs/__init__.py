"""Rigs: the simulated stages, replay of recordings, real controllers and plug-ins."""

from calflow.rigs.plugin import load_rig, resolve_factory
from calflow.rigs.protocol import Rig

__all__ = ["Rig", "load_rig", "resolve_factory"]
