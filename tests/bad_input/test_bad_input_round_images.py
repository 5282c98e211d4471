"""Bad inputs of camera images, written as a new user writes them: the simulated rig's
``sensor: images`` (:data:`IMAGE_CAMPAIGNS`) and recorded camera frames (``format: frames``,
:data:`FRAMES`). Each is refused in one line naming the file, the key and what was expected,
before anything is written: what the campaign file says when it is loaded, before any job;
what a recording's files hold (validation reads no data file) by the step that reads them,
``calflow decode-run`` (the rest of the round: ``test_bad_input_round.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_bad_input_campaigns import _project, case
from test_bad_input_round import _campaign, assert_refused_at_load, pattern_file_text

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError

IMAGES = "xytheta-images"

IMAGE_CAMPAIGNS = [
    case(
        "images: sensor misspelt",
        IMAGES,
        "    sensor: images",
        "    sensor: image",
        "key 'rig.options.sensor'",
        "['model', 'images']",
    ),
    case(
        "images: camera a string",
        IMAGES,
        "camera: {width: 512, height: 384, magnification: 5.0}",
        "camera: basler",
        "key 'rig.options.camera'",
        "a mapping of camera-model fields",
    ),
    case(
        "images: unknown camera field",
        IMAGES,
        "magnification: 5.0}",
        "magnification: 5.0, zoom: 2}",
        "key 'rig.options.camera'",
        "camera.zoom: unknown camera-model field",
    ),
    case(
        "images: camera width 0",
        IMAGES,
        "width: 512",
        "width: 0",
        "key 'rig.options.camera'",
        "Camera.width: expected a positive integer, got 0",
    ),
    case(
        "images: camera width 512.5",
        IMAGES,
        "width: 512",
        "width: 512.5",
        "key 'rig.options.camera'",
        "got 512.5",
    ),
    case(
        "images: camera width as text",
        IMAGES,
        "width: 512",
        "width: '512'",
        "key 'rig.options.camera'",
        "got '512'",
    ),
    case(
        "images: camera width 1e308",
        IMAGES,
        "width: 512",
        "width: 1e308",
        "key 'rig.options.camera'",
        "Camera.width: expected a positive integer",
    ),
    case(
        "images: camera width true",
        IMAGES,
        "width: 512",
        "width: true",
        "key 'rig.options.camera'",
        "got True",
    ),
    case(
        "images: magnification NaN",
        IMAGES,
        "magnification: 5.0",
        "magnification: .nan",
        "key 'rig.options.camera.magnification'",
        "a finite number",
    ),
    case(
        "images: pattern file missing",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/nope.json",
        "key 'rig.options.pattern'",
        "an existing pattern file",
    ),
    case(
        "images: pattern file not one",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/p.json",
        "key 'rig.options.pattern'",
        "data/p.json: format: expected 'calflow-pattern'",
        files={"data/p.json": "{}"},
    ),
    case(
        "images: pattern file not JSON",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/p.json",
        "key 'rig.options.pattern'",
        "not a calflow pattern file",
        files={"data/p.json": "{no"},
    ),
    case(
        "images: pattern smaller than the rig's range",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/pattern.json",
        "key 'rig.options.pattern'",
        "covers the rig's pattern_range_um [9500.0, 4200.0]",
        files={"data/pattern.json": "PATTERN"},
    ),
    case(
        "images: camera too small for the pattern file",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern_range_um: [1500, 1500]\n    pattern: data/pattern.json",
        "key 'rig.options.camera'",
        "needs a field of view",
        files={"data/pattern.json": "PATTERN", "SMALL_CAMERA": ""},
    ),
    case(
        "images: camera too small for the default pattern",
        IMAGES,
        "width: 512, height: 384",
        "width: 32, height: 24",
        "key 'rig.options.camera'",
        "the default pattern",
        "needs a field of view",
    ),
]

# recorded camera frames: a replay of the images campaign's identification run
FRAMES_RIG = (
    "rig:\n  factory: replay\n  options:\n    recordings:\n      identification:\n"
    "        file: data/ident.tif\n        format: frames\n        table: data/ident.csv\n"
    "        pattern: data/pattern.json\n        camera: {width: 352, height: 272, magnification: 5.0}\n"
)
TABLE = "frame,time,cmd_x,cmd_y,cmd_theta,T1\n" + "".join(
    f"{k},{2.0 * k},{100.0 * k},{50.0 * k},{0.5 * k},21.0\n" for k in range(4)
)


def frames(name, old, new, *expected, table=TABLE, stack=4, folder=None, pattern=None, at="decode"):
    """A frame recording with one thing changed: the campaign's text, the table, the stack's
    page count (None: no stack), a folder of frames (file names), the pattern file's text;
    refused ``at`` load (what the campaign file says, the files' presence) or by the decoding
    (what the files hold)."""
    return pytest.param(old, new, expected, table, stack, folder, pattern, at, id=name)


FRAMES = [
    frames(
        "frames: table missing",
        None,
        None,
        "key 'rig.options.recordings.identification.table'",
        "an existing file",
        table=None,
        at="load",
    ),
    frames(
        "frames: table without cmd_theta",
        None,
        None,
        "data/ident.csv: joints table: column 'cmd_theta' missing",
        table=TABLE.replace("cmd_theta", "theta"),
    ),
    frames(
        "frames: table without time",
        None,
        None,
        "joints table: column 'time' missing",
        table=TABLE.replace(",time,", ",t,"),
    ),
    frames("frames: table empty", None, None, "joints table: expected a header row", table=""),
    frames(
        "frames: table of a header only",
        None,
        None,
        "expected one row per frame, got none",
        table=TABLE.splitlines()[0] + "\n",
    ),
    frames(
        "frames: a thermometer cell not a number",
        None,
        None,
        "data/ident.csv: row 2, column 'T1'",
        "expected a number, got 'warm'",
        table=TABLE.replace(",21.0\n", ",warm\n", 1),
    ),
    frames(
        "frames: 5 rows for a stack of 4",
        None,
        None,
        "data/ident.tif: TIFF stack of 4 frames",
        "the joints table has 5 rows",
        table=TABLE + "4,8.0,400,200,2.0,21.0\n",
    ),
    frames(
        "frames: stack not a TIFF", None, None, "data/ident.tif: frames: not a readable TIFF stack", stack=-1
    ),
    frames(
        "frames: stack truncated", None, None, "data/ident.tif: frames: not a readable TIFF stack", stack=-2
    ),
    frames(
        "frames: an empty folder",
        "data/ident.tif",
        "data/frames",
        "data/frames: frame 'f0.png' (table row 2): expected an image file in the folder",
        folder=[],
        table=TABLE.replace("\n0,", "\nf0.png,"),
    ),
    frames(
        "frames: a folder frame named '../x.png'",
        "data/ident.tif",
        "data/frames",
        "frame '../x.png' (table row 2): expected an image file in the folder",
        folder=["x.png"],
        table=TABLE.replace("\n0,", "\n../x.png,"),
    ),
    frames(
        "frames: pattern file missing",
        None,
        None,
        "key 'rig.options.recordings.identification.pattern'",
        "an existing file",
        pattern="",
        at="load",
    ),
    frames(
        "frames: pattern not JSON",
        None,
        None,
        "data/pattern.json: not a calflow pattern file",
        pattern="{not json",
    ),
    frames(
        "frames: pattern of another format",
        None,
        None,
        "data/pattern.json: format: expected 'calflow-pattern'",
        pattern='{"format": "other"}',
    ),
    frames(
        "frames: unknown camera field",
        "magnification: 5.0}",
        "magnification: 5.0, zoom: 2}",
        "camera.zoom: unknown camera-model field",
        at="load",
    ),
    frames(
        "frames: camera width 0",
        "width: 352",
        "width: 0",
        "Camera.width: expected a positive integer",
        at="load",
    ),
    frames("frames: camera width as text", "width: 352", "width: '352'", "got '352'", at="load"),
    frames(
        "frames: camera of another size than the frames",
        "width: 352",
        "width: 400",
        "data/ident.tif: page 0: expected 400 × 272 pixels",
        "got 352 × 272",
    ),
    frames(
        "frames: camera too small for the pattern",
        "width: 352, height: 272",
        "width: 64, height: 64",
        "data/pattern.json: rig.options.recordings.identification.camera",
        "needs a field of view",
    ),
    frames(
        "frames: format misspelt",
        "format: frames",
        "format: frame",
        "key 'rig.options.recordings.identification.format'",
        "expected one of",
        "got 'frame'",
        at="load",
    ),
    frames(
        "frames: run id misspelt",
        "      identification:",
        "      identificaton:",
        "key 'rig.options.recordings.identificaton': expected a run this campaign acquires",
        at="load",
    ),
    frames(
        "frames: run id with '..'",
        "      identification:",
        "      ../identification:",
        "key 'rig.options.recordings'",
        "run ids of letters, digits",
        "got '../identification'",
        at="load",
    ),
]


@pytest.fixture(scope="module")
def rendered():
    return {"pattern": pattern_file_text()}


@pytest.mark.parametrize("base, old, new, expected, files", IMAGE_CAMPAIGNS)
def test_a_bad_images_campaign_is_refused_at_load(
    tmp_path, monkeypatch, rendered, base, old, new, expected, files
):
    assert_refused_at_load(_campaign(tmp_path, monkeypatch, base, old, new, files, rendered), expected)


def _frames_project(tmp_path, monkeypatch, rendered, table, stack, folder, pattern) -> Path:
    import tifffile

    _project(tmp_path, monkeypatch)
    data = tmp_path / "data"
    data.mkdir()
    if table is not None:
        (data / "ident.csv").write_text(table, encoding="utf-8")
    if pattern != "":
        (data / "pattern.json").write_text(
            rendered["pattern"] if pattern is None else pattern, encoding="utf-8"
        )
    if stack == -1:
        (data / "ident.tif").write_text("hello\n")
    elif stack:
        tifffile.imwrite(data / "ident.tif", np.zeros((4, 272, 352), np.uint16), photometric="minisblack")
        if stack == -2:
            raw = (data / "ident.tif").read_bytes()
            (data / "ident.tif").write_bytes(raw[: len(raw) // 2])
    if folder is not None:
        (data / "frames").mkdir()
        for name in folder:
            (data / name).write_bytes(b"")  # beside the folder, not in it
    return tmp_path / "config" / "campaigns"


def _frames_campaign(campaigns: Path) -> str:
    """The images campaign's text with its rig replaced by :data:`FRAMES_RIG`."""
    text = (campaigns / f"{IMAGES}.yaml").read_text(encoding="utf-8")
    return text[: text.index("rig:\n")] + FRAMES_RIG + text[text.index("characterisation:") :]


LOAD = [p for p in FRAMES if p.values[-1] == "load"]  # what the campaign file says
DECODE = [p for p in FRAMES if p.values[-1] == "decode"]  # what the recording's files hold


def _bad_frames(tmp_path, monkeypatch, rendered, old, new, table, stack, folder, pattern) -> Path:
    campaigns = _frames_project(tmp_path, monkeypatch, rendered, table, stack, folder, pattern)
    text = _frames_campaign(campaigns)
    if old is not None:
        assert old in text
        text = text.replace(old, new, 1)
    path = campaigns / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("old, new, expected, table, stack, folder, pattern, at", LOAD)
def test_a_bad_frame_recording_is_refused_at_load(
    tmp_path, monkeypatch, rendered, old, new, expected, table, stack, folder, pattern, at
):
    path = _bad_frames(tmp_path, monkeypatch, rendered, old, new, table, stack, folder, pattern)
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(ConfigError) as info:
        load_campaign(path, [])
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path)), message
    for part in expected:
        assert part in message, message
    assert sorted(tmp_path.rglob("*")) == before  # nothing written


@pytest.mark.parametrize("old, new, expected, table, stack, folder, pattern, at", DECODE)
def test_a_bad_frame_recording_is_refused_by_its_decoding(
    tmp_path, monkeypatch, rendered, capsys, old, new, expected, table, stack, folder, pattern, at
):
    """Validation reads no data file: the campaign loads; the step that reads the recording
    refuses it in one line naming the file, non-zero, with no file written."""
    from calflow.cli import main

    path = _bad_frames(tmp_path, monkeypatch, rendered, old, new, table, stack, folder, pattern)
    assert load_campaign(path, [])["rig"]["factory"] == "replay"
    before = sorted(p for p in tmp_path.rglob("*") if p.is_file())
    out = tmp_path / "results" / "bad" / "decoded" / "identification.nc"
    assert main(["decode-run", "--campaign", str(path), "--run", "identification", "--out", str(out)]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for part in expected:
        assert part in err, err
    assert sorted(p for p in tmp_path.rglob("*") if p.is_file()) == before  # nothing written


def test_a_good_frame_recording_loads(tmp_path, monkeypatch, rendered):
    campaigns = _frames_project(tmp_path, monkeypatch, rendered, TABLE, 4, None, None)
    text = _frames_campaign(campaigns)
    (campaigns / "rec.yaml").write_text(text, encoding="utf-8")
    assert load_campaign(campaigns / "rec.yaml", [])["rig"]["factory"] == "replay"
