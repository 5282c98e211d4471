"""What a simulated nano rig says of itself for tests and reports (:mod:`calflow.nano.stage.rig`).

A mixin of the rig: ``true_position`` (noise-free sensor values, lengths in um, time in s)
and ``truth`` (its physics as JSON), with the helpers they share with the rig's physics
(``_sum`` of the effect terms, ``_long_approach`` play states). Simulated truth is for tests
and reports only; analysis never reads it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["RigTruth"]


class RigTruth:
    """``true_position`` and ``truth`` of a simulated nano rig (module docstring)."""

    def true_position(
        self, command, time: float | np.ndarray | None = None, direction: int | Mapping[str, int] = 0
    ) -> dict[str, float | np.ndarray]:
        """Noise-free sensor values (um) for ``command`` at rig ``time`` (s, default now).

        Every deterministic effect, with the hysteresis of a long approach in ``direction``
        (+1/-1 per joint or for all; 0: none); excludes noise, quantisation, per-move
        repeatability, settling and creep (transients of a move). ``command`` (a mapping
        joint -> um, or a number for a 1-DoF rig) and ``time`` may be arrays.
        """
        cmds, z = self._long_approach(command, direction)
        t = self._t if time is None else np.asarray(time, dtype=float)
        terms = self.effect_terms(cmds, t, z)
        pos = self._sum(cmds, terms)
        return {name: (p if np.ndim(p) else float(p)) for name, p in zip(self.sensors, pos)}

    def truth(self) -> dict:
        """JSON-serialisable true physics parameters (independent of the noise seed)."""
        o = self.options
        keep = {
            k: (list(v) if isinstance(v, tuple) else v)
            for k, v in o.items()
            if k not in ("seed", "start_offset_s", "profile", "profile_params", "world_seed")
        }
        return {
            "rig": self._NAME,
            "joints": list(self.joints),
            "sensors": list(self.sensors),
            "thermometers": list(self.thermometers),
            "room": self.room.describe(),
            "world_seed": int(o["world_seed"]),
            "geometry": self._geometry_truth(),
            "options": keep,
        }

    def _sum(self, cmds, terms):
        return [
            (cmds[a] if a is not None else 0.0) + sum(terms[name][k] for name in terms)
            for k, a in enumerate(self._AXIS)
        ]

    def _long_approach(self, command, direction):
        if not isinstance(command, Mapping):
            command = {self.joints[0]: command}
        cmds = tuple(np.asarray(command[j], dtype=float) for j in self.joints)
        dirs = [
            int(direction.get(j, 0)) if isinstance(direction, Mapping) else int(direction)
            for j in self.joints
        ]
        z = tuple(self.play.long_approach(c, d) for c, d in zip(cmds, dirs))
        return cmds, z
