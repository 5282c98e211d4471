"""A recording of frames holding two HP-code markers replayed relative to the fixed one: the
library's pattern file, a TIFF stack and its joints table decoded into a run dataset
(``calflow decode-run``, the workflow's ``decode_frames`` rule) whose measurement is the
moving marker's pose against the reference marker in the same frames, so that what moves
both (the microscope drifting, the camera shaking) drops out. Frames are drawn by calflow's
own renderer: few and small."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from conftest import SMALL_XYTHETA

from calflow.cli import main
from calflow.data.io import open_dataset
from calflow.data.validate import validate_dataset
from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.hpcode import HPCodePattern
from calflow.instruments.pattern.hpcode.render import render

CAMERA = {"width": 640, "height": 560}  # 0.375 µm pixels (the camera model's default optics)
PATTERN = HPCodePattern(4.0, 17)
REFERENCE = (0, (-60.0, 0.0), 2.0)  # number, centre (µm from the frame centre), Θ (degree)
# the moving marker's centre and turn per frame; the whole frame also shifts (drift)
MOVES = np.array([[55.0, 0.0, 0.0], [56.5, -1.25, 0.3], [54.0, 2.0, -0.5], [57.0, 1.0, 1.0]])
DRIFT = np.array([[0.0, 0.0], [0.7, -0.4], [1.5, 0.2], [-0.8, 0.9]])


def _placed(number, cx, cy, theta):
    t = math.radians(theta)
    return number, -(math.cos(t) * cx + math.sin(t) * cy), -(-math.sin(t) * cx + math.cos(t) * cy), theta


def _truth():
    """The reference's centre in the moving marker's frame (µm) and the angle, per frame: what
    the run must measure — the readings of a camera in the reference's place (Eq. 4.26: the
    angle read is minus the marker's turn seen from the reference)."""
    out = []
    for cx, cy, turn in MOVES:
        t = math.radians(REFERENCE[2] + turn)
        d = np.array(REFERENCE[1]) - (cx, cy)  # the drift moves both: it drops out
        out.append([math.cos(t) * d[0] + math.sin(t) * d[1], -math.sin(t) * d[0] + math.cos(t) * d[1], -turn])
    return np.array(out)


def _campaign(tmp_path, extra: dict, pattern_file: str = "markers.json", magnifications=None):
    """The campaign of a recording of the moves above; with ``magnifications``, one frame each
    (the moves repeated), drawn at that magnification (the recording's camera does not say)."""
    import tifffile

    (tmp_path / "markers.json").write_text(json.dumps(PATTERN.to_library_dict()))
    cameras = (
        [Camera(**CAMERA)] * len(MOVES)
        if magnifications is None
        else [Camera(**CAMERA, magnification=m) for m in magnifications]
    )
    frames = []
    for k, camera in enumerate(cameras):
        (cx, cy, turn), drift = MOVES[k % len(MOVES)], DRIFT[k % len(MOVES)]
        ref = _placed(REFERENCE[0], REFERENCE[1][0] + drift[0], REFERENCE[1][1] + drift[1], REFERENCE[2])
        moving = _placed(5, cx + drift[0], cy + drift[1], REFERENCE[2] + turn)
        frames.append(render(camera, PATTERN, [ref, moving], rng=k))
    tifffile.imwrite(tmp_path / "ident.tif", np.stack(frames), photometric="minisblack")
    lines = ["frame,time,cmd_x,cmd_y,cmd_theta,T1"]
    lines += [f"{k},{2.0 * k},{100.0 * k},{50.0 * k},{0.5 * k},{21.0 + 0.01 * k}" for k in range(len(frames))]
    (tmp_path / "ident.csv").write_text("\n".join(lines) + "\n")
    c = yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))
    entry = {
        "file": str(tmp_path / "ident.tif"),
        "format": "frames",
        "table": str(tmp_path / "ident.csv"),
        "pattern": str(tmp_path / pattern_file),
        "camera": CAMERA,
        **extra,
    }
    c["rig"] = {"factory": "replay", "options": {"recordings": {"identification": entry}}}
    path = tmp_path / "markers-frames.yaml"
    path.write_text(yaml.safe_dump(c))
    return path


@pytest.mark.parametrize("marker", [{"marker": 5}, {}], ids=["marker named", "marker found"])
def test_frames_decode_relative_to_the_reference_marker(tmp_path, marker):
    campaign = _campaign(tmp_path, {**marker, "reference_marker": 0})
    decoded = tmp_path / "decoded" / "identification.nc"
    args = ["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(decoded)]
    assert main(args) == 0
    ds = open_dataset(decoded, kind="run")
    assert validate_dataset(ds) == []
    assert np.all(ds["decode_status"].values == 0)
    truth = _truth()
    assert np.max(np.abs(ds["meas_x"].values - truth[:, 0])) < 0.05
    assert np.max(np.abs(ds["meas_y"].values - truth[:, 1])) < 0.05
    assert np.max(np.abs(ds["meas_theta"].values - truth[:, 2])) < 0.01
    assert ds.attrs["reference"] == "0" and ds.attrs["marker"] == "5"


def test_markers_named_for_another_layout_are_refused_in_one_line(tmp_path, capsys):
    from calflow.instruments.pattern.megarena import MegarenaPattern

    campaign = _campaign(tmp_path, {"reference_marker": 0}, "megarena.json")
    (tmp_path / "megarena.json").write_text(json.dumps(MegarenaPattern(4.0, 6).to_library_dict()))
    decoded = tmp_path / "decoded" / "identification.nc"
    args = ["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(decoded)]
    assert main(args) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reference_marker" in err[0] and "hpcode" in err[0]
    assert not decoded.exists()


def test_a_marker_number_must_be_a_number(tmp_path, capsys):
    campaign = _campaign(tmp_path, {"marker": "five", "reference_marker": 0})
    args = [
        "decode-run",
        "--campaign",
        str(campaign),
        "--run",
        "identification",
        "--out",
        str(tmp_path / "d.nc"),
    ]
    assert main(args) != 0
    assert ".marker" in capsys.readouterr().err


# -- one pixel size pooled over the recording (pixel_size: sequence) ---------------------------
def _decode(tmp_path, campaign, capsys=None):
    out = tmp_path / "decoded" / "identification.nc"
    code = main(["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(out)])
    return code, out


def test_a_pooled_pixel_size_is_the_recordings_scale_and_its_record(tmp_path):
    # one known pixel size, each frame's own noise (the renderer's shot and read noise)
    mags = [Camera(**CAMERA).magnification] * 8
    campaign = _campaign(tmp_path, {"reference_marker": 0, "pixel_size": "sequence"}, magnifications=mags)
    code, out = _decode(tmp_path, campaign)
    assert code == 0
    ds = open_dataset(out, kind="run")
    assert validate_dataset(ds) == []
    assert np.all(ds["decode_status"].values == 0)
    truth = np.tile(_truth(), (2, 1))
    assert np.max(np.abs(ds["meas_x"].values - truth[:, 0])) < 0.05
    assert np.max(np.abs(ds["meas_y"].values - truth[:, 1])) < 0.05
    pixel = np.mean([Camera(**CAMERA, magnification=m).pixel_um for m in mags])
    a = ds.attrs
    assert a["pixel_size"] == "sequence" and a["pixel_size_frames"] == 8 and a["marker"] == "5"
    # within its uncertainty, beside the fit's known edge bias on calflow's renders (-1 to -3e-4)
    assert abs(a["pixel_size_um"] / pixel - 1) < 3 * a["u_pixel_size_um"] / pixel + 4e-4
    assert a["u_pixel_size_um"] > 0
    assert a["pixel_size_drifts"] == "no" and "pooled over 8 frames" in a["pixel_size_statement"]
    # the scale's uncertainty is in u_meas: at least the markers' separation times it
    sep = np.hypot(ds["meas_x"].values, ds["meas_y"].values)
    assert np.all(
        ds["u_meas_x"].values ** 2 + ds["u_meas_y"].values ** 2
        >= (sep * a["u_pixel_size_um"] / a["pixel_size_um"]) ** 2
    )
    # the replay rig serves the run with the pool's record, and the report's summary says it
    from calflow.xytheta.report.instrument import decode_counts

    run = tmp_path / "runs" / "identification.nc"
    argv = ["acquire", "--campaign", str(campaign), "--plan", "identification", "--decoded", str(out)]
    assert main([*argv, "--out", str(run)]) == 0
    served = open_dataset(run, kind="run")
    assert served.attrs["pixel_size_statement"] == a["pixel_size_statement"]
    (said,) = decode_counts([served]).values()
    assert said["pixel_size"]["um"] == a["pixel_size_um"] and said["pixel_size"]["drifts"] is False


def test_a_pooled_pixel_size_scales_one_marker_alone(tmp_path):
    campaign = _campaign(
        tmp_path, {"marker": 5, "pixel_size": "sequence"}, magnifications=[Camera(**CAMERA).magnification] * 5
    )
    code, out = _decode(tmp_path, campaign)
    assert code == 0
    ds = open_dataset(out, kind="run")
    a = ds.attrs
    assert a["pixel_size"] == "sequence" and a["pixel_size_frames"] == 5
    # the frame centre in the moving marker's frame, as drawn
    moves = [(MOVES[k % 4], DRIFT[k % 4]) for k in range(5)]
    want = np.array([_placed(5, m[0] + d[0], m[1] + d[1], REFERENCE[2] + m[2])[1:3] for m, d in moves])
    assert np.max(np.hypot(ds["meas_x"].values - want[:, 0], ds["meas_y"].values - want[:, 1])) < 0.05
    rel = a["u_pixel_size_um"] / a["pixel_size_um"]
    assert np.all(ds["u_meas_x"].values >= np.abs(ds["meas_x"].values) * rel * (1 - 1e-9))


def test_a_drifting_magnification_is_said_in_the_record(tmp_path):
    base = Camera(**CAMERA).magnification
    campaign = _campaign(
        tmp_path,
        {"reference_marker": 0, "pixel_size": "sequence"},
        magnifications=base * (1 + np.linspace(0, 4e-3, 8)),
    )
    code, out = _decode(tmp_path, campaign)
    assert code == 0
    a = open_dataset(out, kind="run").attrs
    assert a["pixel_size_drifts"] == "yes" and set(a["pixel_size_trend_markers"].split(",")) == {"0", "5"}
    assert "The magnification drifts" in a["pixel_size_statement"]


@pytest.mark.parametrize(
    "extra, pattern_file, words",
    [
        ({"pixel_size": "median"}, "markers.json", "pixel_size': expected 'frame'"),
        (
            {"pixel_size": "sequence", "camera": {**CAMERA, "magnification": 16.0}},
            "markers.json",
            "the camera gives one",
        ),
        ({"pixel_size": "sequence"}, "megarena.json", "layout is 'megarena'"),
    ],
    ids=["unknown", "camera gives one", "megarena"],
)
def test_a_pooled_pixel_size_is_refused_where_it_cannot_apply(tmp_path, capsys, extra, pattern_file, words):
    from calflow.instruments.pattern.megarena import MegarenaPattern

    campaign = _campaign(tmp_path, extra, pattern_file, magnifications=[Camera(**CAMERA).magnification] * 5)
    (tmp_path / "megarena.json").write_text(json.dumps(MegarenaPattern(4.0, 6).to_library_dict()))
    code, out = _decode(tmp_path, campaign)
    assert code != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pixel_size" in err[0] and words in err[0], err
    assert not out.exists()
