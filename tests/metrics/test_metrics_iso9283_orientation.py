"""ISO 9283 orientation accuracy and repeatability per rotation axis (7.2.1, 7.2.2)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.metrics.iso9283_orientation import iso9283_orientation

finite = st.floats(-10.0, 10.0, allow_nan=False)


def test_a_worked_example():
    # attained a: 1.0, 1.2, 1.4 about a command 1.0 → ā = 1.2, AP_a = 0.2, S_a = 0.2, RP_a = 0.6
    r = iso9283_orientation([1.0, 0.0, 5.0], [[1.0, 0.0, 5.0], [1.2, 0.0, 5.0], [1.4, 0.0, 5.0]])
    assert r.ap == pytest.approx((0.2, 0.0, 0.0))
    assert r.rp == pytest.approx((0.6, 0.0, 0.0))
    assert r.n == 3


@settings(max_examples=60, deadline=None)
@given(
    arrays(float, (5, 3), elements=finite),
    arrays(float, 3, elements=finite),
    arrays(float, 3, elements=finite),
)
def test_a_common_shift_moves_the_accuracy_only(attained, command, shift):
    """Shifting every attained orientation by δ adds δ to AP and leaves RP unchanged."""
    base = iso9283_orientation(command, attained)
    moved = iso9283_orientation(command, attained + shift)
    assert np.allclose(np.subtract(moved.ap, base.ap), shift, atol=1e-9)
    assert np.allclose(moved.rp, base.rp, atol=1e-9)
    assert all(v >= 0 for v in base.rp)


@settings(max_examples=40, deadline=None)
@given(arrays(float, (6, 2), elements=finite), st.floats(0.1, 10.0))
def test_repeatability_scales_with_the_scatter(attained, k):
    """RP is three sample standard deviations: scaling the scatter about the mean by k scales RP by k."""
    mean = attained.mean(axis=0)
    r1 = iso9283_orientation(mean, attained)
    r2 = iso9283_orientation(mean, mean + k * (attained - mean))
    assert np.allclose(r2.rp, np.multiply(k, r1.rp), rtol=1e-9, atol=1e-9)
    assert np.allclose(r1.rp, 3 * attained.std(axis=0, ddof=1))


@pytest.mark.parametrize(
    "command, attained, message",
    [
        ([0.0], [[0.0]], "n >= 2"),
        ([0.0, 0.0], [[0.0], [1.0]], "shape"),
        ([0.0], [[np.nan], [1.0]], "NaN"),
        ([0.0] * 4, [[0.0] * 4, [1.0] * 4], "k = 1..3"),
    ],
)
def test_bad_input_is_one_clear_error(command, attained, message):
    with pytest.raises(ValueError, match=message):
        iso9283_orientation(command, attained)
