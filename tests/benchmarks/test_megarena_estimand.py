"""The quantity a Megarena decoder estimates on a distorted frame, and the dots' witness of it
(benchmarks/megarena_estimand.py, bench_megarena_witness.py, make_distorted_megarena.py).

The witness is checked on frames calflow's own camera renders and a known lens distortion
resamples: the truth is the uniform plane of the render's own lattice coordinates seen through
the map, pixel by pixel, which the witness never reads."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import megarena_estimand as me  # noqa: E402

from calflow.instruments.pattern import Camera  # noqa: E402
from calflow.instruments.pattern.megarena import MegarenaPattern  # noqa: E402

finite = st.floats(-50, 50, allow_nan=False)
shapes = st.tuples(st.integers(40, 90).map(lambda n: 2 * n), st.integers(40, 90).map(lambda n: 2 * n))


@settings(max_examples=30)
@given(shapes, st.lists(finite, min_size=6, max_size=6))
def test_the_plane_of_an_affine_lattice_is_that_lattice(shape, c):
    """Eq. (1) of an affine map: its own value at p₀ = (w/2, h/2) and its own slopes."""
    h, w = shape
    coef = np.array(c).reshape(2, 3) * np.array([1.0, 0.01, 0.01])
    m = me.LatticeMap(1, np.zeros((3, 2)), ((w - 1) / 2, (h - 1) / 2), max(h, w) / 2)
    # basis (1, ξ, η): the affine map L = a + b·x + c·y in those terms
    a, b, cc = coef[:, 0], coef[:, 1], coef[:, 2]
    m.coef = np.stack([a + b * m.centre[0] + cc * m.centre[1], b * m.scale, cc * m.scale])
    plane = (me.plane_operator(m, shape) @ m.coef).T
    _, _, (x0, y0) = me.library_region(h, w)
    assert (x0, y0) == (w // 2, h // 2)
    np.testing.assert_allclose(plane[:, 0], a + b * x0 + cc * y0, atol=1e-9)
    np.testing.assert_allclose(plane[:, 1:], coef[:, 1:], atol=1e-12)


@settings(max_examples=20)
@given(st.integers(1, 4), st.integers(0, 10_000))
def test_a_polynomial_map_is_recovered_from_exact_points(degree, seed):
    rng = np.random.default_rng(seed)
    shape = (120, 160)
    true = me.LatticeMap(degree, rng.normal(size=(len(me._exponents(degree)), 2)), (79.5, 59.5), 80.0)
    xy = rng.uniform([0, 0], [160, 120], size=(200, 2))
    fitted = me.fit_map(xy, true(xy[:, 0], xy[:, 1]), degree, shape)
    probe = rng.uniform([0, 0], [160, 120], size=(20, 2))
    np.testing.assert_allclose(fitted(*probe.T), true(*probe.T), atol=1e-8)


def test_an_undistorted_frame_has_its_affine_lattice_as_truth():
    affine = np.array([[3.0, 0.1, 0.02], [-1.0, -0.02, 0.1]])
    plane = me.true_plane(affine, me.radial_map((60, 80), (10.0, 50.0), 0.0), (60, 80))
    np.testing.assert_allclose(plane[:, 0], affine[:, 0] + affine[:, 1] * 40 + affine[:, 2] * 30)
    np.testing.assert_allclose(plane[:, 1:], affine[:, 1:], atol=1e-12)


@pytest.fixture(scope="module")
def distorted():
    """A calflow render (384 × 320, 8-pixel period) through a decentred radial distortion strong
    enough to tilt the central half's mean lattice, and its truth (library convention)."""
    import make_distorted_megarena as mk

    cam = Camera(width=384, height=320, sensor_pixel_um=5.0, magnification=10.0, bit_depth=12)
    pattern = MegarenaPattern(4.0, 6)
    pose, centre, k = (310.0, 400.0, 23.0), (330.0, 40.0), 0.02
    frame, truth = mk.distorted_frame(cam, pattern, pose, centre, k, np.random.default_rng(3))
    undistorted = me.library_pose(
        me.true_plane(mk.lattice_affine(cam, pattern, *pose), lambda x, y: (x, y), frame.shape),
        pattern.period_um,
        ((0, 1), (1, 1)),
        0.0,
    )
    return frame, truth, undistorted, pattern


def test_the_witness_recovers_the_distorted_frames_estimand(distorted):
    import bench_megarena_witness as bw

    frame, truth, undistorted, pattern = distorted
    est = bw.estimand_pose(frame, pattern.period_um, pattern.depth, truth, boot=100)
    E, u = est["pose"], est["u"]
    # the distortion moves the quantity well beyond the witness's uncertainty: a witness that
    # ignored it (the render's affine lattice) would fail the checks below
    tilt = abs(me._wrap(truth["alpha"] - undistorted["alpha"]))
    assert tilt > 20 * u["alpha"]
    assert est["degree"] >= 2
    assert abs(me._wrap(E["alpha"] - truth["alpha"])) < 4 * u["alpha"] + 1e-6
    for key in ("x", "y"):  # µm; positions modulo the period, here near the truth
        assert abs(E[key] - truth[key]) < 4 * u[key] + 2e-4
    assert abs(E["pixelSize"] / truth["pixelSize"] - 1) < 1e-4


def test_symmetric_dots_put_the_phase_at_their_centroids(distorted):
    import megarena_dots

    frame, truth, _, pattern = distorted
    s, t, c, period_px, bright = megarena_dots.dots(frame, pattern.depth, region=0.6)
    assert bright
    m = me.fit_map(c, np.stack([s, t], 1), 3, frame.shape)
    delta = me.dot_phase_offset(frame.astype(float), m, c, np.stack([s, t], 1), period_px)
    assert np.all(np.abs(delta) < 2e-3)  # periods: 0.016 pixel at this 8-pixel period
    # a dot made lopsided (a dimmer copy of the frame a quarter period along +x added) moves
    # the phase along the lattice coordinate that x advances, by a fraction of that shift
    from scipy.ndimage import shift

    lopsided = frame + 0.3 * shift(frame.astype(float), (0, 0.25 * period_px), order=3)
    moved = me.dot_phase_offset(lopsided, m, c, np.stack([s, t], 1), period_px)
    grad = np.array([m(c[:, 0] + 1, c[:, 1]) - m(c[:, 0], c[:, 1])]).mean(axis=1)[0]  # dL/dx
    expected = 0.25 * period_px * grad  # the copy's offset in lattice coordinates
    assert np.all(np.sign(moved) == np.sign(expected))
    assert np.all(np.abs(moved) > 0.1 * np.abs(expected))


def test_the_estimand_is_named_in_the_librarys_convention():
    """The lattice coordinate whose gradient points along α is x, the next along α + π/2 is y."""
    plane = np.array([[0.3, 0.0, 0.1], [0.2, -0.1, 0.0]])  # s along +y, t along −x
    (jx, sx), (jy, sy) = me.match_axes(plane, math.pi / 2)
    assert (jx, sx) == (0, 1) and (jy, sy) == (1, 1)
    pose = me.library_pose(plane, 9.0, ((jx, sx), (jy, sy)), 0.0)
    assert pose["alpha"] == pytest.approx(math.pi / 2)
    assert pose["x"] == pytest.approx(-9.0 * 0.3) and pose["y"] == pytest.approx(-9.0 * 0.2)
    assert pose["pixelSize"] == pytest.approx(0.9)


def test_the_distorted_frames_are_written_whole_with_their_truth(tmp_path):
    """make_distorted_megarena's command: every frame and the truth, renamed into place; with
    ``--pose`` every frame is a noise draw of one view, its truth the same each time."""
    import csv

    import make_distorted_megarena as mk
    import tifffile

    out = tmp_path / "frames"
    args = ["--frames", "3", "--size", "160x128", "--pixel-um", "0.5", "--period-um", "4", "--depth", "6"]
    assert mk.main([str(out), *args, "--k", "0", "--pose", "300,400,12"]) == 0
    rows = list(csv.DictReader(open(out / "truth.csv")))
    assert [r["file"] for r in rows] == ["d00.tiff", "d01.tiff", "d02.tiff"]
    assert not list(out.glob("*.part"))
    assert len({(r["x"], r["y"], r["alpha"]) for r in rows}) == 1
    assert float(rows[0]["alpha"]) == pytest.approx(math.radians(12), abs=1e-9)  # no distortion
    frames = [tifffile.imread(out / r["file"]) for r in rows]
    assert frames[0].shape == (128, 160) and not np.array_equal(frames[0], frames[1])  # noise draws


def test_a_sloping_background_does_not_move_the_witness(distorted):
    """The illumination's fall-off under the dots: a ramp and a broad glare added to the frame.
    The lobes' phase does not see them (no power near the lobes); centroids with a constant
    background per window are pulled uphill — the witness takes them on the frame less its
    smooth background, and stays on the truth."""
    import bench_megarena_witness as bw

    frame, truth, _, pattern = distorted
    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w]
    contrast = float(np.percentile(frame, 99) - np.percentile(frame, 1))
    glare = np.exp(-((x - 0.8 * w) ** 2 + (y - 0.3 * h) ** 2) / (2 * (0.3 * w) ** 2))
    lit = frame + contrast * (0.6 * x / w + 0.8 * glare)
    est = bw.estimand_pose(lit, pattern.period_um, pattern.depth, truth, boot=100)
    E, u, raw = est["pose"], est["u"], est["unflattened"]
    # the same centroids without the background taken off: off the truth, well beyond u
    moved = max(abs(raw[k] - truth[k]) / (u[k] + 2e-4) for k in ("x", "y"))
    assert moved > 4
    assert abs(me._wrap(E["alpha"] - truth["alpha"])) < 4 * u["alpha"] + 1e-6
    for key in ("x", "y"):
        assert abs(E[key] - truth[key]) < 4 * u[key] + 2e-4


def test_the_background_is_what_lies_under_the_dots():
    """On a smooth field with no dots the background is the field itself (within the opening's
    reach of its curvature); the dots of a render are cut off: what is left is nearly flat."""
    from megarena_dots import background

    y, x = np.mgrid[0:96, 0:128].astype(float)
    smooth = 100 + 0.5 * x + 0.2 * y
    np.testing.assert_allclose(background(smooth, 8.0)[16:-16, 16:-16], smooth[16:-16, 16:-16], atol=0.5)
    cam = Camera(width=128, height=96, sensor_pixel_um=5.0, magnification=10.0)
    frame = cam.render(MegarenaPattern(4.0, 6), 300.0, 400.0, 10.0, rng=1).astype(float)
    bg = background(frame, 8.0)
    assert np.ptp(bg[16:-16, 16:-16]) < 0.2 * np.ptp(frame[16:-16, 16:-16])


@pytest.mark.parametrize("sigma, centre", [(3.0, "integer"), (3.0, "fitted"), (8.0, "fitted")])
def test_the_librarys_estimator_finds_an_undistorted_lattice(sigma, centre):
    """The library's estimator as bench_megarena_residual changes it (band-pass about the peak bin
    or the frequency, of σ bins; the phase's plane over the central half) on a render of known
    lattice: its plane within the library's own code-dependent error of a small frame
    (10⁻³ period, 3·10⁻⁵ cycle per pixel), where a wrong lobe, sign or branch is off by far more."""
    import make_distorted_megarena as mk

    cam = Camera(width=384, height=320, sensor_pixel_um=5.0, magnification=10.0, bit_depth=12)
    pattern = MegarenaPattern(4.0, 6)
    pose = (310.0, 400.0, 23.0)
    frame, _ = mk.distorted_frame(cam, pattern, pose, (100.0, 100.0), 0.0, np.random.default_rng(3))
    truth = me.true_plane(mk.lattice_affine(cam, pattern, *pose), lambda x, y: (x, y), frame.shape)
    plane = me.band_pass_plane(frame.astype(float), truth[:, 1:], (sigma, sigma), centre, truth)
    np.testing.assert_allclose(plane[:, 0], truth[:, 0], atol=1e-3)
    np.testing.assert_allclose(plane[:, 1:], truth[:, 1:], atol=3e-5)
