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
