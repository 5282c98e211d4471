"""The decoders' small pieces against the library functions they stand in for."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from calflow.instruments.pattern.bits import dilate3, erode3


@settings(max_examples=80, deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), share=st.floats(0.0, 1.0), seed=st.integers(0, 2**31))
def test_the_3x3_dilation_and_erosion_are_scipys(h, w, share, seed):
    mask = np.random.default_rng(seed).random((h, w)) < share
    block = np.ones((3, 3), bool)
    assert np.array_equal(dilate3(mask), ndimage.binary_dilation(mask, block))
    assert np.array_equal(erode3(mask), ndimage.binary_erosion(mask, block, border_value=1))
    assert np.array_equal(
        erode3(dilate3(mask)),
        ndimage.binary_erosion(ndimage.binary_dilation(mask, block), block, border_value=1),
    )


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(1, 400),
    levels=st.integers(1, 1000),
    dtype=st.sampled_from([np.float32, np.float64]),
    q=st.one_of(
        st.integers(0, 100),
        st.floats(0.0, 100.0),
        st.lists(st.floats(0.0, 100.0), min_size=1, max_size=4),
    ),
    seed=st.integers(0, 2**31),
)
def test_the_percentile_is_numpys_bit_for_bit(n, levels, dtype, q, seed):
    from calflow.instruments.pattern.bits import percentile

    rng = np.random.default_rng(seed)
    a = (rng.integers(0, levels, n) * rng.standard_normal()).astype(dtype)  # ties included
    want = np.percentile(a, q)
    got = percentile(a.copy(), q)
    assert np.asarray(got).dtype == np.asarray(want).dtype and type(got) is type(want)
    assert np.array_equal(got, want)
