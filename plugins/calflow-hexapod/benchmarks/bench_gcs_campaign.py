"""The whole hexapod-demo campaign through the C-887 emulator (``rig: gcs``) against the simulated rig.

The method of calflow's reliability benchmark for the XYΘ and nano campaigns
(docs/reliability.md, "What within noise means here"): the campaign
``config/campaigns/hexapod-demo-gcs.yaml`` (hexapod-demo with ``rig: gcs`` on 127.0.0.1,
time scale 200) runs whole through Snakemake against the campaign's C-887 emulator, started
here on 127.0.0.1 (what ``calflow emulate gcs --campaign config/campaigns/hexapod-demo-gcs.yaml
--port 50887 --time-scale 200`` serves); the reference is hexapod-demo on the simulated rig
with the same world, poses and targets and *other* noise (``rig.options.seed`` 101, 202, 303
instead of the campaign's 11; the error budget off, as through the controller). For each
headline figure of the summaries (every number of ``models``: fit, held-out, ISO 9283 and
export figures; counts and settings left out), with m and s the simulated values' mean and
standard deviation, z = |gcs − m| / (s √(1 + 1/n)); the figure is *within noise* when z is
below the two-sided 95 % point of Student's t with n − 1 degrees of freedom (4.30 for n = 3).
Beside it, the gcs run against the simulated run with the *same* noise (seed 11,
``--same results/hexapod-demo/summary.json``): the controller path alone.

    .venv/bin/python plugins/calflow-hexapod/benchmarks/bench_gcs_campaign.py --json

Runs go to ``results/<campaign>`` of the project (campaign files in ``--campaign-dir``, default
``results/.bench_gcs_campaigns``) and are reused when their summary exists. Long: four whole
campaigns, about 4 min each on a shared two-core machine.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from scipy import stats

ROOT = Path(__file__).resolve().parents[3]
GCS = "hexapod-demo-gcs"
# counts and settings, and the export's figures that restate the held-out ones or are 0 by construction
SKIP = {
    "n_targets",
    "cycles",
    "free",
    "n_poses",
    "rejected_poses",
    "parameters",
    "command_difference",
    "difference_um",
    "difference_deg",
    "in_process_accuracy_um",
    "tolerance_um",
}


def headline(summary: dict) -> dict[str, float]:
    """Every finite number under ``models`` (lists and SKIP keys left out), by dotted key."""
    out: dict[str, float] = {}

    def walk(d: dict, prefix: str) -> None:
        for k, v in d.items():
            key = f"{prefix}.{k}"
            if k in SKIP:
                continue
            if isinstance(v, dict):
                walk(v, key)
            elif isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                out[key] = float(v)

    walk(summary["models"], "models")
    return out


def campaigns(folder: Path, seeds: list[int]) -> list[str]:
    """Write the gcs campaign and the simulated reference campaigns into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{GCS}.yaml").write_text((ROOT / "config" / "campaigns" / f"{GCS}.yaml").read_text())
    base = yaml.safe_load((ROOT / "config" / "campaigns" / "hexapod-demo.yaml").read_text())
    base["validation"]["heldout"].pop("error_budget", None)
    names = []
    for seed in seeds:
        c = json.loads(json.dumps(base))
        c["rig"] = {"factory": "simulated", "options": {"seed": seed}}
        names.append(f"hexapod-demo-noise{seed}")
        (folder / f"{names[-1]}.yaml").write_text(yaml.safe_dump(c, sort_keys=False))
    return names


def run(name: str, folder: Path) -> tuple[dict, float | None]:
    """The campaign's summary, after running it through Snakemake unless it exists."""
    summary = ROOT / "results" / name / "summary.json"
    wall = None
    if not summary.exists():
        t0 = time.monotonic()
        subprocess.run(
            [
                str(Path(sys.executable).parent / "snakemake"),
                f"results/{name}/summary.json",
                "--cores",
                "1",
                "--config",
                f"campaign_dir={folder}",
                f"campaigns=[{name!r}]",
                "studies=[]",
            ],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
        wall = time.monotonic() - t0
    return json.loads(summary.read_text()), wall


def compare(gcs: dict, sims: list[dict], same: dict | None) -> dict:
    g, figs = headline(gcs), [headline(s) for s in sims]
    t95 = float(stats.t.ppf(0.975, len(sims) - 1))
    s_same = headline(same) if same else {}
    rows = {}
    for k in sorted(set(g).intersection(*figs)):
        v = np.array([f[k] for f in figs])
        sd = float(v.std(ddof=1))
        if sd > 0:
            z = abs(g[k] - v.mean()) / (sd * math.sqrt(1 + 1 / v.size))
        else:
            z = 0.0 if g[k] == v.mean() else math.inf
        rows[k] = {"gcs": g[k], "simulated": v.tolist(), "z": z, "same_noise": s_same.get(k)}
    z = np.array([r["z"] for r in rows.values()])
    outside = [k for k in rows if rows[k]["z"] >= t95]
    same_diff = {
        k: abs(rows[k]["gcs"] - rows[k]["same_noise"]) / max(abs(rows[k]["gcs"]), 1e-300)
        for k in rows
        if rows[k]["same_noise"] is not None
    }
    return {
        "figures": len(rows),
        "outside_noise": outside,
        "largest_relative_difference_to_same_noise": max(same_diff.values(), default=None),
        "outside_noise_relative_difference_to_same_noise": {k: same_diff.get(k) for k in outside},
        "within_noise": int((z < t95).sum()),
        "t95": t95,
        "median_z": float(np.median(z)),
        "worst": sorted(rows, key=lambda k: -rows[k]["z"])[:6],
        "rows": rows,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, nargs="+", default=[101, 202, 303])
    p.add_argument("--campaign-dir", default=str(ROOT / "results" / ".bench_gcs_campaigns"))
    p.add_argument("--same", default=str(ROOT / "results" / "hexapod-demo" / "summary.json"))
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    from calflow.configuration.campaign import load as load_campaign
    from calflow_hexapod.stage.emulate import campaign_emulator

    folder = Path(a.campaign_dir)
    names = campaigns(folder, a.seeds)
    walls = {}
    sims = []
    for name in names:
        s, walls[name] = run(name, folder)
        sims.append(s)
    c = load_campaign(folder / f"{GCS}.yaml")
    o = c["rig"]["options"]
    emu = campaign_emulator(c, port=int(o["port"]), time_scale=float(o["time_scale"])).start()
    try:
        gcs, walls[GCS] = run(GCS, folder)
    finally:
        emu.stop()
    same = json.loads(Path(a.same).read_text()) if Path(a.same).exists() else None
    out = {"seeds": a.seeds, "wall_s": walls, **compare(gcs, sims, same)}
    print(json.dumps(out) if a.json else json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
