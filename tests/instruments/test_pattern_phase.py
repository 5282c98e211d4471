"""The shared phase part's pieces written for speed are the ones they replace: the Tukey window
is scipy's, and a plan's ring of bins, found from the rows and columns it can reach, is the one
a pass over the whole spectrum finds."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.instruments.pattern.spectrum import RING, ring, tukey


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 3000), alpha=st.one_of(st.just(0.0), st.floats(1e-3, 1.5)))  # below, scipy rounds
def test_the_tukey_window_is_scipys(n, alpha):
    from scipy.signal.windows import tukey as scipy_tukey

    ours = tukey(n, alpha)
    assert ours.dtype == np.float32 and ours.shape == (n,)
    np.testing.assert_allclose(ours, scipy_tukey(n, alpha), rtol=0, atol=2e-7)


@settings(max_examples=60, deadline=None)
@given(h=st.integers(32, 1200), w=st.integers(32, 1200), f0=st.floats(0.02, 0.34))
def test_the_ring_is_the_whole_spectrums(h, w, f0):
    fi = np.fft.fftfreq(h)[:, None]
    fj = np.fft.rfftfreq(w)[None, :]
    rad = np.hypot(fi, fj)
    inside = (rad > RING[0] * f0) & (rad < RING[1] * f0) & ~((fj == 0) & (fi < 0))
    rows, cols = np.nonzero(inside)
    angle = np.degrees(np.arctan2(fi[rows, 0], fj[0, cols]))
    got = ring(h, w, f0)
    assert np.array_equal(got[0], rows) and np.array_equal(got[1], cols)
    assert np.array_equal(got[2], angle)


def test_scratch_arrays_are_reused_per_name_shape_and_thread():
    import threading

    from calflow.instruments.pattern.spectrum import scratch

    a = scratch((4, 5), "t")
    assert scratch((4, 5), "t") is a and a.dtype == np.float32
    assert scratch((4, 5), "u") is not a and scratch((5, 4), "t") is not a
    other = []
    t = threading.Thread(target=lambda: other.append(scratch((5, 4), "t")))
    t.start()
    t.join()
    assert other[0] is not scratch((5, 4), "t")


def test_a_frame_windowed_in_scratch_gives_the_stacks_spectrum():
    from calflow.instruments.pattern.phase import PhaseFitter

    rng = np.random.default_rng(3)
    frames = rng.random((3, 48, 64)).astype(np.float32)
    plan = PhaseFitter((48, 64), 0.1, 1)
    whole = plan.spectrum(frames)  # a stack: a new array
    for k in range(3):  # one frame at a time: the reused array, the same spectrum
        assert np.array_equal(plan.spectrum(frames[k][None])[0], whole[k])


@settings(max_examples=40, deadline=None)
@given(h=st.integers(2, 90), w=st.integers(2, 90), seed=st.integers(0, 2**31))
def test_the_spectrum_is_the_whole_window_times_the_frame(h, w, seed):
    """The window multiplies only its tapered bands: the transform of the frame times all of it."""
    import scipy.fft

    from calflow.instruments.pattern.phase import PhaseFitter
    from calflow.instruments.pattern.spectrum import window

    frames = np.random.default_rng(seed).random((2, h, w)).astype(np.float32) * 1000
    plan = PhaseFitter((h, w), 0.1, 1)
    whole = (frames - frames.mean(axis=(1, 2), keepdims=True)) * window(h, w)
    assert np.array_equal(plan.spectrum(frames), scipy.fft.rfft2(whole, workers=1))
    assert np.array_equal(plan.spectrum(frames[:1]), scipy.fft.rfft2(whole[:1], workers=1))


@settings(max_examples=40, deadline=None)
@given(f0=st.floats(0.02, 0.3), shape=st.tuples(st.integers(40, 300), st.integers(40, 300)))
def test_the_crops_go_into_their_boxes_at_their_offsets(f0, shape):
    from calflow.instruments.pattern.phase import PhaseFitter

    plan = PhaseFitter(shape, f0, 1)
    rng = np.random.default_rng(0)
    crops = (rng.random((2, 2) + plan.di.shape) + 1j).astype(np.complex64)
    want = np.zeros((2, 2, plan.ni, plan.nj), np.complex64)
    want[:, :, plan.di % plan.ni, plan.dj % plan.nj] = crops
    got = np.zeros_like(want)
    plan._into_boxes(got, crops)
    assert np.array_equal(got, want)


@settings(max_examples=60, deadline=None)
@given(f0=st.floats(0.03, 0.2), i0=st.integers(-60, 60), j0=st.integers(0, 40))
def test_a_crop_is_its_bins_mirrored_where_the_column_is_negative(f0, i0, j0):
    from calflow.instruments.pattern.phase import PhaseFitter

    plan = PhaseFitter((96, 128), f0, 1)
    rng = np.random.default_rng(1)
    spec = (rng.standard_normal((1, 96, 65)) + 1j * rng.standard_normal((1, 96, 65))).astype(np.complex64)
    if j0 + plan.bj >= 65:
        return
    want = np.empty(plan.di.shape, np.complex64)
    for (a, b), di in np.ndenumerate(plan.di):
        i, j = i0 + di, j0 + plan.dj[a, b]
        want[a, b] = np.conj(spec[0, -i % 96, -j]) if j < 0 else spec[0, i % 96, j]
    assert np.array_equal(plan.crop(spec, 0, i0, j0), want)
