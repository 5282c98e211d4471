"""A camera over a coded pattern as the ``gcs`` rig's sensor (docs/gcs.md, "Camera sensor").

The ``camera`` sensor grabs one frame per reading from a *frame source* and decodes it
(:mod:`calflow.instruments.pattern`) into the camera point and angle in the pattern frame
(``meas_x``, ``meas_y`` µm, ``meas_theta`` degree, Eq. 4.26), with their standard
uncertainties ``u_meas_*`` and a ``decode_status``. A frame source is anything with::

    class FrameSource(Protocol):
        def grab(self) -> numpy.ndarray: ...   # one monochrome frame (height, width), integers
        def close(self) -> None: ...

and, for an emulated camera only, ``observe(positions, time_s)``: the rig tells it the
stages' positions before each grab (a real camera sees the world instead). Sources:
``genicam`` (any GenICam camera through its GenTL producer, with harvesters: ``pip install
'calflow[genicam]'``), a robot family's emulated camera (``simulated_camera``), or an
allowed ``module:callable``. Options::

    sensor:
      factory: camera
      options:
        source: {factory: genicam, options: {cti: /opt/vendor/lib/producer.cti, serial: "22FK019"}}
        pattern: pattern.json        # the pattern file: calflow's (calflow pattern make, any
                                     #   layout) or the Vernier library's MegarenaPattern JSON
        camera: {}                   # camera-model fields the decoder uses (pixel size, optics)

An emulated source that renders a known pattern with a known camera model (its ``pattern``
and ``camera`` attributes) needs neither option. For a lab's target (a Megarena pattern) the
pixel size is the camera's when ``camera`` gives ``sensor_pixel_um`` or ``magnification`` and
is measured from each frame when it does not, as for a frames recording. HP-code markers
(several a frame): ``marker`` names the one measured (default: the lowest number of the first
frame showing any, kept for the run) and ``reference_marker`` a fixed one it is measured
against, as a frames recording names them (docs/data.md).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from calflow.errors import RigError

READINGS = ("meas_x", "meas_y", "meas_theta", "u_meas_x", "u_meas_y", "u_meas_theta", "decode_status")
INSTALL = "pip install 'calflow[genicam]'"


@runtime_checkable
class FrameSource(Protocol):
    """What the camera sensor grabs frames from."""

    def grab(self) -> np.ndarray: ...

    def close(self) -> None: ...


class CameraSensor:
    """The ``gcs`` rig's sensor that decodes one grabbed frame per reading (module docstring)."""

    sensors = READINGS
    thermometers: tuple[str, ...] = ()

    def __init__(
        self,
        source: FrameSource,
        pattern,
        camera,
        measure_pixel: bool = False,
        marker: int | None = None,
        reference: int | None = None,
    ) -> None:
        self.source, self.pattern, self.camera = source, pattern, camera
        self.measure_pixel = measure_pixel  # a lab's target, its pixel size from each frame
        self.marker, self.reference = marker, reference  # HP-code markers' numbers
        self.frames = 0

    def read(self, positions: Mapping[str, float], time_s: float) -> dict[str, float]:
        from calflow.instruments.readings import check_frame, decode_readings

        observe = getattr(self.source, "observe", None)
        if observe is not None:
            observe(positions, time_s)
        try:
            frame = np.asarray(self.source.grab())
        except RigError:
            raise
        except Exception as exc:  # a driver's own error: one line naming the camera
            raise RigError(f"gcs rig: camera sensor: grab() failed ({type(exc).__name__}: {exc})") from None
        self.frames += 1
        problem = check_frame(frame, self.camera)
        if problem:
            raise RigError(f"gcs rig: camera sensor: frame {self.frames}: {problem}")
        try:
            if getattr(self.pattern, "layout", "cell2x2") == "hpcode":
                return self._marker_reading(frame)
            return decode_readings(frame[None], self.pattern, None if self.measure_pixel else self.camera)[0]
        except ValueError as exc:  # the camera cannot decode this pattern (field of view)
            raise RigError(f"gcs rig: camera sensor: {exc}") from None

    def _marker_reading(self, frame: np.ndarray) -> dict[str, float]:
        """The measured HP-code marker's reading, relative to the reference marker when one is
        named; the marker measured, when not named, is the lowest number (the reference's left
        out) of the first frame showing any, and stays that one."""
        from calflow.instruments.pattern.hpcode import decode, decode_markers
        from calflow.instruments.readings import readings_of

        pixel = None if self.measure_pixel else self.camera.pixel_um
        if self.marker is None:
            found = decode_markers(frame[None], self.pattern, pixel)
            numbers = set(found.number[found.status == "ok"].tolist()) - {self.reference, -1}
            self.marker = min(numbers) if numbers else None
        d = decode(frame[None], self.pattern, pixel, marker=self.marker, reference=self.reference)
        return {k: float(v[0]) for k, v in readings_of(d).items()}

    def close(self) -> None:
        self.source.close()


def camera_sensor(source=None, pattern=None, camera=None, marker=None, reference_marker=None) -> CameraSensor:
    """Built-in sensor ``camera`` of the ``gcs`` rig (module docstring)."""
    from calflow.errors import CalflowError
    from calflow.instruments.pattern.layouts import load_pattern
    from calflow.instruments.readings import camera_of

    if not isinstance(source, Mapping) or "factory" not in source:
        raise RigError(
            "gcs rig: sensor.options.source: expected {factory: genicam (or a family's emulated "
            f"camera, or 'module:callable'), options: {{...}}}}, got {source!r}"
        )
    if pattern is not None and (not isinstance(pattern, str) or not Path(pattern).is_file()):
        raise RigError(f"gcs rig: sensor.options.pattern: expected an existing pattern file, got {pattern!r}")
    grabber = load_source(source)
    if pattern is None:  # an emulated camera knows the pattern it renders; a real one does not
        if getattr(grabber, "pattern", None) is None:
            grabber.close()
            raise RigError("gcs rig: sensor.options.pattern: expected the pattern file the camera looks at")
        pat = grabber.pattern
    else:
        try:
            pat = load_pattern(pattern)
        except (OSError, ValueError, CalflowError) as exc:
            grabber.close()
            text = str(exc)
            raise RigError(text if text.startswith(pattern) else f"{pattern}: pattern file: {text}") from None
    layout = getattr(pat, "layout", "cell2x2")
    problem = _markers_problem(layout, marker, reference_marker)
    if problem:
        grabber.close()
        raise RigError(f"{pattern}: gcs rig: {problem}")
    if camera is None and getattr(grabber, "camera", None) is not None:
        model, measure = grabber.camera, False
    else:
        model = camera_of(camera or {}, "sensor.options.camera", RigError)
        measure = layout != "cell2x2" and not {"sensor_pixel_um", "magnification"} & set(camera or {})
    return CameraSensor(grabber, pat, model, measure, marker, reference_marker)


def _markers_problem(layout: str, marker, reference) -> str | None:
    """What is wrong with the HP-code markers named (``sensor.options.marker``,
    ``reference_marker``) for a pattern of ``layout``, or None."""
    named = {k: v for k, v in (("marker", marker), ("reference_marker", reference)) if v is not None}
    if named and layout != "hpcode":
        key = next(iter(named))
        return f"sensor.options.{key}: only for HP-code markers (layout hpcode); this pattern's layout is {layout!r}"
    for key, v in named.items():
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            return f"sensor.options.{key}: expected the number of an HP-code marker (an integer, 0 or more), got {v!r}"
    if marker is not None and marker == reference:
        return f"sensor.options.reference_marker: expected another marker than sensor.options.marker, got {reference!r}"
    return None


def load_source(spec: Mapping[str, Any]) -> FrameSource:
    """The frame source named by ``{factory, options}``: ``genicam``, a family's registered
    camera, or an allowed ``module:callable`` (plug-ins are code: docs/rigs.md)."""
    from calflow.gcs.sensors import builtin_sensors, resolve

    name, options = str(spec["factory"]), dict(spec.get("options") or {})
    target = {"genicam": "calflow.gcs.camera:genicam", **builtin_sensors()}.get(name, name)
    factory = resolve(target, name, "sensor.options.source.factory")
    try:
        source = factory(**options)
    except (TypeError, ValueError) as exc:
        raise RigError(f"gcs rig: sensor.options.source: {name!r} rejected the options ({exc})") from None
    missing = [m for m in ("grab", "close") if not callable(getattr(source, m, None))]
    if missing:
        raise RigError(
            f"gcs rig: sensor.options.source: {name!r} returned an object without {', '.join(missing)}"
        )
    return source


class GenICamCamera:
    """A GenICam camera through its GenTL producer (``.cti``) with harvesters."""

    def __init__(self, harvester, acquirer, timeout_s: float) -> None:
        self._h, self._ia, self.timeout_s = harvester, acquirer, timeout_s
        self._closed = False

    def grab(self) -> np.ndarray:
        with self._ia.fetch(timeout=self.timeout_s) as buffer:
            c = buffer.payload.components[0]
            return np.array(c.data, copy=True).reshape(c.height, c.width)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            try:
                self._ia.stop()
                self._ia.destroy()
            finally:
                self._h.reset()


def genicam(cti: str | None = None, serial: str | None = None, timeout_s: float = 5.0) -> GenICamCamera:
    """Frame source ``genicam``: the camera (first found, or ``serial``) of the GenTL producer
    ``cti`` (default: the first ``.cti`` on ``GENICAM_GENTL64_PATH``), started, with a
    ``timeout_s`` per frame. Stops in one line when no producer file is given or found, or
    harvesters is not installed."""
    cti = cti or _producer_on_path()
    if not cti:
        raise RigError(
            "gcs rig: camera 'genicam': no GenTL producer (.cti) file: set sensor.options.source.options.cti "
            "to your camera vendor's producer file, or GENICAM_GENTL64_PATH to its folder"
        )
    if not Path(cti).is_file():
        raise RigError(f"{cti}: gcs rig: camera 'genicam': the GenTL producer (.cti) file does not exist")
    try:
        from harvesters.core import Harvester
    except ImportError:
        raise RigError(
            f"gcs rig: camera 'genicam': the harvesters package is not installed: {INSTALL}"
        ) from None
    h = Harvester()
    try:
        h.add_file(str(cti))
        h.update()
        if not h.device_info_list:
            raise RigError(
                f"{cti}: gcs rig: camera 'genicam': the producer finds no camera (connected, powered?)"
            )
        ia = h.create({"serial_number": str(serial)}) if serial else h.create(0)
        ia.start()
    except RigError:
        h.reset()
        raise
    except Exception as exc:  # harvesters/GenTL errors: one line naming the producer
        h.reset()
        raise RigError(f"{cti}: gcs rig: camera 'genicam': cannot open the camera ({exc})") from None
    return GenICamCamera(h, ia, float(timeout_s))


def _producer_on_path() -> str | None:
    for folder in filter(None, os.environ.get("GENICAM_GENTL64_PATH", "").split(os.pathsep)):
        found = sorted(Path(folder).glob("*.cti")) if Path(folder).is_dir() else []
        if found:
            return str(found[0])
    return None
