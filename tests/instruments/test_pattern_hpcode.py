"""HP-code markers: their files (calflow's and the Vernier library's), their drawing, and the
decoder on frames calflow's own renderer draws with several numbered markers at known poses.

Each marker found must carry its own number and the pose it was drawn at (within tens of nm
and µrad: the fit's bias on a marker 16 periods wide, docs/instruments.md); a frame holding no
marker gets a status and one reason, never a pose.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from calflow.errors import CalflowError
from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.decode import STATUSES
from calflow.instruments.pattern.hpcode import HPCodePattern, decode, decode_markers, pose, relative
from calflow.instruments.pattern.hpcode.render import expectation, render
from calflow.instruments.pattern.layouts import load_pattern, read_pattern

PATTERN = HPCodePattern(4.0, 17)  # 10.7 pixels a period: a marker ≈ 180 pixels wide
CAMERA = Camera(width=480, height=400)  # 0.375 µm pixels
WIDE = Camera(width=640, height=560)  # 240 × 210 µm: markers 93 µm across the diagonal, apart at any Θ
POSE_UM, THETA_URAD, PIXEL_REL = 0.05, 100.0, 1e-3


def placed(number, cx, cy, theta):
    """A marker whose centre is at (cx, cy) µm from the frame centre, turned by theta degrees:
    (number, x, y, Θ) with (x, y) the frame centre in the marker's frame."""
    t = math.radians(theta)
    return number, -(math.cos(t) * cx + math.sin(t) * cy), -(-math.sin(t) * cx + math.cos(t) * cy), theta


def check_pose(found, k, truth, camera=CAMERA):
    _, x, y, theta = truth
    assert found.status[k] == "ok", found.reason[k]
    assert abs(found.x_um[k] - x) < POSE_UM and abs(found.y_um[k] - y) < POSE_UM
    turn = (found.theta_deg[k] - theta + 180.0) % 360.0 - 180.0
    assert abs(math.radians(turn)) * 1e6 < THETA_URAD
    assert abs(found.pixel_um[k] / camera.pixel_um - 1) < PIXEL_REL


# -- the files --------------------------------------------------------------------------------
def test_calflow_file_round_trips(tmp_path):
    path = PATTERN.save(tmp_path / "markers.json")
    back = load_pattern(path)
    assert isinstance(back, HPCodePattern) and (back.period_um, back.size) == (4.0, 17)


def test_library_files_are_read_as_written(tmp_path):
    path = tmp_path / "lib.json"
    path.write_text(json.dumps(PATTERN.to_library_dict()))
    back = load_pattern(path)
    assert (back.layout, back.period_um, back.size, back.half_periods) == ("hpcode", 4.0, 17, 33)
    square = read_pattern({"PeriodicPattern": {"period": 15.0, "nRows": 19, "nCols": 19, "margin": 0.0}})
    assert (square.period_um, square.size) == (15.0, 19)


@pytest.mark.parametrize(
    "data, key",
    [
        ({"HPCodePattern": {"period": 0, "size": 17}}, "HPCodePattern.period"),
        ({"HPCodePattern": {"period": 15.5, "size": 7}}, "HPCodePattern.size"),
        ({"HPCodePattern": [15.5, 17]}, "HPCodePattern"),
        ({"format": "calflow-pattern", "version": 1, "layout": "hpcode", "period_um": 4.0}, "size"),
    ],
)
def test_bad_marker_file_is_refused_in_one_line(tmp_path, data, key):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalflowError) as err:
        load_pattern(path)
    text = str(err.value)
    assert "\n" not in text and text.startswith(str(path)) and key in text


# -- the drawing ------------------------------------------------------------------------------
@given(number=st.integers(0, (1 << PATTERN.number_bits) - 1))
def test_the_number_is_the_missing_dots_of_the_first_row(number):
    p, m = PATTERN.period_um, (PATTERN.size - 1) // 2
    cols = PATTERN.number_columns()
    dots = PATTERN.cells((cols - m) * p, np.full(len(cols), -m * p), number)
    assert int(np.sum((~dots).astype(int) << np.arange(len(cols)))) == number
    below = PATTERN.cells((cols - m) * p, np.full(len(cols), (1 - m) * p), number)
    assert below.all()  # the row below is full whatever the number


def test_fiducials_are_rings_around_a_square_in_three_corners():
    half = PATTERN.period_um / 2
    n = PATTERN.half_periods
    cells = (np.arange(n) - (PATTERN.size - 1)) * half
    img = PATTERN.cells(cells[None, :], cells[:, None])
    ring = np.ones((7, 7), bool)
    ring[1:6, 1:6] = False
    ring[2:5, 2:5] = True
    for r0, c0 in ((0, 0), (0, n - 7), (n - 7, 0)):
        assert (img[r0 : r0 + 7, c0 : c0 + 7] == ring).all()
    assert not (img[n - 7 :, n - 7 :] == ring).all()  # the fourth corner holds dots
    assert img[2::2, 2::2][4:-4, 4:-4].all() and not img[1::2, :].any() == img[1::2, :].all()


@pytest.mark.parametrize("bad", [-1, 512, 1.5, True])
def test_a_number_the_marker_cannot_hold_is_refused(bad):
    with pytest.raises(ValueError, match="number"):
        PATTERN.cells(0.0, 0.0, bad)


# -- the decoder ------------------------------------------------------------------------------
# no shrinking: each example renders and decodes a frame; a failure is printed as drawn
@settings(
    max_examples=6,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
)
@given(
    numbers=st.lists(st.integers(0, 511), min_size=3, max_size=3, unique=True),
    thetas=st.lists(st.floats(-180, 180), min_size=3, max_size=3),
    shift=st.tuples(st.floats(-4, 4), st.floats(-4, 4)),
    dark=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_every_marker_has_its_number_and_pose(numbers, thetas, shift, dark, seed):
    camera = Camera(
        width=WIDE.width,
        height=WIDE.height,
        dot_level=0.05 if dark else 1.0,
        background=0.9 if dark else 0.25,
    )
    centres = [(-60.0, -50.0), (60.0, -50.0), (0.0, 55.0)]
    truth = [placed(n, cx + shift[0], cy + shift[1], th) for n, (cx, cy), th in zip(numbers, centres, thetas)]
    found = decode_markers(render(camera, PATTERN, truth, rng=seed), PATTERN)
    assert sorted(found.number.tolist()) == sorted(numbers)
    for t in truth:
        check_pose(found, int(np.nonzero(found.number == t[0])[0][0]), t, camera)


@settings(
    max_examples=6,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
)
@given(
    number=st.integers(0, 511),
    theta=st.floats(-180, 180),
    shift=st.tuples(st.floats(-4, 4), st.floats(-4, 4)),
    magnification=st.sampled_from([8.0, 10.0, 14.0]),
)
def test_the_grid_edge_leaves_no_scale_bias(number, theta, shift, magnification):
    # noise-free: what is left is the fit's bias. Near the grid's edge the lobe's phase bends
    # by c·∇ln|z| (pose.py); the envelope's regressors model it, so the pixel size holds within
    # 5e-5 and Θ 10 µrad (8.5-15 pixels a period). A plain fit on the same samples reads the
    # pixel size over 1e-4 small: the regressors remove it.
    camera = Camera(width=560, height=520, magnification=magnification)
    frame = expectation(camera, PATTERN, [(number, *shift, theta)])
    found = decode_markers(frame, PATTERN)
    assert found.status.tolist() == ["ok"], found.reason[0]
    assert abs(found.pixel_um[0] / camera.pixel_um - 1) < 5e-5
    assert abs(math.radians((found.theta_deg[0] - theta + 180.0) % 360.0 - 180.0)) < 10e-6
    assert abs(found.x_um[0] - shift[0]) < 1e-3 and abs(found.y_um[0] - shift[1]) < 1e-3
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pose, "ENVELOPE", False)
        plain = decode_markers(frame, PATTERN)
    assert plain.pixel_um[0] / camera.pixel_um - 1 < -1e-4


@settings(max_examples=4, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(theta=st.floats(-10, 10), dy=st.floats(-2, 2))
def test_a_marker_one_period_from_another_is_not_pulled(theta, dy):
    # the refit's samples stop half a period inside the outer dots (pose.EDGE): another
    # marker's dots one period beyond them bend its planes less than a plain fit one period in
    # (up to 1.8e-4 in pixel size, 180 µrad, 12 nm; samples on the outer dots: 2.1e-4, 230 µrad)
    camera = Camera(width=640, height=400)
    d = 17 * PATTERN.period_um  # centre to centre: one period between the outer dots
    truth = [placed(3, -d / 2, dy, theta), placed(9, d / 2, -dy, theta + 1.0)]
    found = decode_markers(expectation(camera, PATTERN, truth), PATTERN)
    for number, x, y, th in truth:
        k = int(np.nonzero(found.number == number)[0][0])
        assert found.status[k] == "ok", found.reason[k]
        assert abs(found.pixel_um[k] / camera.pixel_um - 1) < 1.6e-4
        assert abs(math.radians((found.theta_deg[k] - th + 180.0) % 360.0 - 180.0)) < 150e-6
        assert abs(found.x_um[k] - x) < 0.02 and abs(found.y_um[k] - y) < 0.02


def test_a_given_pixel_size_must_match_the_markers():
    frame = render(CAMERA, PATTERN, [placed(5, 0.0, 0.0, 20.0)], rng=1)
    assert decode_markers(frame, PATTERN, pixel_um=CAMERA.pixel_um).status.tolist() == ["ok"]
    wrong = decode_markers(frame, PATTERN, pixel_um=1.3 * CAMERA.pixel_um)
    assert wrong.status.tolist() == ["no_lobes"] and "pixel size" in wrong.reason[0]
    assert np.isnan(wrong.x_um).all()


def test_library_pose_is_the_library_convention():
    truth = placed(3, 20.0, -10.0, 30.0)
    found = decode_markers(expectation(CAMERA, PATTERN, [truth]), PATTERN)
    lib = found.library_pose()
    # the library's (x, y): the marker's centre seen from the pixel (w/2, h/2), in its axes
    t = math.radians(30.0)
    offset = np.array([20.0, -10.0]) - 0.5 * CAMERA.pixel_um  # from (w/2, h/2), camera axes
    want = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]]) @ offset
    assert abs(lib["x"][0] - want[0]) < POSE_UM and abs(lib["y"][0] - want[1]) < POSE_UM
    assert abs(lib["alpha"][0] - t) < THETA_URAD * 1e-6


@settings(
    max_examples=4,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
)
@given(
    turn=st.floats(-20, 20),
    base=st.floats(-180, 180),
    step=st.tuples(st.floats(-8, 8), st.floats(-8, 8)),
)
def test_relative_pose_is_the_reference_seen_from_the_marker(turn, base, step):
    ref_c, mov_c = np.array([-60.0, 0.0]), np.array([55.0, 5.0]) + step
    truth = [placed(0, *ref_c, base), placed(1, *mov_c, base + turn)]
    found = decode_markers(render(WIDE, PATTERN, truth, rng=3), PATTERN)
    rel = relative(found, 1, 0, PATTERN.period_um)
    assert rel.status.tolist() == ["ok"]
    # the reference's centre in the moving marker's frame: R(−Θ_m)(c_r − c_m)
    t = math.radians(base + turn)
    want = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]]) @ (ref_c - mov_c)
    assert np.hypot(rel.x_um[0] - want[0], rel.y_um[0] - want[1]) < POSE_UM
    assert abs(math.radians(rel.theta_deg[0] - turn)) * 1e6 < 2 * THETA_URAD
    assert (rel.u_x_um > 0).all() and (rel.u_theta_deg > 0).all()
    hook = decode(render(WIDE, PATTERN, truth, rng=3)[None], PATTERN, marker=1, reference=0)
    assert np.allclose([hook.x_um[0], hook.y_um[0]], [rel.x_um[0], rel.y_um[0]], atol=1e-9)


def test_a_given_pixel_size_is_the_relative_pose_scale():
    ref_c, mov_c = np.array([-60.0, 0.0]), np.array([55.0, 5.0])
    truth = [placed(0, *ref_c, 10.0), placed(1, *mov_c, 12.0)]
    frame = render(WIDE, PATTERN, truth, rng=5)
    found = decode_markers(frame, PATTERN)
    t = math.radians(12.0)
    want = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]]) @ (ref_c - mov_c)
    given = relative(found, 1, 0, PATTERN.period_um, pixel_um=WIDE.pixel_um)
    assert np.hypot(given.x_um[0] - want[0], given.y_um[0] - want[1]) < POSE_UM
    # the offset follows the scale given, not the markers' own: 0.5 % more, 0.5 % farther
    off = relative(found, 1, 0, PATTERN.period_um, pixel_um=1.005 * WIDE.pixel_um)
    ratio = np.hypot(off.x_um[0], off.y_um[0]) / np.hypot(given.x_um[0], given.y_um[0])
    assert abs(ratio - 1.005) < 1e-9
    assert off.theta_deg[0] == given.theta_deg[0]
    # the layout's hook passes the pixel size on to the relative pose
    hook = decode(frame[None], PATTERN, pixel_um=1.005 * WIDE.pixel_um, marker=1, reference=0)
    assert np.allclose([hook.x_um[0], hook.y_um[0]], [off.x_um[0], off.y_um[0]], atol=1e-9)
    with pytest.raises(ValueError, match="pixel_um"):
        relative(found, 1, 0, PATTERN.period_um, pixel_um=-1.0)


def test_a_missing_reference_is_a_status_not_a_pose():
    frames = np.stack(
        [render(WIDE, PATTERN, [placed(1, 50.0, 0.0, 5.0), placed(0, -60.0, 10.0, 5.0)], rng=1),
         render(WIDE, PATTERN, [placed(1, 50.0, 0.0, 5.0)], rng=2)]
    )  # fmt: skip
    out = decode(frames, PATTERN, marker=1, reference=0)
    assert out.status.tolist() == ["ok", "code_mismatch"]
    assert "reference" in out.reason[1] and "numbered 0" in out.reason[1]
    assert np.isfinite(out.x_um[0]) and np.isnan(out.x_um[1])
    alone = decode(frames, PATTERN)  # no marker named: the lowest number of the first frame
    assert alone.status.tolist() == ["ok", "code_mismatch"] and "numbered 0" in alone.reason[1]
    assert decode(frames, PATTERN, marker=1).status.tolist() == ["ok", "ok"]


def _bad_frames():
    from calflow.instruments.pattern.megarena import MegarenaPattern

    grid = Camera(width=480, height=400).render(MegarenaPattern(4.0, 6), 300.0, 300.0, 10.0, rng=1)
    other = HPCodePattern(4.0, 21)  # another marker size: its fiducials are farther apart
    return {
        "blank": np.zeros((400, 480), np.uint8),
        "saturated": np.full((400, 480), 255, np.uint8),
        "grid without markers": grid,
        "markers of another size": render(CAMERA, other, [placed(2, 0.0, 0.0, 10.0)], rng=4),
    }


@pytest.mark.parametrize("name", list(_bad_frames()))
def test_a_frame_without_markers_gets_a_status_and_one_reason(name):
    found = decode_markers(_bad_frames()[name], PATTERN)
    assert len(found) == 1 and found.status[0] in STATUSES and found.status[0] != "ok"
    assert "\n" not in found.reason[0] and found.reason[0]
    assert np.isnan(found.x_um).all() and found.number.tolist() == [-1]


def test_calflow_decode_writes_one_row_per_marker(tmp_path, capsys):
    import csv

    import tifffile

    from calflow.cli import main

    truth = [placed(7, -60.0, 0.0, 12.0), placed(300, 55.0, 5.0, 14.0)]
    frames = np.stack([render(WIDE, PATTERN, truth, rng=1), np.zeros((WIDE.height, WIDE.width), np.uint8)])
    tifffile.imwrite(tmp_path / "f.tif", frames, photometric="minisblack")
    (tmp_path / "p.json").write_text(json.dumps(PATTERN.to_library_dict()))
    out = tmp_path / "poses.csv"
    assert (
        main(["decode", str(tmp_path / "f.tif"), "--pattern", str(tmp_path / "p.json"), "--out", str(out)])
        == 0
    )
    rows = sorted(
        csv.DictReader(out.open()), key=lambda r: (r["page"], r["number"] == "", int(r["number"] or 0))
    )
    assert [(r["page"], r["number"], r["status"]) for r in rows] == [
        ("0", "7", "ok"),
        ("0", "300", "ok"),
        ("1", "", "bad_frame"),
    ]
    assert abs(float(rows[0]["x_um"]) - truth[0][1]) < POSE_UM and rows[2]["x_um"] == ""
    nc = tmp_path / "poses.nc"
    assert (
        main(["decode", str(tmp_path / "f.tif"), "--pattern", str(tmp_path / "p.json"), "--out", str(nc)])
        != 0
    )
    assert "one row per marker" in capsys.readouterr().err and not nc.exists()
