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


def _campaign(tmp_path, extra: dict, pattern_file: str = "markers.json"):
    import tifffile

    (tmp_path / "markers.json").write_text(json.dumps(PATTERN.to_library_dict()))
    camera = Camera(**CAMERA)
    frames = []
    for k, ((cx, cy, turn), drift) in enumerate(zip(MOVES, DRIFT)):
        ref = _placed(REFERENCE[0], REFERENCE[1][0] + drift[0], REFERENCE[1][1] + drift[1], REFERENCE[2])
        moving = _placed(5, cx + drift[0], cy + drift[1], REFERENCE[2] + turn)
        frames.append(render(camera, PATTERN, [ref, moving], rng=k))
    tifffile.imwrite(tmp_path / "ident.tif", np.stack(frames), photometric="minisblack")
    lines = ["frame,time,cmd_x,cmd_y,cmd_theta,T1"]
    lines += [f"{k},{2.0 * k},{100.0 * k},{50.0 * k},{0.5 * k},{21.0 + 0.01 * k}" for k in range(len(MOVES))]
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
