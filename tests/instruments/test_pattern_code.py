"""The encoded pattern: its m-sequences, the uniqueness of every view, its file."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.errors import CalflowError
from calflow.instruments.pattern import Pattern, codes
from calflow.instruments.pattern.pattern import MIN_DISTANCE, code_distances, distances_ok, site_matrix


@pytest.fixture(scope="module")
def thesis_pattern():
    return Pattern.make(range_um=(9500, 4200))


@given(st.integers(3, 12))
@settings(max_examples=10, deadline=None)
def test_primitive_polynomials_give_maximum_length_sequences(n):
    for poly in codes.primitive_polynomials(n, count=2):
        period = (1 << n) - 1
        bits = codes.lfsr_bits(poly, 2 * period)
        assert np.array_equal(bits[:period], bits[period:])  # periodic with 2^n − 1 …
        words = {tuple(bits[i : i + n]) for i in range(period)}
        assert len(words) == period  # … and every non-zero n-bit word once
        assert codes.check_recurrence(bits, poly) == -1
        assert codes.reciprocal(poly) != poly


def test_non_primitive_polynomial_refused():
    assert not codes.is_primitive((4, 2, 0))  # (x² + x + 1)²
    assert codes.is_primitive((11, 2, 0))
    bits = codes.lfsr_bits((11, 2, 0), 100)
    bits[50] ^= 1
    assert codes.check_recurrence(bits, (11, 2, 0)) == 50


def test_thesis_range_and_ten_centimetres_fit():
    p = Pattern.make(range_um=(100_000, 4200), check=False)  # the distance check is the next test's
    for i in (0, 1):
        assert p.size_um[i] >= p.origin_um[i] + p.range_um[i] + p.min_fov_um[i] / 2
    assert (1 << p.x_order) - 1 >= len(p.x_bits)


def test_every_view_decodes_to_one_place_on_the_matrix(thesis_pattern):
    """Read the codes back from the present/missing matrix itself (undoing the flips), and check
    that every window of the stated field of view is unique and far from every misreading."""
    p = thesis_pattern
    m = p.matrix
    assert m.shape == p.shape
    assert m[0::2, 0::2].all() and m[1::2, 1::2].all()  # the frame dots
    x_rows = m[0::2, 1::2] ^ (np.arange(m.shape[0] // 2) % 2 == 1)[:, None]
    y_cols = m[1::2, 0::2] ^ ((np.arange(m.shape[1] // 2) // 2) % 2 == 1)[None, :]
    assert (x_rows == x_rows[0]).all() and (y_cols == y_cols[:, :1]).all()  # constant after the flips
    x, y = x_rows[0].astype(np.uint8), y_cols[:, 0].astype(np.uint8)
    for bits, w in ((x, p.window_bits[0]), (y, p.window_bits[1])):
        windows = {bits[i : i + w].tobytes() for i in range(len(bits) - w + 1)}
        assert len(windows) == len(bits) - w + 1
    d = code_distances(x, y, p.window_bits)
    assert distances_ok(d), d
    assert min(d["shift_x"], d["shift_y"]) >= MIN_DISTANCE
    # one bit shorter windows would not do (the windows are the shortest that meet the rule)
    shorter = (p.window_bits[0] - 1, p.window_bits[1] - 1)
    assert not distances_ok(code_distances(x, y, shorter))
    # the field of view the file states holds a window of each code (and a cell to spare)
    assert p.min_fov_um == (
        (p.window_bits[0] + 1) * 2 * p.period_um,
        (p.window_bits[1] + 1) * 2 * p.period_um,
    )


@given(
    st.floats(300, 3000),
    st.floats(300, 3000),
    st.sampled_from([3.0, 4.0, 5.0]),
    st.floats(0.3, 0.7),
)
@settings(max_examples=8, deadline=None)
def test_pattern_file_round_trip(tmp_path_factory, rx, ry, period, dot_fraction):
    p = Pattern.make(range_um=(rx, ry), period_um=period, dot_diameter_um=dot_fraction * period)
    path = tmp_path_factory.mktemp("pattern") / "p.json"
    p.save(path)
    q = Pattern.load(path)
    assert q.to_dict() == p.to_dict()
    assert np.array_equal(q.matrix, p.matrix)
    assert np.array_equal(p.matrix, site_matrix(p.x_bits, p.y_bits))
    data = json.loads(path.read_text())
    assert data["min_fov_um"] == list(p.min_fov_um) and data["version"] == 1


def _write(tmp_path, data) -> str:
    path = tmp_path / "bad.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return str(path)


@pytest.mark.parametrize(
    "edit, field",
    [
        (lambda d: "{not json", "expected JSON"),
        (lambda d: d | {"format": "other"}, "format"),
        (lambda d: d | {"version": 2}, "version"),
        (lambda d: d | {"period_um": -4}, "period_um"),
        (lambda d: d | {"dot_diameter_um": 5.0}, "dot_diameter_um"),
        (lambda d: d | {"range_um": [9500]}, "range_um"),
        (lambda d: {k: v for k, v in d.items() if k != "y_code"}, "y_code"),
        (lambda d: d | {"x_code": d["x_code"] | {"polynomial": [4, 2, 0]}}, "x_code.polynomial"),
        (lambda d: d | {"x_code": d["x_code"] | {"bits": d["x_code"]["bits"][:40] + "2"}}, "x_code.bits"),
        (lambda d: d | {"x_code": d["x_code"] | {"bits": _flip(d["x_code"]["bits"], 30)}}, "x_code.bits"),
        (lambda d: d | {"x_code": d["x_code"] | {"window_bits": 3}}, "x_code.window_bits"),
        (lambda d: d | {"range_um": [9500, 42000]}, "y_code.bits"),  # the code cannot cover the range
        (lambda d: d | {"matrix_sha256": "0" * 64}, "matrix_sha256"),
    ],
)
def test_bad_pattern_file_is_one_line_naming_the_field(tmp_path, thesis_pattern, edit, field):
    data = edit(thesis_pattern.to_dict())
    path = _write(tmp_path, data)
    with pytest.raises(CalflowError) as err:
        Pattern.load(path)
    message = str(err.value)
    assert "\n" not in message and path in message and field in message


def _flip(bits: str, i: int) -> str:
    return bits[:i] + ("1" if bits[i] == "0" else "0") + bits[i + 1 :]


def test_code_that_cannot_cover_the_range_is_refused():
    with pytest.raises(ValueError, match="x_order 8"):
        Pattern.make(range_um=(9500, 4200), x_order=8)
    with pytest.raises(ValueError, match="range_um"):
        Pattern.make(range_um=(0, 4200))
