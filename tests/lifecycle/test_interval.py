"""The calibration interval from as-found drift (RP-1 V1) and from as-found decisions
(exponential reliability model): against the textbook formulas, on synthetic data."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize, stats

from calflow.lifecycle.decisions import interval
from calflow.lifecycle.history import build


def textbook_v1(t, y, X, x0_of, as_left, tol, R):
    """The one-sided OLS prediction bound, written out: ŷ(τ) + t_{R,ν}·s·√(1 + x₀ᵀ(XᵀX)⁻¹x₀),
    and the τ where as_left + bound reaches tol (found by bracketing)."""
    XtXi = np.linalg.inv(X.T @ X)
    beta = XtXi @ X.T @ y
    nu = len(y) - X.shape[1]
    s = np.sqrt(np.sum((y - X @ beta) ** 2) / nu)
    k = stats.t.ppf(R, nu)

    def upper(tau):
        x0 = x0_of(tau)
        return as_left + x0 @ beta + k * s * np.sqrt(1 + x0 @ XtXi @ x0)

    grid = np.arange(0, 3 * 365 + 1.0)
    above = np.flatnonzero([upper(g) >= tol for g in grid])
    if above.size == 0 or above[0] == 0:
        return None
    return optimize.brentq(lambda tau: upper(tau) - tol, grid[above[0] - 1], grid[above[0]], xtol=1e-10)


@settings(max_examples=40, deadline=None)
@given(
    rate=st.floats(0.002, 0.05),
    noise=st.floats(0.01, 0.5),
    n=st.integers(3, 12),
    seed=st.integers(0, 2**31 - 1),
    R=st.floats(0.6, 0.99),
)
def test_v1_date_is_the_textbook_prediction_bound(rate, noise, n, seed, R):
    rng = np.random.default_rng(seed)
    t = rng.uniform(30, 200, n)
    y = rate * t + rng.normal(0, noise, n)
    res = interval.variables(t, y, tolerance_um=4.0, as_left_um=1.5, reliability=R)
    ref = textbook_v1(t, y, t[:, None], lambda tau: np.array([tau]), 1.5, 4.0, R)
    if ref is None:
        assert res["interval_days"] in (None, 0.0)
    else:
        assert res["interval_days"] == pytest.approx(ref, abs=1e-6)
        assert res["fit"]["slope_um_per_day"] == pytest.approx(np.sum(t * y) / np.sum(t * t), rel=1e-9)


def test_v1_with_check_offset_and_a_change_level_is_the_textbook_bound():
    """Interim checks (their own offset) and values after a re-mount (their own level): the bound
    for the compensation in use has neither, x₀ = (τ, 0, 0)."""
    rng = np.random.default_rng(3)
    t = np.array([60, 90, 120, 150, 180, 75, 100, 130, 170, 95.0])
    chk = np.array([0, 1, 0, 1, 0, 1, 0, 1, 0, 0], bool)
    lev = np.array([0, 0, 0, 0, 0, 0, 0, 0, 1, 1])
    y = 0.01 * t + 0.8 * chk + 3.0 * (lev == 1) + rng.normal(0, 0.1, t.size)
    res = interval.variables(t, y, 4.0, 1.5, 0.9, checks=chk, levels=lev)
    X = np.column_stack([t, chk, lev == 1]).astype(float)
    ref = textbook_v1(t, y, X, lambda tau: np.array([tau, 0.0, 0.0]), 1.5, 4.0, 0.9)
    assert res["interval_days"] == pytest.approx(ref, abs=1e-6)
    assert res["fit"]["columns"] == ["slope_um_per_day", "check_offset_um", "level_1_um"]
    assert res["fit"]["level_1_um"] == pytest.approx(3.0, abs=0.3)
    assert res["fit"]["dof"] == t.size - 3


def test_v1_says_why_without_enough_history():
    res = interval.variables([90, 180], [0.4, 0.9], 4.0, 1.5, checks=[True, False])
    assert res["interval_days"] is None and "not enough history" in res["statement"]
    assert "0 residual degrees of freedom" in res["statement"] and "interim checks" in res["statement"]
    at_once = interval.variables([30, 60, 90, 120], [0.1, 0.25, 0.28, 0.45], 1.6, 1.59)
    assert at_once["interval_days"] == 0.0 and "no margin" in at_once["statement"]


@settings(max_examples=20, deadline=None)
@given(lam=st.floats(1e-3, 2e-2), seed=st.integers(0, 2**31 - 1))
def test_exponential_mle_recovers_lambda(lam, seed):
    """Decisions drawn from R(t) = exp(−λt) at intervals spread around the mean life: λ̂ within
    four standard errors (its own, from the observed information) and at the likelihood's maximum."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.2, 3.0, 1500) / lam
    x = rng.random(t.size) < np.exp(-lam * t)
    est, se = interval.exponential_mle(t, x)
    assert abs(est - lam) < 4 * se
    nll = lambda v: -(np.sum(-v * t[x]) + np.sum(np.log(-np.expm1(-v * t[~x]))))  # noqa: E731
    best = optimize.minimize_scalar(
        nll, bounds=(est / 2, est * 2), method="bounded", options={"xatol": 1e-12}
    )
    assert est == pytest.approx(best.x, rel=1e-5)
    res = interval.attributes(t, x, 0.9)
    assert res["interval_days"] == pytest.approx(-np.log(0.9) / est)


def test_attributes_without_an_out_of_tolerance_decision_gives_no_date():
    res = interval.attributes([90, 180, 270], [True, True, True])
    assert res["interval_days"] is None and "none of 3" in res["statement"]


@pytest.mark.parametrize("r", [0, 1, 1.5, -0.2, "0.9", True])
def test_refuses_a_reliability_outside_the_unit_interval(r):
    with pytest.raises(ValueError, match=r"interval: key 'reliability': expected a number in \(0, 1\)"):
        interval.variables([90, 180, 270], [0.1, 0.2, 0.3], 4.0, 1.5, reliability=r)


@pytest.mark.parametrize("tol", [0, -1.0, float("nan")])
def test_refuses_a_tolerance_not_above_zero(tol):
    with pytest.raises(ValueError, match="key 'tolerance_um': expected a number > 0"):
        interval.variables([90, 180, 270], [0.1, 0.2, 0.3], tol, 1.5)


def _summary(ap, rp, found=None):
    models = {
        "II": {"parameters": {}, "accuracy_um": ap, "as_left": {"accuracy_um": ap, "repeatability_um": rp}}
    }
    if found:
        models["II"]["as_found"] = found
    return {"robot": "xytheta", "models": models}


def _stage(days_apart, found_ap, left_ap=1.0):
    """Calibrations ``days_apart`` apart, each (after the first) finding ``found_ap`` of the last."""
    import datetime as dt

    t0 = dt.datetime(2026, 1, 5, 8, tzinfo=dt.UTC)
    pairs, t, prev = [], t0, None
    for i, (d, f) in enumerate(zip([0, *days_apart], [None, *found_ap])):
        t = t + dt.timedelta(days=d)
        start = t.isoformat()
        s = _summary(left_ap, 0.2)
        s["models"]["II"]["as_left"]["date"] = start
        if prev:
            s["models"]["II"]["as_found"] = {
                "accuracy_um": f,
                "repeatability_um": 0.3,
                "date": start,
                "reference": prev,
            }
        pairs.append(({"name": f"c{i}", "robot": "xytheta", "stage": "S1", "start": start}, s))
        prev = f"c{i}"
    return pairs


def test_history_interval_from_as_found_values():
    """history.json's interval: V1 on (days since adjustment, as found − as left) with its
    inputs, the due date from it, and the attributes variant beside it."""
    days = [90, 120, 60, 150, 100]
    found = [1.0 + 0.01 * d + e for d, e in zip(days, [0.05, -0.04, 0.02, -0.03, 0.01])]
    h = build("S1", _stage(days, found), {"tolerance_um": 3.0, "model": "II", "reliability": 0.9})
    iv = h["interval"]
    assert iv["inputs"]["days_since_adjustment"] == pytest.approx(days)
    assert iv["inputs"]["as_found_minus_as_left"] == pytest.approx([f - 1.0 for f in found])
    ref = interval.variables(days, [f - 1.0 for f in found], 3.0, 1.0, 0.9)
    assert iv["interval_days"] == pytest.approx(ref["interval_days"])
    assert h["due"]["date"] == iv["date"] and h["due"]["method"] == interval.VARIABLES
    assert iv["attributes"]["inputs"]["in_tolerance"] == [True] * 5
    assert "no finite interval" in iv["attributes"]["statement"]


def test_history_refuses_bad_settings():
    with pytest.raises(ValueError, match="stage settings: key 'reliability'"):
        build("S1", _stage([90], [1.5]), {"tolerance_um": 3.0, "reliability": 1.0})
    with pytest.raises(ValueError, match="stage settings: key 'tolerance_um'"):
        build("S1", _stage([90], [1.5]), {"tolerance_um": -3.0})


@pytest.mark.parametrize(
    "settings,key", [('{"reliability": 1.0}', "reliability"), ('{"tolerance_um": 0}', "tolerance_um")]
)
def test_history_command_refuses_bad_settings_in_one_line(tmp_path, monkeypatch, capsys, settings, key):
    """`calflow history` (:func:`calflow.cli.main`, what ``python -m calflow`` runs, called in
    this process: a new interpreter would spend seconds importing what the worker has)."""
    from calflow.cli import main

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "history.json"
    status = main(
        ["history", "--stage", "S1", "--campaigns", "a.yaml"]
        + ["--summaries", "a.json", "--settings", settings, "--out", str(out)]
    )
    assert status != 0 and not out.exists()
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and f"--settings: stage settings: key '{key}'" in lines[0]


@pytest.mark.parametrize(
    "stage,key",
    [
        ({"reliability": 1.0}, "reliability"),
        ({"reliability": 0.0}, "reliability"),
        ({"tolerance_um": 0}, "tolerance_um"),
    ],
)
def test_configuration_refuses_bad_stage_settings(stage, key):
    from calflow.configuration.config import load_workflow_config
    from calflow.errors import ConfigError

    with pytest.raises(ConfigError, match=rf"config/config\.yaml: key 'stages\.S1\.{key}'"):
        load_workflow_config({"campaigns": ["a"], "stages": {"S1": stage}})


@pytest.mark.parametrize("tolerance", [3.0, None])
def test_history_page_shows_the_interval_in_words(tolerance):
    from calflow.data.io import jsonable
    from calflow.lifecycle.report import render

    days = [90, 120, 60, 150, 100]
    found = [1.0 + 0.01 * d + e for d, e in zip(days, [0.05, -0.04, 0.02, -0.03, 0.01])]
    h = jsonable(build("S1", _stage(days, found), {"tolerance_um": tolerance, "model": "II"}))
    html, _ = render(h, "snakemake", pdf=False)
    assert 'id="as-found"' in html and 'id="fig-interval"' in html
    words = html.split('id="interval-variables">')[1].split("</p>")[0]
    if tolerance:
        assert (
            f'data-key="interval.date">{h["interval"]["date"]}<' in words
            and "prediction bound reaches" in words
        )
        assert f'data-key="interval.inputs.as_found_um.4">{found[4]:.2f}<' in html
    else:
        assert "no tolerance stated" in words
