"""The calibration interval from as-found drift, over simulated stage histories (no workflow runs).

Each simulated stage drifts by wear that each recalibration absorbs: a calibration leaves it
at an as-left AP a + e_left (the stage's own level a, measured with noise σ), and the
value found through that compensation t days later is a + r·t + e_found (the same σ). A
history is ``--intervals`` such intervals of random lengths (60–180 days: a lab's practice
varies); each calibration records its as-found value (through the previous compensation)
and its as-left value, as the workflow writes them to the summary. The due date is the
workflow's own decision code (:func:`calflow.lifecycle.decisions.as_found.from_history`, on the same
history entries :mod:`calflow.lifecycle.history` builds it from); nothing downstream reads
the simulated truth, the measures below do.

Measured, per history:

* the realised in-tolerance rate at the due date: a new as-found value a + r·t_due + e_found
  drawn at the date, inside the tolerance or not — over the histories it should equal the
  reliability target;
* the date against the true crossing: the day the stage as it truly is falls to the target,
  a + r·t + z_R·σ = tolerance (z_R the normal quantile), within ±20 %;
* the attributes variant (exponential model on the as-found decisions) on the same histories:
  how often it gives a date and its realised rate.

With ``suncal`` installed (GPLv3, Sandia PSL; not a dependency of calflow), the V1 interval of
the first histories, suncal's ``VariablesReliabilityTarget`` recomputes from history.json's
``interval`` alone the reliability at calflow's date (the range of its difference from the
target is reported).

Run: python benchmarks/bench_interval.py --json [--histories 1000] [--intervals 6]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import time

import numpy as np
from scipy import stats

from calflow.lifecycle.decisions import as_found

T0 = dt.datetime(2026, 1, 5, 8, tzinfo=dt.UTC)


def calibrate(
    rng, entries: list[dict], t: dt.datetime, level: float, rate: float, sigma: float
) -> float | None:
    """Append one calibration at ``t`` to ``entries`` (as :mod:`calflow.lifecycle.history`
    builds them): its as-found value through the previous one's compensation, its as-left
    value. Returns the as-found AP (None for the first calibration)."""
    start = t.isoformat()
    model = {"as_left": {"accuracy_um": level + rng.normal(0, sigma), "date": start}}
    found = None
    if entries:
        prev = entries[-1]
        days = (t - dt.datetime.fromisoformat(prev["start"])).total_seconds() / 86400
        found = level + rate * days + rng.normal(0, sigma)
        model["as_found"] = {"accuracy_um": found, "date": start, "reference": prev["campaign"]}
    entries.append(
        {"campaign": f"c{len(entries)}", "start": start, "kind": "calibration", "models": {"III": model}}
    )
    return found


def interval_of(entries: list[dict], tol: float, reliability: float) -> dict:
    """The workflow's own interval (history.json's ``interval``) of the history so far."""
    return as_found.from_history(entries, [0] * len(entries), "III", tol, reliability)


def summary(realised: list[bool], ratio: list[float], target: float, skipped: int) -> dict:
    r, q = np.asarray(realised, float), np.asarray(ratio, float)
    n = r.size
    rate_in = float(r.mean()) if n else float("nan")
    return {
        "dated": int(n),
        "no_date": int(skipped),
        "realised_in_tolerance": rate_in,
        "realised_mc_std": float(np.sqrt(rate_in * (1 - rate_in) / n)) if n else None,
        "within_2pct_of_target": bool(abs(rate_in - target) <= 0.02),
        "date_within_20pct_of_true_crossing": float(np.mean(np.abs(q - 1) <= 0.2)) if n else None,
        "median_date_over_true_crossing": float(np.median(q)) if n else None,
        "ratio_p05_p95": [float(np.quantile(q, 0.05)), float(np.quantile(q, 0.95))] if n else None,
    }


def suncal_reliability(iv: dict) -> float | None:
    """suncal's (1.7, ``VariablesReliabilityTarget``) reliability at calflow's interval,
    recomputed from the history's ``interval`` alone; None without suncal. suncal's reliability
    uses the fit's confidence band plus a time-of-test uncertainty u0: with u0 the residual σ
    (on the fit's dof) its variance is the prediction variance and its degrees of freedom
    Welch–Satterthwaite's (≥ the fit's), so it should sit at or a little above the target."""
    try:
        from suncal.intervals import VariablesReliabilityTarget
    except Exception:  # noqa: BLE001 - optional cross-check
        return None
    v = VariablesReliabilityTarget(
        dt=iv["inputs"]["days_since_adjustment"],
        deltas=iv["inputs"]["as_found_minus_as_left"],
        u0=iv["fit"]["residual_std_um"],
        y0=iv["as_left"]["accuracy_um"],
        u0_degf=iv["fit"]["dof"],
    )
    fit = v._fitcurve(order=1)
    return float(v.reliability(iv["interval_days"], None, iv["tolerance_um"], fit))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--histories", type=int, default=1000)
    p.add_argument("--intervals", type=int, default=6, help="recalibrations per history (as-found values)")
    p.add_argument("--reliability", type=float, default=0.95)
    p.add_argument("--tolerance-um", type=float, default=3.5)
    p.add_argument(
        "--sigma-um",
        type=float,
        default=0.3,
        help="scatter of one AP measurement (µm): the default run's small plan, from its held-out AP through the model and through its bundle (3.21 and 2.82, 2.43 and 1.94 µm)",
    )
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--smoke", action="store_true", help="small sizes for CI: 20 histories")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if a.smoke:
        a.histories = 20
    rng = np.random.default_rng(a.seed)
    z = stats.norm.ppf(a.reliability)
    t_start = time.perf_counter()
    fixed = {"realised": [], "ratio": [], "skipped": 0}
    due = {"realised": [], "ratio": [], "skipped": 0}
    a_realised, a_dated, suncal_diff = [], 0, []
    for i in range(a.histories):
        level = rng.uniform(1.2, 1.8)  # the stage's as-left AP (µm)
        crossing = np.exp(rng.uniform(np.log(120), np.log(720)))  # days to the target, in truth
        rate = (a.tolerance_um - level - z * a.sigma_um) / crossing
        # (1) intervals a lab chose (60-180 days), then one due date from the whole history
        entries, t = [], T0
        for k in range(a.intervals + 1):
            t = t + dt.timedelta(days=float(rng.uniform(60, 180))) if k else t
            calibrate(rng, entries, t, level, rate, a.sigma_um)
        iv = interval_of(entries, a.tolerance_um, a.reliability)
        days = iv["interval_days"]
        if days is None:
            fixed["skipped"] += 1
        else:
            fixed["realised"].append(level + rate * days + rng.normal(0, a.sigma_um) <= a.tolerance_um)
            fixed["ratio"].append(days / crossing)
            if i < 50 and days > 0:
                s = suncal_reliability(iv)
                if s is not None:
                    suncal_diff.append(s - a.reliability)
        att = iv["attributes"]["interval_days"]
        if att:
            a_dated += 1
            a_realised.append(level + rate * att + rng.normal(0, a.sigma_um) <= a.tolerance_um)
        # (2) recalibrated at the due date: three intervals a lab chose, then each next
        # calibration on the date the history so far gives (its as-found value is the test)
        entries, t = [], T0
        for k in range(a.intervals + 1):
            if k <= 3:
                step = float(rng.uniform(60, 180)) if k else 0.0
            else:
                step = interval_of(entries, a.tolerance_um, a.reliability)["interval_days"]
                if step is None or step < 1.0:  # no date (beyond the horizon) or "now": not the method's date
                    due["skipped"] += 1
                    step = float(rng.uniform(60, 180)) if step is None else 1.0
                else:
                    due["ratio"].append(step / crossing)
            t = t + dt.timedelta(days=step)
            found = calibrate(rng, entries, t, level, rate, a.sigma_um)
            if k > 3 and len(due["ratio"]) > len(due["realised"]):
                due["realised"].append(found <= a.tolerance_um)
    out = {
        "histories": a.histories,
        "intervals_per_history": a.intervals,
        "reliability_target": a.reliability,
        "tolerance_um": a.tolerance_um,
        "sigma_um": a.sigma_um,
        "variables_v1_one_date_after_chosen_intervals": summary(
            fixed["realised"], fixed["ratio"], a.reliability, fixed["skipped"]
        ),
        "variables_v1_recalibrated_at_due_date": summary(
            due["realised"], due["ratio"], a.reliability, due["skipped"]
        ),
        "attributes_exponential": {
            "dated": a_dated,
            "realised_in_tolerance": float(np.mean(a_realised)) if a_realised else None,
        },
        "suncal_reliability_at_date_minus_target": (
            [float(min(suncal_diff)), float(max(suncal_diff))] if suncal_diff else None
        ),
        "suncal_compared": len(suncal_diff),
        "wall_s": time.perf_counter() - t_start,
        "machine": platform.platform(),
        "load_average": list(os.getloadavg()),
    }
    print(json.dumps(out, indent=None if a.json else 2))


if __name__ == "__main__":
    main()
