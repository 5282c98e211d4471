"""Error rates of a stage history's decisions, over simulated histories (no workflow runs).

Each calibration is simulated as its identified parameter vectors — Models II and III of
the XYΘ thesis rig, with the σ and correlation the default xytheta-thesis campaign
reports (written below) — drawn around the stage's true geometry; the decisions are the
workflow's own code (calflow.lifecycle). Measured:

* false "changed" rate on stable stages (any model flagged by the change test), against α
  with its Monte-Carlo error, with honest σ and with σ understated 1.5× (then the stage's
  own reproducibility must take over after ``min_pairs`` unchanged pairs);
* detection of a re-mount moving α by 0.01° or x_R by 20 µm at the first calibration
  after it (change test), and at the first interim check (the SPRT on the targets the
  workflow chooses, looked at after each cycle from the second, as the runner stops the rig);
* the due date against the true crossing on a linearly drifting stage (±20 %);
* the interim check's rig time against the default run's small calibration (its visits
  as the sequential test used them, the time per sample measured in that run).

Run: python benchmarks/bench_lifecycle.py --json [--histories 400]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from calflow.lifecycle.decisions import change, due
from calflow.lifecycle.decisions.sprt import SPRT

NAMES = ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")
TRUE = np.array([9572.902, 7795.830, 177.689, -0.132])
CORR = np.array(
    [
        [1.0, 0.0, 0.056, -0.026],
        [0.0, 1.0, 0.0, 0.016],
        [0.056, 0.0, 1.0, -0.454],
        [-0.026, 0.016, -0.454, 1.0],
    ]
)
SIGMA = {"II": np.array([4.05, 4.05, 0.00527, 0.0116]), "III": np.array([0.708, 0.707, 0.00092, 0.00203])}
COV = {m: CORR * np.outer(s, s) for m, s in SIGMA.items()}
# rig time, measured in the default run (summary.json interim_check.rig_time_s and
# reference_rig_time_s of demo-sn0042-2026-04-check): a check's sample (home or a visit of the
# far-apart edge targets) and the small routine calibration it checks, the smallest full
# calibration calflow ships (the thesis campaign's runs take 53 495 s)
SAMPLE_S = 19.3 / 5
DEMO_CALIBRATION_S = 609.4


def calibration(rng, shift=None, spread=1.0):
    shift = np.zeros(4) if shift is None else shift
    return {
        m: change.Estimate(NAMES, rng.multivariate_normal(TRUE + shift, spread**2 * c), c)
        for m, c in COV.items()
    }


def stable(rng, n, k, spread, alpha, min_pairs):
    early, late = [], []
    for _ in range(n):
        res = change.changes([calibration(rng, spread=spread) for _ in range(k)], alpha, min_pairs)
        for c in res:  # late: the stage's own reproducibility in use (k² estimated)
            flag = any(r["significant"] for r in c["models"].values())
            (late if any(r["inflation_dof"] > 0 for r in c["models"].values()) else early).append(flag)
    return early, late


def remount(rng, n, shift, alpha, min_pairs, k_before=4):
    hits, per_model = [], {m: [] for m in COV}
    for _ in range(n):
        series = [calibration(rng) for _ in range(k_before)] + [calibration(rng, shift)]
        last = change.changes(series, alpha, min_pairs)[-1]["models"]
        hits.append(any(r["significant"] for r in last.values()))
        for m in COV:
            per_model[m].append(last[m]["significant"])
    return hits, {m: float(np.mean(v)) for m, v in per_model.items()}


def interim_jacobian(count: int) -> np.ndarray:
    """(count, 2, 2): the error (µm) a unit of each watched drift (x_R 20 µm, α 0.01°) gives
    at the ``count`` targets the workflow's own choice picks (calflow.xytheta.plans.interim)
    over the thesis identification workspace, the reference geometry the stage's."""
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.plans.interim import DRIFT, candidates, scaled_jacobian, sensitive_poses

    params = Parameters(x_R=TRUE[0], y_R=TRUE[1], alpha=TRUE[2], beta=TRUE[3])
    q = candidates((0.0, 4000.0), (800.0, 2800.0), (0.0, 5.0))
    return scaled_jacobian(q[sensitive_poses(q, params, count, DRIFT)], params, DRIFT)


def interim(rng, n, G, drift_units, r0, tol, alpha, beta, cycles):
    """Decisions and visits of interim checks on the targets of ``G`` after a change of
    ``drift_units`` (units of the design drift: [1, 0] is x_R + 20 µm, [0, 1] α + 0.01°), the
    reference's error scale r0 as noise; looked at as the workflow's runner looks (end of each
    cycle from the second: calflow.xytheta.report.interim.visit_groups)."""
    from calflow.xytheta.report.interim import MIN_CYCLES

    test = SPRT(r0, tol, alpha, beta)
    count = G.shape[0]
    bias = np.tile(G @ np.asarray(drift_units, float), (cycles, 1))
    groups = np.maximum(np.repeat(np.arange(cycles), count), MIN_CYCLES - 1)
    out, used = [], []
    for _ in range(n):
        e = bias + rng.normal(0, r0 / np.sqrt(2), bias.shape)
        d = test.decide(e, groups, planned=count * cycles)
        out.append(
            d["decision"] == "recalibrate" or (d["decision"] == "undecided" and d["leaning"] == "recalibrate")
        )
        used.append(d["visits"])
    return out, used, float(np.sqrt(np.mean(np.sum((G @ np.asarray(drift_units, float)) ** 2, axis=1))))


def due_dates(rng, n, reliability):
    a, b, tol, noise = 2.0, 0.01, 6.0, 0.1  # µm, µm/day, µm, µm: true crossing at day 400
    days = np.arange(0, 361, 60)
    t0 = np.datetime64("2026-01-05")
    crossing = (tol - a) / b
    errs = []
    for _ in range(n):
        ap = a + b * days + rng.normal(0, noise, days.size)
        dates = [f"{t0 + np.timedelta64(int(d), 'D')}T08:00:00+00:00" for d in days]
        r = due.due_date(dates, ap.tolist(), [0] * days.size, tol, reliability=reliability)
        got = (np.datetime64(r["date"]) - t0).astype(int) if r["date"] else np.inf
        errs.append((got - crossing) / crossing)
    return np.array(errs), crossing


def mc(rate, n):
    return float(np.sqrt(max(rate * (1 - rate), 1e-12) / n))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--histories", type=int, default=400)
    p.add_argument("--smoke", action="store_true", help="small sizes for CI: 20 histories")
    p.add_argument("--json", action="store_true")
    p.add_argument("--seed", type=int, default=2026)
    a = p.parse_args(argv)
    if a.smoke:
        a.histories = 20
    rng = np.random.default_rng(a.seed)
    alpha, min_pairs, n = 0.05, 3, a.histories
    t = time.perf_counter()
    out = {
        "histories": n,
        "alpha": alpha,
        "min_pairs": min_pairs,
        "machine": platform.platform(),
        "models": list(COV),
        "calibrations_per_history": 6,
    }
    early, late = stable(rng, n, 6, 1.0, alpha, min_pairs)
    flags = early + late
    out["false_changed_honest_sigma"] = {
        "rate": float(np.mean(flags)),
        "mc_error": mc(np.mean(flags), len(flags)),
        "changes": len(flags),
        "rate_first_pairs_within_sigma_only": float(np.mean(early)),
        "rate_with_own_reproducibility": float(np.mean(late)),
        "holm_two_independent_models": 1 - (1 - alpha / 2) ** 2,
    }
    early, late = stable(rng, n, 6, 1.5, alpha, min_pairs)
    out["false_changed_sigma_understated_1_5"] = {
        "rate_first_pairs_within_sigma_only": float(np.mean(early)),
        "rate_with_own_reproducibility": float(np.mean(late)),
        "mc_error": mc(np.mean(late), len(late)),
        "changes": len(late),
    }
    for name, shift in (("alpha_0.01deg", [0, 0, 0.01, 0]), ("x_R_20um", [20.0, 0, 0, 0])):
        hits, per = remount(rng, n, np.array(shift), alpha, min_pairs)
        out[f"remount_{name}_detected_at_next_calibration"] = {
            "rate": float(np.mean(hits)),
            "mc_error": mc(np.mean(hits), n),
            "per_model": per,
        }
    # the default run's stage year: r0 its reference's closed-loop rms, its tolerance and plans
    r0, tol = 1.5, 3.5
    out["interim"] = {"r0_um": r0, "tolerance_um": tol, "alpha": alpha, "beta": 0.10}
    cases = {
        "stable": [0.0, 0.0],
        "alpha_0.01deg": [0.0, 1.0],
        "x_R_20um": [1.0, 0.0],
        "demo_knock_alpha_0.05deg_x_R_50um": [2.5, 5.0],
    }
    for plan, (count, cycles) in {"demo_2x3": (2, 3), "default_6x3": (6, 3)}.items():
        G = interim_jacobian(count)
        block = {"targets": count, "cycles": cycles, "planned_visits": count * cycles}
        for name, units in cases.items():
            dec, used, rms = interim(rng, n, G, units, r0, tol, alpha, 0.10, cycles)
            block[name] = {
                "recalibrate_rate": float(np.mean(dec)),
                "mc_error": mc(np.mean(dec), n),
                "mean_visits": float(np.mean(used)),
                "drift_rms_um": rms,
            }
        # rig time: the default run's check spent 19.3 s on home + 4 visits (3.86 s a sample,
        # edge targets far apart) against its reference calibration's 609 s (the runs' time axes)
        block["rig_time_ratio_stable_mean"] = (
            (1 + block["stable"]["mean_visits"]) * SAMPLE_S / DEMO_CALIBRATION_S
        )
        block["rig_time_ratio_worst"] = (1 + count * cycles) * SAMPLE_S / DEMO_CALIBRATION_S
        out["interim"][plan] = block
    for rel in (0.95, 0.5):
        errs, crossing = due_dates(rng, n, rel)
        out[f"due_date_reliability_{rel}"] = {
            "true_crossing_day": crossing,
            "within_20pct": float(np.mean(np.abs(errs) <= 0.2)),
            "median_relative_error": float(np.median(errs)),
        }
    out["wall_s"] = time.perf_counter() - t
    print(json.dumps(out, indent=None if a.json else 2))


if __name__ == "__main__":
    main()
