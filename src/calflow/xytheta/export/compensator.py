"""A calibrated XYΘ model for users' own code: task-space targets to joint commands."""

from __future__ import annotations

import dataclasses

import numpy as np

from calflow.data.bundle import Compensator as CompensatorShell
from calflow.xytheta.export.bundle import read_model


class Compensator(CompensatorShell):
    """The inverse kinematics of an exported model with every table (Eq. 4.19).

    ``Compensator.load("results/<campaign>/export/<model>")`` reads the bundle;
    :meth:`joints` gives the X, Y (µm) and Θ (degree) commands for a sequence of targets
    (x_T, y_T in µm in the world frame of Eq. 4.27, Θ_T in degree) exactly as calflow's
    in-process model commands them — position tables by approach direction, from
    ``start``, and the angle table by the direction of Θ.
    """

    read_model = staticmethod(read_model)

    def joints(self, x_T, y_T, theta_T, start=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint commands X, Y (µm), Θ (degree) for targets commanded in this order from ``start``."""
        x_T, y_T, theta_T = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (x_T, y_T, theta_T))
        X, Y = self.model.inverse(x_T, y_T, theta_T, start=start)
        return np.asarray(X, dtype=float), np.asarray(Y, dtype=float), theta_T.copy()

    def nominal(self, x_T, y_T, theta_T) -> tuple[np.ndarray, np.ndarray]:
        """X, Y (µm) without the position tables: what a controller's kinematics computes
        before its per-axis compensation (:mod:`calflow.xytheta.export.controllers`)."""
        x_T, y_T, theta_T = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (x_T, y_T, theta_T))
        X, Y = dataclasses.replace(self.model, position=None).inverse(x_T, y_T, theta_T)
        return np.asarray(X, dtype=float), np.asarray(Y, dtype=float)

    def forward(self, X, Y, theta, dir_x=1, dir_y=1) -> tuple[np.ndarray, np.ndarray]:
        """The tool point (µm) the model predicts for joints X, Y (µm), Θ (degree), Eq. 4.18."""
        return self.model.forward(X, Y, theta, dir_x, dir_y)
