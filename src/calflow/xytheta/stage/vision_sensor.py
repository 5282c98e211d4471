"""The simulated vision sensor of the XYΘ physics, as a sensor of the ``gcs`` rig.

``simulated_vision`` (registered by the XYΘ family as a built-in sensor of the ``gcs``
rig, :mod:`calflow.gcs.sensors`) is the vision sensor of the simulated XYΘ physics
(:mod:`calflow.xytheta.stage.rig`, Table 3.3, Eq. 4.26), read at the attained stage positions,
which is how the GCS emulator of a campaign (:mod:`calflow.xytheta.stage.emulate`) stands in for
the thesis hardware.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping

import numpy as np

from calflow.errors import RigError
from calflow.xytheta.stage.physics import XYThetaTruth, truth_from_options


class SimulatedVision:
    """The simulated XYΘ vision sensor read at given joint positions.

    ``positions["x"]``, ``["y"]``, ``["theta"]`` are the controller's encoder positions
    (µm, degree; ``POS?``), which see none of the stage's errors. The sensor is the physical
    world: it tracks the approach direction and nut play of each axis from successive
    readings and puts the carriages and the tool where :class:`XYThetaTruth` puts them
    (lead screw, lost motion, coupling, scale, straightness, Θ errors, runout, yaw), then
    adds stage repeatability, noise, decoding and gross errors and drift (Table 3.3);
    mirrors :class:`calflow.xytheta.stage.rig.SimulatedXYTheta`.
    """

    sensors = ("meas_x", "meas_y", "meas_theta")
    thermometers = ("T1",)

    def __init__(self, truth: XYThetaTruth, seed: int = 0, stream: str = "") -> None:
        self.truth_model = truth
        self._last = np.zeros(3)  # the encoder positions of the last reading (home first)
        self._dir = np.ones(3)
        self._lash = np.full(2, 0.5 * truth.backlash_um)
        self._rng = np.random.default_rng(
            np.random.SeedSequence([int(seed), zlib.crc32(f"gcs-vision:{stream}".encode())])
        )

    def tool(self, positions: Mapping[str, float], time_s: float) -> tuple[float, float, float, float]:
        """The tool point (µm), attained angle (degree) and room temperature (degC) at the
        encoder ``positions`` read at ``time_s``, stage repeatability included; tracks the
        approach directions and nut plays from the previous call."""
        t = self.truth_model
        try:
            X, Y, theta = (float(positions[j]) for j in ("x", "y", "theta"))
        except KeyError as exc:
            raise RigError(f"simulated_vision sensor: no position of joint {exc.args[0]!r}") from None
        temperature = float(t.room_temperature(time_s))
        q = np.array([X, Y, theta])
        delta = q - self._last
        half = 0.5 * t.backlash_um
        for k in (0, 1, 2):  # approach directions and the nut play, as the simulated rig tracks them
            if abs(delta[k]) > 1e-9:
                self._dir[k] = np.sign(delta[k])
                if k < 2:
                    self._lash[k] = (
                        np.clip(self._lash[k] + delta[k], -half, half)
                        if t.lost_motion
                        else half * self._dir[k]
                    )
        self._last = q
        Xa, Ya = t.attained_joints(X, Y, self._lash[0], self._lash[1], temperature)
        x_P, y_P, theta_a = t.tool_from_carriages(Xa, Ya, X, Y, theta, self._dir[2])
        jitter = self._rng.normal(0.0, t.stage_repeatability_um, 2)
        return float(x_P) + jitter[0], float(y_P) + jitter[1], float(theta_a), temperature

    def read(self, positions: Mapping[str, float], time_s: float) -> dict[str, float]:
        t = self.truth_model
        x_P, y_P, theta_a, temperature = self.tool(positions, time_s)
        noise = self._rng.normal(0.0, t.sensor_noise_um, 2)
        gross = t.gross_error(*self._rng.random(2))
        x_m, y_m = t.vision(x_P, y_P, theta_a, temperature, noise, gross)
        return {
            "meas_x": float(x_m),
            "meas_y": float(y_m),
            "meas_theta": float(theta_a) + float(self._rng.normal(0.0, t.sensor_theta_noise_deg)),
            "T1": round(temperature + float(self._rng.normal(0.0, 0.005)), 3),
        }

    def close(self) -> None:
        pass


def simulated_vision(seed: int = 0, stream: str = "", **physics) -> SimulatedVision:
    """Built-in sensor ``simulated_vision``; ``physics`` overrides :class:`XYThetaTruth`."""
    return SimulatedVision(truth_from_options(physics), seed=seed, stream=stream)


class SimulatedCamera:
    """An emulated camera over the pattern on the simulated XYΘ stage: a frame source of the
    ``gcs`` rig's ``camera`` sensor (:mod:`calflow.gcs.camera`). ``observe`` puts the tool
    where the physics puts it for the stages' encoder positions (as :class:`SimulatedVision`
    does); ``grab`` renders the pattern at the camera point (Eq. 4.26, thermal drift of the
    mount included) with the camera model (:mod:`calflow.xytheta.stage.images`)."""

    def __init__(self, truth: XYThetaTruth, sensor: dict, seed: int = 0, stream: str = "") -> None:
        from calflow.xytheta.stage.images import ImageSensor

        self.stage = SimulatedVision(truth, seed=seed, stream=f"camera:{stream}")
        self.images = ImageSensor(truth, sensor, seed=seed, stream=f"gcs-camera:{stream}")
        self._point: tuple[float, float, float] | None = None

    @property
    def pattern(self):
        """The pattern it renders (the camera sensor decodes with it)."""
        return self.images.pattern

    @property
    def camera(self):
        """The camera model it renders with."""
        return self.images.camera

    def observe(self, positions: Mapping[str, float], time_s: float) -> None:
        t = self.stage.truth_model
        x_P, y_P, theta_a, temperature = self.stage.tool(positions, time_s)
        x_m, y_m = t.camera_point(x_P, y_P, theta_a, temperature)
        self._point = (float(x_m), float(y_m), theta_a)

    def grab(self) -> np.ndarray:
        if self._point is None:
            raise RigError("simulated_camera: grab() before the rig told it the stages' positions (observe)")
        return self.images.frames(*self._point)[0]

    def close(self) -> None:
        pass


def simulated_camera(
    seed: int = 0, stream: str = "", camera=None, pattern=None, **physics
) -> SimulatedCamera:
    """Frame source ``simulated_camera``: :class:`SimulatedCamera` of the XYΘ physics with
    ``physics`` overrides, the camera-model fields ``camera`` and the ``pattern`` file."""
    from calflow.xytheta.stage.images import check

    sensor = check("images", camera, pattern)
    return SimulatedCamera(truth_from_options(physics), sensor, seed=seed, stream=stream)
