"""The calibration interval from what the stage is found like when it comes back.

A stage is adjusted at a calibration (its new compensation is *as left*: the held-out AP
through the model just identified) and used until the next one, which first measures it
through the compensation still in use (*as found*). The drift that matters is the as-found
value minus the as-left value of the adjustment it was found through, against the time
since that adjustment. Interim checks measure through the bundle in use too: they are
as-found values of their own targets.

Two methods of NCSLI RP-1 (*Establishment and Adjustment of Calibration Intervals*, 2010):

* :func:`variables` — the variables method (V1; Castrup, "Calibration intervals from
  variables data", NCSLI 2005): ordinary least squares of the deviation
  y = as_found − as_left on the days t since the adjustment, through the origin (no drift
  at the adjustment), y = b·t; the interval ends where the one-sided upper prediction bound
  of the value found, y₀ + b·t + t_{R, ν}·s·√(1 + xᵀ(XᵀX)⁻¹x) (y₀ the latest as-left,
  ν the residual degrees of freedom), reaches the tolerance. Pooled over the stage's
  intervals; values found after a detected change (a re-mount between the adjustment and
  the value) get a level of their own per change, and interim checks (another set of
  targets) an offset of their own, so neither bends the drift rate.
* :func:`attributes` — attributes data (in or out of tolerance as found): the exponential
  reliability model R(t) = exp(−λt) that RP-1's method A3 assumes, λ by maximum likelihood
  over every decision at its own interval (the binomial likelihood of method S2 with the
  exponential model); the interval is −ln R*/λ̂ for the reliability target R*.

Both take arrays and return plain dicts with their inputs, so another RP-1 tool (suncal's
``intervals`` module, a spreadsheet) recomputes them from ``history.json`` alone.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
from scipy import optimize, stats

from calflow.lifecycle.decisions.due import bound_crossing

VARIABLES = (
    "NCSLI RP-1 variables method (V1): OLS through the origin of as-found minus as-left on the days "
    "since the adjustment, pooled over the stage's intervals (a level per detected change, an offset "
    "for interim checks); the interval ends where the one-sided upper prediction bound of the value "
    "found, the latest as-left plus the drift, reaches the tolerance"
)
ATTRIBUTES = (
    "NCSLI RP-1 attributes data: exponential reliability model R(t) = exp(-lambda t) (the model of "
    "method A3), lambda by maximum likelihood over the in/out-of-tolerance as-found decisions at "
    "their own intervals (the binomial likelihood of method S2); interval = -ln(R*)/lambda"
)
MIN_DOF = 2


def check_settings(
    reliability: float, tolerance_um: float | None = None, where: str = "stage settings"
) -> None:
    """Raise ``ValueError`` (one line, naming the key) for a reliability target outside (0, 1)
    or a tolerance ≤ 0."""
    r = reliability
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not (0.0 < r < 1.0):
        raise ValueError(f"{where}: key 'reliability': expected a number in (0, 1), got {r!r}")
    t = tolerance_um
    if t is not None and (isinstance(t, bool) or not isinstance(t, (int, float)) or not t > 0 or t != t):
        raise ValueError(f"{where}: key 'tolerance_um': expected a number > 0 (µm), got {t!r}")


def _design(days, checks, levels) -> tuple[np.ndarray, list[str]]:
    """Columns: the drift (days), the checks' offset when both kinds are present, one level per
    detected change (label > 0)."""
    cols, names = [np.asarray(days, float)], ["slope_um_per_day"]
    chk = np.asarray(checks, bool)
    if chk.any() and (~chk).any():
        cols.append(chk.astype(float))
        names.append("check_offset_um")
    lev = np.asarray(levels, int)
    for k in sorted(set(lev[lev > 0].tolist())):
        cols.append((lev == k).astype(float))
        names.append(f"level_{k}_um")
    return np.column_stack(cols), names


def variables(
    days,
    deviation_um,
    tolerance_um: float,
    as_left_um: float,
    reliability: float = 0.95,
    checks=None,
    levels=None,
    horizon_days: float = 3 * 365.0,
    min_dof: int = MIN_DOF,
) -> dict:
    """RP-1 V1 (module docstring). ``days`` since the adjustment each value was found through,
    ``deviation_um`` as found − as left (µm); ``checks`` marks interim checks' values,
    ``levels`` a label per value (0: no detected change in its interval; k > 0: after change
    k). Returns ``{interval_days, statement, coverage_factor, fit: {...}, trend}``;
    ``interval_days`` is None, with the reason in words, when it cannot be told."""
    import statsmodels.api as sm

    check_settings(reliability, tolerance_um, "interval")
    t = np.asarray(days, float)
    y = np.asarray(deviation_um, float)
    n = t.size
    chk = np.zeros(n, bool) if checks is None else np.asarray(checks, bool)
    lev = np.zeros(n, int) if levels is None else np.asarray(levels, int)
    X, names = _design(t, chk, lev)
    dof = n - X.shape[1]
    out = {
        "interval_days": None,
        "coverage_factor": None,
        "fit": {
            "n": int(n),
            "checks": int(chk.sum()),
            "segments": 1 + len(set(lev[lev > 0].tolist())),
            "columns": names,
            "dof": int(max(dof, 0)),
        },
    }
    if n == 0:
        return {**out, "statement": "not enough history: no value found through an earlier adjustment"}
    if dof < min_dof:
        extra = []
        if "check_offset_um" in names:
            extra.append(f"{int(chk.sum())} of them interim checks, with an offset of their own")
        if (lev > 0).any():
            extra.append(f"{int((lev > 0).sum())} after a detected change, with a level of their own")
        why = f" ({'; '.join(extra)})" if extra else ""
        return {
            **out,
            "statement": (
                f"not enough history: {n} as-found value(s){why} leave {max(dof, 0)} residual "
                f"degrees of freedom, at least {min_dof} are needed for a prediction bound"
            ),
        }
    fit = sm.OLS(y, X).fit()
    k = float(stats.t.ppf(reliability, dof))  # one-sided
    cov, s2 = np.asarray(fit.cov_params()), float(fit.scale)
    b, vb = float(fit.params[0]), float(cov[0, 0])
    out["coverage_factor"] = k
    out["fit"].update(
        {
            "slope_um_per_day": b,
            "slope_std": float(np.sqrt(vb)),
            "residual_std_um": float(np.sqrt(s2)),
            **{c: float(v) for c, v in zip(names[1:], fit.params[1:])},
        }
    )

    def upper(tt):  # the bound for the compensation in use: no check offset, no change level
        tt = np.asarray(tt, float)
        return as_left_um + b * tt + k * np.sqrt(s2 + vb * tt**2)

    grid = np.arange(0.0, horizon_days + 1.0, 1.0)
    Xg = np.zeros((grid.size, X.shape[1]))
    Xg[:, 0] = grid
    mean, bound, hit, weeks = bound_crossing(fit, Xg, grid.size, reliability, tolerance_um, as_left_um)
    out["trend"] = {
        "days": grid[weeks].tolist(),
        "mean_um": mean[weeks].tolist(),
        "upper_um": bound[weeks].tolist(),
    }
    if hit.size == 0:
        return {
            **out,
            "statement": (
                f"the upper {reliability:.0%} prediction bound stays below {tolerance_um:g} µm for "
                f"{horizon_days:.0f} days after the adjustment"
            ),
        }
    if hit[0] == 0:
        return {
            **out,
            "interval_days": 0.0,
            "statement": (
                f"the upper {reliability:.0%} prediction bound is at or above {tolerance_um:g} µm already "
                "at the adjustment: the as-left value leaves no margin for the drift"
            ),
        }
    lo, hi = grid[hit[0] - 1], grid[hit[0]]
    days_ = float(optimize.brentq(lambda x: float(upper(x)) - tolerance_um, lo, hi, xtol=1e-9))
    return {
        **out,
        "interval_days": days_,
        "statement": (
            f"the upper {reliability:.0%} prediction bound reaches {tolerance_um:g} µm "
            f"{days_:.0f} days after the adjustment"
        ),
    }


def exponential_mle(days, in_tolerance) -> tuple[float, float]:
    """(λ̂, its standard error) per day of R(t) = exp(−λt) from in/out-of-tolerance
    decisions at their intervals: maximises Σ x_i ln R(t_i) + (1 − x_i) ln(1 − R(t_i)).
    λ̂ = 0 with no decision out of tolerance, ∞ with none in; the standard error is from the
    observed information, Σ (1 − x_i) t_i² e^{−λt_i}/(1 − e^{−λt_i})²."""
    t = np.asarray(days, float)
    x = np.asarray(in_tolerance, bool)
    if t.size == 0 or np.any(t <= 0):
        raise ValueError("exponential_mle: expected at least one decision, each at a positive interval")
    if x.all():
        return 0.0, float("nan")
    if not x.any():
        return float("inf"), float("nan")
    tin, tout = t[x].sum(), t[~x]

    def score(lam):  # d logL / dλ, decreasing in λ
        e = np.exp(-lam * tout)
        return float(np.sum(tout * e / -np.expm1(-lam * tout)) - tin)

    lo, hi = 1e-12 / t.max(), 1.0 / t.min()
    while score(hi) > 0:
        hi *= 10.0
    lam = float(optimize.brentq(score, lo, hi, xtol=1e-15, rtol=1e-12))
    e = np.exp(-lam * tout)
    info = float(np.sum(tout**2 * e / np.expm1(-lam * tout) ** 2))
    return lam, float(1.0 / np.sqrt(info)) if info > 0 else float("nan")


def attributes(days, in_tolerance, reliability: float = 0.95) -> dict:
    """The interval of the exponential reliability model (module docstring):
    ``{interval_days, lambda_per_day, lambda_std, statement, n, out_of_tolerance}``."""
    check_settings(reliability, None, "interval")
    t = np.asarray(days, float)
    x = np.asarray(in_tolerance, bool)
    base = {"interval_days": None, "lambda_per_day": None, "lambda_std": None, "n": int(t.size)}
    base["out_of_tolerance"] = int((~x).sum())
    if t.size == 0:
        return {**base, "statement": "not enough history: no in/out-of-tolerance decision as found"}
    lam, se = exponential_mle(t, x)
    if lam == 0.0:
        return {
            **base,
            "lambda_per_day": 0.0,
            "statement": (
                f"not enough history: none of {t.size} as-found decision(s) out of tolerance, "
                "so the likelihood gives no finite interval"
            ),
        }
    if not np.isfinite(lam):
        return {
            **base,
            "interval_days": 0.0,
            "statement": f"every one of {t.size} as-found decision(s) out of tolerance: the interval is shorter than any tried",
        }
    days_ = float(-np.log(reliability) / lam)
    return {
        **base,
        "interval_days": days_,
        "lambda_per_day": lam,
        "lambda_std": se,
        "statement": f"R(t) = exp(−λt) reaches {reliability:.0%} {days_:.0f} days after the adjustment",
    }


def add_days(start: str, days: float | None) -> str | None:
    """ISO date ``days`` after the ISO 8601 instant ``start``."""
    if days is None:
        return None
    t0 = dt.datetime.fromisoformat(str(start).replace("Z", "+00:00"))
    return (t0 + dt.timedelta(days=float(days))).date().isoformat()
