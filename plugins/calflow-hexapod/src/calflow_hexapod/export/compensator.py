"""A calibrated hexapod for users' own code: wanted pose → the pose to command the C-887.

``Compensator.load("results/<campaign>/export/<model>")`` reads the bundle
(:mod:`calflow_hexapod.export.bundle`); :meth:`Compensator.command` gives, for target poses
M (n, 6) of the measured target in the measurement frame (x y z µm, u v w degree), the poses
to send with ``MOV`` so that the true pose lands on them: P = F M G⁻¹, the identified legs'
lengths of P, the lengths λ the controller must command for them (the leg model inverted),
and the controller's forward kinematics of λ through its nominal geometry about its pivot
(:func:`calflow_hexapod.models.calibration.command`, the same code path as calflow's
in-process model). No workflow, campaign or rig is needed: numpy and this package.
"""

from __future__ import annotations

import numpy as np

from calflow.data.bundle import Compensator as CompensatorShell
from calflow_hexapod.export.bundle import read_model


class Compensator(CompensatorShell):
    """The inverse of an exported hexapod model (µm, degree)."""

    read_model = staticmethod(read_model)

    @property
    def pivot_um(self) -> np.ndarray:
        """The controller's pivot (``SPI`` R S T, µm) the commands are about."""
        return self.model.controller.pivot.copy()

    def command(self, targets, temperature=None) -> np.ndarray:
        """Poses (n, 6) to command for target readings (n, 6); ``temperature`` (n,) degC of the
        legs for a model with a thermal term (None: 20 °C)."""
        return self.model.command(np.atleast_2d(np.asarray(targets, dtype=float)), temperature)

    def predict(self, commands, temperature=None) -> np.ndarray:
        """The readings (n, 6) the model expects for commanded poses (n, 6)."""
        return self.model.predict(np.atleast_2d(np.asarray(commands, dtype=float)), temperature)
