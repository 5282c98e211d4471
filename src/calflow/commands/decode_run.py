"""``calflow decode-run``: a recording of camera frames decoded into a run dataset.

A replay campaign names, for a run id, a frame recording (docs/data.md, "Recorded
frames")::

    rig:
      factory: replay
      options:
        recordings:
          identification:
            file: data/ident.tif            # a TIFF stack, or a folder of image files
            format: frames
            table: data/ident.csv           # frame, time, cmd_<joint>, thermometers
            pattern: data/pattern.json      # the pattern file (calflow pattern make), any layout
            camera: {}                      # optional: camera-model fields (size, pixel, optics)
            marker: 1                       # HP-code markers: the one measured (default: the
            reference_marker: 0             #   lowest number seen) and the fixed one it is
                                            #   measured against (optional)
            pixel_size: sequence            # HP-code markers, no pixel size given: one pooled
                                            #   over the frames (default: frame, each its own)

The workflow's ``decode_frames`` rule runs this command into
``results/<campaign>/decoded/<run>.nc``, a run dataset: ``meas_*`` the decoded pose in the
pattern frame (Eq. 4.26) — with a reference marker, the reference's centre in the measured
marker's frame, so that the signs are a camera's — ``u_meas_*`` their standard uncertainties, ``decode_status``,
``frame_sha256``; the replay rig then serves it as the run (``calflow acquire --decoded``).
Frames stay in their files. A changed decoder reruns this rule; nothing reads the frames
again but it.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import DataError
from calflow.instruments.readings import flags
from calflow.instruments.recorded_frames import FrameFiles, file_sha256, load_pattern, read_table
from calflow.plan import Plan

CHUNK = 16  # frames read and decoded at once
AXES = ("x", "y", "theta")  # what the decoder measures: the camera point and the angle


def decode_recording(entry: dict, run_id: str, campaign: dict) -> xr.Dataset:
    """The run dataset of a frame recording ``entry`` (``{file, format: frames, table,
    pattern, camera}``) for run ``run_id`` of ``campaign`` (its robot, name and start)."""
    from calflow.data.conventions import robot_joints
    from calflow.data.recordings import entry as normalised
    from calflow.instruments.pattern.decode import field_of_view_problem
    from calflow.instruments.pattern.layouts import decode_frames
    from calflow.instruments.readings import camera_of, frame_shape, readings_of
    from calflow.provenance import package_digest

    e = normalised(entry)
    robot = campaign["robot"]
    joints = robot_joints(robot)
    axes = [a for a in AXES if a in joints]
    if not axes:
        raise DataError(
            f"rig.options.recordings.{run_id}: robot {robot!r} has none of the joints {list(AXES)} a camera over a pattern measures"
        )
    table = read_table(e["table"], joints)
    pattern = load_pattern(e["pattern"])
    camera = camera_of(e.get("camera") or {}, f"rig.options.recordings.{run_id}.camera")
    given = {"sensor_pixel_um", "magnification"} & set(e.get("camera") or {})
    if pattern.layout == "cell2x2" or given:  # else a lab's target whose pixel size each frame gives
        problem = field_of_view_problem(*frame_shape(camera), camera.pixel_um, pattern)
        if problem:  # before any frame is read
            raise DataError(f"{e['pattern']}: rig.options.recordings.{run_id}.camera: {problem}")
    frames = FrameFiles(e["file"], table.frame, frame_shape(camera))
    if pattern.layout == "cell2x2":
        options = {"camera": camera}
    else:  # a lab's target: the pixel size measured from each frame unless the camera says it
        options = {"pixel_um": camera.pixel_um} if given else {}
    options.update(_markers(e, pattern, run_id))
    pooled = _pooled_scale_wanted(e, pattern, given, run_id)
    where = f"rig.options.recordings.{run_id}"
    readings, shas, scale = [], [], None

    def add(r, start: int, count: int) -> None:
        for k in range(count):
            i = start + k
            reading = {"time": float(table.time_s[i])}
            reading.update({f"meas_{a}": float(r[f"meas_{a}"][k]) for a in axes})
            reading.update({f"u_meas_{a}": float(r[f"u_meas_{a}"][k]) for a in axes})
            reading["decode_status"] = float(r["decode_status"][k])
            reading.update({name: float(v[i]) for name, v in table.temperatures.items()})
            readings.append(reading)

    if pooled:  # every frame's markers first, then the poses at the sequence's pixel size
        d, shas, scale = _pooled_decode(frames, pattern, options, table.time_s, f"{e['file']}: {where}")
        add(readings_of(d), 0, len(table))
    else:
        for rows, block, digests in frames.chunks(CHUNK):
            try:
                if pattern.layout == "hpcode" and options.get("marker") is None:
                    options["marker"] = _first_marker(block, pattern, options)
                d = decode_frames(block, pattern, **options)
            except ValueError as exc:  # the camera cannot decode this pattern (field of view)
                raise DataError(f"{e['file']}: {where}: {exc}") from None
            add(readings_of(d), rows.start, len(block))
            shas += digests
    n = len(table)
    plan = Plan(
        name=run_id,
        commands=dict(table.commands),
        targets=dict(table.targets),
        pose=table.indices.get("pose", np.arange(n)),
        cycle=table.indices.get("cycle", np.zeros(n, int)),
        direction=table.indices.get("direction", np.zeros(n, int)),
        dwell_s=0.0,
    )
    meta = RunMetadata(
        campaign=campaign["name"],
        robot=robot,
        source="replay",
        plan=run_id,
        config_sha256=file_sha256(table.path),
        start=campaign["start"],
        extra={
            "imported_from": table.path.name,
            "frames": str(e["file"]),
            "frames_sha256": file_sha256(e["file"]) if frames.stack else _digest_of(shas),
            "pattern_sha256": file_sha256(e["pattern"]),
            "decoder_sha256": package_digest("calflow.instruments"),
            **{
                k: str(options[k])
                for k in ("marker", "reference")
                if options.get(k) is not None and pattern.layout == "hpcode"
            },
            **(scale.attrs() if scale is not None else {}),
        },
    )
    sensors = [f"meas_{a}" for a in axes] + [f"u_meas_{a}" for a in axes] + ["decode_status"]
    ds = run_dataset(readings, plan, sensors, tuple(table.temperatures), meta, flags(sensors))
    del ds.attrs["dwell_s"]  # the recording does not say
    ds["frame_sha256"] = xr.Variable(
        ("sample",),
        np.array(shas, dtype=object),
        attrs={"long_name": "SHA-256 of the frame (its file, or a stack page's pixels)"},
    )
    if table.recording_start:
        ds.attrs["recording_start"] = table.recording_start
    if any(f"meas_{a}" in ds and not np.isfinite(ds[f"meas_{a}"].values).any() for a in axes):
        raise DataError(
            f"{e['file']}: no frame of the recording decoded (decode_status gives each frame's reason)"
        )
    return ds


def _digest_of(shas: list[str]) -> str:
    import hashlib

    return hashlib.sha256("\n".join(shas).encode()).hexdigest()


def run(args) -> None:
    """``calflow decode-run --campaign C --run R --out F``."""
    from calflow.commands.common import campaign_of
    from calflow.data.io import output_folder, write_dataset

    c = campaign_of(args)
    recordings = (c["rig"].get("options") or {}).get("recordings")
    if c["rig"]["factory"] != "replay" or not isinstance(recordings, dict) or args.run not in recordings:
        raise DataError(
            f"{args.campaign}: key 'rig.options.recordings.{args.run}': no frame recording of this run"
        )
    output_folder(args.out)
    write_dataset(decode_recording(recordings[args.run], args.run, c), args.out)


def _markers(e: dict, pattern, run_id: str) -> dict:
    """The HP-code markers a recording names (``marker``, ``reference_marker``), refused in one
    line for a pattern of another layout."""
    named = {k: e.get(k) for k in ("marker", "reference_marker") if e.get(k) is not None}
    if named and pattern.layout != "hpcode":
        key = next(iter(named))
        raise DataError(
            f"{e['pattern']}: rig.options.recordings.{run_id}.{key}: only for HP-code markers "
            f"(layout hpcode); this pattern's layout is {pattern.layout!r}"
        )
    if pattern.layout != "hpcode":
        return {}
    return {"marker": e.get("marker"), "reference": e.get("reference_marker")}


def _pooled_scale_wanted(e: dict, pattern, given: set, run_id: str) -> bool:
    """Whether the recording asks for one pixel size pooled over its frames (``pixel_size:
    sequence``), refused in one line where it cannot apply."""
    if e.get("pixel_size", "frame") in (None, "frame"):
        return False
    key = f"rig.options.recordings.{run_id}.pixel_size"
    if pattern.layout != "hpcode":
        raise DataError(
            f"{e['pattern']}: {key}: 'sequence' pools HP-code markers' pixel sizes; this pattern's "
            f"layout is {pattern.layout!r} (expected layout hpcode, or no pixel_size)"
        )
    if given:
        raise DataError(
            f"{e['pattern']}: {key}: 'sequence' pools the frames' own pixel sizes, but the camera "
            f"gives one ({', '.join(sorted(given))}); expected one or the other"
        )
    return True


def _pooled_decode(frames, pattern, options: dict, time_s, where: str):
    """The recording's HP-code markers decoded chunk by chunk (only their poses are kept), one
    pixel size pooled over them (:func:`~calflow.instruments.pattern.hpcode.pool_pixel`, from
    the marker and its reference), and each frame's pose at that scale, its uncertainty in
    ``u_meas_x``/``u_meas_y``: (Decoded, frame digests, SequenceScale). The frames are
    decoded once; the pool rescales their lattices."""
    from calflow.instruments.pattern.hpcode import at_scale, decode_markers, pool_pixel, relative
    from calflow.instruments.pattern.stream import joined_markers

    marker, reference = options.get("marker"), options.get("reference")
    parts, shas = [], []
    for _, block, digests in frames.chunks(CHUNK):
        found = decode_markers(block, pattern)
        if marker is None:  # the rule of the frame-by-frame replay: the first chunk showing one
            marker = _lowest(found, reference)
        parts.append(found)
        shas += digests
    found = joined_markers(parts)
    options["marker"] = marker
    try:
        scale = pool_pixel(found, [marker, reference], time_s)
    except ValueError as exc:
        raise DataError(f"{where}.{exc}") from None
    if reference is None:
        d = at_scale(found, scale.pixel_um, scale.u_pixel_um).of(marker)
    else:
        d = relative(found, marker, reference, pattern.period_um, scale.pixel_um, scale.u_pixel_um)
    return d, shas, scale


def _lowest(found, reference) -> int | None:
    """The lowest marker number decoded in ``found``, the reference's left out; None if none."""
    numbers = set(found.number[found.status == "ok"].tolist()) - {reference, -1}
    return min(numbers) if numbers else None


def _first_marker(block, pattern, options: dict) -> int | None:
    """The lowest marker number decoded in the frames (the reference's left out), so that every
    chunk of the recording measures the same marker; None while none is seen."""
    from calflow.instruments.pattern.hpcode import decode_markers

    return _lowest(decode_markers(block, pattern, options.get("pixel_um")), options.get("reference"))
