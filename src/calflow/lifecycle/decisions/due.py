"""When to recalibrate: the date the trend of the held-out accuracy reaches the tolerance.

NCSLI RP-1 (2010), Appendix C, *variables method* (method V1; the "control chart method"
of ILAC-G24:2007 / OIML D 10:2007 Sec. 4.3 rests on the same drift fit): the values found
at successive calibrations and checks are regressed on time; the interval ends when the
one-sided upper prediction bound of the next value, at the end-of-period reliability
target R, reaches the tolerance. The regression is ordinary least squares
(``statsmodels`` OLS, ``get_prediction().summary_frame``), with one intercept per segment
of the history between detected changes (a re-mount resets the level, the wear rate
carries on) and one common slope in µm/day. Interim checks measure AP on their own few
targets (chosen where the drifts show most), not on the held-out targets: when the series
holds both kinds, the fit gives the checks one offset of their own (a column that is 1 for
a check), and the prediction is of the held-out AP, the quantity the tolerance is stated for.

The prediction interval needs residual degrees of freedom: with fewer than
``min_dof`` (2) after the segment intercepts and the slope, there is "not enough history",
said so, and no date.
"""

from __future__ import annotations

import datetime as dt

import numpy as np

METHOD = (
    "NCSLI RP-1 variables method (V1): OLS drift of the held-out AP with one intercept per segment "
    "between detected changes and a common slope; due when the one-sided upper prediction bound at "
    "the reliability target reaches the tolerance (the control-chart method of ILAC-G24 / OIML D 10)"
)


def parse(start: str) -> dt.datetime:
    return dt.datetime.fromisoformat(str(start).replace("Z", "+00:00"))


def due_date(
    starts: list[str],
    ap_um: list[float],
    segments: list[int],
    tolerance_um: float,
    reliability: float = 0.95,
    horizon_days: float = 3 * 365.0,
    min_dof: int = 2,
    checks: list[bool] | None = None,
) -> dict:
    """``{date, days_after_last, statement, fit: {slope_um_per_day, dof, n, checks}}`` for the
    series (ISO dates, AP in µm, segment index per point, increasing; ``checks`` marks the
    interim checks' values); the prediction is of a calibration's held-out AP in the last
    segment. ``date`` is None with the reason in ``statement`` when it cannot be told."""
    import statsmodels.api as sm

    t0 = parse(min(starts, key=parse))
    days = np.array([(parse(s) - t0).total_seconds() / 86400.0 for s in starts])
    y = np.asarray(ap_um, float)
    seg = np.asarray(segments, int)
    chk = np.zeros(len(y), bool) if checks is None else np.asarray(checks, bool)
    order = np.argsort(days, kind="stable")
    days, y, seg, chk = days[order], y[order], seg[order], chk[order]
    labels = sorted(set(seg.tolist()))
    last = labels[-1] if labels else 0
    offset = bool(chk.any() and (~chk).any())  # both kinds: the checks' own offset
    dof = len(y) - len(labels) - 1 - offset
    base = {
        "date": None,
        "days_after_last": None,
        "reliability": reliability,
        "fit": {
            "n": int(len(y)),
            "checks": int(chk.sum()),
            "segments": len(labels),
            "dof": int(max(dof, 0)),
            "slope_um_per_day": None,
        },
    }
    if dof < min_dof:
        kinds = f" ({int(chk.sum())} of them interim checks, given an offset of their own)" if offset else ""
        return {
            **base,
            "statement": (
                f"not enough history: {len(y)} values{kinds} in {len(labels)} segment(s) leave "
                f"{max(dof, 0)} residual degrees of freedom, at least {min_dof} are needed "
                "for a prediction interval"
            ),
        }
    X = np.column_stack(
        [(seg == k).astype(float) for k in labels] + ([chk.astype(float)] if offset else []) + [days]
    )
    fit = sm.OLS(y, X).fit()
    if offset:
        base["fit"]["check_offset_um"] = float(fit.params[-2])
    slope = float(fit.params[-1])
    base["fit"]["slope_um_per_day"] = slope
    base["fit"]["slope_std"] = float(fit.bse[-1])
    grid = days[-1] + np.arange(0.0, horizon_days + 1.0, 1.0)
    Xg = np.column_stack(
        [np.full_like(grid, 1.0 if k == last else 0.0) for k in labels]
        + ([np.zeros_like(grid)] if offset else [])
        + [grid]
    )
    mean, upper, hit, weeks = bound_crossing(fit, Xg, grid.size, reliability, tolerance_um)
    base["trend"] = {
        "dates": [(t0 + dt.timedelta(days=float(grid[i]))).date().isoformat() for i in weeks],
        "mean_um": mean[weeks].tolist(),
        "upper_um": upper[weeks].tolist(),
    }
    if hit.size == 0:
        return {
            **base,
            "statement": (
                f"the upper {reliability:.0%} prediction bound stays below "
                f"{tolerance_um:g} µm for {horizon_days:.0f} days after the last value"
            ),
        }
    day = float(grid[hit[0]])
    date = t0 + dt.timedelta(days=day)
    after = day - days[-1]
    words = (
        "already at or above the tolerance at the last value: recalibrate now"
        if after == 0
        else f"{after:.0f} days after the last value"
    )
    return {
        **base,
        "date": date.date().isoformat(),
        "days_after_last": after,
        "statement": f"the upper {reliability:.0%} prediction bound reaches {tolerance_um:g} µm {words}",
    }


def bound_crossing(fit, Xg: np.ndarray, days: int, reliability: float, tolerance_um: float, offset_um=None):
    """Where the one-sided upper prediction bound of an OLS drift fit first reaches the
    tolerance, on a grid of ``days`` whole days (the rows of the design matrix ``Xg``).

    Returns ``(mean, upper, hit, weeks)``: the predicted mean and upper bound at each day
    (µm; ``offset_um`` added to both when given, e.g. an as-left value under a drift), the
    indices where the bound is at or above ``tolerance_um`` and the weekly indices the
    report draws, up to the first crossing or a year.
    """
    frame = fit.get_prediction(Xg).summary_frame(alpha=2 * (1 - reliability))
    mean, upper = frame["mean"].to_numpy(), frame["obs_ci_upper"].to_numpy()
    if offset_um is not None:
        mean, upper = offset_um + mean, offset_um + upper
    hit = np.flatnonzero(upper >= tolerance_um)
    end = int(hit[0]) if hit.size else min(365, days - 1)
    return mean, upper, hit, np.unique(np.r_[np.arange(0, end + 1, 7), end])
