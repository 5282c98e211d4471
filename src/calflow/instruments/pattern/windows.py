"""How many bits of each code a view must read: the windows, and the distances that make them unique.

The rule (module :mod:`.pattern` explains the layout it protects): two places along one axis,
and an x window against a complemented one, differ in :data:`MIN_DISTANCE` bits on that axis
alone; a view read backwards (a half turn) differs from every forward one in that many bits
over both axes together. The quarter turns are excluded by the layout's flips.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.instruments.pattern import codes

MIN_DISTANCE = 5  # bits: a reading with one wrong bit still sits 4 bits from any other window


def code_distances(x_bits, y_bits, window_bits) -> dict:
    """The code's distances (bits) for windows of ``window_bits`` (x, y) bits.

    ``shift_*``: between two places of one code (a wrong position on that axis);
    ``complement_*``: between a window and a complemented one (the x reading's flip guessed
    wrong); ``reversed_*`` and ``reversed_complement_*``: between a forward window and a
    backward one, as is or complemented (a half turn misread). A view of the pattern locates
    itself uniquely whatever Θ when every shift and the x complement reach
    :data:`MIN_DISTANCE`, and so does the sum over both axes of the smaller reversed distance;
    the quarter turns are excluded by the layout (module docstring).
    """
    out = {}
    for axis, bits, m in (("x", x_bits, window_bits[0]), ("y", y_bits, window_bits[1])):
        a = np.asarray(bits, np.int8)
        m = int(m)
        out[f"shift_{axis}"] = codes.window_distance(a, a, m, same=True)
        out[f"complement_{axis}"] = codes.window_distance(a, 1 - a, m)
        out[f"reversed_{axis}"] = codes.window_distance(a, a[::-1], m)
        out[f"reversed_complement_{axis}"] = codes.window_distance(a, 1 - a[::-1], m)
    return out


def distances_ok(d: dict) -> bool:
    """Whether :func:`code_distances` meet the rule that makes every view decode to one place."""
    half_turn = sum(min(d[f"reversed_{a}"], d[f"reversed_complement_{a}"]) for a in "xy")
    return min(d["shift_x"], d["shift_y"], d["complement_x"]) >= MIN_DISTANCE and half_turn >= MIN_DISTANCE


def choose_windows(orders, spans, cell, redundancy_bits, check):
    """Window lengths (bits) for codes of these orders, and the code bits the spans need."""
    polys = polynomial_pair(*orders)
    base = [orders[0] + redundancy_bits, orders[1] + redundancy_bits]
    full = [codes.lfsr_bits(p, (1 << n) - 1) for p, n in zip(polys, orders)]
    for i in (0, 1):  # two places on one axis: the m-sequence's lightest window (shift-and-add)
        while _lightest_window(full[i], base[i]) < MIN_DISTANCE:
            base[i] += 1

    def build(extra):
        window = [base[0] + extra[0], base[1] + extra[1]]
        lengths = [cells_needed(s, (w + 1) * cell, cell) for s, w in zip(spans, window)]
        return window, [full[i][: lengths[i]] for i in (0, 1)]

    if not check:
        return build((0, 0))
    extra_x = 0  # the x reading's flip: an x window against complemented ones
    while True:
        window, bits = build((extra_x, 0))
        a = np.asarray(bits[0], np.int8)
        if codes.window_distance(a, 1 - a, window[0]) >= MIN_DISTANCE:
            break
        extra_x += 1

    def half_turn_ok(extra):
        window, bits = build((extra_x + extra, extra))
        return distances_ok(code_distances(bits[0], bits[1], window))

    lo, hi = -1, 0  # a view read backwards (a half turn): both axes together
    while not half_turn_ok(hi):
        lo, hi = hi, 2 * hi + 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if half_turn_ok(mid) else (mid, hi)
    return build((extra_x + hi, hi))


def _lightest_window(full_period: np.ndarray, m: int) -> int:
    """Fewest ones in a cyclic window of ``m`` bits of a whole m-sequence period: by the
    shift-and-add property, the smallest distance between two of its windows."""
    if m >= len(full_period):
        return int(full_period.sum())
    ext = np.concatenate([full_period, full_period[: m - 1]]).astype(np.int32)
    c = np.concatenate(([0], np.cumsum(ext)))
    return int((c[m:] - c[:-m]).min())


def cells_needed(span_um: float, fov_um: float, cell_um: float) -> int:
    """Cells of the code along an axis so that every frame centre in [0, span] sees ``fov``."""
    origin = math.ceil(fov_um / 2 / (cell_um / 2)) * (cell_um / 2)
    extent = origin + span_um + fov_um / 2
    return int(math.ceil(extent / cell_um)) + 1


def polynomial_pair(nx: int, ny: int):
    px = codes.primitive_polynomials(nx)[0]
    for py in codes.primitive_polynomials(ny):
        if py not in (px, codes.reciprocal(px)):
            return px, py
    raise ValueError(f"no pair of distinct primitive polynomials of orders {nx}, {ny}")
