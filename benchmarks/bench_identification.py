#!/usr/bin/env python
"""Cost of the XYΘ identification (issue 15): the five models of a campaign and 100 000 poses.

* ``five_models_1200_ms``: what ``calflow identify`` computes for Models I–V of
  ``xytheta-thesis`` from its 1200-pose identification run, summed over the models —
  the fit with the campaign's robust screening, the identifiability and observability
  diagnostics, the fit quality with its k-fold cross-validation, Model III's position
  table lookups and Models IV–V's angle tables built from their sweeps. Reading the
  campaign file and the netCDF inputs and writing the model file are left out (read once
  beforehand, not written); ``five_models_1200_io_ms`` is the whole step with them.
  Needs a finished run of the campaign (``--results``, default ``results/xytheta-thesis``).
* ``model_ii_100k_s``: Model II identified (with the default robust screening) from
  100 000 poses over the campaign's identification workspace, the tool points from
  Eq. (4.18) at Table 4.6's geometry with 0.5 µm noise per reading and axis and 0.1 %
  misread pattern periods; ``model_ii_100k_peak_mb`` the peak of Python's traced
  allocations (tracemalloc, numpy's included) during that identification.

* ``sigma_ratio_crlb_model_ii``: per parameter, the Monte-Carlo spread of Model II's
  estimate over ``--mc-seeds`` simulated campaigns (100 poses, 0.5 µm sensor noise, the
  thesis rig with every error Model II lacks switched off) divided by the RMS of each
  campaign's Cramér–Rao bound (target ≤ 1.1).

Times are the minimum over ``--repeats`` of the wall clock, and (``*_cpu_*``) of the
process's CPU time, which a machine shared with other work inflates less; the load
average is printed with them. ``--json`` prints one JSON line.

    .venv/bin/python benchmarks/bench_identification.py --json --results results/xytheta-thesis
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
import tracemalloc
from argparse import Namespace
from pathlib import Path
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_montecarlo import machine  # noqa: E402

CAMPAIGN = "xytheta-thesis"


def _step_args(results: Path, campaign: Path, name: str, spec: dict, out: Path) -> Namespace:
    """The arguments the workflow's identify rule gives ``calflow identify`` (rules/common.smk)."""
    args = Namespace(
        campaign=str(campaign),
        model_name=name,
        run=str(results / "runs/identification.nc"),
        luts=None,
        base=None,
        residuals=None,
        out=str(out / f"{name}.nc"),
    )
    if "base" in spec:
        args.base = str(out / f"{spec['base']}.nc")
        args.residuals = str(results / f"runs/angle_residuals_{spec['base']}.nc")
    elif spec.get("position_table"):
        args.luts = str(results / "luts/position.nc")
    return args


def _best(fn, repeats: int) -> tuple[float, float]:
    """Minimum wall time and minimum CPU time (s) of ``fn`` over ``repeats`` calls."""
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu)


def five_models(results: Path, repeats: int) -> dict:
    """ms per model of the identify step without file I/O, and the whole step with it."""
    from calflow.configuration.campaign import load as load_campaign
    from calflow.data.io import open_dataset
    from calflow.xytheta import steps as commands
    from calflow.xytheta.models.ladder import MicroModel

    campaign = ROOT / "config/campaigns" / f"{CAMPAIGN}.yaml"
    c = load_campaign(campaign)  # the step hook gets the loaded campaign (identify(c, args))
    models = c["models"]
    if not (results / "runs/identification.nc").exists():
        raise SystemExit(
            f"{results}: no runs/identification.nc; run the {CAMPAIGN} campaign first "
            f"(snakemake --cores 2 results/{CAMPAIGN}/summary.json) or pass --results"
        )
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        args = {name: _step_args(results, campaign, name, spec, out) for name, spec in models.items()}
        for a in args.values():  # bases first (the campaign's order), also warms the imports
            commands.identify(c, a)
        io_ms = {
            name: 1e3 * _best(lambda a=a: commands.identify(c, a), repeats)[0] for name, a in args.items()
        }
        datasets, bases = {}, {}

        def cached_open(path, kind=None):
            key = (str(path), kind)
            if key not in datasets:
                datasets[key] = open_dataset(path, kind=kind).load()
            return datasets[key]

        read = MicroModel.read  # the step is handed the loaded campaign: nothing to cache there
        for a in args.values():
            if a.base:
                bases[a.base] = read(a.base)
        compute_ms = {}
        with (
            mock.patch.object(commands, "open_dataset", cached_open),
            mock.patch.object(MicroModel, "read", classmethod(lambda cls, path: bases[str(path)])),
            mock.patch.object(MicroModel, "write", lambda self, path, meta: None),
        ):
            for name, a in args.items():
                commands.identify(c, a)  # fill the cache
                compute_ms[name] = [1e3 * v for v in _best(lambda a=a: commands.identify(c, a), repeats)]
    return {
        "compute_ms": {k: v[0] for k, v in compute_ms.items()},
        "compute_cpu_ms": {k: v[1] for k, v in compute_ms.items()},
        "io_ms": io_ms,
    }


def model_ii(n: int, repeats: int, seed: int = 1) -> dict:
    """Seconds and traced peak MB of a Model II identification from ``n`` poses."""
    from calflow.configuration.campaign import load as load_campaign
    from calflow.identification.robust import Robust
    from calflow.xytheta.models.identification import identify
    from calflow.xytheta.models.kinematics import Parameters, forward
    from calflow.xytheta.stage.physics import XYThetaTruth

    p = load_campaign(ROOT / "config/campaigns" / f"{CAMPAIGN}.yaml")["identification"]
    rng = np.random.default_rng(seed)
    X, Y, theta = (rng.uniform(*p[k], n) for k in ("x_um", "y_um", "theta_deg"))
    x, y = forward(X, Y, theta, XYThetaTruth().parameters)
    e = rng.normal(0.0, 0.5, (2, n))
    gross = (rng.random(n) < 0.001) * 8.0 * rng.choice([-1.0, 1.0], n)
    P_mx, P_my = x + 20.0 + e[0] + gross, y - 400.0 + e[1]
    initial, robust = Parameters(**p["initial"]), Robust.from_config(p["robust"])

    def run():
        return identify(X, Y, theta, P_mx, P_my, initial=initial, robust=robust)

    res = run()
    seconds, cpu = _best(run, repeats)
    plain = _best(lambda: identify(X, Y, theta, P_mx, P_my, initial=initial), repeats)[0]
    tracemalloc.start()
    run()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {
        "s": seconds,
        "cpu_s": cpu,
        "plain_s": plain,
        "peak_mb": peak / 2**20,
        "rejected": len(res.rejected),
        "expected_rejected": int(np.count_nonzero(gross)),
    }


def crlb_ratio(seeds: int, noise_um: float = 0.5, poses: int = 100) -> dict:
    """Monte-Carlo σ_empirical / Cramér–Rao bound of Model II over ``seeds`` simulated
    campaigns on the thesis rig with every error Model II does not represent switched off
    (the stage's repeatability and the angle reading's noise stay)."""
    from calflow.configuration.campaign import load as load_campaign
    from calflow.xytheta.stage.physics import options_off
    from calflow.xytheta.studies.aggregate import aggregate
    from calflow.xytheta.studies.montecarlo import run_point

    c = load_campaign(ROOT / "config/campaigns" / f"{CAMPAIGN}.yaml")
    pts = [
        run_point(c, s, noise_um, poses, "II", validation_cycles=2, rig_options=options_off())
        for s in range(seeds)
    ]
    cell = aggregate(pts)["cells"][0]
    return {k: round(v["sigma_ratio_crlb"], 3) for k, v in cell["parameters"].items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON line")
    ap.add_argument("--results", type=Path, default=ROOT / "results" / CAMPAIGN)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--poses", type=int, default=100_000)
    ap.add_argument(
        "--mc-seeds", type=int, default=200, help="Monte-Carlo seeds of sigma_ratio_crlb (0: skip)"
    )
    ap.add_argument(
        "--smoke",
        action="store_true",
        help="small sizes (2000 poses, 2 seeds, one repeat), for CI; the five models only when "
        "--results holds a finished run",
    )
    a = ap.parse_args()
    if a.smoke:
        a.repeats, a.poses, a.mc_seeds = 1, 2000, 2
    have = (a.results / "runs/identification.nc").exists()
    five = five_models(a.results, a.repeats) if have or not a.smoke else None
    big = model_ii(a.poses, max(1, a.repeats // 2))
    out = {
        **(
            {
                "five_models_1200_ms": round(sum(five["compute_ms"].values()), 1),
                "five_models_1200_per_model_ms": {k: round(v, 1) for k, v in five["compute_ms"].items()},
                "five_models_1200_cpu_ms": round(sum(five["compute_cpu_ms"].values()), 1),
                "five_models_1200_io_ms": round(sum(five["io_ms"].values()), 1),
            }
            if five
            else {"five_models_1200_ms": f"not measured: {a.results} holds no finished run"}
        ),
        "model_ii_100k_s": round(big["s"], 3),
        "model_ii_100k_cpu_s": round(big["cpu_s"], 3),
        "model_ii_100k_plain_s": round(big["plain_s"], 3),
        "model_ii_100k_peak_mb": round(big["peak_mb"], 1),
        "model_ii_100k_rejected": big["rejected"],
        "model_ii_100k_gross_errors": big["expected_rejected"],
        "poses": a.poses,
        "sigma_ratio_crlb_model_ii": crlb_ratio(a.mc_seeds) if a.mc_seeds else None,
        "mc_seeds": a.mc_seeds,
        "max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "load_average": [round(v, 1) for v in os.getloadavg()],
        "machine": machine(),
    }
    if a.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
