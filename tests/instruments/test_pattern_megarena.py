"""The Megarena layout: its code, its files (calflow's and the Vernier library's), its GDSII,
the layout registry, and its decoder on frames calflow's own camera renders.

A frame decodes to the pose it was rendered at (within a few nm and µdeg) or gets NaN, a
status and a reason; a neighbouring period (9 µm here) is a bug.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calflow.cli import main
from calflow.errors import CalflowError
from calflow.instruments.pattern import Camera, Pattern
from calflow.instruments.pattern.layouts import layouts, load_pattern, read_pattern
from calflow.instruments.pattern.megarena import MegarenaPattern, code_bits, decode, sequence
from calflow.instruments.pattern.megarena.commands import decode_parallel
from calflow.instruments.pattern.megarena.gds import read_gds_sites, write_gds

PERIOD = 4.0
DEPTH = 6  # 204 sites, 812 µm; a frame needs 3·(6 + 4) periods = 120 µm
CAMERA = Camera(width=384, height=336, sensor_pixel_um=5.0, magnification=10.0)  # 0.5 µm pixels
POSE_UM, THETA_DEG = 5e-3, 2e-3


@pytest.fixture(scope="module")
def pattern():
    return MegarenaPattern(PERIOD, DEPTH)


# -- the code ---------------------------------------------------------------------------------
@pytest.mark.parametrize("depth", range(4, 13))
def test_every_window_of_the_code_occurs_once(depth):
    bits = code_bits(depth)
    assert len(bits) == (1 << depth) + depth - 2
    windows = np.lib.stride_tricks.sliding_window_view(bits, depth) @ (1 << np.arange(depth))
    assert len(np.unique(windows)) == len(windows) == (1 << depth) - 1
    assert 0 not in windows  # the all-zero state is no state of a linear feedback register


@pytest.mark.parametrize("depth", (4, 9, 12))
def test_sequence_carries_the_code_every_third_entry(depth):
    s = sequence(depth)
    assert len(s) == 3 * len(code_bits(depth))
    assert (s[0::3] == 1).all() and (s[2::3] == 1).all()
    assert (s[1::3] == code_bits(depth)).all()


def test_sites_follow_the_layout_rule(pattern):
    m = MegarenaPattern(PERIOD, DEPTH, region_um=(0.0, 0.0, 100 * PERIOD, 100 * PERIOD)).matrix
    s = sequence(DEPTH)[:101].astype(bool)
    r, c = np.mgrid[0:101, 0:101]
    assert (m == (s[r] & s[c] & ~((r % 3 == 0) & (c % 3 == 0)))).all()
    assert not pattern.present(np.array([-1, 0, pattern.n_sites]), np.array([1, -1, 1])).any()


# -- the files --------------------------------------------------------------------------------
def test_file_round_trip(tmp_path, pattern):
    path = pattern.save(tmp_path / "p.json")
    back = load_pattern(path)
    assert isinstance(back, MegarenaPattern)
    assert (back.period_um, back.depth, back.region_um) == (
        pattern.period_um,
        pattern.depth,
        pattern.region_um,
    )


def test_library_file_is_read_as_it_is(tmp_path):
    text = {
        "MegarenaPattern": {
            "description": "a lab's target",
            "unit": "µm",
            "codeDepth": 12,
            "period": 9.0,
            "regionOfInterest": [0.0, 0.0, 3000.0, 2000.0],
            "author": "a lab",
            "date": "2022",
        }
    }
    path = tmp_path / "lab.json"
    path.write_text(json.dumps(text, ensure_ascii=False))
    p = load_pattern(path)
    assert (p.layout, p.depth, p.period_um, p.region_um) == ("megarena", 12, 9.0, (0.0, 0.0, 3000.0, 2000.0))
    again = read_pattern(MegarenaPattern(9.0, 12).to_library_dict())
    assert (again.depth, again.period_um) == (12, 9.0)


@pytest.mark.parametrize(
    "data, key",
    [
        ({"MegarenaPattern": {"period": 9.0, "codeDepth": 13}}, "MegarenaPattern.codeDepth"),
        ({"MegarenaPattern": {"period": -9.0, "codeDepth": 8}}, "MegarenaPattern.period"),
        ({"MegarenaPattern": {"codeDepth": 8}}, "MegarenaPattern.period"),
        (
            {"MegarenaPattern": {"period": 9.0, "codeDepth": 8, "regionOfInterest": [0, 0, 1]}},
            "regionOfInterest",
        ),
        ({"MegarenaPattern": {"period": 9.0, "codeDepth": 8, "dotSize": 9.0}}, "MegarenaPattern.dotSize"),
        ({"MegarenaPattern": {"period": 9.0, "bitSequence": [1, 0, 1]}}, "MegarenaPattern.bitSequence"),
        ({"PeriodicPattern": {"period": 9.0}}, "PeriodicPattern.nRows"),
        ({"PeriodicPattern": {"period": 9.0, "nRows": 37, "nCols": 31}}, "PeriodicPattern.nCols"),
        ({"HPCodePattern": {"period": 9.0, "size": 16}}, "HPCodePattern.size"),
        ({"format": "calflow-pattern", "version": 1, "layout": "hexagons"}, "layout"),
    ],
)
def test_bad_pattern_file_is_refused_in_one_line(tmp_path, data, key):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalflowError) as err:
        load_pattern(path)
    text = str(err.value)
    assert "\n" not in text and text.startswith(str(path)) and key in text


def test_calflow_file_with_a_changed_code_is_refused(tmp_path, pattern):
    data = pattern.to_dict()
    data["code_bits"] = data["code_bits"][:-1] + ("0" if data["code_bits"][-1] == "1" else "1")
    with pytest.raises(CalflowError, match="code_bits"):
        read_pattern(data, "p.json")


def test_registry_holds_both_layouts_and_reads_cell2x2(tmp_path):
    assert {"cell2x2", "megarena"} <= set(layouts())
    path = Pattern.make(range_um=(500.0, 400.0)).save(tmp_path / "c.json")
    assert load_pattern(path).layout == "cell2x2"


def test_gds_places_the_region_of_interest(tmp_path):
    p = MegarenaPattern(9.0, 8, region_um=(100.0, 50.0, 1200.0, 900.0))
    m = read_gds_sites(write_gds(p, tmp_path / "m.gds"), p)
    assert m.shape == p.matrix.shape and (m == p.matrix).all()


# -- decoding ---------------------------------------------------------------------------------
def _right(result, k, pose, pixel=None):
    assert result.status[k] == "ok", result.reason[k]
    assert abs(result.x_um[k] - pose[0]) < POSE_UM
    assert abs(result.y_um[k] - pose[1]) < POSE_UM
    assert abs((result.theta_deg[k] - pose[2] + 180) % 360 - 180) < THETA_DEG
    if pixel is not None:
        assert abs(result.pixel_um[k] / pixel - 1) < 1e-4
        assert 0 < result.u_pixel_um[k] < 1e-3 * pixel


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    x=st.floats(130.0, 680.0),  # the frame's half-diagonal is 128 µm: all of it on the pattern
    y=st.floats(130.0, 680.0),
    theta=st.floats(-180.0, 180.0),
    dark=st.booleans(),
    given_pixel=st.booleans(),
)
def test_rendered_frames_decode_to_their_pose_or_nan(pattern, x, y, theta, dark, given_pixel):
    cam = Camera(**{**CAMERA.__dict__, "dot_level": 0.1 if dark else 1.0})
    frame = cam.render(pattern, x, y, theta)  # noise-free: the decoder's own error
    r = decode(frame, pattern, pixel_um=cam.pixel_um if given_pixel else None)
    if r.status[0] == "ok":
        _right(r, 0, (x, y, theta), cam.pixel_um)
    else:  # never a pose it cannot vouch for
        assert math.isnan(r.x_um[0]) and r.reason[0]


def test_noisy_frames_decode_and_uncertainty_is_of_the_noise(pattern):
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(100, 700, 6), rng.uniform(100, 700, 6), rng.uniform(-180, 180, 6)])
    frames = CAMERA.render_batch(pattern, poses, rng=rng)
    r = decode(frames, pattern)
    for k, pose in enumerate(poses):
        assert r.status[k] == "ok", r.reason[k]
        err = math.hypot(r.x_um[k] - pose[0], r.y_um[k] - pose[1])
        assert err < 0.02  # 8-bit noise on a 256 × 224 frame: a few nm
        assert 0 < r.u_x_um[k] < 0.02 and 0 < r.u_theta_deg[k] < 0.01


def test_library_convention_is_the_equation_of_the_docs(pattern):
    """x_lib, y_lib = −(the pattern point at pixel (w/2, h/2)); alpha the x axis's direction."""
    x, y, theta = 300.0, 420.0, 33.0
    r = decode(CAMERA.render(pattern, x, y, theta), pattern)
    lib = r.library_pose()
    t = math.radians(theta)
    half = 0.5 * CAMERA.pixel_um  # pixel (w/2, h/2) is half a pixel right of and below the centre
    px = x + math.cos(t) * half + math.sin(t) * half
    py = y - math.sin(t) * half + math.cos(t) * half
    assert abs(lib["x"][0] + px) < POSE_UM and abs(lib["y"][0] + py) < POSE_UM
    assert abs(lib["alpha"][0] - t) < math.radians(THETA_DEG)
    assert abs(lib["pixelSize"][0] / CAMERA.pixel_um - 1) < 1e-4


def test_central_fit_region_agrees_on_an_undistorted_frame(pattern):
    frame = CAMERA.render(pattern, 400.0, 300.0, -70.0)
    whole, central = decode(frame, pattern), decode(frame, pattern, fit_region=0.5)
    _right(central, 0, (400.0, 300.0, -70.0))
    assert abs(whole.x_um[0] - central.x_um[0]) < POSE_UM


def test_parallel_decoding_gives_the_same_result(pattern):
    poses = np.column_stack([np.linspace(100, 600, 8), np.linspace(650, 150, 8), np.linspace(-170, 170, 8)])
    frames = CAMERA.render_batch(pattern, poses, rng=5)
    one, two = decode(frames, pattern, workers=1), decode_parallel(frames, pattern, jobs=2)
    assert (one.status == two.status).all()
    np.testing.assert_array_equal(one.x_um, two.x_um)
    np.testing.assert_array_equal(one.pixel_um, two.pixel_um)


class _Grid:
    """A dot grid with every site present: periodic, no code."""

    layout, period_um, dot_diameter_um, origin_um = "grid", PERIOD, PERIOD / 2, (0.0, 0.0)

    def present(self, rows, cols):
        return np.ones(np.broadcast_shapes(np.shape(rows), np.shape(cols)), bool)


def _frames_that_are_no_position(pattern):
    cam8 = CAMERA
    full = cam8.render(_Grid(), 200.0, 200.0, 10.0, rng=1)
    other = cam8.render(Pattern.make(range_um=(400.0, 400.0)), 150.0, 150.0, 5.0, rng=2)
    sat = np.full((CAMERA.height, CAMERA.width), 255, np.uint8)
    half = cam8.render(pattern, 300.0, 300.0, 0.0, rng=3)
    half[:, : int(0.6 * CAMERA.width)] = 255
    return {
        "a periodic grid with no code": full,
        "a frame of another layout": other,
        "a blank frame": np.zeros_like(sat),
        "a saturated frame": sat,
        "a mostly saturated frame": half,
        "noise alone": np.random.default_rng(4).integers(0, 255, sat.shape).astype(np.uint8),
    }


@pytest.mark.parametrize(
    "name",
    [
        "a periodic grid with no code",
        "a frame of another layout",
        "a blank frame",
        "a saturated frame",
        "a mostly saturated frame",
        "noise alone",
    ],
)
def test_bad_frames_get_a_status_and_a_reason_never_a_pose(pattern, name):
    frame = _frames_that_are_no_position(pattern)[name]
    for pixel in (None, CAMERA.pixel_um):
        r = decode(frame, pattern, pixel_um=pixel)
        assert r.status[0] != "ok" and r.reason[0], name
        assert np.isnan([r.x_um[0], r.y_um[0], r.theta_deg[0], r.pixel_um[0]]).all()


def test_frame_of_another_period_is_refused_when_the_pixel_size_is_given(pattern):
    frame = CAMERA.render(MegarenaPattern(6.0, DEPTH), 300.0, 300.0, 0.0, rng=1)
    r = decode(frame, pattern, pixel_um=CAMERA.pixel_um)
    assert r.status[0] == "no_lobes" and "4 µm" in r.reason[0], r.reason[0]


@pytest.mark.parametrize("seed", range(4))
def test_few_bits_in_view_give_the_right_place_or_nan(seed):
    """A 12-bit code seen over 13–15 bits: a place only from overwhelming majorities, else NaN."""
    deep = MegarenaPattern(PERIOD, 12)
    rng = np.random.default_rng(seed)
    pose = (rng.uniform(1000, 45000), rng.uniform(1000, 45000), rng.uniform(-180, 180))  # 49 mm target
    r = decode(CAMERA.render(deep, *pose, rng=rng), deep)
    if r.status[0] == "ok":
        assert math.hypot(r.x_um[0] - pose[0], r.y_um[0] - pose[1]) < 0.05
    else:
        assert r.status[0] in ("ambiguous", "fov_too_small") and np.isnan(r.x_um[0])


def test_too_small_a_field_of_view_says_so():
    deep = MegarenaPattern(PERIOD, 12)  # needs 39 periods, the frame shows 42 across at best
    r = decode(CAMERA.render(deep, 500.0, 700.0, 12.0, rng=1)[:200, :200], deep, pixel_um=CAMERA.pixel_um)
    assert r.status[0] in ("fov_too_small", "ambiguous") and "code" in r.reason[0]


def test_a_frame_partly_beyond_the_targets_edge_decodes_or_says_why(tmp_path):
    """calflow's own target (``pattern make``) has its origin half a field of view inside, so
    every frame centre of [0, range] decodes; near (0, 0) part of the frame is off the target."""
    assert main(
        [
            "pattern",
            "make",
            "--layout",
            "megarena",
            "--range",
            "400x300",
            "--period-um",
            "4",
            "--out",
            str(tmp_path),
        ]
    ) in (0, None)
    made = load_pattern(tmp_path / "pattern.json")
    assert made.range_um == (400.0, 300.0) and made.origin_um[0] > 0
    for k, pose in enumerate([(0.0, 0.0, 0.0), (400.0, 0.0, 3.0), (0.0, 300.0, -3.0), (400.0, 300.0, 90.0)]):
        r = decode(CAMERA.render(made, *pose, rng=k), made, pixel_um=CAMERA.pixel_um)
        _right(r, 0, pose)
        lib = r.library_pose()  # the library's coordinates have no origin
        assert abs(-lib["x"][0] - (pose[0] + made.origin_um[0])) < 0.5


def test_the_images_sensor_reads_a_megarena_target(tmp_path):
    import types

    from calflow.xytheta.stage.images import ImageSensor, check

    assert main(
        [
            "pattern",
            "make",
            "--layout",
            "megarena",
            "--range",
            "600x500",
            "--period-um",
            "4",
            "--out",
            str(tmp_path),
        ]
    ) in (0, None)
    path = str(tmp_path / "pattern.json")
    camera = {"width": 384, "height": 336}
    assert check(sensor="images", camera=camera, pattern=path, range_um=(600.0, 500.0))["pattern"] == path
    sensor = ImageSensor(
        types.SimpleNamespace(pattern_range_um=(600.0, 500.0)), {"camera": camera, "pattern": path}, seed=1
    )
    x, y, t = np.array([0.0, 300.0, 600.0]), np.array([500.0, 250.0, 0.0]), np.array([0.5, -1.0, 2.0])
    r = sensor.read(x, y, t)
    assert np.all(r["decode_status"] == 0)
    assert np.max(np.abs(r["meas_x"] - x)) < 0.01 and np.max(np.abs(r["meas_y"] - y)) < 0.01


def test_sixteen_bit_frames_decode_like_eight_bit_ones(pattern):
    deep = Camera(**{**CAMERA.__dict__, "bit_depth": 12})
    frame = deep.render(pattern, 333.0, 444.0, -33.0, rng=2)
    assert frame.dtype == np.uint16
    _right(decode(frame, pattern), 0, (333.0, 444.0, -33.0))


@settings(max_examples=60, deadline=None)
@given(
    shape=st.tuples(st.integers(1, 30), st.integers(1, 30)),
    first=st.tuples(st.integers(-50, 50), st.integers(-50, 50)),
    seed=st.integers(0, 2**32 - 1),
    misread=st.floats(0.0, 0.6),
)
def test_the_arrangements_scores_are_the_sites_own(shape, first, seed, misread):
    """The 36 arrangements scored from nine class counts: the scores a pass over every site
    (the holes that must be empty, the always-full classes' sites that must carry dots) gives."""
    from calflow.instruments.pattern.megarena.reading import classes

    rng = np.random.default_rng(seed)
    S, T = np.arange(shape[1]) + first[0], np.arange(shape[0]) + first[1]
    a0, b0 = rng.integers(3, size=2)
    present = ~(((S % 3)[None, :] == a0) & ((T % 3)[:, None] == b0))  # a grid whose holes are (a0, b0)
    present ^= rng.random(shape) < misread
    known = rng.random(shape) < 0.9
    rs, rt = (S % 3)[None, :], (T % 3)[:, None]
    scores = []
    for a in range(3):
        for b in range(3):
            hole = known & (rs == a) & (rt == b)
            for ds in (1, -1):
                for dt in (1, -1):
                    a2, b2 = (a + (2 if ds > 0 else 1)) % 3, (b + (2 if dt > 0 else 1)) % 3
                    full = known & ((rs == a) | (rs == a2)) & ((rt == b) | (rt == b2)) & ~hole
                    sure = int(hole.sum() + full.sum())
                    if sure:
                        bad = int((present & hole).sum() + (~present & full).sum())
                        scores.append((bad / sure, (a, ds, b, dt)))
    scores.sort(key=lambda s: s[0])
    got = classes(present, known, S, T)
    if not scores or scores[0][0] > 0.2:
        assert got is None
    else:
        assert got == (scores[0][1], scores[1][0] - scores[0][0], scores[0][0])
