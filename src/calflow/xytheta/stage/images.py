"""The simulated XYΘ rig's vision sensor through images (``rig.options.sensor: images``).

Instead of the noise model of :meth:`XYThetaTruth.vision` (noise, per-pose decoding error,
gross errors, resolution, all drawn from magnitudes), the camera point M seen in the
pattern frame (Eq. 4.26) is rendered as a microscope frame of the coded pattern by the
camera model and read back by the decoder (:mod:`calflow.instruments.pattern`): what the
sensor adds to a reading is what images and their decoding add. The thermal drift of
the camera mount (Table 3.3) stays a physical shift of where the camera looks.

Options (``rig.options``):

* ``sensor``: ``model`` (the noise model, the default) or ``images``;
* ``camera``: overrides of :class:`calflow.instruments.pattern.Camera` fields (e.g. a
  smaller sensor, ``{width: 512, height: 384}``, for a quick campaign);
* ``pattern``: a pattern file of any layout (``calflow pattern make``, ``--layout megarena`` too); by default the pattern made
  for the rig's ``pattern_range_um`` with the pattern's default period and dot size (the
  noise model's ``pattern_period_um``, ``sensor_noise_um``, ``decode_error_um``,
  ``gross_error_rate`` and ``sensor_resolution_um`` then play no part).

Each reading keeps ``meas_*``, their standard uncertainties ``u_meas_*`` from the
decoder's phase-plane fit and a ``decode_status`` (0 decoded; a frame that does not
decode gives NaN readings and its reason's code).
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import numpy as np

from calflow.errors import OptionError

SENSORS = ("model", "images")
IMAGE_CHANNELS = ("u_meas_x", "u_meas_y", "u_meas_theta", "decode_status")  # beside meas_*
CHUNK = 16  # frames rendered and decoded at once: bounds the memory of a long visit()


def check(sensor="model", camera=None, pattern=None, range_um=None) -> dict:
    """The sensor options checked: ``sensor`` one of :data:`SENSORS`, ``camera`` a mapping
    of known :class:`Camera` fields, ``pattern`` a readable pattern file that covers the
    rig's ``range_um`` (its ``pattern_range_um``) and that the camera's field of view can
    decode. Raises :class:`OptionError`."""
    if sensor not in SENSORS:
        raise OptionError("sensor", f"one of {list(SENSORS)}", sensor)
    if sensor == "model":
        for key, value in (("camera", camera), ("pattern", pattern)):
            if value is not None:
                raise OptionError(key, "no value: it applies to sensor 'images' only", value)
        return {"sensor": "model"}
    from calflow.instruments.readings import camera_of

    if camera is not None and not isinstance(camera, Mapping):
        raise OptionError("camera", "a mapping of camera-model fields", camera)
    camera = dict(camera or {})
    try:
        cam = camera_of(camera, "camera", ValueError)
    except ValueError as exc:
        raise OptionError("camera", f"camera-model fields the model accepts ({exc})", camera) from None
    if pattern is not None and not (isinstance(pattern, str) and Path(pattern).is_file()):
        raise OptionError("pattern", "an existing pattern file (calflow pattern make)", pattern)
    if pattern is not None:
        _check_pattern(pattern, cam, range_um)
    elif range_um is not None:
        _check_default_pattern(cam, range_um, camera)
    return {"sensor": "images", "camera": camera, "pattern": pattern}


def _check_pattern(path: str, camera, range_um) -> None:
    """The pattern file read (one line when it is not one), its range covering ``range_um``
    and the camera's field of view enough to decode it."""
    from calflow.errors import DataError
    from calflow.instruments.pattern.decode import field_of_view_problem
    from calflow.instruments.readings import frame_shape
    from calflow.instruments.recorded_frames import load_pattern

    try:
        pat = load_pattern(path)
    except DataError as exc:
        raise OptionError("pattern", f"a calflow pattern file ({exc})", path) from None
    if range_um is not None and any(p < r for p, r in zip(pat.range_um, range_um)):
        raise OptionError(
            "pattern",
            f"a pattern whose range covers the rig's pattern_range_um {list(range_um)} µm "
            f"(calflow pattern make --range), its range is {list(pat.range_um)} µm",
            path,
        )
    problem = field_of_view_problem(*frame_shape(camera), camera.pixel_um, pat)
    if problem:
        raise OptionError("camera", f"a field of view the pattern can be decoded in ({problem})", path)


def _check_default_pattern(camera, range_um, fields: dict) -> None:
    """The camera's field of view against the default pattern for ``range_um``: its windows
    before they are checked apart (``check=False``, milliseconds) need the least field of
    view, so a camera refused here cannot decode the pattern the rig makes."""
    from calflow.instruments.pattern import Pattern
    from calflow.instruments.pattern.decode import field_of_view_problem
    from calflow.instruments.readings import frame_shape

    try:
        least = Pattern.make(range_um=tuple(range_um), check=False)
    except ValueError:
        return  # a range no pattern covers: the rig's own check says so when it is built
    problem = field_of_view_problem(*frame_shape(camera), camera.pixel_um, least)
    if problem:
        raise OptionError(
            "camera", f"a field of view the default pattern can be decoded in ({problem})", fields
        )


def _frozen(mapping: Mapping) -> tuple:
    return tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in mapping.items()))


@lru_cache(maxsize=4)
def _instrument(camera: tuple, pattern: str | None, range_um: tuple):
    """(pattern, camera) of the options; the default pattern (made for the rig's
    ``pattern_range_um`` with the pattern's own default period and dots) once per process."""
    from calflow.instruments.pattern import Camera, Pattern
    from calflow.instruments.pattern.layouts import load_pattern

    cam = Camera(**dict(camera))
    pat = load_pattern(pattern) if pattern else Pattern.make(range_um=range_um)
    return pat, cam


class ImageSensor:
    """Rendered frames of the pattern at the camera point, decoded (module docstring).

    ``truth`` gives the default pattern's range; the camera's noise draws come
    from their own stream of (``seed``, ``stream``), so the stage's draws are the same
    whichever sensor reads it.
    """

    def __init__(self, truth, options: Mapping, seed: int = 0, stream: str = "") -> None:
        self.options = {"sensor": "images", "camera": dict(options.get("camera") or {})}
        if options.get("pattern"):
            self.options["pattern"] = str(options["pattern"])
        self.pattern, self.camera = _instrument(
            _frozen(self.options["camera"]),
            self.options.get("pattern"),
            tuple(float(v) for v in truth.pattern_range_um),
        )
        self._rng = np.random.default_rng(
            np.random.SeedSequence([int(seed), zlib.crc32(f"images:{stream}".encode())])
        )

    def frames(self, x_m, y_m, theta_deg) -> np.ndarray:
        """Frames (n, height, width) with the camera point at (``x_m``, ``y_m``) µm in the
        pattern frame (Eq. 4.26) and the stage at ``theta_deg``."""
        from calflow.instruments.readings import render_poses

        return self.camera.render_batch(self.pattern, render_poses(x_m, y_m, theta_deg), self._rng)

    def read(self, x_m, y_m, theta_deg) -> dict[str, np.ndarray]:
        """Decoded readings of frames at the camera points (:meth:`frames`): ``meas_x``,
        ``meas_y`` (µm), ``meas_theta`` (degree), ``u_meas_*`` and ``decode_status``."""
        from calflow.instruments.pattern import decode
        from calflow.instruments.readings import READINGS, readings_of

        x_m, y_m, theta_deg = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (x_m, y_m, theta_deg))
        out = {k: np.full(len(x_m), np.nan) for k in READINGS}
        for start in range(0, len(x_m), CHUNK):
            part = slice(start, start + CHUNK)
            r = readings_of(
                decode(self.frames(x_m[part], y_m[part], theta_deg[part]), self.pattern, self.camera)
            )
            for k in READINGS:
                out[k][part] = r[k]
        return out
