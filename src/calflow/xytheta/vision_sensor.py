"""The simulated vision sensor of the XYΘ physics, as a sensor of the ``gcs`` rig.

``simulated_vision`` (registered by the XYΘ family as a built-in sensor of the ``gcs``
rig, :mod:`calflow.gcs.sensors`) is the vision sensor of the simulated XYΘ physics
(:mod:`calflow.xytheta.rig`, Table 3.3, Eq. 4.26), read at the attained stage positions,
which is how the GCS emulator of a campaign (:mod:`calflow.xytheta.emulate`) stands in for
the thesis hardware.
"""

from __future__ import annotations

import zlib
from typing import Any, Mapping

import numpy as np

from calflow.errors import RigError
from calflow.xytheta.kinematics import forward
from calflow.xytheta.rig import XYThetaTruth, check_options



class SimulatedVision:
    """The simulated XYΘ vision sensor read at given joint positions.

    ``positions["x"]``, ``["y"]`` are the *attained* X/Y joint positions (µm; the campaign
    emulator's ``POS?`` includes the lead-screw errors, Fig. 4.8, 4.9), ``["theta"]`` the
    rotation (degree). Adds the Θ-dependent errors (Sec. 4.5.5), stage repeatability,
    the sensor's noise, resolution and thermal drift (Table 3.3); mirrors
    :meth:`calflow.xytheta.rig.SimulatedXYTheta.read`.
    """

    sensors = ("meas_x", "meas_y", "meas_theta")
    thermometers = ("T1",)

    def __init__(self, truth: XYThetaTruth, seed: int = 0, stream: str = "") -> None:
        self.truth_model = truth
        self._rng = np.random.default_rng(np.random.SeedSequence(
            [int(seed), zlib.crc32(f"gcs-vision:{stream}".encode())]))

    def read(self, positions: Mapping[str, float], time_s: float) -> dict[str, float]:
        t = self.truth_model
        try:
            X, Y, theta = (float(positions[j]) for j in ("x", "y", "theta"))
        except KeyError as exc:
            raise RigError(f"simulated_vision sensor: no position of joint {exc.args[0]!r}") from None
        f_ax, f_ay = t.angle_error(theta)
        x_P, y_P = forward(X, Y, theta, t.parameters, f_ax=f_ax, f_ay=f_ay)
        jitter = self._rng.normal(0.0, t.stage_repeatability_um, 2)
        temperature = float(t.room_temperature(time_s))
        noise = self._rng.normal(0.0, t.sensor_noise_um, 2)
        x_m, y_m = t.vision(float(x_P) + jitter[0], float(y_P) + jitter[1], theta, temperature, noise)
        return {
            "meas_x": float(x_m),
            "meas_y": float(y_m),
            "meas_theta": theta + float(self._rng.normal(0.0, t.sensor_theta_noise_deg)),
            "T1": round(temperature + float(self._rng.normal(0.0, 0.005)), 3),
        }

    def close(self) -> None:
        pass


def truth_from_options(physics: Mapping[str, Any]) -> XYThetaTruth:
    """An :class:`XYThetaTruth` with ``physics`` overrides, checked as the simulated rig's
    options are (:func:`calflow.xytheta.rig.check_options`)."""
    o = check_options(**physics)
    del o["seed"], o["stream"]
    return XYThetaTruth(**o)


def simulated_vision(seed: int = 0, stream: str = "", **physics) -> SimulatedVision:
    """Built-in sensor ``simulated_vision``; ``physics`` overrides :class:`XYThetaTruth`."""
    return SimulatedVision(truth_from_options(physics), seed=seed, stream=stream)
