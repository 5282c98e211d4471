"""Reduction of high-rate streams to sample rows (Sec. 5.3.2: mean of the last 5 s)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.acquisition.streams import DwellReducer, reduce_dwell
from calflow.nano.stage.rig import nano1d


def _naive(chunks, window_s):
    cat = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    t = cat["time"]
    sel = t > t[-1] - window_s + 1e-6
    row = {k: float(np.mean(v[sel])) for k, v in cat.items() if k != "time"}
    return row, float(t[-1]), int(sel.sum())


def test_reduce_dwell_equals_naive_mean_of_last_5s_on_a_rig_stream():
    rig = nano1d(profile="lab5day", seed=2)
    rig.move({"x": 270.0})
    chunks = list(rig.stream(25.0, rate_hz=10.0, chunk=7))  # chunks straddle the window
    row = reduce_dwell(iter(chunks), window_s=5.0)
    expected, t_last, n = _naive(chunks, 5.0)
    assert row["n"] == n == 50  # 5 s at 10 Hz (Sec. 5.3.2)
    assert row["time"] == t_last == pytest.approx(29.0)
    assert set(row) == {"time", "n", *rig.sensors, *rig.thermometers}
    for key, value in expected.items():
        assert row[key] == pytest.approx(value, rel=0, abs=1e-12)
    # and it is not the mean of the whole dwell (noise differs sample to sample)
    assert row["meas_x"] != pytest.approx(
        np.concatenate([c["meas_x"] for c in chunks]).mean(), rel=0, abs=1e-9
    )


@settings(max_examples=60, deadline=None)
@given(
    sizes=st.lists(st.integers(0, 40), min_size=1, max_size=30),
    window=st.floats(0.05, 3.0),
    rate=st.sampled_from([10.0, 50.0, 1000.0]),
)
def test_any_chunking_gives_the_naive_result(sizes, window, rate):
    n = sum(sizes)
    if n == 0:
        return
    i = np.arange(n)
    t = 100.0 + (i + 1) / rate
    a = np.sin(i * 0.37) + 0.01 * i
    chunks, start = [], 0
    for s in sizes:
        chunks.append({"time": t[start : start + s], "a": a[start : start + s], "b": -a[start : start + s]})
        start += s
    row = reduce_dwell(chunks, window_s=window)
    expected, t_last, k = _naive(chunks, window)
    assert row["n"] == k and row["time"] == t_last
    assert row["a"] == pytest.approx(expected["a"], abs=1e-9)
    assert row["b"] == pytest.approx(-expected["a"], abs=1e-9)


def test_short_stream_averages_everything_and_errors_are_reported():
    chunks = [{"time": np.array([1.0, 2.0]), "v": np.array([1.0, 3.0])}]
    assert reduce_dwell(chunks, window_s=5.0) == {"time": 2.0, "v": 2.0, "n": 2}
    with pytest.raises(ValueError, match="empty"):
        reduce_dwell([], window_s=5.0)
    with pytest.raises(ValueError, match="non-decreasing"):
        reduce_dwell(
            [{"time": np.array([2.0]), "v": np.array([1.0])}, {"time": np.array([1.0]), "v": np.array([1.0])}]
        )
    with pytest.raises(ValueError, match="channels"):
        reduce_dwell(
            [{"time": np.array([1.0]), "v": np.array([1.0])}, {"time": np.array([2.0]), "w": np.array([1.0])}]
        )
    with pytest.raises(ValueError, match="window_s"):
        reduce_dwell(chunks, window_s=0.0)


def _synthetic(n_chunks, chunk, rate, channels=6):
    for c in range(n_chunks):
        i = np.arange(c * chunk, (c + 1) * chunk, dtype=float)
        out = {"time": (i + 1.0) / rate}
        for k in range(channels):
            out[f"ch{k}"] = np.sin(i * 1e-3 * (k + 1))
        yield out


def test_reducer_keeps_o_window_state_on_a_long_stream():
    """8.2e6 samples at 1 kHz (2.3 h, 7 channels: ~460 MB if concatenated)."""
    rate, chunk, n_chunks, window = 1000.0, 4096, 2000, 5.0
    reducer = DwellReducer(window)
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        max_kept = 0
        for c in _synthetic(n_chunks, chunk, rate):
            reducer.update(c)
            max_kept = max(max_kept, reducer.n_kept)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert max_kept <= window * rate + 1
    assert peak < 8 * 2**20  # a few window-sized buffers plus one chunk, not 460 MB
    row = reducer.row()
    assert row["n"] == 5000
    i = np.arange(n_chunks * chunk - 5000, n_chunks * chunk, dtype=float)  # the last 5 s
    assert row["time"] == pytest.approx(n_chunks * chunk / rate)
    assert row["ch0"] == pytest.approx(np.sin(i * 1e-3).mean(), abs=1e-9)
    assert row["ch5"] == pytest.approx(np.sin(i * 6e-3).mean(), abs=1e-9)


def test_rig_stream_at_1khz_is_reduced_in_bounded_memory():
    rig = nano1d(profile="lab5day")
    rig.move({"x": 100.0})
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        row = reduce_dwell(rig.stream(600.0, rate_hz=1000.0), window_s=5.0)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert row["n"] == 5000 and row["time"] == pytest.approx(604.0)
    assert peak < 16 * 2**20  # 600k samples x 7 channels would be 34 MB
    assert abs(row["meas_x"] - rig.true_position(100.0)["meas_x"]) < 0.1
