"""The identified hexapod geometry for users' code and the rig: the bundle and its Compensator."""

from calflow_hexapod.export.compensator import Compensator

__all__ = ["Compensator"]
