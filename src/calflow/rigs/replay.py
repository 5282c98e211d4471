"""Replay of recorded run files: a rig that serves what a run dataset recorded.

A replay rig stands in for the rig that made a recording. It is given the run files
of a campaign (a ``results/<campaign>/runs/`` folder of ``<run id>.nc`` files, or a
mapping run id → file) and the run id to serve (``stream``). Acquisition drives it
like any rig; each ``move`` advances to the next recorded sample and must command
exactly the recorded joint positions (within ``tolerance_um``), otherwise the replay
raises :class:`~calflow.errors.RigError` — a replay never serves the wrong pose. A
recording must meet the data contract (:func:`calflow.data.validate.validate_dataset`:
units µm / degree / degC, finite non-decreasing ``time``, the robot's ``meas_*``, not all
NaN) or it is refused when the rig is opened.
``read`` returns the recorded ``time`` (s since the campaign start), sensor readings
(µm, degree; NaN preserved) and temperatures (degC) of the current sample. Time is
that of the recording, so ``wait`` does not change it.

A replay of a recorded campaign with the same plans reproduces its run datasets, and
so its analysis, exactly.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from calflow.data.conventions import robot_joints
from calflow.data.io import open_dataset
from calflow.errors import CalflowError, OptionError, RigError

RUN_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]*")  # a run's file name (runs/<run id>.nc)


def _resolve(recordings: str | os.PathLike | Mapping[str, object], stream: str):
    """The recording of run id ``stream`` among ``recordings``: a run file's path, or a
    recording entry of a mapping (:func:`calflow.data.recordings.load`)."""
    if isinstance(recordings, Mapping):
        files = {str(k): v for k, v in recordings.items()}
        where = "replay recordings"
    else:
        folder = Path(recordings)
        if not folder.is_dir():
            raise RigError(f"{folder}: replay recordings: expected a folder of <run id>.nc run files")
        files = {p.stem: p for p in sorted(folder.glob("*.nc"))}
        where = str(folder)
    if not stream:
        if len(files) == 1:
            return next(iter(files.values()))
        raise RigError(f"{where}: replay stream: expected a run id, one of {sorted(files)}")
    if stream not in files:
        raise RigError(
            f"{where}: replay stream {stream!r}: no recording; recorded run ids are {sorted(files)}"
        )
    return files[stream]


class ReplayRig:
    """Serves one recorded run dataset through the rig protocol (docs/rigs.md).

    ``joints`` are the recorded ``cmd_*`` variables, ``sensors`` the ``meas_*``
    variables (and, from an image sensor, their ``u_meas_*`` and ``decode_status``), ``thermometers`` the ``sensor`` coordinate of ``temperature``.
    Commands are compared with the recording within ``tolerance`` in each joint's
    own unit (µm for translations, degree for rotations).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        stream: str = "",
        tolerance: float = 1e-6,
        dataset=None,
        recorded_plan=None,
    ):
        self.path = Path(path)
        self.stream = stream or self.path.stem
        self.tolerance = float(tolerance)
        #: the plan an instrument's own recording ran (ISO 230-2 file, tracker export, CSV):
        #: acquisition commands it instead of the campaign's; None for calflow run files.
        self.recorded_plan = recorded_plan
        try:
            ds = open_dataset(self.path, kind="run") if dataset is None else dataset
        except CalflowError as exc:
            raise RigError(f"replay: {exc}") from None
        from calflow.data.validate import validate_dataset

        problems = validate_dataset(ds)  # the data contract, units included: a replay serves µm and degree
        if problems:
            more = (
                f" (and {len(problems) - 1} more; calflow validate {self.path} lists them)"
                if len(problems) > 1
                else ""
            )
            raise RigError(f"{self.path}: replay: {problems[0]}{more}")
        self.attrs = dict(ds.attrs)
        self.units = {name: str(ds[name].attrs.get("units", "")) for name in ds.data_vars}
        order = robot_joints(str(ds.attrs.get("robot")))
        cmd = [n[4:] for n in ds.data_vars if n.startswith("cmd_")]
        self.joints = tuple([j for j in order if j in cmd] + [j for j in cmd if j not in order])
        meas = [n for n in ds.data_vars if n.startswith("meas_")]
        ordered = [f"meas_{j}" for j in order if f"meas_{j}" in meas]
        ordered += [m for m in meas if m not in ordered]
        decoder = [f"u_{m}" for m in ordered if f"u_{m}" in ds.data_vars]  # an image sensor's decoder
        decoder += ["decode_status"] if "decode_status" in ds.data_vars else []
        self.sensors = tuple(ordered + decoder)
        if "temperature" in ds.data_vars:
            if ds["temperature"].dims != ("sample", "sensor") or "sensor" not in ds.coords:
                raise RigError(
                    f"{self.path}: variable 'temperature': expected dims ('sample', 'sensor') "
                    f"with a 'sensor' coordinate, got {ds['temperature'].dims}"
                )
            self.thermometers = tuple(str(s) for s in ds["sensor"].values)
            self._temps = np.asarray(ds["temperature"].values, dtype=float)
        else:
            self.thermometers = ()
            self._temps = np.zeros((ds.sizes.get("sample", 0), 0))
        if "time" not in ds.variables or "sample" not in ds.dims:
            raise RigError(f"{self.path}: replay: expected a 'time' variable along dimension 'sample'")
        if not self.joints:
            raise RigError(f"{self.path}: replay: the recording has no cmd_* variables to replay")
        self.n = int(ds.sizes["sample"])
        self._time = np.asarray(ds["time"].values, dtype=float)
        self._cmd = {j: np.asarray(ds[f"cmd_{j}"].values, dtype=float) for j in self.joints}
        self._meas = {s: np.asarray(ds[s].values, dtype=float) for s in self.sensors}
        self._i = -1  # index of the current sample; -1 before the first move
        self._closed = False

    @property
    def served(self) -> int:
        """Number of recorded samples moved to so far."""
        return self._i + 1

    @property
    def exhausted(self) -> bool:
        """True when every recorded sample has been served."""
        return self._i + 1 >= self.n

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise RigError(f"{self.path}: replay: {what} after close()")

    def move(self, command: Mapping[str, float]) -> None:
        """Advance to the next recorded sample; its ``cmd_*`` must equal ``command``.

        Raises :class:`RigError` naming the file, the sample index (0-based), the joint
        and the recorded and requested values when they differ by more than the
        tolerance, when ``command`` lacks a recorded joint or names another one, or when
        the recording has no more samples.
        """
        self._check_open("move()")
        i = self._i + 1
        if i >= self.n:
            raise RigError(
                f"{self.path}: replay: move() past the end of the recording "
                f"({self.n} samples); the plan has more rows than the recorded run"
            )
        unknown = sorted(set(command) - set(self.joints))
        if unknown:
            raise RigError(
                f"{self.path}: sample {i}: command names joint(s) {unknown} "
                f"the recording does not have {list(self.joints)}"
            )
        for joint in self.joints:
            if joint not in command:
                raise RigError(f"{self.path}: sample {i}: command lacks joint {joint!r}")
            recorded = float(self._cmd[joint][i])
            requested = float(command[joint])
            same = (math.isnan(recorded) and math.isnan(requested)) or abs(
                recorded - requested
            ) <= self.tolerance
            if not same:
                unit = {"um": "µm"}.get(
                    self.units.get(f"cmd_{joint}", ""), self.units.get(f"cmd_{joint}", "")
                )
                raise RigError(
                    f"{self.path}: sample {i}: joint {joint!r}: recorded command {recorded!r} {unit}, "
                    f"requested {requested!r} {unit} (tolerance {self.tolerance:g} {unit}); "
                    "the replayed plan differs from the recorded one"
                )
        self._i = i

    def wait(self, seconds: float) -> None:
        """No-op: time comes from the recording."""
        self._check_open("wait()")

    def read(self) -> dict[str, float]:
        """The recorded ``time`` (s), sensors (µm, degree) and temperatures (degC) of the current sample."""
        self._check_open("read()")
        i = self._i
        if i < 0:
            raise RigError(
                f"{self.path}: replay: read() before the first move(); "
                "a recording has readings of settled poses only"
            )
        if i >= self.n:  # cannot happen through move(), kept as a guard
            raise RigError(f"{self.path}: replay: read() past the end of the recording ({self.n} samples)")
        reading = {"time": float(self._time[i])}
        for sensor in self.sensors:
            reading[sensor] = float(self._meas[sensor][i])
        for k, name in enumerate(self.thermometers):
            reading[name] = float(self._temps[i, k])
        return reading

    def close(self) -> None:
        self._closed = True

    def truth(self) -> dict:
        """The truth recorded beside the runs (``../truth/<run id>.json``), else ``{"available": False}``."""
        folder = self.path.parent.parent / "truth"
        for name in dict.fromkeys((self.stream, self.path.stem)):
            candidate = folder / f"{name}.json"
            if candidate.is_file():
                try:
                    return json.loads(candidate.read_text(encoding="utf-8"))
                except (OSError, ValueError) as exc:
                    raise RigError(f"{candidate}: replay truth: not readable JSON ({exc})") from None
        return {"available": False}


def replay(
    recordings: str | os.PathLike | Mapping[str, object],
    stream: str = "",
    tolerance_um: float = 1e-6,
    seed: int | None = None,
    campaign_start: str | None = None,
    decoded: str | None = None,
) -> ReplayRig:
    """Factory of the replay rig (``rig: {factory: replay, options: {recordings: ...}}``).

    ``recordings`` is a folder of ``<run id>.nc`` run files (a campaign's
    ``results/<campaign>/runs/``) or a mapping run id → recording: a run file, or an
    instrument's file (``{file, format[, mapping]}``, :mod:`calflow.data.recordings`:
    ISO 230-2 ``.dat``, laser-tracker or mapped CSV), served with the plan it recorded
    (``ReplayRig.recorded_plan``); ``stream`` is the run id
    to serve (``identification``, ``validation_<model>``, …), optional when there is a
    single recording. ``tolerance_um`` is the largest accepted difference between a
    command and the recorded one, in each joint's unit (µm; degree for rotations).
    ``seed`` is accepted and ignored: a recording has no randomness left.
    ``campaign_start`` (ISO 8601, given by ``calflow acquire``): an instrument's recording
    with a clock is served in seconds since it, not since its own first timestamp.
    ``decoded``: the run file a ``frames`` recording was decoded into (``calflow
    decode-run``; ``calflow acquire --decoded`` gives it).
    """
    del seed
    tolerance = float(tolerance_um)
    if not tolerance >= 0:
        raise RigError(f"rig.options.tolerance_um: expected a number >= 0, got {tolerance_um!r}")
    entry = _resolve(recordings, stream)
    if not isinstance(recordings, Mapping):
        return ReplayRig(entry, stream=stream, tolerance=tolerance)
    from calflow.data.recordings import in_campaign_time, load

    try:
        path, ds, plan = load(entry, stream or next(iter(recordings)), "rig.options.recordings", decoded)
        if ds is not None and campaign_start:
            ds = in_campaign_time(ds, campaign_start)
    except CalflowError as exc:
        raise RigError(str(exc)) from None
    return ReplayRig(path, stream=stream, tolerance=tolerance, dataset=ds, recorded_plan=plan)


def check_options(
    recordings=None,
    stream: str = "",
    tolerance_um: float = 1e-6,
    seed=None,
    campaign_start=None,
    decoded=None,
) -> None:
    """The config check of the replay rig's options (:func:`calflow.configuration.rig_factory.check_rig`):
    ``recordings`` given, each entry of a mapping well formed and its files present (a frame
    recording's camera-model fields too), the tolerance a number >= 0. Recordings are read
    when a run is acquired or decoded, not here."""
    from calflow.data.recordings import BadEntry, check_entry

    if isinstance(recordings, Mapping):
        for run_id, spec in recordings.items():
            if not (isinstance(run_id, str) and RUN_ID.fullmatch(run_id)):
                raise OptionError(
                    "recordings", "run ids of letters, digits, '-' or '_' (a run's file name)", run_id
                )
            try:
                check_entry(spec)
            except BadEntry as exc:
                raise OptionError(f"recordings.{run_id}{exc.key}", exc.expected, exc.value) from None
            if isinstance(spec, Mapping) and spec.get("format") == "frames":
                _check_camera(run_id, spec.get("camera"))
    elif not isinstance(recordings, (str, os.PathLike)) or not str(recordings):
        raise OptionError(
            "recordings", "a folder of <run id>.nc run files or a mapping run id -> recording", recordings
        )
    if (
        isinstance(tolerance_um, bool)
        or not isinstance(tolerance_um, (int, float))
        or not tolerance_um >= 0
        or not math.isfinite(tolerance_um)
    ):
        raise OptionError("tolerance_um", "a finite number >= 0 (µm; degree for rotations)", tolerance_um)
    if not isinstance(stream, str):
        raise OptionError("stream", "a run id (string)", stream)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise OptionError("seed", "an integer", seed)


class _CameraFields(ValueError):
    pass


def _check_camera(run_id: str, fields) -> None:
    """A frame recording's ``camera`` fields, as the decoder's camera model takes them
    (:func:`calflow.instruments.readings.camera_of`); nothing of the recording is read."""
    from calflow.instruments.readings import camera_of

    try:
        camera_of(fields or {}, "camera", error=_CameraFields)
    except _CameraFields as exc:
        raise OptionError(
            f"recordings.{run_id}.camera", f"fields the camera model takes ({exc})", fields
        ) from None
