"""Designed versus random identification poses on xytheta-thesis (issue 15).

    python benchmarks/bench_design.py [--json] [--cores 2] [--space-filling F] [--criterion D|MV|discrepancy]
        [--time-budget F] [--poses N] [--seed N] [--smoke]

The bound (before acquisition): the Cramér–Rao σ of Model II's parameters of the
``optimal`` plan against the 1200 random poses, under the campaign's noise model, and the
virtual rig time of each. The result (after): the workflow run in a scratch copy of the
project on the same simulated rig and sensor, once with the random plan and once with the
designed one — identification, the angle and position tables, and the held-out validation
of Models II–V, exactly as the default run does them; achieved σ, rig time of the
identification run (its last reading's virtual time) and held-out AP (ISO 9283, max over
the targets) of each model.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("II", "III", "IV", "V")


#: ``--smoke``: xytheta-thesis shortened (the same steps: characterisation, tables, Models
#: II–V, held-out validation), so CI runs the benchmark's path in a minute or two
SMOKE = {
    "characterisation": {"step_um": 50, "cycles": 2},
    "xy_tests": {"compensation": []},
    "identification.poses": 120,
    "observability": {"max_poses": 200, "steps": 3, "repeats": 1},
    "angle_residuals": {"positions": 2, "theta_deg": [0, 5], "step_deg": 0.5, "cycles": 2},
    "validation": {"cycles": 3, "heldout": {"targets": 8, "cycles": 2}},
}


def _thesis_text(seed: int | None, smoke: bool = False) -> str:
    """xytheta-thesis's campaign, with another campaign seed (rig noise, poses, targets) if
    given, shortened (:data:`SMOKE`) for ``--smoke``."""
    text = (ROOT / "config/campaigns/xytheta-thesis.yaml").read_text()
    if smoke:
        import yaml

        body = yaml.safe_load(text)
        for key, value in SMOKE.items():
            section, _, leaf = key.partition(".")
            if leaf:
                body[section][leaf] = value
            else:
                body[section] = {**body.get(section, {}), **value}
        body.pop("reference", None)  # the thesis's values are for its full-size campaign
        text = yaml.safe_dump(body, sort_keys=False)
    if seed is None:
        return text
    lines = [f"seed: {seed}" if line.startswith("seed:") else line for line in text.splitlines()]
    return "\n".join(lines) + "\n"


def _campaign_text(
    space_filling: float,
    criterion: str,
    seed: int | None = None,
    poses: int | None = None,
    time_budget: float | None = None,
    smoke: bool = False,
) -> str:
    extra = "" if poses is None else f", poses: {int(poses)}"
    extra += "" if time_budget is None else f", time_budget: {time_budget}"
    design = f"  plan: optimal\n  design: {{criterion: {criterion}, space_filling: {space_filling}{extra}}}\n"
    return _thesis_text(seed, smoke).replace("identification:\n", "identification:\n" + design, 1)


def _run_workflow(work: Path, campaigns: list[str], cores: int) -> None:
    targets = [f"results/{c}/metrics/validation_heldout_{m}.nc" for c in campaigns for m in MODELS]
    targets += [f"results/{c}/runs/identification.nc" for c in campaigns]
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT / "src"),
        "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}",
    }
    cmd = [
        str(Path(sys.executable).parent / "snakemake"),
        *targets,
        "--cores",
        str(cores),
        "--quiet",
        "all",
        "--config",
        f"campaigns={json.dumps(campaigns)}",
        "studies=[]",
    ]
    subprocess.run(cmd, cwd=work, env=env, check=True, stdout=subprocess.DEVNULL)


def _results(work: Path, campaign: str) -> dict:
    from calflow.data.io import open_dataset

    base = work / "results" / campaign
    run = open_dataset(base / "runs/identification.nc")
    model = open_dataset(base / "models/II.nc")
    return {
        "poses": int(run.sizes["sample"]),
        "rig_time_h": float(run["time"].values[-1]) / 3600.0,
        "design": json.loads(run.attrs["design"]),
        "sigma": {p: float(model[p].attrs["std"]) for p in ("x_R", "y_R", "alpha", "beta")},
        "heldout_ap_um": {
            m: float(open_dataset(base / f"metrics/validation_heldout_{m}.nc").attrs["accuracy_um"])
            for m in MODELS
        },
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--space-filling", type=float, default=0.0)
    ap.add_argument(
        "--criterion",
        default="D",
        help="D, A, MV, O1-O4, or discrepancy (its kernel from the "
        "campaign's characterisation tables, as the workflow makes them)",
    )
    ap.add_argument(
        "--time-budget", type=float, help="design.time_budget: rig time as a fraction of the random plan's"
    )
    ap.add_argument(
        "--poses", type=int, help="designed poses (design.poses) instead of the fewest reaching the bound"
    )
    ap.add_argument("--keep", help="keep the scratch project here")
    ap.add_argument("--smoke", action="store_true", help="CI: xytheta-thesis shortened (SMOKE)")
    ap.add_argument(
        "--seed",
        type=int,
        help="campaign seed (rig noise, random poses, held-out targets) "
        "instead of xytheta-thesis's, for the spread over rigs",
    )
    args = ap.parse_args()
    work = Path(args.keep or tempfile.mkdtemp())
    work.mkdir(parents=True, exist_ok=True)
    try:
        for part in ("Snakefile", "workflow", "config"):
            src = ROOT / part
            if not (work / part).exists():
                (shutil.copytree if src.is_dir() else shutil.copy)(src, work / part)
        (work / "config/campaigns/xytheta-random.yaml").write_text(_thesis_text(args.seed, args.smoke))
        (work / "config/campaigns/xytheta-design.yaml").write_text(
            _campaign_text(
                args.space_filling, args.criterion, args.seed, args.poses, args.time_budget, args.smoke
            )
        )
        t0 = time.perf_counter()
        _run_workflow(work, ["xytheta-random", "xytheta-design"], args.cores)
        wall = time.perf_counter() - t0
        rnd, des = _results(work, "xytheta-random"), _results(work, "xytheta-design")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    b_r, b_d = rnd["design"]["crlb_sigma"]["II"], des["design"]["crlb_sigma"]["II"]
    keys = {"x_R": "x_R_um", "y_R": "y_R_um", "alpha": "alpha_deg", "beta": "beta_deg"}
    out = {
        "random_poses": rnd["poses"] - 1,  # the home row is not one of the drawn poses
        "designed_poses": des["poses"] - 1,
        "criterion": args.criterion,
        "space_filling": args.space_filling,
        "time_budget": args.time_budget,
        "discrepancy": des["design"].get("discrepancy"),
        "sigma_ratio_max": max(b_d[k] / b_r[k] for k in b_d),  # Cramér–Rao σ, Model II
        "sigma_ratio_max_achieved": max(des["sigma"][p] / rnd["sigma"][p] for p in rnd["sigma"]),
        "time_ratio": des["rig_time_h"] / rnd["rig_time_h"],
        "time_ratio_expected": des["design"]["rig_time_h"] / rnd["design"]["rig_time_h"],
        "rig_time_h_random": rnd["rig_time_h"],
        "rig_time_h_designed": des["rig_time_h"],
        "crlb_sigma_random": b_r,
        "crlb_sigma_designed": b_d,
        "sigma_random": {keys[k]: v for k, v in rnd["sigma"].items()},
        "sigma_designed": {keys[k]: v for k, v in des["sigma"].items()},
        "heldout_ap_um_random": rnd["heldout_ap_um"],
        "heldout_ap_um_designed": des["heldout_ap_um"],
        "seed": args.seed,
        "workflow_s": wall,
        "machine": f"{os.cpu_count()} cores",
    }
    out = {k: (float(np.round(v, 6)) if isinstance(v, float) else v) for k, v in out.items()}
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
