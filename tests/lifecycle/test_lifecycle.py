"""The decisions of a stage's history: change test, control charts, due date, interim SPRT."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.lifecycle.decisions import change, charts, due
from calflow.lifecycle.decisions.sprt import SPRT

COV = np.array(
    [
        [16.0, 0.0, 0.002, -0.01],
        [0.0, 16.0, 0.0, 0.005],
        [0.002, 0.0, 2.8e-5, -2.8e-5],
        [-0.01, 0.005, -2.8e-5, 1.35e-4],
    ]
)  # x_R, y_R (µm), α, β (deg): Model II's order of size
NAMES = ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")
TRUE = np.array([9572.9, 7795.8, 177.689, -0.132])


def draw(rng, mean=TRUE, cov=COV):
    return change.Estimate(NAMES, rng.multivariate_normal(mean, cov), cov)


def test_null_rejects_at_alpha():
    """Two calibrations of an unchanged stage with honest covariances: the χ² test flags
    them at α (binomial 3σ band over 4000 pairs)."""
    rng = np.random.default_rng(1)
    alpha, n = 0.05, 4000
    p = [change.p_value(*change.wald(draw(rng), draw(rng)), 1.0, 0)[0] for _ in range(n)]
    rate = np.mean(np.array(p) < alpha)
    assert abs(rate - alpha) < 3 * np.sqrt(alpha * (1 - alpha) / n)


def test_inflated_history_keeps_alpha_with_birge_scaling():
    """σ understated by a factor 2: the plain χ² test flags nearly every pair, the test with the
    stage's own reproducibility (after min_pairs unchanged pairs) stays near α."""
    rng = np.random.default_rng(2)
    alpha, runs, flags, naive = 0.05, 400, 0, 0
    for _ in range(runs):
        series = [
            {"II": change.Estimate(NAMES, rng.multivariate_normal(TRUE, 4 * COV), COV)} for _ in range(6)
        ]
        res = change.changes(series, alpha=alpha, min_pairs=3)
        flags += res[-1]["models"]["II"]["significant"]
        naive += res[0]["models"]["II"]["significant"]
    assert naive / runs > 0.5
    assert flags / runs < alpha + 3 * np.sqrt(alpha * (1 - alpha) / runs) + 0.03  # dependence of pairs


def test_detects_remount():
    rng = np.random.default_rng(3)
    shift = np.array([20.0, 0.0, 0.02, 0.0])
    detected = [
        change.p_value(*change.wald(draw(rng), draw(rng, TRUE + shift)), 1.0, 0)[0] < 0.0125
        for _ in range(200)
    ]
    assert np.mean(detected) > 0.9


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.floats(-5, 5), min_size=4, max_size=4), st.lists(st.floats(0.01, 100), min_size=4, max_size=4)
)
def test_wald_invariant_to_units_and_order(d, scale):
    """W is the same in any units (diagonal rescaling) and for b − a as for a − b."""
    a = change.Estimate(NAMES, TRUE, COV)
    b = change.Estimate(NAMES, TRUE + np.array(d) * np.sqrt(np.diag(COV)), COV)
    w, dof = change.wald(a, b)
    w_ba, _ = change.wald(b, a)
    s = np.array(scale)
    a2 = change.Estimate(NAMES, TRUE * s, COV * np.outer(s, s))
    b2 = change.Estimate(NAMES, b.value * s, COV * np.outer(s, s))
    w2, _ = change.wald(a2, b2)
    assert dof == 4 and w >= 0
    assert w == pytest.approx(w_ba, rel=1e-9, abs=1e-9)
    assert w == pytest.approx(w2, rel=1e-6, abs=1e-6)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=6), st.sampled_from([0.01, 0.05, 0.1]))
def test_holm_matches_statsmodels(p, alpha):
    from unittest import mock

    from statsmodels.stats.multitest import multipletests

    got = change.holm({str(i): v for i, v in enumerate(p)}, alpha)
    # statsmodels' Holm branch ends in gc.collect(), a full collection of the test worker's
    # heap: 0.1-0.6 s an example, most of this test's time. It frees memory and changes no
    # result, so the oracle runs without it.
    with mock.patch("gc.collect"):
        want = multipletests(p, alpha=alpha, method="holm")[0]
    assert [got[str(i)] for i in range(len(p))] == [bool(w) for w in want]


def test_holm_is_stepdown():
    flags = change.holm({"a": 0.001, "b": 0.02, "c": 0.04, "d": float("nan")}, alpha=0.05)
    # 0.001 < 0.05/3, 0.02 < 0.05/2, 0.04 < 0.05/1: Holm rejects all three, Bonferroni only the first
    assert flags == {"a": True, "b": True, "c": True, "d": False}
    assert change.holm({"a": 0.03, "b": 0.04}, alpha=0.05) == {"a": False, "b": False}


def test_individuals_limits_from_moving_range():
    x = [10.0, 12.0, 11.0, 13.0, 30.0]
    c = charts.individuals(x)
    mr = np.mean(np.abs(np.diff(x)))
    assert c["ucl"] == pytest.approx(np.mean(x) + 3 * mr / 1.128)
    assert c["out"] == [] or 4 in c["out"]
    steady = charts.individuals([10.0, 10.5, 9.8, 10.2, 10.1, 9.9, 25.0])
    assert 6 in steady["out"]


def test_ewma_flags_slow_drift_more_often_than_shewhart():
    """A 1σ shift after a 20-point baseline: EWMA (λ 0.2, L 2.7) signals within the next 20
    points far more often than the 3σ individuals chart (Lucas & Saccucci 1990: ARL ≈ 10 against ≈ 44)."""
    rng = np.random.default_rng(4)
    ew = sh = 0
    for _ in range(300):
        x = rng.normal(0, 1, 40) + np.r_[np.zeros(20), np.full(20, 1.0)]
        ew += any(i >= 20 for i in charts.ewma(x, baseline=20)["out"])
        sh += any(i >= 20 for i in charts.individuals(x, baseline=20)["out"])
    assert ew > 1.5 * sh and ew / 300 > 0.6


def _dates(days):
    t0 = dt.datetime(2026, 1, 1, tzinfo=dt.UTC)
    return [(t0 + dt.timedelta(days=float(d))).isoformat() for d in days]


def test_due_date_brackets_the_true_crossing():
    """A stage drifting 0.01 µm/day from 2 µm, tolerance 5 µm: the true crossing is day 300;
    the upper bound crosses before it (reliability), and close to it with little noise."""
    rng = np.random.default_rng(5)
    days = np.arange(0, 181, 30)
    ap = 2.0 + 0.01 * days + rng.normal(0, 0.05, days.size)
    r = due.due_date(_dates(days), ap.tolist(), [0] * days.size, 5.0, reliability=0.95)
    crossing = dt.date(2026, 1, 1) + dt.timedelta(days=300)
    got = dt.date.fromisoformat(r["date"])
    assert got <= crossing
    assert (crossing - got).days < 60
    assert r["fit"]["slope_um_per_day"] == pytest.approx(0.01, rel=0.2)


def test_due_date_segment_reset():
    """A re-mount lowers the level; the common slope carries on from the new level."""
    days = np.array([0, 30, 60, 90, 120, 150, 180])
    ap = 2.0 + 0.01 * days
    ap[4:] -= 1.0
    seg = [0, 0, 0, 0, 1, 1, 1]
    r = due.due_date(_dates(days), (ap + np.array([0, 1e-3, -1e-3, 0, 1e-3, 0, -1e-3])).tolist(), seg, 5.0)
    assert r["fit"]["segments"] == 2
    assert r["fit"]["slope_um_per_day"] == pytest.approx(0.01, rel=0.05)
    assert 380 < (dt.date.fromisoformat(r["date"]) - dt.date(2026, 1, 1)).days <= 400


def test_not_enough_history_in_words():
    r = due.due_date(_dates([0, 90, 180]), [2.0, 2.5, 3.0], [0, 0, 1], 5.0)
    assert r["date"] is None and r["statement"].startswith("not enough history")


@pytest.mark.parametrize("truth,limit", [("H0", 0.05), ("H1", 0.10)])
def test_sprt_error_rates(truth, limit):
    """Wald's bounds keep the error rates near α (false recalibrate) and β (missed)."""
    rng = np.random.default_rng(6)
    test = SPRT(r0_um=2.0, r1_um=4.0, alpha=0.05, beta=0.10)
    r = 2.0 if truth == "H0" else 4.0
    n, wrong = 2000, 0
    for _ in range(n):
        res = test.decide(rng.normal(0, r / np.sqrt(2), (200, 2)))
        wrong += res["decision"] == ("recalibrate" if truth == "H0" else "within tolerance")
    assert wrong / n < limit + 3 * np.sqrt(limit * (1 - limit) / n)


def test_sprt_refuses_tolerance_below_reference():
    with pytest.raises(ValueError, match="tolerance"):
        SPRT(r0_um=3.0, r1_um=2.0)


def test_due_date_gives_interim_checks_their_own_offset():
    """Checks read 1.5 µm above the held-out AP (their targets sit where errors are largest):
    the fit recovers the offset and the slope, and predicts the held-out AP's crossing —
    a fit that mixed the two would cross earlier."""
    days = np.array([0, 45, 90, 135, 180, 225, 270])
    checks = np.array([False, True, False, True, True, False, True])
    ap = 2.0 + 0.01 * days + 1.5 * checks + np.array([0, 1e-3, -1e-3, 0, 1e-3, 0, -1e-3])
    r = due.due_date(_dates(days), ap.tolist(), [0] * days.size, 6.0, checks=checks.tolist())
    assert r["fit"]["checks"] == 4 and r["fit"]["dof"] == days.size - 3
    assert r["fit"]["check_offset_um"] == pytest.approx(1.5, abs=0.01)
    assert r["fit"]["slope_um_per_day"] == pytest.approx(0.01, rel=0.01)
    assert 385 < (dt.date.fromisoformat(r["date"]) - dt.date(2026, 1, 1)).days <= 400  # true: day 400
    mixed = due.due_date(_dates(days), ap.tolist(), [0] * days.size, 6.0)
    assert dt.date.fromisoformat(mixed["date"]) < dt.date.fromisoformat(r["date"])


def test_due_date_offset_costs_a_degree_of_freedom():
    r = due.due_date(_dates([0, 90, 180, 270]), [2.0, 3.0, 2.5, 3.6], [0] * 4, 5.0, checks=[0, 1, 0, 1])
    assert r["date"] is None and r["fit"]["dof"] == 1
    assert "interim checks, given an offset of their own" in r["statement"]


def test_group_sequential_sprt_looks_only_at_group_ends():
    """Errors far beyond the tolerance from the first visit: the plain SPRT stops at once;
    looking at the end of each cycle of 4 it stops at the 4th visit, with the same decision."""
    test = SPRT(1.0, 3.0, alpha=0.05, beta=0.1)
    e = np.full((12, 2), 6.0)
    assert test.decide(e)["visits"] == 1
    r = test.decide(e, groups=np.repeat([1, 1, 2], 4), planned=24)
    assert (r["decision"], r["visits"], r["planned"]) == ("recalibrate", 8, 24)
    quiet = test.decide(np.zeros((3, 2)), groups=[1, 1, 1], planned=8)  # stops at the group's end
    assert (quiet["decision"], quiet["visits"]) == ("within tolerance", 3)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), size=st.sampled_from([2, 3, 4]))
def test_group_sequential_decision_is_one_the_plain_test_could_reach(seed, size):
    """Looking less often never reverses a decision taken at a look: at the visit where the
    grouped test stops, the running LLR is beyond the bound it names."""
    rng = np.random.default_rng(seed)
    test = SPRT(1.0, 2.0)
    e = rng.normal(0, rng.uniform(0.5, 2.5), (24, 2)) / np.sqrt(2)
    r = test.decide(e, groups=np.repeat(np.arange(24 // size), size))
    llr = np.cumsum(test.llr(e))[r["visits"] - 1]
    low, high = test.bounds
    if r["decision"] == "recalibrate":
        assert llr >= high and r["visits"] % size == 0
    elif r["decision"] == "within tolerance":
        assert llr <= low and r["visits"] % size == 0
    else:
        assert r["visits"] == 24 and low < llr < high


def test_inflation_recovers_the_between_campaign_factor_from_kept_pairs():
    """Wald statistics of unchanged pairs with σ² off by a factor c (above or below 1): the
    truncation-corrected pooled Birge ratio recovers c, where the plain mean of the kept
    pairs (those below the χ² quantile) is biased low."""
    rng = np.random.default_rng(11)
    for c in (0.5, 1.0, 2.0):
        prior = [(float(c * rng.chisquare(4)), 4) for _ in range(4000)]
        k2, dof = change.inflation(prior, min_pairs=3, alpha=0.05)
        assert k2 == pytest.approx(c, rel=0.05) and 0 < dof <= 4 * 4000
        kept = [w for w, p in prior if w / k2 <= 9.488]  # χ²₄ 95 %
        assert np.mean(kept) / 4 < 0.93 * k2
