"""U of the headline figures (calflow.metrics.uncertainty): GUM, Welch–Satterthwaite, Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from calflow.metrics.uncertainty import (
    Term,
    chi_rp_factor,
    coverage_factor,
    gum_linear,
    largest_bounds,
    maximum_interval,
    pooled_scatter,
    welch_satterthwaite,
)
from calflow.metrics.uncertainty.montecarlo import candidate_count, candidates, lower_risk
from calflow.metrics.uncertainty_iso import iso230_2_uncertainty, iso9283_uncertainty


def test_welch_satterthwaite_one_finite_term_gives_its_dof():
    # u_c^4 / (u_1^4 / nu_1) with u_2 infinite-dof: nu_1 (u_c/u_1)^4
    assert welch_satterthwaite([1.0, 1.0], [10, math.inf]) == pytest.approx(10 * 4)
    assert welch_satterthwaite([1.0], [7]) == pytest.approx(7)
    assert math.isinf(welch_satterthwaite([1.0, 2.0], [math.inf, math.inf]))


def test_coverage_factor_is_students_t():
    assert coverage_factor(math.inf) == pytest.approx(1.959964, abs=1e-6)
    assert coverage_factor(4) == pytest.approx(2.776445, abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    dof=st.one_of(st.floats(0.5, 1e7), st.integers(1, 10_000).map(float), st.just(math.inf)),
    level=st.floats(0.5, 0.999),
    s=st.floats(1e-6, 1e3),
)
def test_quantiles_by_scipy_special_are_scipy_stats_to_the_byte(dof, level, s):
    """The summary takes its t, normal, χ² and F quantiles from the scipy.special functions
    scipy.stats calls, so as not to import scipy.stats: the same numbers, not merely close."""
    from calflow.metrics.uncertainty import robust_sd, sigma_interval
    from calflow.xytheta.report.heldout import adequacy

    q = (1.0 + level) / 2.0
    want = float(stats.norm.ppf(q) if math.isinf(dof) else stats.t.ppf(q, dof))
    assert coverage_factor(dof, level) == want
    if math.isfinite(dof):
        a = (1.0 - level) / 2.0
        assert sigma_interval(s, dof, level) == (
            s * math.sqrt(dof / stats.chi2.ppf(1 - a, dof)),
            s * math.sqrt(dof / stats.chi2.ppf(a, dof)),
        )
        floor = {"floor_um": s, "dof": dof}
        fit = s * level * 2
        got = adequacy(fit, 40, 4, floor)
        assert got["p_value"] == float(stats.f.sf(fit**2 / s**2, 2 * 39 - 4, dof))
    x = np.random.default_rng(int(dof) % 997 if math.isfinite(dof) else 1).standard_normal(501) * s
    lo, hi = np.quantile(x, [stats.norm.cdf(-1.0), stats.norm.cdf(1.0)])
    assert robust_sd(x) == float(hi - lo) / 2.0


@pytest.mark.parametrize("d", [1, 2, 3])
def test_rp_factor_matches_simulation(d):
    z = np.random.default_rng(d).standard_normal((400_000, d))
    r = np.linalg.norm(z, axis=1)
    assert chi_rp_factor(d) == pytest.approx(r.mean() + 3 * r.std(), rel=5e-3)


def test_gum_and_monte_carlo_agree_on_the_signed_mean_reversal():
    """B̄ is linear in the cell means: the GUM U and the Monte Carlo spread of the same model agree."""
    rng = np.random.default_rng(4)
    t = np.linspace(0, 100, 8)
    f = t[:, None] + 0.2 + rng.normal(0, 0.1, (8, 6))
    b = t[:, None] + rng.normal(0, 0.1, (8, 6))
    terms = [Term("drift", 0.05, scope="target")]
    r = iso230_2_uncertainty(t, f, b, terms, trials=20_000)
    gum = r["B_mean"]
    assert "GUM" in gum.method
    # the same model by Monte Carlo: cell means with σ drawn from its posterior, the drift per cell
    s, dof = pooled_scatter([row[:, None] for row in np.vstack([f, b])])
    m = 400_000
    g = np.random.default_rng(1)
    sigma = s[0] * np.sqrt(dof / g.chisquare(dof, m))
    e = g.standard_normal((m, 16)) * (sigma[:, None] / math.sqrt(6)) + g.normal(0, 0.05, (m, 16))
    mc = gum.value + (e[:, :8] - e[:, 8:]).mean(axis=1)
    assert np.std(mc) == pytest.approx(gum.u, rel=0.02)
    lo, hi = np.quantile(mc, [0.025, 0.975])
    assert (hi - lo) / 2 == pytest.approx(gum.U, rel=0.03)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.1, 5.0), st.floats(0.1, 5.0), st.integers(3, 30))
def test_gum_linear_is_root_sum_of_squares(a, b, dof):
    r = gum_linear(1.0, {"a": a, "b": b}, {"a": dof})
    uc = math.hypot(a, b)
    assert r.u == pytest.approx(uc)
    assert r.dof_eff == pytest.approx(dof * (uc / a) ** 4)
    assert r.U == pytest.approx(stats.t.ppf(0.975, r.dof_eff) * uc)
    assert r.interval == pytest.approx((1.0 - r.U, 1.0 + r.U))


def test_maximum_interval_of_one_clear_maximum_is_its_cells():
    rng = np.random.default_rng(0)
    draws = np.column_stack([rng.normal(10, 1, 100_000), rng.normal(0, 1, 100_000)])
    lo, hi, t_eff = maximum_interval([10.0, 0.0], draws)
    assert t_eff == pytest.approx(1.0, abs=1e-3)
    assert (lo, hi) == pytest.approx((10 - 1.96, 10 + 1.96), abs=0.05)


def test_maximum_interval_widens_with_ties():
    rng = np.random.default_rng(0)
    draws = rng.normal(0, 1, (50_000, 6))
    lo1, hi1, _ = maximum_interval([0.0], draws[:, :1])
    lo, hi, t_eff = maximum_interval(np.zeros(6), draws)
    assert t_eff > 4
    assert hi - lo > hi1 - lo1


@settings(max_examples=40, deadline=None)
@given(
    cells=st.integers(1, 12),
    spread=st.floats(0.0, 5.0),
    shift=st.floats(-1e3, 1e3),
    t_eff=st.floats(1.0, 12.0),
    seed=st.integers(0, 2**16),
)
def test_largest_bounds_skips_only_cells_that_cannot_set_them(cells, spread, shift, t_eff, seed):
    """The pruned search gives exactly the largest bounds over every cell's percentiles."""
    from scipy.special import ndtr, ndtri

    rng = np.random.default_rng(seed)
    y = shift + spread * rng.standard_normal(cells)
    d = y + rng.standard_normal((2000, cells)) * rng.uniform(0.1, 2.0, cells)
    za = ndtri(1.0 - (1.0 - lower_risk(0.95, t_eff)) ** (1.0 / t_eff))  # the lower bounds: Šidák
    zb = ndtri((1.0 - 0.95) / 2.0)  # the upper bounds: each cell's own
    z0 = ndtri(np.clip(np.mean(d < y, axis=0), 1 / 2000, 1 - 1 / 2000))
    lo = max(np.quantile(d[:, j], ndtr(2 * z0[j] + za)) for j in range(cells))
    hi = max(np.quantile(d[:, j], ndtr(2 * z0[j] - zb)) for j in range(cells))
    assert largest_bounds(y, lambda j: d[:, j], d.max(axis=0), 2000, 0.95, t_eff) == (lo, hi)


@settings(max_examples=60, deadline=None)
@given(level=st.floats(0.5, 0.999), count=st.floats(1.0, 50.0))
def test_the_two_sides_share_the_risk_whatever_the_tie(level, count):
    """One clear maximum: α/2 a side; m tied cells: the upper side misses (α/2)^m, the lower
    side takes the rest; the risk never exceeds α and grows with the count."""
    a = 1.0 - level
    assert lower_risk(level, 1.0) == pytest.approx(a / 2)
    assert lower_risk(level, count) + (a / 2) ** count == pytest.approx(a)
    assert a / 2 - 1e-15 <= lower_risk(level, count) <= lower_risk(level, count + 1.0) <= a


@settings(max_examples=30, deadline=None)
@given(cells=st.integers(2, 12), seed=st.integers(0, 2**16))
def test_candidates_are_the_cells_that_can_be_the_maximum(cells, seed):
    """Equal cells with equal spread all count; one cell far above the rest counts alone."""
    rng = np.random.default_rng(seed)
    tied = rng.standard_normal((4000, cells))
    assert candidate_count(np.zeros(cells), tied) == cells
    y = np.r_[50.0, np.zeros(cells - 1)]
    assert candidate_count(y, y + tied) == 1


@settings(max_examples=40, deadline=None)
@given(
    cells=st.integers(2, 10),
    spread=st.floats(0.0, 4.0),
    common=st.floats(0.0, 50.0),
    seed=st.integers(0, 2**16),
)
def test_what_the_cells_share_does_not_make_them_candidates(cells, spread, common, seed):
    """A per-trial error shared by every cell (a common term, a per-trial addition) cancels in
    the paired differences: the count is the same with it as without it, however large. The
    draws are multiples of 2⁻⁶ so that adding and subtracting the shared error is exact."""
    rng = np.random.default_rng(seed)
    y = np.round(64 * spread * rng.standard_normal(cells)) / 64
    d = y + np.round(64 * rng.standard_normal((3000, cells))) / 64
    shared = np.round(64 * common * rng.standard_normal((3000, 1))) / 64
    assert candidate_count(y, d + shared) == candidate_count(y, d)


@settings(max_examples=40, deadline=None)
@given(cells=st.integers(2, 10), spread=st.floats(0.0, 4.0), seed=st.integers(0, 2**16))
def test_candidates_read_only_cells_that_can_count_and_each_once(cells, spread, seed):
    """Skipping the cells whose largest draw lies below the top's smallest gives the count from
    every cell; no cell's draws are asked twice (a streamed cell is drawn again once)."""
    rng = np.random.default_rng(seed)
    y = spread * rng.standard_normal(cells)
    d = y + rng.standard_normal((2000, cells)) * rng.uniform(0.1, 2.0, cells)
    asked = []

    def column(j):
        asked.append(j)
        return d[:, j]

    pruned = candidates(y, column, d.max(axis=0), 2000)
    assert len(asked) == len(set(asked))
    assert pruned == candidates(y, lambda j: d[:, j], np.full(cells, np.inf), 2000)
    assert 1 <= pruned <= cells


@settings(max_examples=30, deadline=None)
@given(cells=st.integers(3, 10), gap=st.floats(6.0, 40.0), seed=st.integers(0, 2**16))
def test_a_cell_clearly_below_the_top_is_not_a_candidate_even_if_the_intervals_overlap(cells, gap, seed):
    """Two cells tie at the top; the others lie ``gap`` standard deviations of a difference
    below them but carry a common error ten times larger, so that every cell's own interval
    overlaps the top's: only the two tied cells count."""
    rng = np.random.default_rng(seed)
    y = np.r_[0.0, 0.0, np.full(cells - 2, -gap * math.sqrt(2.0))]
    d = y + rng.standard_normal((4000, cells)) + 10.0 * rng.standard_normal((4000, 1))
    assert candidate_count(y, d) == 2


def test_ap_interval_covers_the_truth_when_eight_targets_tie():
    """Eight targets equally far from their commands, five cycles: the interval of the
    maximum covers the true AP in 93–97 % (±2σ of 150 stages: 0.91–0.99); the draws' shares
    of being the maximum (the count before) covered it in ≈ 0.89."""
    hits = 0
    for seed in range(150):
        rng = np.random.default_rng(10_000 + seed)
        angle = rng.uniform(0, 2 * np.pi, 8)
        bias = 2.0 * np.column_stack([np.cos(angle), np.sin(angle)])
        cmd = rng.uniform(-1000, 1000, (8, 2))
        att = [c + b + rng.normal(0, 0.5, (5, 2)) for c, b in zip(cmd, bias, strict=True)]
        lo, hi = iso9283_uncertainty(cmd, att, trials=2000, seed=seed)["accuracy"].interval
        hits += lo <= 2.0 <= hi
    assert 0.91 <= hits / 150 <= 0.99


def test_ap_interval_covers_the_truth_on_synthetic_stages():
    """95 % intervals of AP cover a known true AP in 93–97 % of synthetic stages (±2σ of 150 draws)."""
    hits = 0
    for seed in range(150):  # 150 synthetic stages, 2000 trials each
        rng = np.random.default_rng(seed)
        cmd = rng.uniform(-1000, 1000, (6, 2))
        bias = rng.normal(0, 1.0, (6, 2))
        att = [c + b + rng.normal(0, 0.3, (4, 2)) for c, b in zip(cmd, bias)]
        lo, hi = iso9283_uncertainty(cmd, att, trials=2000, seed=seed)["accuracy"].interval
        hits += lo <= np.max(np.linalg.norm(bias, axis=1)) <= hi
    assert 0.90 <= hits / 150 <= 0.99


def test_relative_terms_scale_with_position_and_common_offsets_cancel_in_ranges():
    t = np.linspace(0, 1000, 6)
    rng = np.random.default_rng(2)
    f = t[:, None] + rng.normal(0, 0.01, (6, 5))
    b = t[:, None] + rng.normal(0, 0.01, (6, 5))
    r = iso230_2_uncertainty(
        t, f, b, [Term("scale", 10.0, relative=True), Term("offset", 5.0)], trials=20_000
    )
    # a 10 ppm scale over 1000 µm makes E = |ε|·1000 µm: SD 10 nm·sqrt(1 − 2/π); an offset cancels
    assert r["E"].budget["scale"] == pytest.approx(0.01 * math.sqrt(1 - 2 / math.pi), rel=0.1)
    assert r["E"].budget["offset"] == pytest.approx(0.0, abs=1e-9)
    assert r["E"].interval[0] <= r["E"].value <= r["E"].interval[1]


def test_reading_terms_are_listed_not_added():
    rng = np.random.default_rng(3)
    cmd = np.zeros((3, 1))
    att = [rng.normal(1.0, 0.1, (10, 1)) for _ in range(3)]
    a = iso9283_uncertainty(cmd, att, trials=5000)["accuracy"]
    b = iso9283_uncertainty(cmd, att, [Term("noise", 0.1, scope="reading")], trials=5000)["accuracy"]
    assert b.U == pytest.approx(a.U)
    assert "noise (in the sample term)" in b.budget


def test_bad_inputs():
    with pytest.raises(ValueError, match="scope"):
        Term("x", 1.0, scope="sometimes")
    with pytest.raises(ValueError, match=">= 0"):
        Term("x", -1.0)
    with pytest.raises(ValueError, match="two or more"):
        iso9283_uncertainty(np.zeros((1, 2)), [np.zeros((1, 2))])
    with pytest.raises(ValueError, match="unique"):
        iso9283_uncertainty(np.zeros((1, 1)), [np.zeros((3, 1))], [Term("a", 1), Term("a", 2)])


def test_rp_factor_of_unequal_axes_matches_simulation_and_reduces_to_chi():
    from calflow.metrics.uncertainty_iso import rp_factor

    assert rp_factor([1.0, 1.0, 1.0]) == chi_rp_factor(3)
    r = np.array([0.5, 1.2, 1.2]) / math.sqrt(np.mean(np.array([0.5, 1.2, 1.2]) ** 2))
    z = np.linalg.norm(np.random.default_rng(1).standard_normal((400_000, 3)) * r, axis=1)
    assert rp_factor(r) == pytest.approx(z.mean() + 3 * z.std(), rel=5e-3)
