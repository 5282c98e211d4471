"""The streamed, adaptive Monte Carlo (calflow.metrics.uncertainty: draws, stream, adaptive):
the same intervals as from the whole array of draws, reproducible blocks, JCGM 101 §7.9's
stopping rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from calflow.metrics.uncertainty import Term, largest_bounds, maximum_interval
from calflow.metrics.uncertainty import stream as stream_module
from calflow.metrics.uncertainty.adaptive import numerical_tolerance, spread
from calflow.metrics.uncertainty.draws import Draws, block_sizes
from calflow.metrics.uncertainty.stream import Maximum, Span, simulate
from calflow.metrics.uncertainty.tails import BlockTails, TailSample

TERMS = [
    Term("cal", 0.5, scope="common", relative=True),
    Term("drift", 0.02, scope="target"),
    Term("offset", 0.03, scope="common"),
]


def _whole(draws, positions, n, sizes):
    """Every block of every group drawn again and assembled: the (M, cells, d) error."""
    blocks = []
    for b, m in enumerate(sizes):
        e = np.zeros((m, draws.cells, draws.d))
        for g, idx in enumerate(draws.groups):
            e[:, idx] = draws.error(b, m, g, positions, n)[0]
        blocks.append(e)
    return np.concatenate(blocks)


@settings(max_examples=30, deadline=None)
@given(
    cells=st.integers(1, 9),
    d=st.integers(1, 2),
    group=st.integers(1, 4),
    watch=st.integers(0, 3),
    trials=st.integers(20, 90),
    block=st.integers(7, 40),
    spread_=st.floats(0.0, 3.0),
    seed=st.integers(0, 2**32 - 1),
)
@example(cells=6, d=1, group=2, watch=0, trials=60, block=25, spread_=0.0, seed=1)
@example(
    cells=2, d=1, group=1, watch=1, trials=20, block=13, spread_=0.25, seed=2
)  # a kept column partitioned in place
def test_streamed_maximum_is_the_whole_arrays(cells, d, group, watch, trials, block, spread_, seed):
    """Blocks, groups, kept and redrawn cells: the interval of the maximum is exactly
    maximum_interval's over the whole (M, cells) array of the same draws."""
    rng = np.random.default_rng(seed)
    dev = spread_ * rng.standard_normal((cells, d)) + 1.0
    positions, n = rng.uniform(10, 1000, (cells, d)), rng.integers(2, 6, cells).astype(float)
    groups = [np.arange(a, min(a + group, cells)) for a in range(0, cells, group)]
    draws = Draws(np.full(d, 0.3), 7, cells, d, TERMS, seed, groups=groups)

    def cells_of(error, g):
        v = dev[draws.groups[g]][None] + error
        return {"ap": (np.sqrt(np.sum(v * v, axis=2)), draws.groups[g])}

    y = np.linalg.norm(dev, axis=1)
    old = stream_module.WATCH
    stream_module.WATCH = watch
    try:
        out = simulate(
            draws, positions, n, cells_of, {"ap": cells}, {"a": Maximum("ap", y)},
            lambda name, tmax, tmin, ext: tmax["ap"], trials=trials, block=block,
        )  # fmt: skip
    finally:
        stream_module.WATCH = old
    e = _whole(draws, positions, n, block_sizes(trials, block))
    full = np.linalg.norm(dev[None] + e, axis=2)
    assert out.intervals["a"] == maximum_interval(y, full)
    assert np.array_equal(out.stats["a"], full.max(axis=1))
    assert out.record == {
        "trials": trials,
        "blocks": len(block_sizes(trials, block)),
        "block": None,
        "adaptive": False,
    }


@settings(max_examples=20, deadline=None)
@given(
    targets=st.integers(2, 8),
    group=st.integers(1, 3),
    trials=st.integers(20, 70),
    block=st.integers(9, 30),
    seed=st.integers(0, 2**32 - 1),
)
def test_streamed_range_is_the_whole_arrays(targets, group, trials, block, seed):
    """A range's interval (max over pairs of cells, with a per-trial addition) is the one of
    the whole array of the same draws."""
    rng = np.random.default_rng(seed)
    P = targets
    mean = rng.normal(0, 0.2, 2 * P)
    runs = [np.arange(a, min(a + group, P)) for a in range(0, P, group)]
    draws = Draws([0.1], 5, 2 * P, 1, TERMS[1:2], seed, groups=[np.concatenate([r, P + r]) for r in runs])
    positions, n = np.ones((2 * P, 1)), np.full(2 * P, 3.0)

    def cells_of(error, g):
        idx = draws.groups[g]
        return {"mu": (mean[idx][None] + error[:, :, 0], idx)}

    def extras(b, m):
        return {"add": np.abs(draws.chisquare(b, m, 4))}

    out = simulate(
        draws, positions, n, cells_of, {"mu": 2 * P}, {"A": Span("mu", mean, 0.4, "add")},
        lambda name, tmax, tmin, ext: tmax["mu"] - tmin["mu"] + ext["add"], extras, trials=trials, block=block,
    )  # fmt: skip
    mu = mean[None] + _whole(draws, positions, n, block_sizes(trials, block))[:, :, 0]
    add = np.concatenate([extras(b, m)["add"] for b, m in enumerate(block_sizes(trials, block))])
    top, bottom = np.unique(np.argmax(mu, axis=1)), np.unique(np.argmin(mu, axis=1))
    e = (mean[top][:, None] - mean[bottom][None, :]).ravel() + 0.4
    pairs = (mu[:, top][:, :, None] - mu[:, bottom][:, None, :]).reshape(len(mu), -1) + add[:, None]
    p_max = np.bincount(np.argmax(mu, axis=1), minlength=2 * P) / len(mu)
    p_min = np.bincount(np.argmin(mu, axis=1), minlength=2 * P) / len(mu)
    t_eff = 1 / np.sum(p_max**2) + 1 / np.sum(p_min**2) - 1
    want = largest_bounds(e, lambda k: pairs[:, k], pairs.max(axis=0) + 1e-9, len(mu), 0.95, t_eff)
    assert out.intervals["A"][:2] == pytest.approx(want, rel=0, abs=1e-12)
    assert out.intervals["A"][2] == pytest.approx(t_eff)


@settings(max_examples=25, deadline=None)
@given(
    block=st.integers(0, 50), group=st.integers(0, 5), m=st.integers(1, 30), seed=st.integers(0, 2**32 - 1)
)
def test_a_block_is_drawn_again_alone_and_a_short_block_is_its_beginning(block, group, m, seed):
    draws = Draws([0.2, 0.1], 4, 12, 2, TERMS, seed, groups=[np.arange(2 * i, 2 * i + 2) for i in range(6)])
    pos, n = np.arange(24.0).reshape(12, 2), np.full(12, 3.0)
    first = draws.error(block, m + 5, group, pos, n)[0]
    draws.error(block + 1, 3, (group + 1) % 6, pos, n)  # another block and group in between
    again = draws.error(block, m + 5, group, pos, n)[0]
    assert np.array_equal(first, again)
    assert np.array_equal(draws.error(block, m, group, pos, n)[0], first[:m])
    assert not np.array_equal(draws.error(block + 1, m + 5, group, pos, n)[0], first)


@settings(max_examples=200, deadline=None)
@given(st.floats(1e-9, 1e9), st.integers(1, 2))
@example(0.096, 1)
@example(0.0374, 1)
def test_numerical_tolerance_is_half_a_unit_of_the_last_digit(u, digits):
    """JCGM 101 §7.2.2: u = c × 10^l with c of ``digits`` digits, δ = ½ × 10^l."""
    delta = numerical_tolerance(u, digits)
    unit = 2 * delta
    c = round(u / unit)
    assert 10 ** (digits - 1) <= c <= 10**digits
    assert abs(u - c * unit) <= delta * (1 + 1e-9)
    assert numerical_tolerance(0.0374) == pytest.approx(0.005)
    assert numerical_tolerance(0.096) == pytest.approx(0.05)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=30))
def test_spread_is_twice_the_standard_deviation_of_the_mean(values):
    x = np.asarray(values)
    assert spread(x) == pytest.approx(2 * np.std(x, ddof=1) / math.sqrt(x.size), rel=1e-9, abs=1e-9)
    assert math.isinf(spread(x[:1]))


def test_adaptive_stops_at_the_tolerance_and_reproduces_to_the_byte():
    from calflow.metrics.uncertainty_iso import iso230_2_uncertainty, iso9283_uncertainty

    rng = np.random.default_rng(5)
    cmd = rng.uniform(-500, 500, (12, 2))
    att = [c + rng.normal(0, 1.0, 2) + rng.normal(0, 0.2, (4, 2)) for c in cmd]
    one = iso9283_uncertainty(cmd, att, TERMS, seed=3)["accuracy"]
    two = iso9283_uncertainty(cmd, att, TERMS, seed=3)["accuracy"]
    assert one.record() == two.record()
    mc = one.monte_carlo
    assert mc["adaptive"] and mc["reached"] and mc["trials"] == 10_000 * mc["blocks"] >= 20_000
    assert mc["spread"] <= mc["tolerance"] == numerical_tolerance(one.u)
    assert f"M = {mc['trials']} trials" in one.method
    t = np.linspace(0, 100, 40)
    f = t[:, None] + 0.3 * np.sin(t / 9)[:, None] + rng.normal(0, 0.05, (40, 3))
    b = f - 0.5 + rng.normal(0, 0.05, (40, 3))
    r = iso230_2_uncertainty(t, f, b, TERMS[1:2])
    for key in "EMBAR":
        assert r[key].monte_carlo["reached"], key
        assert r[key].monte_carlo["spread"] <= r[key].monte_carlo["tolerance"]


@settings(max_examples=60, deadline=None)
@given(
    sizes=st.lists(st.integers(1, 80), min_size=1, max_size=4),
    scale=st.floats(0.01, 100.0),
    qs=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=4),
    seed=st.integers(0, 2**32 - 1),
)
def test_tails_give_the_whole_columns_percentiles(sizes, scale, qs, seed):
    """Percentiles read off the blocks' tails are np.quantile's of the whole column, to the
    byte, whether the tails hold them or the column is asked for; so is the share below."""
    rng = np.random.default_rng(seed)
    cols = [scale * rng.standard_normal((m, 3)) for m in sizes]
    y = scale * rng.standard_normal(3)
    blocks = []
    for c in cols:
        blocks.append(BlockTails(len(c), 3))
        blocks[-1].take(c, np.arange(3), y)
    whole = np.concatenate(cols)
    qs = [*qs, 0.001, 0.999]
    for j in range(3):
        sample = TailSample(blocks, j, lambda j=j: whole[:, j])
        assert sample.share_below() == np.mean(whole[:, j] < y[j])
        assert sample.quantile(qs) == np.quantile(whole[:, j], qs).tolist()


@settings(max_examples=80, deadline=None)
@given(
    m=st.integers(1, 400),
    q=st.floats(0.0, 1.0),
    ties=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
@example(m=1, q=0.5, ties=False, seed=0)
@example(m=7, q=1.0, ties=True, seed=1)
def test_a_columns_percentile_and_its_count_test_are_np_quantiles(m, q, ties, seed):
    """A column's percentile from the partial sort at its two order statistics is
    np.quantile's to the byte; the count that rules a bound out (at_most) never rules out one
    the percentile exceeds, and rules out the upper order statistic it is read below; the
    candidates' sign test is the sorted column's."""
    from calflow.metrics.uncertainty.montecarlo import _reaches_zero, _sorted_quantile
    from calflow.metrics.uncertainty.tails import Column, quantile

    rng = np.random.default_rng(seed)
    x = rng.standard_normal(m) * rng.uniform(0.01, 10.0) + rng.uniform(-1.0, 1.0)
    if ties:
        x = np.round(x, 1)
    exact = float(np.quantile(x, q))
    assert quantile(x, q) == exact
    column = Column(x, 0.0)
    assert column.quantile([q, 1.0 - q]) == np.quantile(x, [q, 1.0 - q]).tolist()
    for bound in (*rng.choice(x, 3), exact, -np.inf, np.inf):
        if column.at_most(q, float(bound)):
            assert exact <= bound
    upper = np.sort(x)[min(math.floor((m - 1) * q) + 1, m - 1)]
    assert column.at_most(q, float(upper))
    negative = int(np.count_nonzero(x < 0.0))
    assert _reaches_zero(x, negative, q) == (_sorted_quantile(np.sort(x), q) >= 0.0)


@settings(max_examples=40, deadline=None)
@given(
    sizes=st.lists(st.integers(1, 80), min_size=1, max_size=4),
    q=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_tails_rule_a_bound_out_only_below_the_percentile(sizes, q, seed):
    """A cell's tails say a bound cannot move (at_most) only when its percentile is ≤ it."""
    rng = np.random.default_rng(seed)
    cols = [rng.standard_normal((m, 2)) for m in sizes]
    blocks = []
    for c in cols:
        blocks.append(BlockTails(len(c), 2))
        blocks[-1].take(c, np.arange(2), np.zeros(2))
    whole = np.concatenate(cols)
    for j in range(2):
        sample = TailSample(blocks, j, lambda j=j: whole[:, j])
        exact = float(np.quantile(whole[:, j], q))
        for bound in (*rng.choice(whole[:, j], 4), exact):
            if sample.at_most(q, float(bound)):
                assert exact <= bound


@pytest.mark.parametrize("block", [0, 1, 3])
def test_every_block_draws_the_same_error_whether_its_inputs_are_apart_or_summed(block):
    """Block 0 draws each input apart (the budget's), later blocks the sample and per-cell terms
    as one normal: per cell and axis the variance is the same, σ² E[ν/χ²_ν] / n + Σ u²
    (relative terms scaled by the position), and the common terms stay shared by every cell."""
    dof, s_ = 9.0, np.array([0.2, 0.1])
    pos, n = np.array([[100.0, 50.0], [900.0, 300.0], [10.0, 10.0]]), np.array([2.0, 5.0, 3.0])
    terms = [Term("cal", 0.5, scope="common", relative=True), Term("drift", [0.02, 0.05], scope="target"),
             Term("lin", 30.0, scope="target", relative=True), Term("offset", 0.03, scope="common")]  # fmt: skip
    draws = Draws(s_, dof, 3, 2, terms, 7)
    e = draws.error(block, 200_000, 0, pos, n)[0]
    common = (0.5e-6 * pos) ** 2 + 0.03**2
    want = s_**2 * dof / (dof - 2) / n[:, None] + np.array([0.02, 0.05]) ** 2 + (30e-6 * pos) ** 2 + common
    assert e.var(axis=0) == pytest.approx(want, rel=0.03)
    # the shared offset and scale error: covariance between cells
    cov = np.mean((e[:, 0, 0] - e[:, 0, 0].mean()) * (e[:, 2, 0] - e[:, 2, 0].mean()))
    assert cov == pytest.approx(0.03**2 + 0.5e-6**2 * pos[0, 0] * pos[2, 0], rel=0.1)


@settings(max_examples=20, deadline=None)
@given(
    cells=st.integers(1, 8),
    group=st.integers(1, 3),
    trials=st.integers(20, 90),
    block=st.integers(7, 40),
    seed=st.integers(0, 2**32 - 1),
)
def test_streamed_maximum_with_a_per_trial_addition_is_the_whole_arrays(cells, group, trials, block, seed):
    """A maximum whose cells all carry the same per-trial addition (ISO 230-2's R = |reversal|
    + 4σ̂): its tails, its count and its bounds are those of the whole array plus the addition."""
    rng = np.random.default_rng(seed)
    dev = rng.normal(0, 0.3, cells)
    groups = [np.arange(a, min(a + group, cells)) for a in range(0, cells, group)]
    draws = Draws([0.1], 5, cells, 1, TERMS[1:2], seed, groups=groups)
    positions, n = np.ones((cells, 1)), np.full(cells, 3.0)

    def cells_of(error, g):
        idx = draws.groups[g]
        return {"r": (np.abs(dev[idx][None] + error[:, :, 0]), idx)}

    def extras(b, m):
        return {"add": 0.4 * np.sqrt(draws.chisquare(b, m, 4) / 4)}

    y = np.abs(dev) + 0.4
    out = simulate(
        draws, positions, n, cells_of, {"r": cells}, {"R": Maximum("r", y, "add")},
        lambda name, tmax, tmin, ext: tmax["r"] + ext["add"], extras, trials=trials, block=block,
    )  # fmt: skip
    sizes = block_sizes(trials, block)
    r = np.abs(dev[None] + _whole(draws, positions, n, sizes)[:, :, 0])
    add = np.concatenate([extras(b, m)["add"] for b, m in enumerate(sizes)])
    assert out.intervals["R"] == maximum_interval(y, r + add[:, None])


@settings(max_examples=30, deadline=None)
@given(
    cells=st.integers(1, 6),
    d=st.integers(1, 2),
    readings=st.integers(2, 6),
    m=st.integers(1, 40),
    block=st.integers(1, 5),
    seed=st.integers(0, 2**32 - 1),
)
def test_cells_alike_draw_the_error_of_each_cells_own_variance(cells, d, readings, m, block, seed):
    """Cells with the same readings and no relative term of their own share one variance per
    trial: the error is to the byte the one from each cell's own variance (every input in the
    draws' order: the sample term and per-cell terms as one normal, then the common terms)."""
    from calflow.metrics.uncertainty.draws import _SAMPLE, _TERMS

    terms = [Term("res", 0.01, scope="reading"), *TERMS, Term("drift2", [0.04, 0.01][:d], scope="target")]
    s_ = np.array([0.2, 0.1])[:d]
    draws = Draws(s_, 6.5, cells, d, terms, seed)
    pos = np.random.default_rng(seed).uniform(1, 900, (cells, d))
    n = np.full(cells, float(readings))
    got = draws.error(block, m, 0, pos, n)[0]
    sigma = s_[None, :] * draws.scale(block, m)[:, None]
    var = (sigma * sigma)[:, None, :] / n[None, :, None]
    for t in draws.terms:
        if t.scope != "common":
            var += (np.broadcast_to(t.per_axis(d), (cells, d)) ** 2)[None]
    want = draws.rng(block, _SAMPLE, 0).standard_normal((m, cells, d)) * np.sqrt(var)
    for i, t in enumerate(draws.terms):
        if t.scope == "common":
            e = draws.rng(block, _TERMS + i).standard_normal((m, 1, d)) * t.per_axis(d)
            want += e * (1e-6 * pos[None]) if t.relative else e
    assert np.array_equal(got, want)


@settings(max_examples=15, deadline=None)
@given(
    targets=st.integers(3, 12), group=st.integers(1, 3), m=st.integers(20, 60), seed=st.integers(0, 2**32 - 1)
)
def test_a_ranges_cells_are_kept_as_the_block_is_drawn(targets, group, m, seed):
    """A range's look over one block reads the cells that are its largest or smallest in some
    trial from what the block kept while it was drawn: no group is drawn again (no cell is
    watched here, so nothing else could have kept them)."""
    rng = np.random.default_rng(seed)
    P = targets
    mean = rng.normal(0, 0.05, 2 * P)
    runs = [np.arange(a, min(a + group, P)) for a in range(0, P, group)]
    draws = Draws([0.1], 5, 2 * P, 1, TERMS[1:2], seed, groups=[np.concatenate([r, P + r]) for r in runs])
    calls = []
    error = draws.error
    draws.error = lambda *a, **k: calls.append(a[:3]) or error(*a, **k)

    def cells_of(e, g):
        idx = draws.groups[g]
        return {"mu": (mean[idx][None] + e[:, :, 0], idx)}

    old = stream_module.WATCH
    stream_module.WATCH = 0
    try:
        out = simulate(
            draws, np.ones((2 * P, 1)), np.full(2 * P, 3.0), cells_of, {"mu": 2 * P}, {"E": Span("mu", mean)},
            lambda name, tmax, tmin, ext: tmax["mu"] - tmin["mu"], trials=m, block=m,
        )  # fmt: skip
    finally:
        stream_module.WATCH = old
    assert sorted(calls) == sorted((0, m, g) for g in range(len(runs)))
    mu = mean[None] + _whole(draws, np.ones((2 * P, 1)), np.full(2 * P, 3.0), [m])[:, :, 0]
    assert out.stats["E"] == pytest.approx(mu.max(axis=1) - mu.min(axis=1), rel=0, abs=0)
