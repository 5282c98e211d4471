"""Render → decode: the pose comes back within its stated uncertainty, or the frame says why not.

Frames here are small (a 224 × 192 camera of 1.2 µm pixels over a 2 × 1.5 mm pattern) to keep
the suite fast; the full-size figures are benchmarks/bench_pattern.py's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calflow.instruments.pattern import STATUSES, Camera, Pattern, decode

CAMERA = Camera(width=224, height=192, sensor_pixel_um=12.0)


@pytest.fixture(scope="module")
def pattern():
    return Pattern.make(range_um=(2000, 1500))


def _wrap(deg):
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


@given(
    x=st.floats(0, 2000),
    y=st.floats(0, 1500),
    theta=st.floats(-180, 180),
    seed=st.integers(0, 2**31),
)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_render_decode_recovers_the_pose_within_its_uncertainty(pattern, x, y, theta, seed):
    frame = CAMERA.render(pattern, x, y, theta, rng=seed)
    d = decode(frame, pattern, CAMERA)
    assert d.status[0] == "ok", d.reason[0]
    # 5 standard uncertainties, plus what the phase planes' model leaves (measured: < 0.05 nm)
    assert abs(d.x_um[0] - x) <= 5 * d.u_x_um[0] + 1e-4
    assert abs(d.y_um[0] - y) <= 5 * d.u_y_um[0] + 1e-4
    assert abs(_wrap(d.theta_deg[0] - theta)) <= 5 * d.u_theta_deg[0] + 1e-5
    assert 0 < d.u_x_um[0] < 0.01 and 0 < d.u_theta_deg[0] < 0.01


def test_batch_equals_frames_one_by_one(pattern):
    poses = np.array([[100.0, 200.0, 0.0], [1500.5, 700.25, 91.0], [20.0, 1490.0, -135.0]])
    frames = CAMERA.render_batch(pattern, poses, rng=7)
    assert frames.dtype == np.uint8 and frames.shape == (3, 192, 224)
    batch = decode(frames, pattern, CAMERA)
    for k in range(3):
        one = decode(frames[k], pattern, CAMERA)
        assert one.status[0] == batch.status[k] == "ok"
        np.testing.assert_allclose(one.x_um[0], batch.x_um[k], atol=1e-9)
    np.testing.assert_allclose(batch.x_um, poses[:, 0], atol=2e-3)
    np.testing.assert_allclose(_wrap(batch.theta_deg - poses[:, 2]), 0, atol=1e-3)


def test_dark_dots_and_sixteen_bits_decode(pattern):
    cam = dataclasses.replace(CAMERA, dot_level=0.1, background=0.8, bit_depth=12)
    frame = cam.render(pattern, 812.3, 640.7, 33.0, rng=3)
    assert frame.dtype == np.uint16 and frame.max() <= 4095
    d = decode(frame, pattern, cam)
    assert d.status[0] == "ok", d.reason[0]
    assert abs(d.x_um[0] - 812.3) < 2e-3 and abs(d.y_um[0] - 640.7) < 2e-3


def test_frames_that_cannot_be_decoded_say_why_and_give_nan(pattern):
    rng = np.random.default_rng(0)
    other = Pattern.make(range_um=(2000, 1500), period_um=4.0, x_order=10)  # another code, same grid
    frames = np.stack(
        [
            np.full((192, 224), 80, np.uint8),  # uniform
            rng.integers(0, 255, (192, 224)).astype(np.uint8),  # noise: no grid
            CAMERA.render(pattern, 1000, 700, 0, rng=1),
            CAMERA.render(pattern, 5000, 700, 0, rng=1),  # off the pattern
        ]
    )
    d = decode(frames, pattern, CAMERA)
    assert list(d.status[:2]) == ["bad_frame", "no_lobes"]
    assert d.status[2] == "ok"
    assert d.status[3] != "ok"
    for k in (0, 1, 3):
        assert np.isnan([d.x_um[k], d.y_um[k], d.theta_deg[k], d.u_x_um[k]]).all()
        assert d.status[k] in STATUSES and d.reason[k]
    # a frame of another pattern is never read as a place on this one
    if not np.array_equal(other.x_bits, pattern.x_bits):
        wrong = decode(CAMERA.render(other, 1000, 700, 10, rng=2), pattern, CAMERA)
        assert wrong.status[0] != "ok" or abs(wrong.x_um[0] - 1000) < 1e-2


def test_defects_dust_and_defocus_are_right_or_flagged(pattern):
    """Never a silent jump: every frame is right to well within a period, or not ok."""
    cam = dataclasses.replace(
        CAMERA, dust_count=2, dust_size_um=15, missing_dot_rate=0.05, extra_dot_rate=0.05, defocus_um=2.0
    )
    rng = np.random.default_rng(11)
    poses = np.c_[rng.uniform(0, 2000, 12), rng.uniform(0, 1500, 12), rng.uniform(-180, 180, 12)]
    d = decode(cam.render_batch(pattern, poses, rng=5), pattern, cam)
    ok = d.ok
    assert ok.sum() >= 10
    assert np.all(np.abs(d.x_um[ok] - poses[ok, 0]) < 0.05)
    assert np.all(np.abs(d.y_um[ok] - poses[ok, 1]) < 0.05)


@pytest.mark.parametrize(
    "frames, match",
    [
        (np.zeros((2, 3, 192, 224)), "shape"),
        (np.zeros((192, 224), dtype=complex), "dtype"),
        (np.zeros((192, 224), dtype=bool), "dtype"),
        (np.zeros((8, 8)), "16 × 16"),
        (np.zeros((100, 224)), "224 × 192 pixels"),
    ],
)
def test_bad_frames_raise_one_line(pattern, frames, match):
    with pytest.raises(ValueError, match=match) as err:
        decode(frames, pattern, CAMERA)
    assert "\n" not in str(err.value)


def test_field_of_view_too_small_raises(pattern):
    with pytest.raises(ValueError, match="field of view") as err:
        decode(np.zeros((100, 224)), pattern, pixel_um=CAMERA.pixel_um)
    assert "min_fov_um" in str(err.value)


def test_bad_pixel_size_raises(pattern):
    with pytest.raises(ValueError, match="pixel_um"):
        decode(np.zeros((192, 224)), pattern, pixel_um=-1.0)
