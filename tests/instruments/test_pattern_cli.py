"""``calflow pattern make`` and ``calflow decode``: files written, poses printed, bad input refused."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
import xarray as xr
from PIL import Image

from calflow.cli import main
from calflow.instruments.pattern import Camera, Pattern
from calflow.instruments.pattern.frames import write_frames_tiff
from calflow.instruments.pattern.gds import read_gds_sites

CAMERA = Camera(width=224, height=192, sensor_pixel_um=12.0)
PIXEL = ["--pixel-um", str(CAMERA.pixel_um)]


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    out = tmp_path_factory.mktemp("pattern")
    assert main(["pattern", "make", "--range", "2000x1500", "--out", str(out)]) == 0
    return out, Pattern.load(out / "pattern.json")


def test_pattern_make_writes_file_gds_and_preview(made):
    out, pattern = made
    assert sorted(p.name for p in out.iterdir()) == ["pattern.gds", "pattern.json", "pattern.png"]
    assert pattern.range_um == (2000.0, 1500.0)
    assert np.array_equal(read_gds_sites(out / "pattern.gds", pattern), pattern.matrix)
    preview = np.asarray(Image.open(out / "pattern.png").convert("L")) > 127
    assert np.array_equal(preview, pattern.matrix)  # small enough for one pixel per dot site


def test_decode_prints_and_writes_poses(made, tmp_path, capsys):
    out, pattern = made
    poses = np.array([[500.0, 400.0, 0.0], [1200.25, 900.5, 120.0]])
    frames = CAMERA.render_batch(pattern, poses, rng=1)
    write_frames_tiff(frames, tmp_path / "stack.tif")
    Image.fromarray(frames[0]).save(tmp_path / "one.png")
    args = [str(tmp_path / "stack.tif"), str(tmp_path / "one.png"), "--pattern", str(out / "pattern.json")]
    assert main(["decode", *args, *PIXEL]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert [r["status"] for r in rows] == ["ok"] * 3
    assert [int(r["page"]) for r in rows] == [0, 1, 0]
    got = np.array([[float(r["x_um"]), float(r["y_um"]), float(r["theta_deg"])] for r in rows])
    np.testing.assert_allclose(got, poses[[0, 1, 0]], atol=2e-3)
    assert main(["decode", *args, *PIXEL, "--out", str(tmp_path / "poses.nc")]) == 0
    ds = xr.open_dataset(tmp_path / "poses.nc")
    np.testing.assert_allclose(ds["meas_x"].values, poses[[0, 1, 0], 0], atol=2e-3)
    assert ds["meas_theta"].attrs["units"] == "degree" and list(ds["decode_status"].values) == ["ok"] * 3


def _bad_inputs(tmp_path, made):
    out, pattern = made
    frames = CAMERA.render_batch(pattern, [[500.0, 400.0, 0.0], [600.0, 400.0, 0.0]], rng=1)
    write_frames_tiff(frames, tmp_path / "good.tif")
    data = (tmp_path / "good.tif").read_bytes()
    (tmp_path / "truncated.tif").write_bytes(data[: len(data) // 3])
    (tmp_path / "noise.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    Image.fromarray(np.dstack([frames[0]] * 3)).save(tmp_path / "colour.png")
    Image.fromarray(frames[0][:100, :100]).save(tmp_path / "small.png")
    (tmp_path / "frame.bmp").write_bytes(b"BM")
    (tmp_path / "broken.json").write_text('{"format": "calflow-pattern", "version": 1}')
    return {
        "truncated TIFF": (["truncated.tif"], "truncated.tif"),
        "not a PNG": (["noise.png"], "noise.png"),
        "colour": (["colour.png"], "colour.png"),
        "frame of another size": (["good.tif", "small.png"], "small.png"),
        "unknown type": (["frame.bmp"], "frame.bmp"),
        "missing file": (["absent.tif"], "absent.tif"),
    }


def test_bad_frames_and_files_are_one_line_and_write_nothing(made, tmp_path, capsys):
    out, _ = made
    for name, (files, where) in _bad_inputs(tmp_path, made).items():
        target = tmp_path / f"{name}.csv"
        argv = ["decode", *[str(tmp_path / f) for f in files], "--pattern", str(out / "pattern.json")]
        assert main([*argv, *PIXEL, "--out", str(target)]) == 2, name
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and where in err and err.startswith("calflow: error:"), (name, err)
        assert not target.exists()
    # a malformed pattern file, a field of view too small for the pattern
    good = [str(tmp_path / "good.tif")]
    assert main(["decode", *good, "--pattern", str(tmp_path / "broken.json"), *PIXEL]) == 2
    assert "broken.json: period_um" in capsys.readouterr().err
    assert main(["decode", *good, "--pattern", str(out / "pattern.json"), "--pixel-um", "0.5"]) == 2
    assert "field of view" in capsys.readouterr().err


def test_pattern_make_bad_range_and_folder(tmp_path, capsys):
    assert main(["pattern", "make", "--range", "9500", "--out", str(tmp_path / "p")]) == 2
    assert "--range" in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    assert main(["pattern", "make", "--range", "100x100", "--out", str(tmp_path / "file")]) == 2
    assert "is a file" in capsys.readouterr().err
    assert not (tmp_path / "p").exists()
