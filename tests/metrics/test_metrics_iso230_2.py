"""ISO 230-2 bidirectional analysis: a hand-worked example and properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.metrics import iso230_2

# 3 targets; 4 forward cycles, 3 backward cycles.
TARGETS = np.array([0.0, 10.0, 20.0])
FORWARD = np.array(
    [
        [-1.0, 3.0, 3.0, 3.0],  # deviations -1, 3, 3, 3
        [9.0, 9.0, 9.0, 9.0],  # deviations -1, -1, -1, -1
        [24.5, 24.5, 24.5, 22.5],  # deviations 4.5, 4.5, 4.5, 2.5
    ]
)
BACKWARD = np.array(
    [
        [2.0, 3.0, 4.0],  # deviations 2, 3, 4
        [7.0, 8.0, 9.0],  # deviations -3, -2, -1
        [20.0, 20.0, 20.0],  # deviations 0, 0, 0
    ]
)


def test_hand_worked_example():
    r = iso230_2(TARGETS, FORWARD, BACKWARD)
    # Mean unidirectional deviations:
    #   x̄↑ = (-1+3+3+3)/4 = 2, -1, (4.5*3+2.5)/4 = 4      x̄↓ = 3, -2, 0
    np.testing.assert_allclose(r.x_fwd, [2.0, -1.0, 4.0])
    np.testing.assert_allclose(r.x_bwd, [3.0, -2.0, 0.0])
    # s↑: pos 0 residuals -3, 1, 1, 1 -> 12/3 = 4 -> 2; pos 1 -> 0;
    #     pos 2 residuals .5, .5, .5, -1.5 -> 3/3 = 1 -> 1
    # s↓: pos 0 residuals -1, 0, 1 -> 2/2 = 1 -> 1; pos 1 -> 1; pos 2 -> 0
    np.testing.assert_allclose(r.s_fwd, [2.0, 0.0, 1.0])
    np.testing.assert_allclose(r.s_bwd, [1.0, 1.0, 0.0], atol=1e-15)
    # x̄_i = (x̄↑ + x̄↓)/2 = 2.5, -1.5, 2 ; B_i = x̄↑ - x̄↓ = -1, 1, 4
    np.testing.assert_allclose(r.x_bidir, [2.5, -1.5, 2.0])
    np.testing.assert_allclose(r.B_i, [-1.0, 1.0, 4.0])
    # R↑_i = 4 s↑ = 8, 0, 4 ; R↓_i = 4, 4, 0
    np.testing.assert_allclose(r.R_fwd_i, [8.0, 0.0, 4.0])
    np.testing.assert_allclose(r.R_bwd_i, [4.0, 4.0, 0.0], atol=1e-15)
    # 2s↑ + 2s↓ + |B_i| = 4+2+1 = 7, 0+2+1 = 3, 2+0+4 = 6
    # R_i = max(7, 8, 4) = 8, max(3, 0, 4) = 4, max(6, 4, 0) = 6
    np.testing.assert_allclose(r.R_i, [8.0, 4.0, 6.0])
    # Axis values
    assert r.R_fwd == pytest.approx(8.0)
    assert r.R_bwd == pytest.approx(4.0)
    assert r.R == pytest.approx(8.0)
    assert r.E_fwd == pytest.approx(4.0 - -1.0)  # 5
    assert r.E_bwd == pytest.approx(3.0 - -2.0)  # 5
    assert r.E == pytest.approx(4.0 - -2.0)  # max over both 4, min over both -2 -> 6
    assert r.M == pytest.approx(2.5 - -1.5)  # 4
    assert r.B == pytest.approx(4.0)  # largest |B_i|
    assert r.B_mean == pytest.approx((-1.0 + 1.0 + 4.0) / 3.0)
    # A↑: x̄↑+2s↑ = 6, -1, 6 ; x̄↑-2s↑ = -2, -1, 2 -> 6 - -2 = 8
    # A↓: x̄↓+2s↓ = 5, 0, 0 ; x̄↓-2s↓ = 1, -4, 0 -> 5 - -4 = 9
    # A: max(6, 5) - min(-2, -4) = 10
    assert r.A_fwd == pytest.approx(8.0)
    assert r.A_bwd == pytest.approx(9.0)
    assert r.A == pytest.approx(10.0)
    assert r.positions == 3
    assert r.dev_fwd.shape == (3, 4) and r.dev_bwd.shape == (3, 3)


def test_axis_reversal_is_the_largest_magnitude_and_the_mean_keeps_its_sign():
    # backward above forward at two targets: B_i = -0.5, -3, 1 -> B = max |B_i| = 3 (ISO 230-2
    # clause 3: an absolute value), B̄ = -2.5/3 (signed)
    t = np.array([0.0, 1.0, 2.0])
    fwd = np.repeat(np.array([[0.0], [1.0], [3.0]]), 2, axis=1)
    bwd = np.repeat(np.array([[0.5], [4.0], [2.0]]), 2, axis=1)
    r = iso230_2(t, fwd, bwd)
    np.testing.assert_allclose(r.B_i, [-0.5, -3.0, 1.0])
    assert r.B == pytest.approx(3.0)
    assert r.B_mean == pytest.approx(-2.5 / 3.0)


@pytest.mark.parametrize(
    "targets, fwd, bwd, match",
    [
        (np.zeros(3), np.zeros((3, 1)), np.zeros((3, 3)), "at least 2 cycles"),
        (np.zeros(3), np.zeros((2, 4)), np.zeros((3, 3)), "forward has 2 positions"),
        (np.zeros(3), np.zeros((3, 4)), np.zeros(3), r"backward must have shape"),
        (np.zeros((3, 1)), np.zeros((3, 4)), np.zeros((3, 4)), "targets must be"),
        (np.zeros(3), np.full((3, 4), np.nan), np.zeros((3, 4)), "NaN"),
    ],
)
def test_bad_input_raises_clear_errors(targets, fwd, bwd, match):
    with pytest.raises(ValueError, match=match):
        iso230_2(targets, fwd, bwd)


vals = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False)


@st.composite
def axis_data(draw):
    m = draw(st.integers(1, 8))
    nf = draw(st.integers(2, 6))
    nb = draw(st.integers(2, 6))
    targets = draw(arrays(float, (m,), elements=vals))
    fwd = draw(arrays(float, (m, nf), elements=vals))
    bwd = draw(arrays(float, (m, nb), elements=vals))
    return targets, fwd, bwd


@settings(max_examples=200, deadline=None)
@given(axis_data())
def test_swapping_directions_changes_only_signs_of_reversal(data):
    targets, fwd, bwd = data
    a = iso230_2(targets, fwd, bwd)
    b = iso230_2(targets, bwd, fwd)
    for name in ("E", "M", "R", "A"):
        assert getattr(b, name) == getattr(a, name), name
    assert b.E_fwd == a.E_bwd and b.E_bwd == a.E_fwd
    assert b.R_fwd == a.R_bwd and b.R_bwd == a.R_fwd
    assert b.A_fwd == a.A_bwd and b.A_bwd == a.A_fwd
    assert b.B == a.B  # max |B_i| does not depend on which direction is called forward
    assert b.B_mean == -a.B_mean
    np.testing.assert_array_equal(b.B_i, -a.B_i)
    np.testing.assert_array_equal(b.R_i, a.R_i)
    np.testing.assert_array_equal(b.x_bidir, a.x_bidir)


@settings(max_examples=200, deadline=None)
@given(axis_data())
def test_orderings_that_always_hold(data):
    targets, fwd, bwd = data
    r = iso230_2(targets, fwd, bwd)
    tol = 1e-9
    assert r.E >= max(r.E_fwd, r.E_bwd) - tol
    assert r.E >= r.M - tol
    assert r.R == pytest.approx(max(r.R_i))
    assert r.R >= max(r.R_fwd, r.R_bwd) - tol
    assert r.A >= max(r.A_fwd, r.A_bwd, r.E) - tol
    assert r.B >= 0.0
    assert r.B == np.max(np.abs(r.B_i))
    assert r.B >= abs(r.B_mean) - tol


@settings(max_examples=100, deadline=None)
@given(axis_data(), vals)
def test_common_shift_of_attained_positions(data, c):
    # Adding c to every attained position shifts every mean deviation by c: spans,
    # repeatabilities and reversal values are unchanged.
    targets, fwd, bwd = data
    a = iso230_2(targets, fwd, bwd)
    b = iso230_2(targets, fwd + c, bwd + c)
    for name in ("E", "E_fwd", "E_bwd", "M", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd", "B", "B_mean"):
        assert getattr(b, name) == pytest.approx(getattr(a, name), abs=1e-8), name
    np.testing.assert_allclose(b.B_i, a.B_i, atol=1e-8)


@settings(max_examples=100, deadline=None)
@given(axis_data(), vals)
def test_translating_the_axis_changes_nothing(data, c):
    # Moving targets and attained positions together (another origin of the axis) leaves
    # the deviations, hence every ISO 230-2 value, as they were.
    targets, fwd, bwd = data
    a = iso230_2(targets, fwd, bwd)
    b = iso230_2(targets + c, fwd + c, bwd + c)
    for name in ("E", "E_fwd", "E_bwd", "M", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd", "B", "B_mean"):
        assert getattr(b, name) == pytest.approx(getattr(a, name), abs=1e-8), name
    assert b.B >= 0.0


@settings(max_examples=200, deadline=None)
@given(axis_data())
def test_reversal_value_is_never_negative_and_is_the_largest_magnitude(data):
    targets, fwd, bwd = data
    r = iso230_2(targets, fwd, bwd)
    assert r.B >= 0.0
    assert r.B == np.max(np.abs(r.B_i))
    assert r.B == pytest.approx(np.max(np.abs(r.x_fwd - r.x_bwd)), abs=1e-9)


def _tables_by_loop(x, target, direction, cycle):
    """The tables as the standard reads them: each target, cycle and direction's readings
    averaged, one cell at a time (what tables_of_run computes at once)."""
    key = np.round(target, 6)
    both = np.array(sorted(set(key[direction > 0]) & set(key[direction < 0])))
    out = []
    for sign in (1, -1):
        d = direction == sign
        cycles = np.unique(cycle[d])
        a = np.full((both.size, cycles.size), np.nan)
        for j, c in enumerate(cycles):
            for i, t in enumerate(both):
                sel = d & (cycle == c) & (key == t)
                if sel.any():
                    a[i, j] = np.nanmean(x[sel]) if np.isfinite(x[sel]).any() else np.nan
        keep = np.all(np.isfinite(a), axis=0)
        out += [a[:, keep], cycles[keep]]
    return both, out


@settings(max_examples=80, deadline=None)
@given(
    n=st.integers(2, 80),
    targets=st.integers(1, 6),
    cycles=st.integers(1, 4),
    missing=st.floats(0.0, 0.3),
    seed=st.integers(0, 2**32 - 1),
)
def test_tables_of_a_run_are_each_cells_mean_of_its_readings(n, targets, cycles, missing, seed):
    """A run's tables hold, per target reached both ways and per cycle, the mean of that
    cell's readings (NaN ignored, several readings a cell averaged in their order), to the
    byte; a cycle missing a cell is dropped for that direction."""
    import xarray as xr

    from calflow.metrics.iso230_2_runs import tables_of_run

    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n) * 10.0
    x[rng.random(n) < missing] = np.nan
    target = rng.integers(0, targets, n) * 2.5
    direction = np.where(rng.random(n) < 0.5, 1, -1)
    cycle = rng.integers(0, cycles, n)
    run = xr.Dataset(
        {
            "meas_x": ("sample", x),
            "target_x": ("sample", target),
            "direction": ("sample", direction),
            "cycle": ("sample", cycle),
        }
    )
    both, (fwd, fc, bwd, bc) = _tables_by_loop(x, target, direction, cycle)
    if both.size == 0:
        with pytest.raises(Exception, match="both directions"):
            tables_of_run(run)
        return
    got = tables_of_run(run)
    for mine, theirs in zip(got[:5], (both, fwd, bwd, fc, bc), strict=True):
        assert mine.shape == theirs.shape and mine.tobytes() == theirs.tobytes()
