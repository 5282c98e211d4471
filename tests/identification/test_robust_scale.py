"""The robust noise scale of identification (``mad_sigma``): scipy's normal-consistent
median absolute deviation, with the properties outlier screening relies on."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.identification.robust import mad_sigma

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
samples = arrays(np.float64, st.integers(5, 60), elements=finite)


@settings(max_examples=60, deadline=None)
@given(samples, finite, st.floats(0.01, 100))
def test_shift_invariant_and_scale_equivariant(r, shift, scale):
    assert mad_sigma(r + shift) == pytest.approx(mad_sigma(r), rel=1e-9, abs=1e-6)
    assert mad_sigma(-scale * r) == pytest.approx(scale * mad_sigma(r), rel=1e-9, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.integers(20, 80), st.floats(1e3, 1e9), st.integers(0, 2**31 - 1))
def test_gross_errors_below_half_leave_it_bounded(n, gross, seed):
    """Fewer than half the readings replaced by arbitrarily large ones: the scale stays
    within the spread of the clean readings (breakdown point 50 %)."""
    rng = np.random.default_rng(seed)
    clean = rng.normal(0.0, 1.0, n)
    dirty = clean.copy()
    dirty[: (n - 1) // 2 - 1] = gross
    assert mad_sigma(dirty) <= 1.4827 * (clean.max() - clean.min())


def test_normal_consistency_and_non_finite_readings():
    """σ of normal noise (the 1 / Φ⁻¹(3/4) factor); NaN and inf readings are left out."""
    r = np.random.default_rng(3).normal(0.0, 2.5, 200_000)
    assert mad_sigma(r) == pytest.approx(2.5, rel=0.01)
    assert mad_sigma(np.r_[r[:1001], np.nan, np.inf]) == mad_sigma(r[:1001])
    assert np.isnan(mad_sigma(np.array([np.nan])))
