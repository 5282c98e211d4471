"""Space and time robustness R_S, R_T (thesis Eq. 5.8, 5.9)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.metrics import robustness, space_robustness, time_robustness

# Three tests with different numbers of poses (per-pose AP, µm).
TESTS = [
    [0.2, 0.5, 0.3],  # max 0.5, min 0.2, spread 0.3
    [0.1, 0.4],  # max 0.4, min 0.1, spread 0.3
    [0.6, 0.6, 0.9, 0.3],  # max 0.9, min 0.3, spread 0.6
]


def test_space_robustness_by_hand():
    # R_S = (0.3 + 0.3 + 0.6) / 3 = 0.4 µm
    assert space_robustness(TESTS) == pytest.approx(0.4)


def test_time_robustness_by_hand():
    # R_T = ((0.5 + 0.4 + 0.9) / 3) / 10 h = 0.6 / 10 = 0.06 µm/h
    assert time_robustness(TESTS, 10.0) == pytest.approx(0.06)


def test_both_and_array_input():
    ap = np.array([[0.1, 0.3], [0.2, 0.6]])
    r = robustness(ap, duration=4.0)
    # R_S = (0.2 + 0.4) / 2 = 0.3 ; R_T = ((0.3 + 0.6) / 2) / 4 = 0.1125
    assert r.space == pytest.approx(0.3)
    assert r.time == pytest.approx(0.1125)
    assert r.n_tests == 2 and r.duration == 4.0


def test_single_pose_tests_have_zero_space_robustness():
    assert space_robustness([[0.7], [0.2]]) == 0.0


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: space_robustness([]), "empty"),
        (lambda: space_robustness([[0.1, -0.2]]), "negative"),
        (lambda: space_robustness([[0.1, np.nan]]), "NaN"),
        (lambda: space_robustness([[]]), "non-empty"),
        (lambda: space_robustness(np.zeros((2, 2, 2))), "n_tests, n_poses"),
        (lambda: time_robustness(TESTS, 0.0), "positive"),
        (lambda: time_robustness(TESTS, float("nan")), "positive"),
    ],
)
def test_bad_input_raises_clear_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


pos = st.floats(min_value=0.0, max_value=1e3, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(arrays(float, st.tuples(st.integers(1, 6), st.integers(1, 6)), elements=pos), st.floats(0.1, 100.0))
def test_properties(ap, c):
    rs = space_robustness(ap)
    # adding a constant accuracy offset to every pose leaves the spread unchanged
    assert space_robustness(ap + c) == pytest.approx(rs, abs=1e-9)
    # R_T is inversely proportional to the duration
    assert time_robustness(ap, 2.0 * c) == pytest.approx(time_robustness(ap, c) / 2.0)
    # spread never exceeds the worst accuracy: R_S <= R_T * Time
    assert rs <= time_robustness(ap, 1.0) + 1e-12
