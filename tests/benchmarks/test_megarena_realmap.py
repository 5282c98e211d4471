"""A real frame's lattice distortion carried onto calflow's camera (benchmarks/megarena_realmap.py,
make_distorted_megarena.py --map-from): the render seen through q shows the real lattice, in
the render's labels, whatever the real frame's rotation, shear, axis order and signs; beyond the
dots it stays continuous; the light carried over leaves a render's own light unchanged; and on a
frame of known distortion the re-render's truth is that frame's."""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import megarena_estimand as me  # noqa: E402
import megarena_realmap as mr  # noqa: E402

SHAPE = (200, 240)  # h, w


def synthetic(render: np.ndarray, R0: np.ndarray, k0: np.ndarray, bend: float, seed: int) -> mr.RealLattice:
    """A 'real' lattice whose labels are the render's turned by R0 and shifted by k0, bent by a
    cubic of ``bend`` periods at the box's corners, its dots on a grid inside a box."""
    rng = np.random.default_rng(seed)
    h, w = SHAPE
    centre, scale = ((w - 1) / 2, (h - 1) / 2), max(h, w) / 2
    m = me.LatticeMap(3, np.zeros((10, 2)), centre, scale)
    # the render's affine lattice in the map's basis (1, ξ, η), then R0ᵀ(· − k0), then the bend
    a, J = render[:, 0], render[:, 1:]
    lin = np.stack([a + J @ np.array(centre), J[:, 0] * scale, J[:, 1] * scale])  # (3, 2)
    lin[0] -= k0
    m.coef[:3] = lin @ R0  # rows of coef are basis functions: L_real = R0ᵀ·L_render
    m.coef[6:] = bend * rng.uniform(-1, 1, size=(4, 2))
    gy, gx = np.mgrid[30:170:7, 40:200:7]
    xy = np.stack([gx.ravel(), gy.ravel()], 1).astype(float)
    stv = m(xy[:, 0], xy[:, 1])
    A = np.stack([np.ones(len(xy)), xy[:, 0], xy[:, 1]], 1)
    affine = np.linalg.lstsq(A, stv, rcond=None)[0].T
    box = (xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max())
    return mr.RealLattice(m, affine, xy, np.rint(stv), box, 10.0, True, 0.0, 0.0)


def render_affine(theta: float, period_px: float, shear: float) -> np.ndarray:
    """A lattice whose axes step ``period_px`` pixels along θ and θ + 90° + shear (radians)."""
    g = period_px * np.array(
        [
            [math.cos(theta), math.cos(theta + math.pi / 2 + shear)],
            [math.sin(theta), math.sin(theta + math.pi / 2 + shear)],
        ]
    )
    return np.column_stack([np.array([1234.25, -56.5]), np.linalg.inv(g)])


signed_perms = [
    np.array(m, float) for m in ([[1, 0], [0, 1]], [[0, 1], [1, 0]], [[-1, 0], [0, 1]], [[0, -1], [-1, 0]])
]


@settings(max_examples=30, deadline=None)
@example(2.0, 6.0, 0.0234375, 0, (0, 0), 0.0, 0)  # the labels' drift at the dots' centre rounds to 1
@example(2.0, 6.0, 0.0, 1, (7, -3), 0.02, 5)  # no shear: k is k0 itself
@given(
    st.floats(-math.pi, math.pi),
    st.floats(6.0, 15.0),
    st.floats(-0.03, 0.03),
    st.sampled_from(range(len(signed_perms))),
    st.tuples(st.integers(-40, 40), st.integers(-40, 40)),
    st.floats(0.0, 0.05),
    st.integers(0, 1000),
)
def test_the_render_through_q_shows_the_real_lattice(theta, period, shear, perm, k0, bend, seed):
    """Eq. (1): A_r(q(p)) = R·M(p) + k inside the dots' box, R and k found back from the dots.
    Under shear the two lattices' labels part across the frame, so k is the integer offset at
    the dots' centre c: k0 + (J_r − J_s)·c to within half a period (and the bend's 0.05)."""
    render, sheared = render_affine(theta, period, 0.0), render_affine(theta, period, shear)
    R0 = signed_perms[perm]
    real = synthetic(sheared, R0, np.array(k0, float), bend, seed)
    q, R, k = mr.real_warp(real, render)
    np.testing.assert_array_equal(R, R0)
    drift = (render[:, 1:] - sheared[:, 1:]) @ real.xy.mean(axis=0)
    assert np.all(np.abs(k - (np.array(k0, float) + drift)) <= 0.5 + 0.05 + 1e-9), (k, k0, drift)
    if shear == 0.0:
        np.testing.assert_array_equal(k, np.array(k0, float))
    rng = np.random.default_rng(seed + 1)
    x, y = rng.uniform(40, 190, 50), rng.uniform(30, 160, 50)
    qx, qy = q(x, y)
    shown = render[:, 0] + np.stack([qx, qy], -1) @ render[:, 1:].T
    np.testing.assert_allclose(shown, real.map(x, y) @ R.T + k, atol=1e-8)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.005, 0.05), st.integers(0, 1000))
def test_beyond_the_dots_the_map_is_continuous_and_bounded(bend, seed):
    """Clamped: the affine part continued, the bend frozen at the box; with an outer map: its
    change from the box's edge. Both agree with the map inside and are continuous at the edge."""
    real = synthetic(render_affine(0.3, 9.0, 0.01), signed_perms[0], np.zeros(2), bend, seed)
    x0, x1, y0, y1 = real.box
    inside = (np.array([x0 + 5, x1 - 5]), np.array([y0 + 5, y1 - 5]))
    np.testing.assert_allclose(real(*inside), real.map(*inside), atol=1e-12)
    far = (np.array([-300.0, 900.0]), np.array([-200.0, 700.0]))
    clip = (np.clip(far[0], x0, x1), np.clip(far[1], y0, y1))
    np.testing.assert_allclose(real.nonaffine(*far), real.nonaffine(*clip), atol=1e-12)
    outer = synthetic(render_affine(0.3, 9.0, 0.01), signed_perms[0], np.zeros(2), 2 * bend, seed + 7)
    real.outer = outer
    np.testing.assert_allclose(real(*inside), real.map(*inside), atol=1e-12)
    edge = (np.array([x1, x1 + 1e-6]), np.array([y0 + 20, y0 + 20]))
    a, b = real(*edge)
    assert np.all(np.abs(a - b) < 1e-6)
    # beyond the box it follows the outer map's change, not the inner polynomial's runaway
    np.testing.assert_allclose(real(*far) - real(*clip), outer(*far) - outer(*clip), atol=1e-9)


@pytest.mark.parametrize("shear_deg", [0.0, 1.27, -3.0])
def test_the_shear_of_a_lattice(shear_deg):
    assert mr.shear_deg(render_affine(0.7, 9.3, math.radians(shear_deg))) == pytest.approx(
        abs(shear_deg), abs=1e-9
    )


@settings(max_examples=15, deadline=None)
@given(st.floats(0.2, 5.0), st.integers(0, 1000))
def test_a_renders_own_light_carried_over_changes_nothing(scale, seed):
    """relight(E, E·s, ·, 1/s) = E: the render's background and dot tops are its own."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:96, 0:128]
    dots = (np.cos(2 * np.pi * x / 8.0) * np.cos(2 * np.pi * y / 8.0) > 0.5).astype(float)
    light = 1 + 0.3 * rng.uniform() * x / 128
    E = (20 + 100 * dots) * light
    np.testing.assert_allclose(mr.relight(E, E * scale, 8.0, 1 / scale), E, rtol=1e-5)


def test_map_from_a_known_distortion_gives_back_its_truth(tmp_path):
    """A frame through a known radial map, then --map-from it: the re-render's truth is the
    original's, where the distortion itself moves the truth far more than that."""
    import make_distorted_megarena as mk

    small = ["--period-um", "9", "--depth", "8", "--size", "512x512"]
    assert mk.main([str(tmp_path / "a"), "--frames", "1", "--k", "0.01", "--seed", "3", *small]) == 0
    again = [str(tmp_path / "b"), "--map-from", str(tmp_path / "a" / "d00.tiff"), "--frames", "1", *small]
    assert mk.main([*again, "--seed", "4"]) == 0
    assert mk.main([str(tmp_path / "c"), "--frames", "1", "--k", "0", "--seed", "3", *small]) == 0
    a, b, c = (next(csv.DictReader(open(tmp_path / d / "truth.csv"))) for d in "abc")
    moved = 1e6 * abs(float(a["alpha"]) - float(c["alpha"]))  # what the lens does to the truth
    assert moved > 100
    assert 1e6 * abs(float(a["alpha"]) - float(b["alpha"])) < 15
    for key in ("x", "y"):
        assert 1000 * abs(float(a[key]) - float(b[key])) < 3
