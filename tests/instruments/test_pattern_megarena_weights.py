"""The phase planes' weights: calflow's (the lobe's power) and the Vernier library's (equal).

On a frame a lens distorts, the lattice's phase curves and a plane fitted to it is a mean
lattice that depends on the weights. The library's estimand is the equal-weight plane of the
lattice's own coordinates over the frame's central half; ``plane_weights="uniform"`` is
calflow's estimate of it, the default ``"power"`` another mean. Frames: calflow's camera,
noise-free, resampled through a known decentred radial distortion (as
benchmarks/make_distorted_megarena.py does, on a small frame), the truth computed pixel by
pixel from the render's pose and the map.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from calflow.cli import main
from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.megarena import MegarenaPattern, decode

SIDE, PIXEL_UM = 448, 0.9
PATTERN = MegarenaPattern(9.0, 8, dot_diameter_um=4.5)
CAMERA = Camera(width=SIDE, height=SIDE, sensor_pixel_um=10 * PIXEL_UM, magnification=10.0)


def _distorted(seed: int, k: float):
    """A frame through q = c + (p − c)(1 + k|p − c|²/R²) and the angle (rad) of its lattice's
    x axis in the equal-weight plane over the central half (the library's region)."""
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(seed)
    x, y, theta = rng.uniform(300, 900), rng.uniform(300, 900), rng.uniform(-180, 180)
    c = rng.uniform(0, SIDE, 2)
    R2 = 2 * (SIDE - 1) ** 2 / 4.0

    def q(px, py):
        dx, dy = px - c[0], py - c[1]
        f = 1.0 + k * (dx * dx + dy * dy) / R2
        return c[0] + dx * f, c[1] + dy * f

    py, px = np.mgrid[0:SIDE, 0:SIDE].astype(float)
    qx, qy = q(px, py)
    frame = map_coordinates(CAMERA.expectation(PATTERN, x, y, theta), [qy, qx], order=3, mode="reflect")
    # the undistorted lattice's x coordinate is affine in the pixel: from the camera's object points
    U, _ = np.broadcast_arrays(
        *CAMERA.object_points(x + PATTERN.origin_um[0], y + PATTERN.origin_um[1], theta)
    )
    A = np.stack([np.ones(px[::7, ::7].size), px[::7, ::7].ravel(), py[::7, ::7].ravel()], 1)
    affine = np.linalg.lstsq(A, U[::7, ::7].ravel(), rcond=None)[0]
    lo, n = SIDE // 4, SIDE - 2 * (SIDE // 4)
    rx, ry = qx[lo : lo + n, lo : lo + n].ravel(), qy[lo : lo + n, lo : lo + n].ravel()
    L = affine[0] + affine[1] * rx + affine[2] * ry  # the lattice's x coordinate seen at each pixel
    B = np.stack(
        [np.ones(L.size), px[lo : lo + n, lo : lo + n].ravel(), py[lo : lo + n, lo : lo + n].ravel()], 1
    )
    plane = np.linalg.lstsq(B, L, rcond=None)[0]
    return frame.astype(np.float32), math.atan2(plane[2], plane[1])


def _angle_error(result, truth: float) -> float:
    return 1e6 * ((float(result.library_pose()["alpha"][0]) - truth + math.pi) % (2 * math.pi) - math.pi)


def test_uniform_weights_estimate_the_equal_weight_plane_of_a_distorted_frame():
    power, uniform = [], []
    for seed in range(6):
        frame, truth = _distorted(seed, 0.01)
        a = decode(frame, PATTERN, fit_region=0.5, workers=1)
        b = decode(frame, PATTERN, fit_region=0.5, plane_weights="uniform", workers=1)
        assert a.status[0] == b.status[0] == "ok"
        power.append(_angle_error(a, truth))
        uniform.append(_angle_error(b, truth))
    rms_power, rms_uniform = (float(np.sqrt(np.mean(np.square(e)))) for e in (power, uniform))
    assert rms_power > 50.0  # the lobe's power gives another mean lattice here
    assert rms_uniform < 0.4 * rms_power, (power, uniform)


def test_the_weights_agree_on_an_undistorted_frame_and_power_has_the_smaller_variance():
    for seed in range(3):
        frame, truth = _distorted(seed, 0.0)
        rng = np.random.default_rng(seed)
        noisy = frame + rng.normal(0.0, 0.05 * float(np.ptp(frame)), frame.shape).astype(np.float32)
        a = decode(noisy, PATTERN, fit_region=0.5, workers=1)
        b = decode(noisy, PATTERN, fit_region=0.5, plane_weights="uniform", workers=1)
        assert abs(_angle_error(a, truth)) < 5 * 1e6 * math.radians(a.u_theta_deg[0]) + 5.0
        assert abs(_angle_error(b, truth)) < 5 * 1e6 * math.radians(b.u_theta_deg[0]) + 5.0
        # Gauss–Markov: the power weights are the phase noise's inverse variance
        for key in ("u_x_um", "u_y_um", "u_theta_deg"):
            assert getattr(b, key)[0] >= getattr(a, key)[0] * (1 - 1e-9), key


def test_uniform_weights_over_the_whole_frame_decode():
    frame, _ = _distorted(1, 0.0)
    r = decode(frame, PATTERN, plane_weights="uniform", workers=1)
    assert r.status[0] == "ok" and np.isfinite(r.u_theta_deg[0])


def test_misspelt_weights_are_refused_in_one_line():
    frame, _ = _distorted(0, 0.0)
    with pytest.raises(ValueError, match=r"^plane_weights: expected one of power, uniform, got 'unifrom'$"):
        decode(frame, PATTERN, plane_weights="unifrom")


def test_the_cli_refuses_misspelt_weights(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["decode", "frame.tiff", "--pattern", "p.json", "--plane-weights", "equal"])
    assert exc.value.code != 0
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--plane-weights" in err and "equal" in err


def test_the_vernier_convention_is_the_librarys_estimand_unless_told_otherwise(tmp_path, capsys):
    import tifffile

    frame, _ = _distorted(3, 0.01)  # a frame where the two conventions' angles differ
    tifffile.imwrite(tmp_path / "f.tif", frame)
    spec = PATTERN.save(tmp_path / "p.json")
    expected = {
        (): decode(frame, PATTERN, fit_region=0.5, plane_weights="uniform").library_pose(),
        ("--plane-weights", "power", "--fit-region", "1"): decode(frame, PATTERN).library_pose(),
    }
    assert (
        abs(
            expected[()]["alpha"][0] - expected[("--plane-weights", "power", "--fit-region", "1")]["alpha"][0]
        )
        > 5e-5
    )
    for extra, pose in expected.items():
        capsys.readouterr()
        base = ["decode", str(tmp_path / "f.tif"), "--pattern", str(spec), "--convention", "vernier"]
        assert main([*base, *extra, "--jobs", "1"]) == 0
        row = capsys.readouterr().out.strip().splitlines()[1].split(",")
        assert row[-2] == "ok"
        for col, key in zip(row[2:6], ("x", "y", "alpha", "pixelSize")):
            assert float(col) == pytest.approx(float(pose[key][0]), rel=1e-6), key  # the CSV keeps 7 digits


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(64, 400),
    w=st.integers(64, 400),
    period=st.floats(5.0, 20.0),
    fraction=st.floats(0.3, 0.9),
)
def test_the_region_shares_count_the_regions_pixels(h, w, period, fraction):
    """Σ share·(coarse step)² is the region's pixel count: each pixel of the region alike."""
    from calflow.instruments.pattern.phase import PhaseFitter

    f = PhaseFitter((h, w), 1.0 / period, workers=1, pad=True)
    # the samples' cells end half a coarse step before the far edges: regions within them
    assume(int(h * (1 - fraction) / 2) >= f.h / f.ni / 2 and int(w * (1 - fraction) / 2) >= f.w / f.nj / 2)
    share = f.region_share(fraction)
    assert share.min() >= 0.0 and share.max() <= 1.0 + 1e-12
    rows = h - 2 * int(h * (1 - fraction) / 2)
    cols = w - 2 * int(w * (1 - fraction) / 2)
    area = share.sum() * (f.h / f.ni) * (f.w / f.nj)
    assert area == pytest.approx(rows * cols, rel=1e-9)


def test_plane_weights_on_another_layout_are_refused_in_one_line(tmp_path, capsys):
    import tifffile

    from calflow.instruments.pattern import Pattern

    spec = Pattern.make(range_um=(500.0, 400.0)).save(tmp_path / "c.json")
    tifffile.imwrite(tmp_path / "f.tif", np.zeros((64, 64), np.uint16))
    capsys.readouterr()
    assert (
        main(["decode", str(tmp_path / "f.tif"), "--pattern", str(spec), "--plane-weights", "uniform"]) != 0
    )
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--plane-weights" in err and "Megarena" in err


def test_the_envelope_is_fitted_beside_the_lattices_curvature():
    """A strongly distorted frame lit unevenly (a 40 % decentred fall-off): the envelope's
    coefficient fitted beside a plane alone takes up part of the curved phase through the
    regressors' smooth part and tilts the plane (48 µrad rms on these frames); fitted beside a
    cubic surface — a radial lens's phase — it does not."""
    errors = []
    y, x = np.mgrid[0:SIDE, 0:SIDE]
    light = 1 - 0.4 * ((x - 0.2 * SIDE) ** 2 + (y - 0.7 * SIDE) ** 2) / SIDE**2
    for seed in range(6):
        frame, truth = _distorted(seed, 0.01)
        b = decode(
            (frame * light).astype(np.float32), PATTERN, fit_region=0.5, plane_weights="uniform", workers=1
        )
        assert b.status[0] == "ok"
        errors.append(_angle_error(b, truth))
    assert float(np.sqrt(np.mean(np.square(errors)))) < 32.0, errors


@settings(max_examples=40, deadline=None)
@given(
    c=st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2),
    cubic=st.lists(st.floats(-0.3, 0.3), min_size=7, max_size=7),
    seed=st.integers(0, 2**31),
)
def test_the_envelope_comes_out_whole_beside_a_cubic_phase(c, cubic, seed):
    """A lobe's phase = plane + cubic surface + c·g (g any regressors): the plane returned is the
    equal-weight plane of plane + cubic, c·g taken out exactly (Eq. of the uniform module)."""
    from calflow.instruments.pattern.megarena.uniform import _envelope_out
    from calflow.instruments.pattern.phase import PhaseFitter

    rng = np.random.default_rng(seed)
    f = PhaseFitter((160, 192), 0.1, workers=1, envelope=True, pad=True)
    x, y = f.xm.ravel(), f.ym.ravel()
    dx, dy = x - f.xc, y - f.yc
    s = max(f.frame_shape) / 2.0
    u, v = dx / s, dy / s
    terms = [u**3, u**2 * v, u * v**2, v**3, u**2, u * v, v**2]
    surface = sum(a * t for a, t in zip(cubic, terms))  # radians
    g = rng.normal(0.0, 0.05, (2, x.size))  # 1/px: the regressors
    bin_ = np.array([3, 19])
    plane = (1.3, (19.4 / f.w, 3.2 / f.h))  # phase at the centre (rad), cycles per pixel
    phi = plane[0] + 2 * np.pi * (plane[1][0] * dx + plane[1][1] * dy) + surface + np.array(c) @ g
    z = np.exp(1j * (phi - 2 * np.pi * (bin_[1] / f.w * x + bin_[0] / f.h * y)))
    kept = ((np.abs(dx) < 60) & (np.abs(dy) < 50)) * 1.0
    kept = kept * rng.uniform(0.5, 1.0, x.size)
    phase, freq, cov = _envelope_out(f, z, kept, bin_, *plane, g, np.ones(x.size))
    # the weighted plane of plane + surface, directly
    m = kept > 0
    A = np.stack([np.ones(m.sum()), dx[m], dy[m]], 1)
    W = kept[m][:, None]
    want = np.linalg.solve(A.T @ (A * W), (A * W).T @ (phi - np.array(c) @ g)[m])
    assert phase == pytest.approx(want[0], abs=1e-9)
    np.testing.assert_allclose(2 * np.pi * np.array(freq), want[1:], atol=1e-11)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
