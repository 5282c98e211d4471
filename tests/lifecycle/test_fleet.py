"""Fleets of stages: Bartlett's homogeneity test, pooled reproducibility, typical vs guaranteed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from calflow.lifecycle.fleet import bartlett, fleets, tolerance_factor, typical_fleet


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 5), st.integers(3, 8))
def test_bartlett_matches_scipy_on_raw_samples(seed, k, n):
    rng = np.random.default_rng(seed)
    groups = [rng.normal(0, 1 + i, n) for i in range(k)]
    ours = bartlett([g.var(ddof=1) for g in groups], [n - 1] * k)
    ref = stats.bartlett(*groups)
    assert ours == pytest.approx((ref.statistic, ref.pvalue), rel=1e-9)


def test_tolerance_factor_matches_the_iso_16269_6_table():
    # one-sided 95 %/95 % k for n = 10 and 20 (ISO 16269-6 Table C; NIST handbook 7.2.6.3)
    assert tolerance_factor(10) == pytest.approx(2.911, abs=2e-3)
    assert tolerance_factor(20) == pytest.approx(2.396, abs=2e-3)


def test_guaranteed_bound_covers_95_percent_of_the_fleet_in_95_percent_of_fleets():
    rng = np.random.default_rng(1)
    q95 = 3.0 + 0.5 * stats.norm.ppf(0.95)
    hits = sum(typical_fleet(list(rng.normal(3.0, 0.5, 8)))["guaranteed_um"] >= q95 for _ in range(2000))
    assert hits / 2000 == pytest.approx(0.95, abs=0.015)


def _history(stage, aps, segments=None, fleet=None):
    segments = segments or [0] * len(aps)
    return {
        "stage": stage,
        "robot": "xytheta",
        "settings": {"fleet": fleet} if fleet else {},
        "due": {"model": "III"},
        "segments": segments,
        "campaigns": [{"kind": "calibration", "models": {"III": {"accuracy_um": a}}} for a in aps],
    }


def test_a_short_history_borrows_the_pooled_spread_of_homogeneous_siblings():
    hs = [
        _history("A", [3.0, 3.2, 2.9, 3.1]),
        _history("B", [2.5, 2.7, 2.6, 2.4]),
        _history("NEW", [3.3, 3.4]),
    ]
    (f,) = fleets(hs)
    assert f["homogeneous"] is True
    by = {s["stage"]: s for s in f["stages"]}
    assert by["NEW"]["dof"] == 1 and by["NEW"]["borrowed"] and by["NEW"]["used_sd_um"] == f["pooled_sd_um"]
    assert not by["A"]["borrowed"] and by["A"]["used_sd_um"] == by["A"]["own_sd_um"]
    assert f["typical_um"]["median"] == pytest.approx(3.1)
    assert f["guaranteed_um"] > max(f["latest_ap_um"])


def test_heterogeneous_spreads_are_not_pooled_and_segments_reset_the_level():
    hs = [
        _history("A", [3.0, 3.01, 2.99, 3.0, 3.02]),
        _history("B", [1.0, 5.0, 2.0, 6.0, 0.5]),
        _history("C", [3.3, 3.4]),
    ]
    (f,) = fleets(hs)
    assert f["homogeneous"] is False and "nothing is pooled" in f["statement"]
    assert not any(s["borrowed"] for s in f["stages"])
    # a re-mount: two levels, the spread about each segment's mean
    (g,) = fleets([_history("S", [1.0, 1.2, 5.0, 5.2], [0, 0, 1, 1])])
    assert g["stages"][0]["dof"] == 2 and g["stages"][0]["own_sd_um"] == pytest.approx(math.sqrt(0.04 / 2))


def test_fleets_are_grouped_by_setting_then_robot_and_say_what_they_cannot_tell():
    out = fleets([_history("A", [3.0]), _history("B", [2.0], fleet="PI-M-111")])
    assert [f["fleet"] for f in out] == ["PI-M-111", "xytheta"]
    assert all(f["guaranteed_um"] is None and "at least 3" in f["guarantee"] for f in out)
