"""A camera over a coded pattern as a sensor: decoded frames as run readings.

What every sensor built on :mod:`calflow.instruments.pattern` shares — the simulated XYΘ
rig's ``sensor: images``, the ``gcs`` rig's ``camera`` sensor, a recording of frames
decoded by ``calflow decode-run`` —, so that they all write the same readings:

* ``meas_x``, ``meas_y`` (µm), ``meas_theta`` (degree): the camera point M (the frame's
  centre) in the pattern frame and the pattern's angle Θ, as Eq. (4.26) defines them:
  an offset c of the camera plane (columns, rows) is R(Θ)·c in the pattern frame. The camera
  model and the decoder give the pattern's axes as turned by Θ_d in the frame, an offset c
  being R(−Θ_d)·c on the pattern (:mod:`calflow.instruments.pattern.render`): Θ = −Θ_d;
* ``u_meas_x``, ``u_meas_y``, ``u_meas_theta``: their standard uncertainties (the decoder's
  phase-plane fit);
* ``decode_status``: 0 when the frame decoded, else the code of its reason
  (:data:`STATUS_MEANINGS`, the CF flag meanings of the run variable); NaN readings then.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from calflow.errors import DataError

MEAS = ("meas_x", "meas_y", "meas_theta")
UNCERTAINTY = ("u_meas_x", "u_meas_y", "u_meas_theta")
READINGS = (*MEAS, *UNCERTAINTY, "decode_status")


def status_meanings() -> tuple[str, ...]:
    """The decoder's statuses, ``ok`` first: flag value k of ``decode_status`` means the k-th."""
    from calflow.instruments.pattern import STATUSES

    names = tuple(str(s) for s in STATUSES)
    return names if names[0] == "ok" else ("ok", *[n for n in names if n != "ok"])


def status_codes(statuses) -> np.ndarray:
    """Flag values (float, for a reading) of the decoder's per-frame statuses."""
    meanings = status_meanings()
    index = {name: k for k, name in enumerate(meanings)}
    return np.array([index.get(str(s), len(meanings) - 1) for s in np.atleast_1d(statuses)], dtype=float)


def camera_of(options: Mapping, where: str, error=DataError):
    """A :class:`calflow.instruments.pattern.Camera` with the fields ``options`` overrides;
    ``error`` (naming ``where`` and the field) for an unknown field or a value it refuses."""
    from dataclasses import fields

    from calflow.instruments.pattern import Camera

    if not isinstance(options, Mapping):
        raise error(f"{where}: expected a mapping of camera-model fields, got {options!r}")
    known = {f.name for f in fields(Camera)}
    for key in options:
        if key not in known:
            raise error(
                f"{where}.{key}: unknown camera-model field; expected one of {', '.join(sorted(known))}"
            )
    try:
        return Camera(**{k: tuple(v) if isinstance(v, list) else v for k, v in options.items()})
    except (TypeError, ValueError) as exc:
        raise error(f"{where}: the camera model refuses the fields ({exc})") from None


def frame_shape(camera) -> tuple[int, int]:
    """(height, width) in pixels of the camera's frames."""
    return int(camera.height), int(camera.width)


def check_frame(frame: np.ndarray, camera) -> str | None:
    """What is wrong with ``frame`` for ``camera`` (type, size), or None."""
    if frame.ndim != 2 or frame.dtype.kind not in "uif":
        return f"expected a monochrome frame of integers or floats, got {frame.dtype} of shape {frame.shape}"
    h, w = frame_shape(camera)
    if frame.shape != (h, w):
        return f"expected {w} × {h} pixels (the camera's width × height), got {frame.shape[1]} × {frame.shape[0]}"
    return None


def decode_readings(frames: np.ndarray, pattern, camera) -> list[dict[str, float]]:
    """One reading (module docstring) per frame of ``frames`` (n, height, width)."""
    from calflow.instruments.pattern import decode

    d = decode(frames, pattern, camera)
    columns = readings_of(d)
    return [{k: float(columns[k][i]) for k in READINGS} for i in range(len(frames))]


def readings_of(d) -> dict[str, np.ndarray]:
    """The readings (module docstring) of a :class:`Decoded` batch, as arrays."""
    return {
        "meas_x": np.asarray(d.x_um, dtype=float),
        "meas_y": np.asarray(d.y_um, dtype=float),
        "meas_theta": -np.asarray(d.theta_deg, dtype=float),  # Eq. (4.26): module docstring
        "u_meas_x": np.asarray(d.u_x_um, dtype=float),
        "u_meas_y": np.asarray(d.u_y_um, dtype=float),
        "u_meas_theta": np.asarray(d.u_theta_deg, dtype=float),
        "decode_status": status_codes(d.status),
    }


def render_poses(x_m, y_m, theta_deg) -> np.ndarray:
    """The camera model's render poses (n, 3) of a camera point (``x_m``, ``y_m``) µm in the
    pattern frame and the angle ``theta_deg`` (Eq. 4.26): the poses whose frames decode to
    those readings (Θ_d = −Θ, module docstring)."""
    x, y, t = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (x_m, y_m, theta_deg))
    return np.column_stack([x, y, -t])


def flags(sensors) -> dict[str, dict]:
    """The CF flag attributes of those of ``sensors`` that are flags (``decode_status``), for
    :func:`calflow.data.runs.run_dataset`."""
    return {"decode_status": status_attrs()} if "decode_status" in sensors else {}


def status_attrs() -> dict:
    """CF flag attributes of the ``decode_status`` run variable."""
    meanings = status_meanings()
    return {
        "units": "1",
        "long_name": "decode status of the sensor's frame",
        "flag_values": np.arange(len(meanings), dtype="int8"),
        "flag_meanings": " ".join(m.replace(" ", "_") for m in meanings),
    }
