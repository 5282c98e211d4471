"""The Megarena decoder's angle on noise-free frames: a few µrad, not tens.

The code's rows and columns left out modulate the grid's lobes, and a dot's transfer function
falls across a lobe, so a plain plane fit to the lobes' phase tilts with the code in view
(phase module docstring, "The code's envelope"). These frames are calflow's own renders of
the library-sized target (9 µm, depth 12, 1024 × 768) at known poses, with no noise: what is
left is the decoder's own bias, over the central half (the library's fit region) and the
whole frame, for several pixel sizes, angles, dot sizes and focus.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.megarena import MegarenaPattern, decode
from calflow.instruments.pattern.spectrum import TUKEY, on_flat, tukey

ANGLE_URAD = {0.5: 5.0, 1.0: 15.0}  # largest error of each axis's direction, by fit region
# Within a few degrees of a pixel axis, at 18–19 pixels a period, the central half's angle is
# 5–8.5 µrad off (a sweep of θ = ±3° about both axes: 14 of 98 poses beyond 5 µrad at
# 0.484 µm pixels, 38 of 98 at 0.5 µm, none at 0.45, 0.47 or 0.55; the whole frame 1.9 µrad at
# most there; docs/instruments.md, "Angle near a pixel axis"): a known bias, not yet explained,
# held here at its measured size rather than hidden by a looser bound everywhere.
NEAR_AXIS_DEG = 3.0
NEAR_AXIS_URAD = {0.5: 10.0, 1.0: 15.0}
POSITION_NM = {0.5: 0.5, 1.0: 2.0}


def _frame(pixel_um, theta, x, y, dot=0.5, defocus=0.0):
    pattern = MegarenaPattern(9.0, 12, dot_diameter_um=9.0 * dot)
    cam = Camera(
        width=1024, height=768, sensor_pixel_um=10 * pixel_um, magnification=10.0, defocus_um=defocus
    )
    return pattern, cam.render(pattern, x, y, theta)  # noise-free


def _errors(r, theta, x, y):
    """Each axis's direction off the truth (µrad) and the position's (nm)."""

    def urad(deg):
        return 1e6 * math.radians((deg - theta + 180.0) % 360.0 - 180.0)

    return (
        urad(r.theta_x_deg[0]),
        urad(r.theta_y_deg[0] - 90.0),
        1e3 * math.hypot(r.x_um[0] - x, r.y_um[0] - y),
    )


# poses where a plain plane fit is 10–40 µrad off over the central half
CASES = [
    (0.47, 15.70, 61000.0, 23000.0, 0.5),
    (0.47, -165.25, 30500.0, 71000.0, 0.5),
    (0.55, 82.68, 45000.0, 52000.0, 0.4),
    (0.59, 72.10, 83600.0, 44800.0, 0.6),
    (0.76, -169.80, 12000.0, 90000.0, 0.5),
    (0.88, -131.37, 77000.0, 15000.0, 0.45),
]


@pytest.mark.parametrize("region", [0.5, 1.0])
@pytest.mark.parametrize(("pixel_um", "theta", "x", "y", "dot"), CASES)
def test_noise_free_frames_angle_within_a_few_microradians(pixel_um, theta, x, y, dot, region):
    pattern, frame = _frame(pixel_um, theta, x, y, dot)
    r = decode(frame, pattern, fit_region=region, workers=1)
    assert r.status[0] == "ok", r.reason[0]
    ex, ey, d = _errors(r, theta, x, y)
    assert abs(ex) < ANGLE_URAD[region] and abs(ey) < ANGLE_URAD[region], (ex, ey)
    assert d < POSITION_NM[region]


def _bound(theta: float, region: float) -> float:
    near_axis = abs((theta + 45.0) % 90.0 - 45.0) < NEAR_AXIS_DEG
    return (NEAR_AXIS_URAD if near_axis else ANGLE_URAD)[region]


@settings(max_examples=6, deadline=None)
@example(pixel_um=0.484375, theta=1.0, x=2000.0, y=36882.0, dot=0.5, defocus=0.0)  # a local find: 5.05 µrad
@given(
    pixel_um=st.floats(0.45, 0.9),
    theta=st.floats(-180.0, 180.0),
    x=st.floats(2000.0, 100000.0),
    y=st.floats(2000.0, 100000.0),
    dot=st.floats(0.35, 0.65),
    defocus=st.floats(0.0, 3.0),
)
def test_the_angle_holds_whatever_the_dots_size_and_focus(pixel_um, theta, x, y, dot, defocus):
    pattern, frame = _frame(pixel_um, theta, x, y, dot, defocus)
    for region in (0.5, 1.0):
        r = decode(frame, pattern, fit_region=region, workers=1)
        assume(r.status[0] == "ok")  # a frame it cannot read gets NaN and a reason (tested apart)
        ex, ey, d = _errors(r, theta, x, y)
        assert abs(ex) < _bound(theta, region) and abs(ey) < _bound(theta, region), (region, ex, ey)
        assert d < POSITION_NM[region]


@settings(max_examples=60, deadline=None)
@given(n=st.integers(8, 3000))
def test_the_flat_part_is_where_the_window_is_one(n):
    w = tukey(n, TUKEY).astype(float)
    flat = on_flat(np.arange(n), n)
    assert (w[flat] == 1).all()  # no sample of the taper is taken for the flat part
    assert flat.sum() >= (1 - TUKEY) * n - 2  # and the flat part is all of the rest


def test_a_frame_of_a_slow_fft_length_is_padded_and_decodes_to_its_pose():
    """334 = 2 × 167 rows: the plan zero-pads the transform to 336 rows; the pose is unchanged."""
    from calflow.instruments.pattern.phase import PhaseFitter

    pattern = MegarenaPattern(4.0, 6)
    cam = Camera(width=384, height=334, sensor_pixel_um=5.0, magnification=10.0)
    plan = PhaseFitter((334, 384), 0.5 / 4.0, 1, envelope=True, pad=True)
    assert (plan.h, plan.w) == (336, 384) and plan.frame_shape == (334, 384)
    assert plan.spectrum(np.zeros((1, 334, 384))).shape == (1, 336, 193)
    x, y, theta = 400.0, 380.0, -33.0
    for region in (0.5, 1.0):
        r = decode(cam.render(pattern, x, y, theta), pattern, fit_region=region, workers=1)
        assert r.status[0] == "ok", r.reason[0]
        ex, ey, d = _errors(r, theta, x, y)
        assert abs(ex) < 50 and abs(ey) < 50 and d < 5.0  # a 167 × 192 µm view: µrad and nm
        assert abs(r.pixel_um[0] / cam.pixel_um - 1) < 1e-4


# poses whose strongest spectral peak is the diagonal harmonic (1, 1) at √2·f₀, not the fundamental
DIAGONAL = [
    (0.488542125214631, -94.74821762540411, 80326.17205543329, 58634.041570372414),
    (0.4506705375789763, 170.44569891590857, 30541.72107867069, 32084.61420139934),
    (0.7960725693861583, 67.01434607466331, 56536.88578948341, 66710.55998530627),
]


@pytest.mark.parametrize(("pixel_um", "theta", "x", "y"), DIAGONAL)
def test_the_fundamental_is_found_below_a_stronger_diagonal_harmonic(pixel_um, theta, x, y):
    import sys

    from calflow.instruments.pattern.megarena.period import _band, fundamental

    module = sys.modules["calflow.instruments.pattern.megarena.decode"]
    pattern, frame = _frame(pixel_um, theta, x, y)
    plan = module._fitter(768, 1024, -116, 1)
    spec = plan.spectrum(frame[None])[0]
    flat, rad, *_ = _band(plan.h, plan.w, 3.0 * 13 / 768)  # the band looked over
    strongest = rad[np.argmax(np.abs(spec.ravel()[flat]))]  # not the fundamental here
    assert abs(strongest / (pixel_um / 9.0) - math.sqrt(2)) < 0.05
    assert abs(fundamental(spec, plan.h, plan.w, 12) / (pixel_um / 9.0) - 1) < 0.03
    r = decode(frame, pattern, workers=1)  # no pixel size given: measured from the frame
    assert r.status[0] == "ok", r.reason[0]
    assert abs(r.pixel_um[0] / pixel_um - 1) < 1e-4 and _errors(r, theta, x, y)[2] < 2.0


@pytest.mark.parametrize(("pixel_um", "theta"), [(0.5, 89.375), (0.484375, -0.625)])
def test_near_a_pixel_axis_the_bias_is_the_central_halfs(pixel_um, theta):
    """The sweep's worst poses (module's NEAR_AXIS_URAD): the central half within its known
    bias, the whole frame, over the same lattice, within a few µrad — the bias is the central
    half's, not the lattice's."""
    x, y = 20000.0, 36882.0
    pattern, frame = _frame(pixel_um, theta, x, y)
    central = _errors(decode(frame, pattern, fit_region=0.5, workers=1), theta, x, y)
    whole = _errors(decode(frame, pattern, fit_region=1.0, workers=1), theta, x, y)
    assert max(abs(central[0]), abs(central[1])) < NEAR_AXIS_URAD[0.5], central
    assert max(abs(whole[0]), abs(whole[1])) < 3.0, whole
