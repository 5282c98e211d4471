"""``calflow pattern make --layout megarena`` and ``calflow decode`` on Megarena frames: the
target's files, poses in both conventions, bad files refused in one line. Frames are rendered
by calflow's camera model: few and small."""

from __future__ import annotations

import numpy as np
import pytest

from calflow.cli import main
from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.layouts import load_pattern
from calflow.instruments.pattern.megarena import MegarenaPattern

CAMERA = Camera(width=384, height=336, sensor_pixel_um=5.0, magnification=10.0)  # 0.5 µm pixels


@pytest.fixture(scope="module")
def pattern():
    return MegarenaPattern(4.0, 6)


def test_pattern_make_and_decode_commands(tmp_path, capsys, pattern):
    assert main(
        [
            "pattern",
            "make",
            "--layout",
            "megarena",
            "--range",
            "600x400",
            "--period-um",
            "4",
            "--out",
            str(tmp_path),
        ]
    ) in (0, None)
    for name in ("pattern.json", "pattern.vernier.json", "pattern.gds", "pattern.png"):
        assert (tmp_path / name).stat().st_size > 0
    made = load_pattern(tmp_path / "pattern.json")
    assert made.layout == "megarena" and made.region_um[2] >= 600
    import tifffile

    poses = [(250.0, 200.0, 5.0), (320.0, 150.0, -95.0)]
    frames = np.stack([CAMERA.render(made, *p, rng=k) for k, p in enumerate(poses)])
    tifffile.imwrite(tmp_path / "f.tif", frames)
    capsys.readouterr()
    assert main(["decode", str(tmp_path / "f.tif"), "--pattern", str(tmp_path / "pattern.vernier.json")]) == 0
    rows = capsys.readouterr().out.strip().splitlines()
    assert rows[0].split(",")[2:5] == ["x_um", "y_um", "theta_deg"] and "pixel_um" in rows[0]
    for row, pose in zip(rows[1:], poses):
        cols = row.split(",")
        assert cols[-2] == "ok", rows
        assert abs(float(cols[2]) - pose[0] - made.origin_um[0]) < 0.02  # the library's file has no origin
    assert (
        main(
            [
                "decode",
                str(tmp_path / "f.tif"),
                "--pattern",
                str(tmp_path / "pattern.json"),
                "--convention",
                "vernier",
            ]
        )
        == 0
    )
    rows = capsys.readouterr().out.strip().splitlines()
    assert rows[0] == "file,page,x,y,alpha,pixelSize,status,reason"
    assert abs(float(rows[1].split(",")[2]) + poses[0][0] + made.origin_um[0]) < 1.0  # −x, to half a pixel


@pytest.mark.parametrize("suffix", [".jpg", ".png"])
def test_truncated_or_unreadable_image_is_refused_in_one_line(tmp_path, capsys, pattern, suffix):
    from PIL import Image

    good = tmp_path / f"good{suffix}"
    Image.fromarray(CAMERA.render(pattern, 300.0, 300.0, 0.0, rng=1)).save(good)
    cut = tmp_path / f"cut{suffix}"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    junk = tmp_path / f"junk{suffix}"
    junk.write_bytes(b"not an image at all")
    spec = tmp_path / "p.json"
    pattern.save(spec)
    for bad in (cut, junk):
        capsys.readouterr()
        out = tmp_path / "poses.csv"
        assert main(["decode", str(good), str(bad), "--pattern", str(spec), "--out", str(out)]) != 0
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and str(bad) in err and not out.exists()


def test_decode_to_netcdf_keeps_the_measured_pixel_size(tmp_path, pattern):
    import tifffile

    from calflow.data.io import open_dataset

    spec = pattern.save(tmp_path / "p.json")
    tifffile.imwrite(tmp_path / "f.tif", np.stack([CAMERA.render(pattern, 300.0, 250.0, 7.0, rng=1)] * 2))
    out = tmp_path / "poses.nc"
    assert main(["decode", str(tmp_path / "f.tif"), "--pattern", str(spec), "--out", str(out)]) == 0
    ds = open_dataset(out)
    assert ds["pixel_size"].attrs["units"] == "um"
    assert np.allclose(ds["pixel_size"].values, CAMERA.pixel_um, rtol=1e-4)
    assert np.all(ds["u_pixel_size"].values > 0) and list(ds["decode_status"].values) == ["ok", "ok"]
