"""Coverage of U and the risk of guarded acceptance, over simulated stages (no workflow runs).

Running the full workflow hundreds of times is not affordable, so each seed simulates only
what one headline's U is computed from — the readings of a validation (targets × cycles)
and, for E, a bidirectional ISO 230-2 sweep — with the family's own sensor terms and
calflow's own U code (:mod:`calflow.metrics.uncertainty`, the families' ``certificate``
modules). What is simulated, per family:

* **XYΘ** (world frame, µm): 8 held-out targets over ±2 mm × ±1.5 mm, 3 cycles; the stage's
  systematic error at each target N(0, 1.5 µm) per axis (a calibrated stage's residual),
  its repeatability σ = 0.3 µm per axis; the vision sensor of the simulated rig (noise
  0.05 µm, 10 nm quantisation, Table 3.3 drift 0.157 / 1.357 µm/°C) with the temperature
  of each target's visits U(±0.1 °C) around the first reading's, the run's thermometer
  recording that excursion; the family's terms from its run (``vision_terms``). E: one
  axis's sweep, 11 targets over 4 mm, 5 cycles each way, a lead-screw error of a few µm and
  2 µm of backlash.
* **nano 1-DoF** (µm): 11 poses over the 500 µm stroke, 5 cycles each way (AP and RP over
  the 22 (pose, direction) cells, as the family's runs give a pose one direction); the cubic
  geometric error of ~400 nm peak to valley and a random hysteresis (forward − backward)
  ~20 nm per pose; intrinsic repeatability 35 nm; the interferometer's Table 3.4 terms
  drawn as they act (relative: U_1, U_4, U_8; one offset U_6; per target U_3, U_5, U_7;
  per reading U_2), and the family's terms from the same budget (``interferometer_terms``).
* **hexapod** (measurement frame, µm): 8 held-out poses within ±10 mm, 3 cycles; the
  platform's systematic error N(0, 5 µm) per axis, its repeatability 1 µm; the family's
  simulated laser tracker (:func:`calflow_hexapod.stage.tracker.read`: ADM and transverse
  random errors at MPE/4, the angle encoders' systematic error, 0.1 µm rounding) and its
  declared terms (``tracker_terms``, the whole transverse MPE/4 as systematic per target).

Truth: AP = max over targets of |true mean error| (the sensor's errors excluded); RP =
the population value E[l] + 3 SD[l] of the readings' scatter at a target (stage and
sensor noise, as the RP measurand is defined); E = range of the true cell means.

Decision risk: 2000 XYΘ stages whose worst target's true AP is uniform within ±1.2 µm of
a 3.5 µm tolerance; guarded acceptance (w = U); the observed false-accept rate among
accepted stages against the mean of their specific PFAs.

Run: python benchmarks/bench_certificate.py --json [--seeds 200] [--stages 2000] [--trials 5000]
(``--stages 0``: coverage only)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time

import numpy as np
import xarray as xr

from calflow.metrics.uncertainty_iso import iso230_2_uncertainty, iso9283_uncertainty

TOL = 3.5


def _rp_truth(sd: np.ndarray, rng) -> float:
    """E[l] + 3 SD[l] of a normal scatter with per-axis σ ``sd`` (by simulation, 200 000 draws)."""
    l_ = np.linalg.norm(rng.standard_normal((200_000, len(sd))) * sd, axis=1)
    return float(l_.mean() + 3 * l_.std())


def _fake_run(temps: np.ndarray, theta: np.ndarray, pose: np.ndarray) -> xr.Dataset:
    return xr.Dataset(
        {
            "temperature": (("sample", "sensor"), temps[:, None]),
            "meas_theta": ("sample", theta),
            "pose": ("sample", pose),
        }
    )


def xytheta_case(rng, trials, bias_sd=1.5, bias=None):
    from calflow.xytheta.report.certificate import vision_terms

    T, n, sig, noise, q = 8, 3, 0.3, 0.05, 0.01
    drift = np.array([0.157, 1.357])
    cmd = np.column_stack([rng.uniform(-2000, 2000, T), rng.uniform(-1500, 1500, T)])
    b = rng.normal(0, bias_sd, (T, 2)) if bias is None else bias
    dT = rng.uniform(-0.1, 0.1, T)
    att, temps, thetas, poses = [], [], [], []
    for j in range(T):
        true = cmd[j] + b[j] + rng.normal(0, sig, (n, 2))
        read = true + drift * dT[j] + rng.normal(0, noise, (n, 2))
        att.append(np.round(read / q) * q)
        temps += [20 + dT[j]] * n
        thetas += list(rng.normal(0, 2e-4, n))
        poses += [j + 1] * n
    run = _fake_run(np.array([20.0, *temps]), np.array([0.0, *thetas]), np.array([0, *poses]))
    terms, _ = vision_terms(run)
    r = iso9283_uncertainty(cmd, att, terms, trials=trials, seed=int(rng.integers(1 << 31)))
    sd = np.full(2, math.sqrt(sig**2 + noise**2 + q**2 / 12))
    truth = {"AP": float(np.max(np.linalg.norm(b, axis=1))), "RP": _rp_truth(sd, rng)}
    # E of one axis's sweep: lead-screw error + backlash, the x drift coefficient
    t = np.linspace(0, 4000, 11)
    lead = 2.0 * np.sin(2 * np.pi * t / 400.0 + rng.uniform(0, 2 * np.pi)) + rng.normal(0, 0.5, 11)
    mf, mb = lead + 1.0, lead - 1.0
    dTs = rng.uniform(-0.1, 0.1, (2, 11))
    f = t[:, None] + (mf + drift[0] * dTs[0])[:, None] + rng.normal(0, math.hypot(sig, noise), (11, 5))
    bw = t[:, None] + (mb + drift[0] * dTs[1])[:, None] + rng.normal(0, math.hypot(sig, noise), (11, 5))
    sweep = _fake_run(np.array([20.0, 20.1]), np.zeros(2), np.array([1, 1]))  # 0.1 °C excursion
    e = iso230_2_uncertainty(t, f, bw, vision_terms(sweep, (0,))[0], trials=trials, seed=1)["E"]
    both = np.concatenate([mf, mb])
    truth["E"] = float(both.max() - both.min())
    return {"AP": r["accuracy"], "RP": r["repeatability"], "E": e}, truth


def nano_case(rng, trials):
    from calflow.instruments.interferometer import interferometer_budget
    from calflow.nano.certificate import interferometer_terms

    budget = interferometer_budget()
    terms = interferometer_terms(budget)
    t = np.linspace(0, 500, 11)
    x = t / 250.0 - 1.0
    geo = rng.uniform(0.1, 0.2) * (x**3 - x) * rng.choice([-1, 1]) * 2.6 + rng.normal(
        0, 0.02, 11
    )  # ~400 nm p-v
    hyst = rng.normal(0, 0.02, 11)
    sig = 0.035

    def sensor(cells):  # the Table 3.4 terms as they act on each (target, direction) cell
        e = np.zeros(cells)
        for tm in terms:
            if tm.scope == "reading":
                continue
            u = float(tm.per_axis(1)[0])
            draw = rng.normal(0, u) if tm.scope == "common" else rng.normal(0, u, cells)
            e = e + (draw * 1e-6 * np.concatenate([t, t]) if tm.relative else draw)
        return e

    s = sensor(22)
    u2 = budget.U_2 / 1e3
    f = t[:, None] + (geo + hyst / 2 + s[:11])[:, None] + rng.normal(0, math.hypot(sig, u2), (11, 5))
    b = t[:, None] + (geo - hyst / 2 + s[11:])[:, None] + rng.normal(0, math.hypot(sig, u2), (11, 5))
    seed = int(rng.integers(1 << 31))
    # AP, RP: each (pose, direction) a target of its own, as the family's runs have them
    cells = [f[i] for i in range(11)] + [b[i] for i in range(11)]
    ap_rp = iso9283_uncertainty(
        np.concatenate([t, t])[:, None], [c[:, None] for c in cells], terms, trials=trials, seed=seed
    )
    iso = iso230_2_uncertainty(t, f, b, terms, trials=trials, seed=seed)
    sd = math.hypot(sig, u2)
    cell = np.concatenate([geo + hyst / 2, geo - hyst / 2])
    truth = {
        "AP": float(np.max(np.abs(cell))),
        "RP": float(sd * (math.sqrt(2 / math.pi) + 3 * math.sqrt(1 - 2 / math.pi))),
        "E": float(cell.max() - cell.min()),
    }
    return {"AP": ap_rp["accuracy"], "RP": ap_rp["repeatability"], "E": iso["E"]}, truth


def hexapod_case(rng, trials):
    from calflow_hexapod.certificate import tracker_terms
    from calflow_hexapod.stage import tracker
    from calflow_hexapod.stage.physics import HexapodTruth

    truth_rig = HexapodTruth()
    T, n = 8, 3
    poses = np.zeros((T, 6))
    poses[:, :3] = rng.uniform(-10_000, 10_000, (T, 3))
    err = rng.normal(0, 5.0, (T, 3))
    cmd, att, ap = [], [], []
    for j in range(T):
        target, _ = tracker.probe_pose(truth_rig, poses[j : j + 1])
        actual = np.repeat(poses[j : j + 1], n, axis=0)
        actual[:, :3] += err[j] + rng.normal(0, 1.0, (n, 3))
        r = tracker.read(truth_rig, actual, rng.standard_normal((n, 6)))
        cmd.append(target[0])
        att.append(np.column_stack([r["meas_x"], r["meas_y"], r["meas_z"]]))
        mean_true, _ = tracker.probe_pose(truth_rig, np.r_[poses[j, :3] + err[j], poses[j, 3:]][None])
        ap.append(np.linalg.norm(mean_true[0] - target[0]))
    res = iso9283_uncertainty(
        np.array(cmd),
        att,
        tracker_terms(truth_rig.tracker_distance_m),
        trials=trials,
        seed=int(rng.integers(1 << 31)),
    )
    # RP truth: the scatter of readings at one target (platform 1 µm + tracker random), by simulation
    s_r, s_t, _ = tracker.sigmas(truth_rig, np.array(cmd[:1]))
    sd = np.sqrt(np.array([s_r[0], s_t[0], s_t[0]]) ** 2 + 1.0)
    return {"AP": res["accuracy"], "RP": res["repeatability"]}, {
        "AP": float(max(ap)),
        "RP": _rp_truth(sd, rng),
    }


def coverage(seeds: int, trials: int) -> dict:
    out = {}
    for family, case in (("xytheta", xytheta_case), ("stage1d", nano_case), ("hexapod", hexapod_case)):
        hits, width, t0 = {}, {}, time.perf_counter()
        for seed in range(seeds):
            results, truth = case(np.random.default_rng(seed), trials)
            for k, u in results.items():
                hits.setdefault(k, []).append(u.interval[0] <= truth[k] <= u.interval[1])
                width.setdefault(k, []).append(u.U / max(truth[k], 1e-12))
        out[family] = {
            k: {
                "coverage": float(np.mean(v)),
                "mc_error": float(math.sqrt(0.95 * 0.05 / len(v))),
                "within_93_97": bool(0.93 <= np.mean(v) <= 0.97),
                "median_U_over_truth": float(np.median(width[k])),
            }
            for k, v in hits.items()
        }
        out[family]["wall_s"] = time.perf_counter() - t0
    return out


def decision_risk(stages: int, trials: int) -> dict:
    from calflow.certificate.conformity import decide

    accepted = false_accept = 0
    pfas, t0 = [], time.perf_counter()
    for seed in range(stages):
        rng = np.random.default_rng(10_000 + seed)
        b = rng.normal(0, 0.6, (8, 2))
        worst = rng.uniform(TOL - 1.2, TOL + 1.2)  # the worst target's true AP near the tolerance
        angle = rng.uniform(0, 2 * np.pi)
        b[0] = worst * np.array([math.cos(angle), math.sin(angle)])
        results, truth = xytheta_case(rng, trials, bias=b)
        u = results["AP"].record()
        d = decide(results["AP"].value, TOL, "guarded", u["U"], u["k"], u["dof_eff"])
        if d["decision"] == "pass":
            accepted += 1
            false_accept += truth["AP"] > TOL
            pfas.append(d["pfa"])
    rate = false_accept / accepted if accepted else float("nan")
    se = math.sqrt(max(np.mean(pfas), 1e-12) * (1 - np.mean(pfas)) / accepted) if accepted else float("nan")
    return {
        "stages": stages,
        "tolerance_um": TOL,
        "accepted": accepted,
        "false_accepts": int(false_accept),
        "false_accept_rate_among_accepted": rate,
        "false_accept_rate_of_all_stages": false_accept / stages,
        "mean_specific_pfa_of_accepted": float(np.mean(pfas)) if pfas else None,
        "mc_error_of_rate": se,
        "agree_within_2_mc_errors": bool(abs(rate - np.mean(pfas)) <= 2 * se) if pfas else None,
        "rate_at_most_2_5_percent": bool(rate <= 0.025),
        "wall_s": time.perf_counter() - t0,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=200)
    p.add_argument("--stages", type=int, default=2000)
    p.add_argument(
        "--trials", type=int, default=5000, help="Monte Carlo trials per U (the workflow uses 50 000)"
    )
    p.add_argument("--smoke", action="store_true", help="small sizes for CI: 4 seeds, 20 stages, 2000 trials")
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    if a.smoke:
        a.seeds, a.stages, a.trials = 4, 20, 2000
    out = {
        "coverage": coverage(a.seeds, a.trials),
        "decision_risk": decision_risk(a.stages, a.trials) if a.stages > 0 else None,
        "seeds": a.seeds,
        "trials": a.trials,
        "machine": f"{platform.machine()} {platform.python_version()} load {os.getloadavg()[0]:.2f}",
    }
    print(json.dumps(out, indent=None if a.json else 2))


if __name__ == "__main__":
    main()
