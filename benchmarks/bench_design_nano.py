"""Designed versus grid training plans of the nano campaigns (issue 15).

    python benchmarks/bench_design_nano.py [--json] [--campaign nano1d-thesis] [--tests N] [--seed N] [--smoke]

For each plan — the thesis's grid (``training.plan: grid``), the designed plan with its
default sizing (``optimal``: D-optimal positions, the fewest cycles whose Cramér–Rao σ of
the geometric correction matches the grid's, ending when validation starts), and the
designed positions over the grid's duration (``optimal`` with ``min_training_h`` = the
grid's time) — the campaign is run as ``calflow`` does it on the same simulated rig: the
training run, the single and KMZ models (1-DoF) or Eq. (5.10) (2-DoF), the validation
through the run-time controllers, its metrics. Reported per plan: training time (h), the
bound before (σ of the geometric correction over the stroke, nm), the achieved σ of the
geometric coefficients (stepwise standard errors) beside their bound, and the held-out
accuracy of each model on the validation (max AP over every pose of every test of the
mode, and over the positions training never visited), nm. ``--tests`` shortens the
validation (default: the campaign's own, five days for nano1d-thesis). ``study``: the
design study of :func:`calflow.nano.plans.designed.design_study` (σ after an hour and hours
for the grid's σ, against the count of positions, grid against designed; no acquisition).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _calflow(*args: str, cwd: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    subprocess.run(
        [sys.executable, "-m", "calflow", *args], cwd=cwd, env=env, check=True, stdout=subprocess.DEVNULL
    )


def _variant(text: str, training: str, tests: int | None, seed: int | None = None) -> str:
    """The campaign text with ``training`` keys added to its training mapping (flow style in the
    thesis files), ``tests`` validation tests and another campaign ``seed`` (rig noise, room) if given."""
    lines = []
    for line in text.splitlines():
        if seed is not None and line.startswith("seed:"):
            line = f"seed: {seed}"
        if line.startswith("training: {") and training:
            line = line.rstrip()[:-1] + ", " + training + "}"
        if tests is not None and line.strip().startswith("tests:"):
            indent = line[: len(line) - len(line.lstrip())]
            line = f"{indent}tests: {tests}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def _run(work: Path, name: str, text: str, two_dof: bool) -> dict:
    from calflow.configuration.campaign import load as load_campaign
    from calflow.data.io import open_dataset
    from calflow.nano.models.registry import model_from_dataset
    from calflow.nano.report.summary import heldout_block, mode_block

    path = work / f"{name}.yaml"
    path.write_text(text)
    c = str(path)
    _calflow("acquire", "--campaign", c, "--plan", "training", "--out", f"{name}-training.nc", cwd=work)
    names = ["two_dof"] if two_dof else ["single", "adaptive_kmz"]
    for m in names:
        _calflow(
            "identify",
            "--campaign",
            c,
            "--model-name",
            m,
            "--run",
            f"{name}-training.nc",
            "--out",
            f"{name}-{m}.nc",
            cwd=work,
        )
    models = [a for m in names for a in ("--model", f"{name}-{m}.nc")]
    _calflow(
        "acquire",
        "--campaign",
        c,
        "--plan",
        "validation",
        *models,
        "--out",
        f"{name}-validation.nc",
        cwd=work,
    )
    for run in ("training", "validation"):
        _calflow(
            "metrics",
            "--campaign",
            c,
            "--run",
            f"{name}-{run}.nc",
            "--out",
            f"{name}-{run}-metrics.nc",
            cwd=work,
        )
    campaign = load_campaign(path)
    run = open_dataset(work / f"{name}-training.nc")
    record = json.loads(run.attrs["design"])
    val, train = (open_dataset(work / f"{name}-{r}-metrics.nc") for r in ("validation", "training"))
    tests, _ = mode_block(val)
    heldout_block(val, train, tests)
    table = model_from_dataset(open_dataset(work / f"{name}-{names[0]}.nc")).coefficients
    achieved = {
        r["name"]: (float(r["std_error"]) if r["in_model"] else None)
        for r in table.to_dict(orient="records")
        if r["name"] in record["crlb_sigma"]
    }
    return {
        "positions": record["positions"],
        "cycles": record["cycles"],
        "training_h": record["rig_time_h"],
        "training_start_h": record["start_h"],
        "bound_shape_sigma_nm": record["crlb_shape_sigma_nm"],
        "bound_sigma": record["crlb_sigma"],
        "achieved_sigma": achieved,
        "achieved_to_bound_max": max(
            achieved[k] / record["crlb_sigma"][k] for k in achieved if achieved[k] is not None
        ),
        "heldout_ap_nm": {m: t["max_accuracy_nm"] for m, t in tests.items()},
        "heldout_unvisited_ap_nm": {m: t.get("heldout_max_accuracy_nm") for m, t in tests.items()},
        "validation_tests": int(campaign["validation"]["tests"]),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", action="store_true", help="print the figures as one JSON line")
    p.add_argument("--campaign", default="nano1d-thesis", help="a nano campaign of config/campaigns")
    p.add_argument("--tests", type=int, default=None, help="validation tests (default: the campaign's)")
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="another campaign seed: rig noise and room (default: the campaign's)",
    )
    p.add_argument(
        "--smoke",
        action="store_true",
        help="CI: nano2d-thesis with 2 training cycles and two validation tests of 3 cycles",
    )
    args = p.parse_args()
    sys.path.insert(0, str(ROOT / "src"))
    if args.smoke:
        args.campaign, args.tests = (
            "nano2d-thesis",
            2,
        )  # one test of each mode (order: no_calibration, single)
    text = (ROOT / "config" / "campaigns" / f"{args.campaign}.yaml").read_text()
    if args.smoke:  # the same plans and models, on a short training and validation
        text = text.replace("cycles: 12,", "cycles: 2,").replace("\n  cycles: 20\n", "\n  cycles: 3\n")
        assert "cycles: 2," in text and "\n  cycles: 3\n" in text, (
            "nano2d-thesis.yaml changed: update --smoke"
        )
    two_dof = "robot: stage2d" in text
    out = {"campaign": args.campaign, "seed": args.seed}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        grid = _run(work, "grid", _variant(text, "", args.tests, args.seed), two_dof)
        designed = _run(work, "optimal", _variant(text, "plan: optimal", args.tests, args.seed), two_dof)
        equal = _run(
            work,
            "optimal_equal_time",
            _variant(
                text,
                f"plan: optimal, design: {{min_training_h: {grid['training_h']:.6f}}}",
                args.tests,
                args.seed,
            ),
            two_dof,
        )
    from calflow.configuration.campaign import load as load_campaign
    from calflow.nano.plans.designed import design_study

    c = load_campaign(ROOT / "config" / "campaigns" / f"{args.campaign}.yaml")
    counts = (16, 25, 36, 49, 64, 81) if two_dof else (4, 6, 8, 12, 17, 24, 33)
    counts = counts[:2] if args.smoke else counts
    out.update(
        grid=grid,
        optimal=designed,
        optimal_equal_time=equal,
        time_ratio=designed["training_h"] / grid["training_h"],
        study=design_study(c, counts),
    )
    if args.json:
        print(json.dumps(out))
        return
    for name in ("grid", "optimal", "optimal_equal_time"):
        r = out[name]
        print(
            f"{name}: {r['positions']} positions x {r['cycles']} cycles = {r['training_h']:.1f} h; bound "
            f"{r['bound_shape_sigma_nm']:.2f} nm; achieved/bound max {r['achieved_to_bound_max']:.1f}; "
            f"AP {r['heldout_ap_nm']} nm; unvisited {r['heldout_unvisited_ap_nm']} nm"
        )


if __name__ == "__main__":
    main()
