"""The rig protocol (docs/rigs.md): what acquisition needs from any positioning rig."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol, runtime_checkable


@runtime_checkable
class Rig(Protocol):
    """A positioning rig: joints to command, sensors and thermometers to read.

    Commands are in micrometres (``um``) for translations and ``degree`` for rotations;
    readings are in the sensor's own frame, in the same units, temperatures in ``degC``.
    """

    joints: tuple[str, ...]
    sensors: tuple[str, ...]
    thermometers: tuple[str, ...]

    def move(self, command: Mapping[str, float]) -> None:
        """Command every joint to the given position; return when settled."""

    def wait(self, seconds: float) -> None:
        """Dwell for ``seconds`` (virtual time on a simulator)."""

    def read(self) -> Mapping[str, float]:
        """Return ``time`` (s since start), each sensor and each thermometer."""

    def close(self) -> None:
        """Release the rig."""


REQUIRED_ATTRIBUTES = ("joints", "sensors", "thermometers", "move", "wait", "read", "close")


def missing_members(obj: object) -> list[str]:
    """Names of the rig protocol members ``obj`` lacks (empty when it is a rig)."""
    return [name for name in REQUIRED_ATTRIBUTES if not hasattr(obj, name)]
