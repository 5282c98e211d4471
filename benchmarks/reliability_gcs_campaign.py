"""The thesis nano campaigns' training runs through the E-727-class emulator vs the simulated rig.

For ``nano1d-thesis`` and ``nano2d-thesis`` (config/campaigns/), the training plan is
acquired twice: on the ``simulated`` rig and with ``rig: gcs`` through the piezo controller
emulation (:mod:`calflow.nano.stage.emulate`), whose stage is the same physics with its own noise.
Per pose and approach direction, the stage's error ``meas - cmd`` averaged over the cycles
is compared: the figure is the fraction of (pose, direction, sensor) cells whose difference
is within 3 combined standard errors, and the largest difference in those units.

For ``xytheta-thesis`` (``--campaigns xytheta-thesis``), the identification run goes through
the C-863 campaign emulator (time scale at most 100) and Model II is identified on both
runs; the figure is each parameter's difference in combined standard deviations.

``python benchmarks/reliability_gcs_campaign.py --json [--time-scale 500]`` (about 5 min);
``--smoke`` (CI): nano2d-thesis's training shortened to 2 cycles, at time scale 2000.

``--thesis [CAMPAIGN ...]``: the whole workflow (every plan, models, summary) of each thesis
campaign through Snakemake with ``rig: gcs`` against its emulator (C-863 for XYΘ at time
scale 100, E-727 class for nano at 500), and three simulated runs of the same world with
other noise (the campaign's seed, 101, 202); each headline figure of the summaries compared
in units of the simulated runs' spread (:func:`compare_thesis`). Long (the nano1d-thesis gcs
run alone is about 20 min on 2 cores): run one campaign at a time with ``nice``; runs are
kept under ``--root`` and reused, ``--only simulated|gcs`` runs without comparing.
``--matched`` adds three simulated runs given the gcs run's sample period per run
(:func:`matched_runs`), which separates the controller path from the campaign-time stretch.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _cells(ds, sensors):
    """{(pose, direction, sensor): (mean, standard error)} of meas - cmd over the cycles."""
    out = {}
    joints = {"meas_x": "x", "meas_y": "y"}
    for s in sensors:
        cmd = ds[f"cmd_{joints[s]}"].values if f"cmd_{joints[s]}" in ds else 0.0
        err = ds[s].values - cmd
        for p, d in sorted(set(zip(ds["pose"].values, ds["direction"].values))):
            m = (ds["pose"].values == p) & (ds["direction"].values == d) & np.isfinite(err)
            if m.sum() > 1:
                out[(int(p), int(d), s)] = (
                    float(err[m].mean()),
                    float(err[m].std(ddof=1) / math.sqrt(m.sum())),
                )
    return out


def compare(campaign: str, time_scale: float, cycles: int | None = None) -> dict:
    from calflow.acquisition.runner import acquire
    from calflow.commands.common import meta
    from calflow.configuration.campaign import load as load_campaign
    from calflow.family import family_of
    from calflow.gcs.rig import gcs
    from calflow.nano.stage.emulate import emulated_rig_options
    from calflow.rigs import load_rig

    c = load_campaign(ROOT / "config" / "campaigns" / f"{campaign}.yaml")
    if cycles:  # a shorter training plan (--smoke); a loaded campaign is immutable
        import copy

        c = copy.deepcopy(c)
        c["training"] = {**c["training"], "cycles": cycles}
    fam = family_of(c["robot"])
    job = fam.plan(c["robot"], "training")(c, argparse.Namespace(model=None))
    plan = job.plan
    from calflow.family import resolve

    sim_opts = resolve(fam.rig_options)(
        c, "simulated", job.run_id, dict(c["rig"].get("options", {})), plan.start_s
    )
    t0 = time.monotonic()
    sim_rig, _ = load_rig("simulated", c["robot"], sim_opts)
    sim = acquire(plan, sim_rig, meta(c, "simulated", "training", None))
    t_sim = time.monotonic() - t0
    emu, options = emulated_rig_options(c, time_scale=time_scale)
    try:
        options = resolve(fam.rig_options)(c, "gcs", job.run_id, options, plan.start_s)
        t0 = time.monotonic()
        rig = gcs(**options)
        try:
            run = acquire(plan, rig, meta(c, "gcs", "training", None))
        finally:
            rig.close()
        t_gcs = time.monotonic() - t0
    finally:
        emu.stop()
    a, b = _cells(sim, rig.sensors), _cells(run, rig.sensors)
    z = np.array([abs(a[k][0] - b[k][0]) / math.hypot(a[k][1], b[k][1]) for k in a if k in b])
    diff_nm = np.array([abs(a[k][0] - b[k][0]) * 1e3 for k in a if k in b])
    ptp_nm = max(np.ptp([a[k][0] for k in a if k[2] == s]) for s in rig.sensors) * 1e3
    return {
        "campaign": campaign,
        "samples": len(plan),
        "cells": int(z.size),
        "within_3se": round(float(np.mean(z < 3)), 3),
        "max_z": round(float(z.max()), 2),
        "median_abs_diff_nm": round(float(np.median(diff_nm)), 2),
        "error_curve_ptp_nm": round(float(ptp_nm), 1),
        "all_samples": bool(run.sizes["sample"] == len(plan)),
        "wall_s_simulated": round(t_sim, 1),
        "wall_s_gcs": round(t_gcs, 1),
        "time_scale": time_scale,
    }


def compare_xytheta(campaign: str, time_scale: float) -> dict:
    """The identification run of an XYΘ campaign through the C-863 campaign emulator vs the
    simulated rig: Model II identified on both, parameters compared in combined sigma."""
    from calflow.acquisition.runner import acquire
    from calflow.commands.common import meta
    from calflow.configuration.campaign import load as load_campaign
    from calflow.family import family_of, resolve
    from calflow.gcs.rig import gcs
    from calflow.rigs import load_rig
    from calflow.xytheta.models import cost
    from calflow.xytheta.models.identification import identify
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.stage.emulate import emulated_rig_options

    c = load_campaign(ROOT / "config" / "campaigns" / f"{campaign}.yaml")
    fam = family_of(c["robot"])
    job = fam.plan(c["robot"], "identification")(c, argparse.Namespace(model=None))
    plan, opts = job.plan, dict(c["rig"].get("options", {}))
    sim_rig, _ = load_rig(
        "simulated", c["robot"], resolve(fam.rig_options)(c, "simulated", job.run_id, opts, 0.0)
    )
    sim = acquire(plan, sim_rig, meta(c, "simulated", "identification", None))
    emu, options = emulated_rig_options(c, time_scale=time_scale, timeout=2.0)
    try:
        t0 = time.monotonic()
        rig = gcs(**{**resolve(fam.rig_options)(c, "gcs", job.run_id, options, 0.0), "poll_s": 0.002})
        try:
            run = acquire(plan, rig, meta(c, "gcs", "identification", None))
        finally:
            rig.close()
        wall = time.monotonic() - t0
    finally:
        emu.stop()

    def fit(ds):
        theta = ds["meas_theta"].values - ds["meas_theta"].values[0]
        pm = cost.measured_points(ds["meas_x"].values, ds["meas_y"].values, theta)
        return identify(
            ds["cmd_x"].values,
            ds["cmd_y"].values,
            theta,
            *pm,
            free=("x_R", "y_R", "alpha", "beta"),
            initial=Parameters(**c["identification"]["initial"]),
        )

    a, b = fit(sim), fit(run)
    z = {
        k: round(abs(getattr(a.parameters, k) - getattr(b.parameters, k)) / math.hypot(a.std[k], b.std[k]), 2)
        for k in ("x_R", "y_R", "alpha", "beta")
    }
    d = np.abs(sim["meas_x"].values - run["meas_x"].values)
    return {
        "campaign": campaign,
        "plan": "identification",
        "samples": len(plan),
        "all_samples": bool(run.sizes["sample"] == len(plan)),
        "model_II_z": z,
        "median_abs_meas_x_diff_um": round(float(np.nanmedian(d)), 3),
        "wall_s_gcs": round(wall, 1),
        "time_scale": time_scale,
    }


def workflow_small_nano1d(workdir: Path) -> dict:
    """The small nano1d campaign of the tests through the whole workflow (training,
    metrology, validation with its run-time models, summary) with ``rig: gcs`` and with the
    simulated rig; the summaries' headline figures side by side (nm)."""
    import shutil

    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import SMALL_NANO1D, make_workdir, snakemake

    from calflow.nano.stage.emulate import campaign_rig, emulated_rig_options

    shutil.rmtree(workdir, ignore_errors=True)
    out = {}
    for rig in ("gcs", "simulated"):
        (workdir / rig).mkdir(parents=True)
        emu = None
        c = dict(SMALL_NANO1D)
        if rig == "gcs":
            emu, options = emulated_rig_options(SMALL_NANO1D, time_scale=1000.0, timeout=2.0)
            c["rig"] = campaign_rig(options, SMALL_NANO1D)
        try:
            work = make_workdir(workdir / rig, {"small": c})
            t0 = time.monotonic()
            proc = snakemake(work, "results/small/summary.json", "--resources", "rig=1")
            if proc.returncode:
                raise RuntimeError(proc.stderr[-2000:])
            wall = time.monotonic() - t0
        finally:
            if emu is not None:
                emu.stop()
        s = json.loads((work / "results" / "small" / "summary.json").read_text())
        out[rig] = {
            "wall_s": round(wall, 1),
            "intrinsic_ap_nm": round(s["intrinsic"]["accuracy_nm"], 1),
            "intrinsic_rp_nm": round(s["intrinsic"]["repeatability_nm"], 1),
            **{f"{m}_max_ap_nm": round(t["max_accuracy_nm"], 1) for m, t in s["tests"].items()},
            **{f"{m}_max_rp_nm": round(t["max_repeatability_nm"], 1) for m, t in s["tests"].items()},
        }
    return {"campaign": "tests/conftest.py SMALL_NANO1D, whole workflow", **out}


# ---------------------------------------------------------------- whole thesis campaigns
FAMILY_TIME_SCALE = {"xytheta": 100.0, "nano": 500.0}
SECTIONS = {
    "xytheta": ("characterisation", "iso230_2", "models", "xy_tests", "validation"),
    "nano": ("intrinsic", "training", "iso230_2", "tests", "iso9283", "validation"),
}
# key segments that are settings, counts or plan facts, not measured figures
SKIP = {
    "cycles",
    "cycles_forward",
    "cycles_backward",
    "n_tests",
    "targets",
    "poses",
    "cv_folds",
    "fit_dof",
    "floor_dof",
    "dof",
    "alpha",
    "reference_targets",
    "error_budget_nm",
    "start_h",
    "end_h",
    "days",
    "frames_per_pose",
    "rig_time_h",
    "rig_time_h_achieved",
    "condition_number",
    "rate_hz",
    "record_s",
    "band_nm",
    "p_value",
    "floor_um",
    "test",
    "first_test",
    "last_test",
    "command_distance_um",
    "period_h",
    "duration_h",
    "crlb_sigma",
    "heldout",
    "step_deg",
    "sweep_step_deg",
    "shortest_period_deg",
    "undersampled",
    "command_difference_um",
    "training_end_h",
    "validation_start_h",
    "n_poses",
}


PERIOD_OPTION = {"nano": ("rise_time_s", 4.0), "xytheta": ("settle_s", 0.5)}  # time a move takes (defaults)


def _spans(runs: Path) -> dict[str, tuple[int, float]]:
    """(samples, time from first to last sample, s) of each run file in ``runs``."""
    import xarray as xr

    out = {}
    for f in sorted(runs.glob("*.nc")):
        with xr.open_dataset(f, decode_times=False) as ds:
            if "record" in ds.dims or ds.sizes.get("sample", 0) < 2:
                continue  # recorded moves: no dwell between them
            t = ds["time"].values
            out[f.stem] = (int(t.size), float(t[-1] - t[0]))
    return out


def matched_runs(name: str, root: Path) -> dict[str, dict]:
    """``rig.runs`` overrides that give the simulated rig the gcs run's sample period: per
    run, the time a move takes plus the gcs run's extra time per sample (the per-sample
    message and polling overhead times the time scale, docs/reliability.md)."""
    import yaml

    c = yaml.safe_load((ROOT / "config" / "campaigns" / f"{name}.yaml").read_text())
    fam = "xytheta" if c["robot"] == "xytheta" else "nano"
    option, default = PERIOD_OPTION[fam]
    base = float((c["rig"].get("options") or {}).get(option, default))
    runs = lambda label: root / name / label / "project" / "results" / name / "runs"  # noqa: E731
    gcs, sim = _spans(runs("gcs")), _spans(runs("simulated"))
    return {
        r: {option: round(base + max(0.0, (gcs[r][1] - sim[r][1]) / (n - 1)), 3)}
        for r, (n, _) in gcs.items()
        if r in sim and sim[r][0] == n
    }


def _campaign(name: str, rig: str, noise_seed: int | None, runs: dict | None = None) -> tuple[dict, object]:
    """The thesis campaign ``name`` for ``rig`` ("simulated" or "gcs"): with ``noise_seed``,
    the same world (nano: ``world_seed``; XYΘ: the physics options) with other noise; for
    "gcs", its emulator started (the caller stops it). XYΘ error budget replays are off (the
    gcs rig has none; they are not compared)."""
    import yaml

    c = yaml.safe_load((ROOT / "config" / "campaigns" / f"{name}.yaml").read_text())
    nano = c["robot"] != "xytheta"
    if not nano:
        c.setdefault("validation", {}).setdefault("heldout", {})["error_budget"] = False
    if noise_seed is not None:
        opts = c["rig"].setdefault("options", {})
        if nano:
            opts["world_seed"], c["seed"] = c["seed"], noise_seed
        else:
            opts["seed"] = noise_seed
    if rig == "simulated":
        for run, extra in (runs or {}).items():  # e.g. the metrology room keeps its profile
            c["rig"].setdefault("runs", {}).setdefault(run, {}).update(extra)
        return c, None
    ts = FAMILY_TIME_SCALE["nano" if nano else "xytheta"]
    if nano:
        from calflow.nano.stage.emulate import campaign_rig, emulated_rig_options

        emu, options = emulated_rig_options(c, time_scale=ts, timeout=2.0)
        c["rig"] = campaign_rig(options, c)
    else:
        from calflow.xytheta.stage.emulate import emulated_rig_options

        emu, options = emulated_rig_options(c, time_scale=ts, timeout=2.0)
        c["rig"] = {"factory": "gcs", "options": {**options, "poll_s": 0.002}}
    return c, emu


def thesis_run(
    name: str, label: str, root: Path, rig: str, noise_seed: int | None = None, runs: dict | None = None
) -> dict:
    """One whole-workflow run (every plan, then the summary) of thesis campaign ``name``
    with Snakemake in ``root/name/label``; reused when its summary exists."""
    import os
    import subprocess

    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import make_workdir

    base = root / name / label
    summary = base / "project" / "results" / name / "summary.json"
    if not summary.exists():
        import shutil

        shutil.rmtree(base, ignore_errors=True)
        base.mkdir(parents=True)
        c, emu = _campaign(name, rig, noise_seed, runs)
        try:
            work = make_workdir(base, {name: c})
            env = {
                **os.environ,
                "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
            }
            t0 = time.monotonic()
            proc = subprocess.run(
                [
                    str(Path(sys.executable).parent / "snakemake"),
                    f"results/{name}/summary.json",
                    "--cores",
                    "2",
                    "--resources",
                    "rig=1",
                ],
                cwd=work,
                env=env,
                capture_output=True,
                text=True,
            )
            (base / "wall_s").write_text(f"{time.monotonic() - t0:.1f}\n")
            if proc.returncode:
                raise RuntimeError(f"{name} {label}: snakemake failed: {proc.stderr[-3000:]}")
        finally:
            if emu is not None:
                emu.stop()
    return {"summary": json.loads(summary.read_text()), "wall_s": float((base / "wall_s").read_text())}


def headline(summary: dict, family: str) -> dict[str, float]:
    """The summary's numeric figures of the headline sections (counts and settings left out)."""
    out: dict[str, float] = {}

    def walk(d, prefix):
        for k, v in d.items():
            key = f"{prefix}.{k}" if prefix else str(k)
            if str(k) in SKIP or str(k).startswith("thesis_"):
                continue
            if isinstance(v, dict):
                walk(v, key)
            elif isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                out[key] = float(v)

    walk({k: summary[k] for k in SECTIONS[family] if k in summary}, "")
    return out


T2_95 = 4.303  # Student t, 2 degrees of freedom, two-sided 95 %


def compare_thesis(
    name: str, root: Path, noise_seeds: tuple[int, ...] = (101, 202), matched: bool = False
) -> dict:
    """Whole workflow of a thesis campaign with ``rig: gcs`` against its emulator vs three
    simulated runs (the campaign's seed and ``noise_seeds``, same world): per headline
    figure, z = |gcs - mean(sim)| / (s sqrt(1 + 1/3)), s the simulated runs' standard
    deviation; "within noise" is z < 4.30, the two-sided 95 % point of Student's t with 2
    degrees of freedom (docs/reliability.md). ``matched``: the simulated runs take the gcs
    run's sample period (:func:`matched_runs`)."""
    fam = "xytheta" if name.startswith("xytheta") else "nano"
    gcs_run = thesis_run(name, "gcs", root, "gcs")
    runs = matched_runs(name, root) if matched else None
    prefix = "matched" if matched else "simulated"
    sims = [
        thesis_run(name, prefix if s is None else f"{prefix}-{s}", root, "simulated", s, runs)
        for s in (None, *noise_seeds)
    ]
    figs = [headline(r["summary"], fam) for r in sims]
    g = headline(gcs_run["summary"], fam)
    rows = {}
    for k in sorted(set(g).intersection(*figs)):
        v = np.array([f[k] for f in figs])
        sd = float(v.std(ddof=1))
        z = (
            abs(g[k] - v.mean()) / (sd * math.sqrt(1 + 1 / v.size))
            if sd > 0
            else (0.0 if g[k] == v.mean() else math.inf)
        )
        rows[k] = {"gcs": round(g[k], 6), "simulated": [round(x, 6) for x in v], "z": round(z, 2)}
    z = np.array([r["z"] for r in rows.values()])
    span = {
        "gcs": (gcs_run["summary"].get("validation") or {}).get("duration_h"),
        "simulated": (sims[0]["summary"].get("validation") or {}).get("duration_h"),
    }
    return {
        "campaign": name,
        "reference": prefix,
        "figures": len(rows),
        "within_noise": int((z < T2_95).sum()),
        "validation_span_h": span,
        "median_z": round(float(np.median(z)), 2),
        "worst": sorted(rows, key=lambda k: -rows[k]["z"])[:5],
        "wall_s_gcs": gcs_run["wall_s"],
        "wall_s_simulated": [r["wall_s"] for r in sims],
        "time_scale": FAMILY_TIME_SCALE[fam],
        "rows": rows,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--campaigns", nargs="+", default=["nano1d-thesis", "nano2d-thesis"])
    p.add_argument("--time-scale", type=float, default=500.0)
    p.add_argument("--json", action="store_true")
    p.add_argument(
        "--smoke",
        action="store_true",
        help="CI: nano2d-thesis's training at 2 cycles through the emulator at time scale 2000",
    )
    p.add_argument(
        "--workflow",
        action="store_true",
        help="instead: the small nano1d campaign through Snakemake, gcs vs simulated",
    )
    p.add_argument(
        "--thesis",
        nargs="*",
        metavar="CAMPAIGN",
        help="instead: the whole workflow of these thesis campaigns (default: all three), gcs "
        "against three simulated runs (long: run one at a time, with nice)",
    )
    p.add_argument(
        "--root",
        type=Path,
        default=Path("/tmp/calflow-gcs-thesis"),
        help="work folders of --thesis; a run whose summary exists there is reused",
    )
    p.add_argument(
        "--only", choices=["simulated", "gcs"], help="with --thesis: run only these runs, compare nothing"
    )
    p.add_argument(
        "--matched",
        action="store_true",
        help="with --thesis: also compare with simulated runs given the gcs run's sample period",
    )
    a = p.parse_args(argv)
    if a.smoke:
        r = compare("nano2d-thesis", 2000.0, cycles=2)
        print(json.dumps(r, indent=1) if a.json else r)
        return 0 if r["all_samples"] and r["cells"] > 0 else 1
    if a.thesis is not None:
        names = a.thesis or ["nano2d-thesis", "xytheta-thesis", "nano1d-thesis"]
        if a.only:
            for name in names:
                if a.only == "gcs":
                    thesis_run(name, "gcs", a.root, "gcs")
                else:
                    for s in (None, 101, 202):
                        thesis_run(
                            name, "simulated" if s is None else f"simulated-{s}", a.root, "simulated", s
                        )
            return 0
        results = [
            compare_thesis(name, a.root, matched=m) for name in names for m in (False, True)[: 1 + a.matched]
        ]
        print(json.dumps(results, indent=1) if a.json else "\n".join(map(str, results)))
        return 0
    if a.workflow:
        r = workflow_small_nano1d(Path("/tmp/calflow-gcs-workflow"))
        print(json.dumps(r, indent=1) if a.json else r)
        return 0
    results = [
        compare_xytheta(name, min(a.time_scale, 100.0))
        if name.startswith("xytheta")
        else compare(name, a.time_scale)
        for name in a.campaigns
    ]
    print(json.dumps(results, indent=1) if a.json else "\n".join(map(str, results)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
