"""1-D accuracy and intrinsic / extrinsic repeatability (thesis Eq. 3.13-3.18)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.metrics import accuracy_1d, decompose_repeatability, repeatability_1d

vals = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False)


def test_eq_3_13_and_3_14_by_hand():
    # x_m = 10, 12, 14, 16 at target 11: x̄ = 13 -> AP = 2
    x = [10.0, 12.0, 14.0, 16.0]
    assert accuracy_1d(x, 11.0) == pytest.approx(2.0)
    # |x - x̄| = 3, 1, 1, 3 -> mean 2; σ^2 = 4 * 1 / 3 -> RP = 2 + 3 * 2/sqrt(3) = 2 + 2 sqrt(3)
    assert repeatability_1d(x) == pytest.approx(2.0 + 2.0 * math.sqrt(3.0))


def test_decomposition_by_hand():
    # Eq. (3.11): x_m = P + x_T + g + L with x_T = 100, g = 0.5,
    # P = 1, -1, 1, -1 (mean 0) and thermal drift L = 0, 2, 4, 6 (mean 3).
    x_t, g = 100.0, 0.5
    p = np.array([1.0, -1.0, 1.0, -1.0])
    drift = np.array([0.0, 2.0, 4.0, 6.0])
    x_m = p + x_t + g + drift  # 101.5, 101.5, 105.5, 105.5
    d = decompose_repeatability(x_m, x_t, drift)
    # Eq. (3.15): AP_E = |g + P̄ + L̄| = |0.5 + 0 + 3| = 3.5
    assert d.ap == pytest.approx(3.5)
    # Eq. (3.16), first line: |x - x̄| = 2, 2, 2, 2 -> mean 2, σ_E = 0 -> RP_E = 2
    assert d.rp == pytest.approx(2.0)
    assert d.mean_abs_deviation == pytest.approx(2.0)
    assert d.sigma == pytest.approx(0.0)
    # intrinsic P - P̄ = 1, -1, 1, -1 ; extrinsic L - L̄ = -3, -1, 1, 3
    np.testing.assert_allclose(d.intrinsic, [1.0, -1.0, 1.0, -1.0])
    np.testing.assert_allclose(d.extrinsic, [-3.0, -1.0, 1.0, 3.0])
    assert d.intrinsic_term == pytest.approx(1.0)  # mean |P - P̄|
    assert d.extrinsic_term == pytest.approx(2.0)  # (3 + 1 + 1 + 3) / 4
    assert d.rp_bound == pytest.approx(1.0 + 2.0 + 0.0)  # bound of Eq. (3.16): 3 >= 2
    assert d.extrinsic_mean == pytest.approx(3.0)
    # Eq. (3.13) on drift-free data x - L = 100.5 + P: AP_I = |g + P̄| = 0.5
    assert d.ap_intrinsic == pytest.approx(0.5)
    # Eq. (3.14) on x - L: |P - P̄| = 1 each -> mean 1, σ 0 -> RP_I = 1
    assert d.rp_intrinsic == pytest.approx(1.0)
    assert d.n == 4


def test_residual_after_calibration_eq_3_17_3_18():
    # With calibration x_m = P + x_T + T (Eq. 3.17): same decomposition with T for L.
    p = np.array([0.2, -0.2, 0.0])
    t_res = np.array([-1.0, 0.0, 1.0])
    x_m = 50.0 + p + t_res
    d = decompose_repeatability(x_m, 50.0, t_res)
    # AP_S = |P̄ + T̄| = |0 + 0| = 0
    assert d.ap == pytest.approx(0.0, abs=1e-12)
    # |x - x̄| = 0.8, 0.2, 1.0 -> mean 2/3 ; σ^2 = ((0.8-2/3)^2 + (0.2-2/3)^2 + (1-2/3)^2) / 2
    l = np.array([0.8, 0.2, 1.0])
    sigma = math.sqrt(float(np.sum((l - 2.0 / 3.0) ** 2)) / 2.0)
    assert d.rp == pytest.approx(2.0 / 3.0 + 3.0 * sigma)
    assert d.intrinsic_term == pytest.approx(0.4 / 3.0)
    assert d.extrinsic_term == pytest.approx(2.0 / 3.0)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: accuracy_1d([1.0], 0.0), "n >= 2"),
        (lambda: accuracy_1d([[1.0, 2.0]], 0.0), "1-D"),
        (lambda: accuracy_1d([1.0, 2.0], [0.0, 1.0]), "single value"),
        (lambda: repeatability_1d([1.0, np.nan]), "NaN"),
        (lambda: decompose_repeatability([1.0, 2.0, 3.0], 0.0, [0.0, 1.0]), "one value per measurement"),
    ],
)
def test_bad_input_raises_clear_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@st.composite
def series_with_drift(draw):
    n = draw(st.integers(2, 15))
    x = draw(arrays(float, (n,), elements=vals))
    drift = draw(arrays(float, (n,), elements=vals))
    return x, drift


@settings(max_examples=200, deadline=None)
@given(series_with_drift(), vals)
def test_rp_never_exceeds_the_bound_of_eq_3_16(data, target):
    x, drift = data
    d = decompose_repeatability(x, target, drift)
    assert d.rp <= d.rp_bound + 1e-9
    assert d.rp == pytest.approx(repeatability_1d(x))
    assert d.ap == pytest.approx(accuracy_1d(x, target))
    # extrinsic + intrinsic deviations recompose the measured deviations
    np.testing.assert_allclose(d.intrinsic + d.extrinsic, x - x.mean(), atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(arrays(float, st.integers(2, 15), elements=vals), vals)
def test_without_drift_everything_is_intrinsic(x, target):
    d = decompose_repeatability(x, target, np.zeros_like(x))
    assert d.extrinsic_term == 0.0
    assert d.rp_bound == pytest.approx(d.rp)
    assert d.rp_intrinsic == pytest.approx(d.rp)
    assert d.ap_intrinsic == pytest.approx(d.ap)


@settings(max_examples=100, deadline=None)
@given(arrays(float, st.integers(2, 15), elements=vals), vals, vals)
def test_1d_translation_invariance(x, target, shift):
    assert accuracy_1d(x + shift, target + shift) == pytest.approx(accuracy_1d(x, target), abs=1e-9)
    assert repeatability_1d(x + shift) == pytest.approx(repeatability_1d(x), abs=1e-9)
