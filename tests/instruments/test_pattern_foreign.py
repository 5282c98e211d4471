"""The decoder on frames that calflow's camera model did not make.

A lab renders or photographs frames with its own code from the pattern file alone
(docs/instruments.md is the contract). The renderer here reads the file with ``json`` and
uses only its documented fields (period, dot diameter, origin, shape, the two codes and the
``cell2x2`` rule, the pose convention): anti-aliased discs, a Gaussian blur
(``scipy.ndimage.gaussian_filter``), uneven light, noise, other frame sizes, pixel sizes,
bit depths and both polarities. A frame either decodes to the right place or is NaN with a
reason; a wrong position is a bug.
"""

from __future__ import annotations

import csv
import functools
import hashlib
import io
import json
import math

import numpy as np
import pytest
import tifffile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image, ImageFile
from scipy.ndimage import gaussian_filter

from calflow.cli import main
from calflow.errors import CalflowError
from calflow.instruments.pattern import Pattern, decode

RANGE = (2000.0, 1500.0)  # needs a 216 × 160 µm field of view
PIXEL = 0.5  # µm in the object plane
# decoded − true on noise-free frames (a period jump would be 4 µm); 8-bit rounding of a grid
# that repeats every 8 pixels (Θ = 0) is itself a systematic error of ~1 nm
POSE_UM, THETA_DEG = 3e-3, 2e-3


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    path = tmp_path_factory.mktemp("foreign") / "pattern.json"
    Pattern.make(range_um=RANGE).save(path)
    data = json.loads(path.read_text())
    data["path"] = str(path)
    data["matrix"] = _matrix(data)
    return data


def _matrix(d) -> np.ndarray:
    """The present/missing matrix from the documented ``cell2x2`` rule."""
    rows, cols = d["shape"]
    x = np.frombuffer(d["x_code"]["bits"].encode(), np.uint8) - ord("0")
    y = np.frombuffer(d["y_code"]["bits"].encode(), np.uint8) - ord("0")
    r, c = np.mgrid[0:rows, 0:cols]
    m = r % 2 == c % 2
    xs = (r % 2 == 0) & (c % 2 == 1)
    ys = (r % 2 == 1) & (c % 2 == 0)
    m[xs] = (x[c[xs] // 2] ^ ((r[xs] // 2) % 2)).astype(bool)
    m[ys] = (y[r[ys] // 2] ^ ((c[ys] // 4) % 2)).astype(bool)
    return m


def render(
    d,
    x,
    y,
    theta_deg,
    size=(640, 480),
    pixel_um=PIXEL,
    blur_um=0.4,
    dots=1.0,
    background=0.2,
    vignetting=0.0,
    noise=0.0,
    dtype=np.float64,
    rng=0,
    aliased=False,
) -> np.ndarray:
    """A frame (h, w) of the pattern at pose (x, y, Θ), from the file's fields only."""
    w, h = size
    j, i = np.meshgrid(np.arange(w), np.arange(h))
    cx, cy = pixel_um * (j - (w - 1) / 2), pixel_um * (i - (h - 1) / 2)
    t = math.radians(theta_deg)
    px = x + math.cos(t) * cx + math.sin(t) * cy  # (x, y) + R(−Θ)·c
    py = y - math.sin(t) * cx + math.cos(t) * cy
    p = d["period_um"]
    col = (px + d["origin_um"][0]) / p
    row = (py + d["origin_um"][1]) / p
    rows, cols = d["shape"]
    if aliased:  # anti-aliased discs drawn on the pixels, then blurred on the pixels
        sigma, spread = blur_um / pixel_um, pixel_um
        profile = _disc(d["dot_diameter_um"], 0.0, pixel_um)
    else:  # blurred (optics and the pixel's area) before the pixels sample it
        sigma, spread = 0.0, 4 * math.hypot(blur_um, pixel_um / math.sqrt(12))
        profile = _disc(d["dot_diameter_um"], spread / 4)
    reach = math.ceil((d["dot_diameter_um"] / 2 + spread) / p)  # sites on each side that touch a pixel
    r0, c0 = np.floor(row).astype(int), np.floor(col).astype(int)
    cover = np.zeros(px.shape)
    for dr in range(1 - reach, reach + 1):
        for dc in range(1 - reach, reach + 1):
            rc, cc = r0 + dr, c0 + dc
            inside = (rc >= 0) & (rc < rows) & (cc >= 0) & (cc < cols)
            present = np.zeros(rc.shape, bool)
            present[inside] = d["matrix"][rc[inside], cc[inside]]
            cover += present * profile(p * np.hypot(row - rc, col - cc))
    img = background + (dots - background) * cover
    if sigma:
        img = gaussian_filter(img, sigma)
    if vignetting:
        r2 = (cx**2 + cy**2) / (cx[0, 0] ** 2 + cy[0, 0] ** 2)
        img = img * (1 - vignetting * r2) * (1 + 0.3 * vignetting * cx / abs(cx[0, 0]))
    if noise:
        img = img + np.random.default_rng(rng).normal(0.0, noise, img.shape)
    if np.dtype(dtype).kind == "u":
        top = np.iinfo(dtype).max
        return np.clip(np.rint(img * 0.8 * top), 0, top).astype(dtype)
    return img.astype(dtype)


@functools.cache
def _disc(diameter_um, blur_um, ramp_um=0.0):
    """A disc's radial profile: blurred by a Gaussian (``gaussian_filter`` of the disc drawn
    on a grid of 0.02 µm or finer than the blur), or with an edge ramp one pixel (``ramp_um``) wide, not blurred."""
    if ramp_um:
        return lambda r: np.clip((diameter_um / 2 - r) / ramp_um + 0.5, 0.0, 1.0)
    step = max(0.02, blur_um / 15)
    half = int((diameter_um / 2 + 5 * blur_um) / step) + 2
    r = np.hypot(*np.mgrid[-half : half + 1, -half : half + 1]) * step
    disc = gaussian_filter((r <= diameter_um / 2).astype(float), blur_um / step)[half, half:]
    radius = np.arange(len(disc)) * step
    return lambda d: np.interp(d, radius, disc, right=0.0)


def _right(result, k, pose, tol_um=POSE_UM, tol_deg=THETA_DEG):
    got = np.array([result.x_um[k], result.y_um[k], result.theta_deg[k]])
    dth = (got[2] - pose[2] + 180.0) % 360.0 - 180.0
    return abs(got[0] - pose[0]) <= tol_um and abs(got[1] - pose[1]) <= tol_um and abs(dth) <= tol_deg


def test_documented_rule_gives_the_file_matrix(spec):
    text = "\n".join("".join("1" if v else "0" for v in row) for row in spec["matrix"])
    assert hashlib.sha256(text.encode()).hexdigest() == spec["matrix_sha256"]


@pytest.mark.parametrize(
    "size, pixel_um, dtype, dots, background",
    [
        ((640, 480), 0.5, np.uint8, 1.0, 0.2),  # bright dots on dark (reflection)
        ((640, 480), 0.5, np.uint8, 0.15, 0.9),  # dark dots on bright (transmission)
        ((1280, 1024), 0.25, np.uint16, 0.9, 0.3),
        ((601, 457), 0.52, np.float32, 0.1, 0.7),  # not a multiple of 8
        ((500, 700), 0.45, np.float64, 1.0, 0.0),  # portrait
        ((377, 251), 1.1, np.uint16, 0.2, 1.0),  # coarse pixels: 3.6 pixels a period
    ],
)
def test_foreign_frames_decode(spec, size, pixel_um, dtype, dots, background):
    pattern = Pattern.load(spec["path"])
    poses = [(523.1, 411.7, 0.0), (1517.3, 1204.9, 37.0), (80.2, 1450.6, -151.5)]
    poses = poses[::2] if size[0] * size[1] > 1e6 else poses
    frames = np.stack(
        [
            render(spec, *pose, size=size, pixel_um=pixel_um, dtype=dtype, dots=dots, background=background)
            for pose in poses
        ]
    )
    result = decode(frames, pattern, pixel_um=pixel_um)
    assert list(result.status) == ["ok"] * len(poses), list(result.reason)
    for k, pose in enumerate(poses):
        assert _right(result, k, pose), (pose, result.x_um[k], result.y_um[k], result.theta_deg[k])


def test_other_pixel_types_and_scales(spec):
    """12 bits in 16, dark-subtracted signed integers, 32-bit integers, floats scaled far from
    one (1e30 once overflowed the spectrum's squares: no_lobes) or on a large offset."""
    pattern = Pattern.load(spec["path"])
    pose = (700.3, 300.2, 12.0)
    f = render(spec, *pose, noise=0.02)
    frames = [
        np.clip(np.rint(f * 3000), 0, 4095).astype(np.uint16),
        np.rint((f - 0.5) * 2000).astype(np.int16),
        np.rint(f * 1e6).astype(np.uint32),
        f * 1e30,
        (f * 1e-25).astype(np.float32),
        1e5 + f,
        f.astype(np.float16),
    ]
    for frame in frames:
        result = decode(frame, pattern, pixel_um=PIXEL)
        assert result.status[0] == "ok", (frame.dtype, result.reason[0])
        assert _right(result, 0, pose, 0.005, 0.005), (frame.dtype, result.x_um[0], result.y_um[0])
    huge = np.random.default_rng(1).uniform(-1.0, 1.0, (480, 640)) * 1e308
    with np.errstate(all="raise"):  # no overflow warning reaches the user either
        assert decode(huge, pattern, pixel_um=PIXEL).status[0] != "ok"


def test_frames_drawn_on_the_pixels_then_blurred(spec):
    """Discs drawn anti-aliased on the pixel grid and blurred there (``gaussian_filter``): the
    frame holds aliases of the dots' harmonics, which move a grid commensurate with the
    pixels (Θ = 0, 8 pixels a period) by ~8 nm — the frame's content, not the decoder's."""
    pattern = Pattern.load(spec["path"])
    poses = [(523.1, 411.7, 0.0), (1517.3, 1204.9, 90.0), (80.2, 1450.6, -151.5)]
    frames = np.stack([render(spec, *p, aliased=True, dtype=np.uint8) for p in poses])
    result = decode(frames, pattern, pixel_um=PIXEL)
    assert list(result.status) == ["ok"] * 3, list(result.reason)
    for k, pose in enumerate(poses):
        assert _right(result, k, pose, tol_um=0.015, tol_deg=THETA_DEG), (result.x_um[k], result.y_um[k])


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    x=st.floats(0, RANGE[0]),
    y=st.floats(0, RANGE[1]),
    theta=st.floats(-180, 180),
    dark=st.booleans(),
    scale=st.sampled_from([1.0, 1.005, 0.995]),
)
def test_any_pose_any_angle_and_a_slight_scale_error(spec, x, y, theta, dark, scale):
    """Θ anywhere in the turn; the pixel size told the decoder off by up to 0.5 %."""
    pattern = Pattern.load(spec["path"])
    levels = {"dots": 0.1, "background": 0.8} if dark else {}
    frame = render(spec, x, y, theta, pixel_um=PIXEL * scale, dtype=np.uint8, **levels)
    result = decode(frame, pattern, pixel_um=PIXEL)
    assert result.status[0] == "ok", result.reason[0]
    assert _right(result, 0, (x, y, theta)), (result.x_um[0], result.y_um[0], result.theta_deg[0])


def test_a_wrong_pixel_size_is_flagged_or_right_never_wrong(spec):
    """The pixel size told the decoder only places the search for the grid: off by 15 % the
    position is still right; off by a third it is flagged."""
    pattern = Pattern.load(spec["path"])
    pose = (700.0, 300.0, 10.0)
    frame = render(spec, *pose, size=(800, 600))
    for told in (0.43, 0.575, 0.375, 0.7, 1.0):
        result = decode(frame, pattern, pixel_um=told)
        if abs(told / PIXEL - 1) <= 0.15:
            assert result.status[0] == "ok" and _right(result, 0, pose, 0.01, 0.01), (told, result.reason[0])
        else:
            assert result.status[0] != "ok" and np.isnan(result.x_um[0]), (told, result.x_um[0])


def test_strong_vignetting_and_low_snr(spec):
    pattern = Pattern.load(spec["path"])
    poses = [(700.3, 300.2, 12.0), (1900.0, 100.0, -100.0)]
    frames = np.stack(
        [render(spec, *p, vignetting=0.7, noise=0.15, rng=k, dtype=np.float32) for k, p in enumerate(poses)]
        + [render(spec, *p, noise=0.35, rng=9 + k) for k, p in enumerate(poses)]  # SNR ≈ 2 per pixel
    )
    result = decode(frames, pattern, pixel_um=PIXEL)
    assert list(result.status) == ["ok"] * 4, list(result.reason)
    for k, pose in enumerate(poses + poses):
        assert _right(result, k, pose, tol_um=0.05, tol_deg=0.05), (k, result.x_um[k], result.y_um[k])


def test_noise_that_hides_frame_dots_does_not_move_the_position(spec):
    """At SNR ≈ 2 per pixel noise hides frame dots all over the frame; the fine position stays
    within its stated uncertainty (a refit around them once moved it by half a period)."""
    pattern = Pattern.load(spec["path"])
    pose = (700.3, 300.2, 12.0)
    frames = np.stack([render(spec, *pose, noise=nz, rng=3) for nz in (0.4, 0.5)])
    result = decode(frames, pattern, pixel_um=PIXEL)
    assert list(result.status) == ["ok"] * 2, list(result.reason)
    for k in range(2):
        assert _right(result, k, pose, tol_um=0.03, tol_deg=0.01), (result.x_um[k], result.y_um[k])
        assert abs(result.y_um[k] - pose[1]) < 4 * result.u_y_um[k] < 0.03


def test_the_range_corners_decode(spec):
    """Every frame centre in [0, range] decodes (docs), also when the frame is larger than the
    field of view the code needs, so that a third of it is beyond the pattern's edge."""
    pattern = Pattern.load(spec["path"])
    poses = [(0.0, 0.0, 0.0), (0.0, 0.0, 45.0), (RANGE[0], 0.0, -90.0), (0.0, RANGE[1], 170.0)]
    frames = np.stack([render(spec, *p, noise=0.05, rng=k) for k, p in enumerate(poses)])
    result = decode(frames, pattern, pixel_um=PIXEL)
    assert list(result.status) == ["ok"] * 4, list(result.reason)
    for k, pose in enumerate(poses):
        assert _right(result, k, pose, tol_um=0.01, tol_deg=0.01), (pose, result.x_um[k], result.y_um[k])


def test_off_the_pattern_is_nan_with_a_reason_never_a_wrong_place(spec):
    pattern = Pattern.load(spec["path"])
    o = spec["origin_um"]
    poses = [
        (-o[0] - 60.0, 700.0, 0.0),  # the centre off the pattern's left edge: 3/8 of the view on it
        (1000.0, RANGE[1] + 140.0, 30.0),
        (-o[0], -o[1], 45.0),  # the centre on the pattern's corner: a quarter of the view
        (-o[0] + 40.0, 700.0, 0.0),  # most of the view on the pattern
        (RANGE[0] + 60.0, 700.0, 90.0),
    ]
    frames = np.stack([render(spec, *p, noise=0.05, rng=k) for k, p in enumerate(poses)])
    result = decode(frames, pattern, pixel_um=PIXEL)
    for k, pose in enumerate(poses):
        if result.status[k] == "ok":
            assert _right(result, k, pose, tol_um=0.05, tol_deg=0.05), (pose, result.x_um[k], result.y_um[k])
        else:
            assert np.isnan(result.x_um[k]) and np.isnan(result.theta_deg[k]) and result.reason[k]
    assert all(result.status[:3] != "ok"), list(result.reason)  # too little of the code in view


def test_a_mirrored_view_is_flagged(spec):
    """A camera looking through the substrate of a pattern not mirrored at the mask sees it
    mirrored: that reads no place of the codes (flagged), never a wrong one."""
    pattern = Pattern.load(spec["path"])
    a, b = render(spec, 523.1, 411.7, 20.0), render(spec, 1517.3, 1204.9, -110.0)
    result = decode(np.stack([a[:, ::-1], b[::-1]]), pattern, pixel_um=PIXEL)
    assert list(result.status) == ["code_mismatch"] * 2 and np.isnan(result.x_um).all(), list(result.reason)


def test_a_frame_of_another_pattern_is_flagged(spec, tmp_path):
    """A frame of another pattern file (other codes) decoded with this one: flagged."""
    other = tmp_path / "other.json"
    Pattern.make(range_um=(1000.0, 2500.0)).save(other)
    o = json.loads(other.read_text())
    o["matrix"] = _matrix(o)
    frames = np.stack([render(o, 400.0, 900.0, 30.0), render(o, 900.0, 2100.0, -120.0)])
    result = decode(frames, Pattern.load(spec["path"]), pixel_um=PIXEL)
    assert all(result.status != "ok") and np.isnan(result.x_um).all(), list(result.reason)


def test_blank_uniform_and_code_free_frames_are_flagged(spec):
    pattern = Pattern.load(spec["path"])
    blank = spec | {"matrix": np.zeros_like(spec["matrix"])}  # a clean substrate
    full = spec | {"matrix": np.ones_like(spec["matrix"])}  # a plain grid: no code to read
    frames = np.stack(
        [
            np.full((480, 640), 77.0),
            render(blank, 500.0, 500.0, 10.0, noise=0.02),
            render(full, 500.0, 500.0, 10.0, noise=0.02),
            render(spec, 500.0, 500.0, 10.0, blur_um=6.0, aliased=True),  # far out of focus
        ]
    )
    result = decode(frames, pattern, pixel_um=PIXEL)
    assert all(result.status != "ok") and np.isnan(result.x_um).all(), list(result.status)
    assert result.status[0] == "bad_frame" and all(len(r) > 0 for r in result.reason)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["uniform8", "normal", "poisson16", "blobs"]))
def test_random_noise_is_never_a_position(spec, seed, kind):
    pattern = Pattern.load(spec["path"])
    g = np.random.default_rng(seed)
    shape = (2, 480, 640)
    if kind == "uniform8":
        frames = g.integers(0, 256, shape, dtype=np.uint8)
    elif kind == "normal":
        frames = g.normal(0.0, 1.0, shape)
    elif kind == "poisson16":
        frames = g.poisson(300.0, shape).astype(np.uint16)
    else:  # noise blurred to about the dots' size
        frames = gaussian_filter(g.normal(0.0, 1.0, shape), (0, 2.0, 2.0)).astype(np.float32)
    result = decode(frames, pattern, pixel_um=PIXEL)
    assert all(result.status != "ok") and np.isnan(result.x_um).all(), list(result.reason)


def test_calflow_decode_reads_a_labs_tiff_and_png(spec, tmp_path, capsys):
    poses = [(611.5, 822.25, 171.0), (1400.0, 300.75, -60.0)]
    tifffile.imwrite(
        tmp_path / "stack.tif",
        np.stack([render(spec, *p, dtype=np.uint16, pixel_um=0.4, size=(800, 600)) for p in poses]),
    )
    frame = render(spec, *poses[0], dtype=np.uint8, pixel_um=0.4, size=(800, 600), dots=0.1, background=0.9)
    Image.fromarray(frame).save(tmp_path / "dark.png")
    argv = ["decode", str(tmp_path / "stack.tif"), str(tmp_path / "dark.png")]
    assert main([*argv, "--pattern", spec["path"], "--pixel-um", "0.4"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert [r["status"] for r in rows] == ["ok"] * 3
    got = np.array([[float(r[k]) for k in ("x_um", "y_um", "theta_deg")] for r in rows])
    np.testing.assert_allclose(got, np.array(poses)[[0, 1, 0]], atol=POSE_UM)


def _broken_patterns(spec):
    good = json.loads(open(spec["path"]).read())
    yield "not json", "{"
    yield "a list", "[]"
    yield "nested too deep", "[" * 100_000 + "]" * 100_000
    for key, value in [
        ("period_um", "four"),
        ("period_um", None),
        ("dot_diameter_um", [2]),
        ("range_um", 5),
        ("range_um", [1, "a"]),
        ("origin_um", None),
        ("origin_um", [1, 2, 3]),
        ("shape", [10]),
        ("shape", "big"),
        ("shape", [10.5, 3]),
        ("x_code", 5),
        ("x_code", {**good["x_code"], "polynomial": "x11"}),
        ("x_code", {**good["x_code"], "polynomial": [11.0, 2, 0]}),
        ("x_code", {**good["x_code"], "polynomial": [10**6, 0]}),  # must not spin on it
        ("x_code", {**good["x_code"], "polynomial": [True, 0]}),
        ("x_code", {**good["x_code"], "window_bits": "33"}),
        ("x_code", {**good["x_code"], "window_bits": True}),
        ("y_code", {**good["y_code"], "bits": 101}),
        ("y_code", {**good["y_code"], "order": "ten"}),
        ("y_code", {**good["y_code"], "length": None}),
        ("y_code", {**good["y_code"], "seed": 3}),
        ("matrix_sha256", 7),
        ("min_fov_um", "x"),
        ("min_fov_um", [1e9, 1e9]),
    ]:
        yield f"{key}={value!r}"[:60], json.dumps({**good, key: value})
    for key in good:
        if key != "layout":  # the only layout of version 1 may go without saying
            yield f"no {key}", json.dumps({k: v for k, v in good.items() if k != key})


def test_a_bad_pattern_file_is_one_line_and_nothing_written(spec, tmp_path, capsys):
    frame = render(spec, 500.0, 500.0, 0.0, dtype=np.uint8)
    Image.fromarray(frame).save(tmp_path / "f.png")
    bad = tmp_path / "bad.json"
    out = tmp_path / "poses.csv"
    for label, text in _broken_patterns(spec):
        bad.write_text(text)
        with pytest.raises(CalflowError) as exc:
            Pattern.load(bad)
        assert str(exc.value).startswith(f"{bad}: ") and "\n" not in str(exc.value), label
        code = main(["decode", str(tmp_path / "f.png"), "--pattern", str(bad), "--out", str(out)])
        err = capsys.readouterr().err.strip().splitlines()
        assert code != 0 and len(err) == 1 and str(bad) in err[0], (label, err)
        assert not out.exists(), label


def test_a_truncated_png_is_refused_even_after_weasyprint(spec, tmp_path, monkeypatch, capsys):
    frame = render(spec, 500.0, 500.0, 0.0, dtype=np.uint8)
    Image.fromarray(frame).save(tmp_path / "f.png")
    data = (tmp_path / "f.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    monkeypatch.setattr(ImageFile, "LOAD_TRUNCATED_IMAGES", True)  # what importing WeasyPrint does
    out = tmp_path / "poses.csv"
    argv = ["decode", str(tmp_path / "cut.png"), "--pattern", spec["path"], "--pixel-um", "0.5"]
    argv += ["--out", str(out)]
    assert main(argv) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cut.png" in err[0] and not out.exists(), err
    assert ImageFile.LOAD_TRUNCATED_IMAGES is True  # the reader leaves the process's setting alone


def test_an_image_pillow_calls_a_decompression_bomb_is_one_line(spec, tmp_path, monkeypatch, capsys):
    Image.fromarray(render(spec, 500.0, 500.0, 0.0, dtype=np.uint8)).save(tmp_path / "f.png")
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)  # the frame is over twice the limit
    out = tmp_path / "poses.csv"
    argv = ["decode", str(tmp_path / "f.png"), "--pattern", spec["path"], "--pixel-um", "0.5"]
    assert main([*argv, "--out", str(out)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "f.png" in err[0] and not out.exists(), err
