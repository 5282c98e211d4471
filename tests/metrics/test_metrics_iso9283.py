"""ISO 9283 AP / RP (thesis Eq. 3.5-3.8), checked by hand and by properties."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.metrics import accuracy_1d, iso9283, iso9283_test, repeatability_1d

finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False)


@st.composite
def pose_data(draw):
    d = draw(st.integers(1, 3))
    n = draw(st.integers(2, 12))
    command = draw(arrays(float, (d,), elements=finite))
    attained = draw(arrays(float, (n, d), elements=finite))
    return command, attained


# --------------------------------------------------------------------------- by hand


def test_2d_by_hand():
    # attained around barycentre G = ((0+4+2+2)/4, (0+0+3-3)/4) = (2, 0)
    attained = np.array([[0.0, 0.0], [4.0, 0.0], [2.0, 3.0], [2.0, -3.0]])
    command = np.array([-1.0, 4.0])
    r = iso9283(command, attained)
    # G - O_c = (2 - -1, 0 - 4) = (3, -4) -> AP = 5
    np.testing.assert_allclose(r.barycentre, [2.0, 0.0])
    np.testing.assert_allclose(r.ap_components, [3.0, -4.0])
    assert r.ap == pytest.approx(5.0)
    # l_j = distances to G: 2, 2, 3, 3 -> l̄ = 2.5
    np.testing.assert_allclose(r.l, [2.0, 2.0, 3.0, 3.0])
    assert r.l_mean == pytest.approx(2.5)
    # S_l = sqrt(4 * 0.5^2 / (4 - 1)) = sqrt(1/3); RP = 2.5 + 3 sqrt(1/3) = 2.5 + sqrt(3)
    assert r.s_l == pytest.approx(math.sqrt(1.0 / 3.0))
    assert r.rp == pytest.approx(2.5 + math.sqrt(3.0))
    assert r.n == 4


def test_3d_by_hand():
    # offsets from G = (10, 20, 30), summing to zero, with lengths 3, 3, 4, 4, 7, 7
    offsets = np.array([[1, 2, 2], [-1, -2, -2], [0, 0, 4], [0, 0, -4], [2, 3, 6], [-2, -3, -6]], dtype=float)
    attained = np.array([10.0, 20.0, 30.0]) + offsets
    r = iso9283([8.0, 18.0, 29.0], attained)
    # G - O_c = (2, 2, 1) -> AP = sqrt(4 + 4 + 1) = 3
    np.testing.assert_allclose(r.ap_components, [2.0, 2.0, 1.0])
    assert r.ap == pytest.approx(3.0)
    # l̄ = 28 / 6 = 14/3; deviations -5/3, -5/3, -2/3, -2/3, 7/3, 7/3
    # sum of squares = 2 (25 + 4 + 49) / 9 = 52/3; S_l^2 = (52/3) / 5 = 52/15
    assert r.l_mean == pytest.approx(14.0 / 3.0)
    assert r.s_l == pytest.approx(math.sqrt(52.0 / 15.0))
    assert r.rp == pytest.approx(14.0 / 3.0 + 3.0 * math.sqrt(52.0 / 15.0))


def test_uses_corrected_eq_3_7_not_the_printed_typo():
    # Printed Eq. (3.7) would use x_j in the y term: for attained (0, 5), (0, -5) with
    # G = (0, 0) the printed form gives l_j = sqrt(0 + 0) = 0; the correct one gives 5.
    r = iso9283([0.0, 0.0], [[0.0, 5.0], [0.0, -5.0]])
    np.testing.assert_allclose(r.l, [5.0, 5.0])
    assert r.rp == pytest.approx(5.0)  # l̄ = 5, S_l = 0


def test_1d_equals_eq_3_13_and_3_14_by_hand():
    x = [1.0, 2.0, 3.0, 6.0]
    # x̄ = 3; AP = |3 - 2| = 1
    # |x - x̄| = 2, 1, 0, 3 -> mean 1.5; σ^2 = (0.25 + 0.25 + 2.25 + 2.25) / 3 = 5/3
    expected_rp = 1.5 + 3.0 * math.sqrt(5.0 / 3.0)
    assert accuracy_1d(x, 2.0) == pytest.approx(1.0)
    assert repeatability_1d(x) == pytest.approx(expected_rp)
    for r in (iso9283([2.0], np.array(x)[:, None]), iso9283(2.0, x)):
        assert r.ap == pytest.approx(1.0)
        assert r.rp == pytest.approx(expected_rp)


def test_test_of_m_poses_takes_maxima_and_accepts_ragged_sets():
    commands = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    attained = [
        np.array([[1.0, 0.0], [1.0, 0.0]]),  # AP 1, RP 0
        np.array([[10.0, 1.0], [10.0, -1.0], [10.0, 3.0], [10.0, -3.0]]),  # AP 0
        np.array([[0.0, 12.0], [0.0, 12.0], [0.0, 12.0]]),  # AP 2, RP 0
    ]
    t = iso9283_test(commands, attained)
    np.testing.assert_allclose(t.ap, [1.0, 0.0, 2.0], atol=1e-12)
    # pose 2: l = 1, 1, 3, 3 -> l̄ = 2, S_l = sqrt(4 / 3) -> RP = 2 + 3 sqrt(4/3)
    np.testing.assert_allclose(t.rp, [0.0, 2.0 + 3.0 * math.sqrt(4.0 / 3.0), 0.0], atol=1e-12)
    assert t.ap_max == pytest.approx(2.0)
    assert t.rp_max == pytest.approx(2.0 + 3.0 * math.sqrt(4.0 / 3.0))
    assert t.m == 3 and t.poses[1].n == 4


def test_test_accepts_a_3d_array():
    commands = np.zeros((2, 3))
    attained = np.zeros((2, 5, 3))
    attained[1, :, 0] = 4.0
    t = iso9283_test(commands, attained)
    np.testing.assert_allclose(t.ap, [0.0, 4.0])
    assert t.ap_max == pytest.approx(4.0)


def test_results_are_frozen():
    r = iso9283([0.0], [[1.0], [2.0]])
    with pytest.raises(AttributeError):
        r.ap = 3.0
    with pytest.raises(ValueError):
        r.barycentre[0] = 1.0


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "command, attained, match",
    [
        ([0.0, 0.0], [[1.0, 2.0]], "n >= 2"),
        ([0.0, 0.0], [[1.0, 2.0], [1.0, np.nan]], "NaN"),
        ([0.0, np.inf], [[1.0, 2.0], [1.0, 3.0]], "NaN or infinite"),
        ([0.0, 0.0, 0.0], [[1.0, 2.0], [1.0, 3.0]], r"shape \(2,\)"),
        ([0.0] * 4, np.zeros((3, 4)), "d = 4"),
        ([0.0], np.zeros((2, 2, 1)), r"shape \(n, d\)"),
    ],
)
def test_bad_input_raises_clear_errors(command, attained, match):
    with pytest.raises(ValueError, match=match):
        iso9283(command, attained)


def test_test_with_mismatched_counts_raises():
    with pytest.raises(ValueError, match="M = 2"):
        iso9283_test(np.zeros((2, 2)), [np.zeros((3, 2))])
    with pytest.raises(ValueError, match="pose 1"):
        iso9283_test(np.zeros((2, 2)), [np.zeros((3, 2)), np.zeros((1, 2))])


# --------------------------------------------------------------------------- properties


@settings(max_examples=200, deadline=None)
@given(pose_data(), arrays(float, (3,), elements=finite))
def test_translation_invariance(data, shift):
    command, attained = data
    t = shift[: command.size]
    r0 = iso9283(command, attained)
    r1 = iso9283(command + t, attained + t)
    assert r1.ap == pytest.approx(r0.ap, abs=1e-9)
    assert r1.rp == pytest.approx(r0.rp, abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(arrays(float, st.integers(1, 3), elements=finite), st.integers(2, 20))
def test_perfect_data_gives_zero(command, n):
    r = iso9283(command, np.tile(command, (n, 1)))
    assert r.ap == pytest.approx(0.0, abs=1e-10)
    assert r.rp == pytest.approx(0.0, abs=1e-10)


@settings(max_examples=200, deadline=None)
@given(pose_data(), st.floats(min_value=0.0, max_value=100.0))
def test_rp_scales_linearly_with_spread(data, k):
    command, attained = data
    g = attained.mean(axis=0)
    r0 = iso9283(command, attained)
    r1 = iso9283(command, g + k * (attained - g))
    assert r1.rp == pytest.approx(k * r0.rp, rel=1e-9, abs=1e-8)
    assert r1.ap == pytest.approx(r0.ap, abs=1e-9)  # barycentre unchanged


@settings(max_examples=200, deadline=None)
@given(arrays(float, st.integers(2, 15), elements=finite), finite)
def test_1d_iso_equals_eq_3_13_3_14(x, target):
    r = iso9283([target], x[:, None])
    assert r.ap == pytest.approx(accuracy_1d(x, target), abs=1e-12)
    assert r.rp == pytest.approx(repeatability_1d(x), abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(pose_data())
def test_ap_is_norm_of_components_and_rp_at_least_mean_distance(data):
    command, attained = data
    r = iso9283(command, attained)
    assert r.ap == pytest.approx(float(np.linalg.norm(r.ap_components)))
    assert r.rp >= r.l_mean - 1e-12
    assert r.ap >= 0.0
