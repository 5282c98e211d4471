"""One pixel size pooled over a sequence of HP-code frames (:mod:`.hpcode.scale`): the pool
recovers the pixel size within the uncertainty it states from the frames' scatter, leaves a
misfitted frame out, and says in words when the magnification drifts instead of hiding it.

The pooling's statistics are checked on marker tables built with a known scatter; the
decoder's side on sequences calflow's own renderer draws at known, jittered or drifting
magnifications."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.hpcode import (
    HPCodePattern,
    at_scale,
    decode_markers,
    pool_pixel,
    relative,
)
from calflow.instruments.pattern.hpcode.decode import EXTRA, FIELDS, Markers
from calflow.instruments.pattern.hpcode.render import render

PATTERN = HPCodePattern(4.0, 17)
# the fit's own bias of the pixel size on the renderer's noise-free frames (pose.py: < 2e-5)
RENDER_BIAS = 5e-5


def table(pixels: np.ndarray, u_fit: float = 1e-6) -> Markers:
    """A marker table of two markers (0 and 1) a frame, with these pixel sizes (n, 2) µm."""
    n = len(pixels)
    cols = {k: np.full(2 * n, np.nan) for k in FIELDS + EXTRA}
    cols["pixel_um"] = pixels.reshape(-1).astype(float)
    cols["u_pixel_um"] = np.full(2 * n, u_fit)
    return Markers(
        frame=np.repeat(np.arange(n), 2),
        number=np.tile([0, 1], n),
        columns=cols,
        status=np.full(2 * n, "ok"),
        reason=np.full(2 * n, "decoded"),
        n_frames=n,
        shape=(400, 480),
    )


@settings(max_examples=30, deadline=None, derandomize=True)
@given(
    truth=st.floats(0.1, 5.0),
    sigma=st.floats(1e-5, 1e-3),
    n=st.integers(10, 60),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_pool_recovers_the_pixel_size_within_its_uncertainty(truth, sigma, n, seed):
    rng = np.random.default_rng(seed)
    pixels = truth * (1 + sigma * rng.standard_normal((n, 2)))
    pool = pool_pixel(table(pixels))
    # 6 u: the uncertainty is the frames' scatter over √n_eff, not the fits' stated 1e-6 µm
    assert abs(pool.pixel_um - truth) < 6 * pool.u_pixel_um
    assert pool.u_pixel_um > 0.2 * truth * sigma / math.sqrt(2 * n)
    assert pool.scatter_um > 0.3 * truth * sigma / math.sqrt(2)
    assert pool.u_fit_um == pytest.approx(1e-6)


@settings(max_examples=20, deadline=None, derandomize=True)
@given(n=st.integers(10, 40), bad=st.integers(0, 9), factor=st.sampled_from([0.98, 1.03, 1.5]))
def test_a_misfitted_frame_is_left_out(n, bad, factor):
    rng = np.random.default_rng(n)
    pixels = 0.5 * (1 + 1e-4 * rng.standard_normal((n, 2)))
    pixels[bad] *= factor
    pool = pool_pixel(table(pixels))
    # the misfitted frame is left out; a good one only rarely (5 robust σ, from n frames)
    assert bad in pool.rejected and len(pool.rejected) <= 2
    assert pool.n_frames == n - len(pool.rejected)
    assert abs(pool.pixel_um / 0.5 - 1) < 1e-4


def test_a_steady_sequence_is_not_said_to_drift():
    rng = np.random.default_rng(7)
    pool = pool_pixel(table(0.5 * (1 + 1e-4 * rng.standard_normal((40, 2)))), time_s=np.arange(40) * 2.0)
    assert not pool.drifts and "no drift" in pool.statement
    assert pool.attrs()["pixel_size_drifts"] == "no"


@settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(12, 60), change=st.floats(1e-3, 1e-2), sign=st.sampled_from([-1, 1]))
def test_a_drifting_magnification_is_said_in_words(n, change, sign):
    # the magnification changes by 10 to 100 times a frame's scatter over the sequence
    rng = np.random.default_rng(n)
    ramp = sign * change * np.linspace(0, 1, n)[:, None]
    pool = pool_pixel(table(0.5 * (1 + ramp + 1e-4 * rng.standard_normal((n, 2)))))
    assert pool.drifts and pool.magnification_drifts and "The magnification drifts" in pool.statement
    assert np.sign(pool.drift_um) == sign
    assert abs(pool.drift_um - 0.5 * sign * change) < 5 * pool.u_drift_um + 0.5 * 1e-4
    assert pool.attrs()["pixel_size_drifts"] == "yes"


def test_one_marker_trending_is_not_called_the_magnification():
    # the moving marker's pixel size follows its travel, the fixed one's does not (Image140)
    rng = np.random.default_rng(11)
    pixels = 0.5 * (1 + 1e-4 * rng.standard_normal((40, 2)))
    pixels[:, 1] *= 1 + 5e-4 * np.linspace(0, 1, 40)
    pool = pool_pixel(table(pixels), [0, 1])
    assert pool.drifts and not pool.magnification_drifts and pool.trending == (1,)
    assert "Not a change of the magnification" in pool.statement and "marker 0's not" in pool.statement
    assert pool.attrs()["pixel_size_trend_markers"] == "1"
    # both markers alike: the magnification
    pixels[:, 0] *= 1 + 5e-4 * np.linspace(0, 1, 40)
    both = pool_pixel(table(pixels), [0, 1])
    assert both.magnification_drifts and both.trending == (0, 1)
    assert "The magnification drifts" in both.statement


def test_the_pool_only_takes_the_markers_named_and_needs_frames():
    pixels = np.column_stack([np.full(10, 0.5), np.full(10, 0.6)])
    pixels = pixels * (1 + 1e-5 * np.random.default_rng(1).standard_normal((10, 2)))
    assert pool_pixel(table(pixels), [0]).pixel_um == pytest.approx(0.5, rel=1e-4)
    assert pool_pixel(table(pixels), [1, None]).pixel_um == pytest.approx(0.6, rel=1e-4)
    with pytest.raises(ValueError, match="pixel_size: expected at least 5 frames"):
        pool_pixel(table(pixels[:4]))


def test_at_scale_keeps_directions_and_sets_lengths():
    found = table(np.array([[0.5, 0.4]]))
    found.columns["x_um"][:] = [10.0, -20.0]
    found.columns["y_um"][:] = [5.0, 8.0]
    found.columns["u_x_um"][:] = 0.01
    found.columns["u_y_um"][:] = 0.01
    found.columns["theta_deg"][:] = [3.0, 4.0]
    scaled = at_scale(found, 0.45, 0.45e-4)
    assert np.allclose(scaled.x_um, [9.0, -22.5]) and np.allclose(scaled.y_um, [4.5, 9.0])
    assert np.array_equal(scaled.theta_deg, found.theta_deg)
    assert np.allclose(scaled.pixel_um, 0.45) and np.allclose(scaled.u_pixel_um, 0.45e-4)
    assert np.allclose(scaled.u_x_um, np.hypot([0.009, 0.01125], np.abs([9.0, -22.5]) * 1e-4))


# -- rendered sequences ------------------------------------------------------------------------
def _sequence(magnifications, seed=0):
    """Frames of two markers (0 fixed, 1 beside it) at these magnifications, each frame's pixel
    size the camera model's 6.0 µm sensor pixel over its magnification."""
    frames, cameras = [], []
    for k, m in enumerate(magnifications):
        cam = Camera(width=640, height=560, magnification=m)
        frames.append(
            render(cam, PATTERN, [(0, 60.0, 0.0, 2.0), (1, -55.0, -3.0 - 0.2 * k, 2.5)], rng=seed + k)
        )
        cameras.append(cam)
    return np.stack(frames), cameras


def test_a_rendered_sequence_pools_its_known_pixel_size():
    rng = np.random.default_rng(3)
    base = Camera(width=640, height=560).magnification
    mags = base * (1 + 3e-4 * rng.standard_normal(8))  # each frame's own optics, jittered
    frames, cameras = _sequence(mags)
    truth = np.array([c.pixel_um for c in cameras])
    found = decode_markers(frames, PATTERN)
    assert (found.status == "ok").sum() == 16, found.reason
    pool = pool_pixel(found, [1, 0])
    assert pool.n_frames == 8 and not pool.drifts
    # within its uncertainty of the frames' mean truth, beside the renderer's known bias
    assert abs(pool.pixel_um / truth.mean() - 1) < 3 * pool.u_pixel_um / pool.pixel_um + RENDER_BIAS
    assert pool.u_pixel_um / pool.pixel_um > 3e-4 / math.sqrt(8) * 0.3  # the scatter's, not the fit's
    rel = relative(found, 1, 0, PATTERN.period_um, pool.pixel_um, pool.u_pixel_um)
    own = relative(found, 1, 0, PATTERN.period_um)
    assert (rel.status == "ok").all()
    assert np.all(rel.u_x_um > 0) and not np.allclose(rel.x_um, own.x_um, rtol=0, atol=1e-6)


def test_a_rendered_drifting_magnification_is_flagged():
    base = Camera(width=640, height=560).magnification
    frames, _ = _sequence(base * (1 + np.linspace(0, 4e-3, 8)))
    pool = pool_pixel(decode_markers(frames, PATTERN), [0, 1], time_s=np.arange(8) * 5.0)
    assert pool.drifts, pool.statement
    # a rising magnification is a shrinking pixel: 0.4 % over the sequence
    assert pool.drift_um < 0 and abs(pool.drift_um / pool.pixel_um + 4e-3) < 1e-3
    assert "The magnification drifts" in pool.statement


# -- calflow decode --pixel-size sequence ------------------------------------------------------
def test_decode_pools_the_pixel_size_on_request(tmp_path, capsys):
    import csv

    import tifffile

    from calflow.cli import main

    frames, cameras = _sequence([Camera(width=640, height=560).magnification] * 6)
    tifffile.imwrite(tmp_path / "frames.tif", frames, photometric="minisblack")
    pattern = PATTERN.save(tmp_path / "markers.json")
    argv = ["decode", str(tmp_path / "frames.tif"), "--pattern", str(pattern), "--jobs", "1"]
    assert main([*argv, "--pixel-size", "sequence", "--out", str(tmp_path / "pooled.csv")]) == 0
    assert "pooled over 6 frames" in capsys.readouterr().err
    assert main([*argv, "--out", str(tmp_path / "own.csv")]) == 0
    pooled = list(csv.DictReader(open(tmp_path / "pooled.csv")))
    own = list(csv.DictReader(open(tmp_path / "own.csv")))
    assert len(pooled) == len(own) == 12
    assert len({r["pixel_um"] for r in pooled}) == 1 and len({r["pixel_um"] for r in own}) > 1
    for p, o in zip(pooled, own):  # the pose rescaled, the direction kept
        ratio = float(p["pixel_um"]) / float(o["pixel_um"])
        assert float(p["x_um"]) == pytest.approx(float(o["x_um"]) * ratio, rel=1e-5, abs=2e-6)
        assert p["theta_deg"] == o["theta_deg"]
    capsys.readouterr()
    assert main([*argv, "--pixel-size", "sequence", "--pixel-um", "0.375"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--pixel-size sequence" in err[0] and "--pixel-um" in err[0]
    import json

    from calflow.instruments.pattern.megarena import MegarenaPattern

    (tmp_path / "megarena.json").write_text(json.dumps(MegarenaPattern(4.0, 6).to_library_dict()))
    argv[3] = str(tmp_path / "megarena.json")
    assert main([*argv, "--pixel-size", "sequence"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "only for HP-code markers" in err[0] and "megarena" in err[0]
