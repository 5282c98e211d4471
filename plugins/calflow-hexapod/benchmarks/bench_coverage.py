#!/usr/bin/env python
"""Coverage of the identified parameters' 95 % intervals on hexapods with only the model's errors.

For each of ``--seeds`` simulated H-811-class hexapods (:mod:`calflow_hexapod.models.synthetic`):
the model's identifiable parameters drawn about the nominal geometry (joint centres 50 µm,
leg offsets 20 µm, leg scales 100 ppm, instrument frames mm and degree; the parameters the
QR analysis fixes stay nominal — the gauge in which the identification reports them),
``--poses`` random poses in half the datasheet travel, the instrument's Gaussian noise
(0.5 µm and 2·10⁻⁵ degree per axis). The model is identified and each parameter's interval
estimate ± 1.96 σ is checked against the truth. Target: 90–99 % of the intervals cover.
``--json`` prints one JSON line.

    .venv/bin/python plugins/calflow-hexapod/benchmarks/bench_coverage.py --json
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from printing import print_figures  # noqa: E402

from calflow_hexapod.models import synthetic  # noqa: E402
from calflow_hexapod.models.geometry import h811  # noqa: E402
from calflow_hexapod.models.identification import identify  # noqa: E402
from calflow_hexapod.models.ladder import LADDER, Parameters  # noqa: E402

SIGMA_POSE = (0.5, 0.5, 0.5, 2e-5, 2e-5, 2e-5)
Z95 = 1.959963984540054


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--model", default="geometric", choices=sorted(LADDER))
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--poses", type=int, default=300)
    ap.add_argument("--sigma-leg-um", type=float, default=0.05, help="the legs' own noise (µm)")
    ap.add_argument(
        "--probe-z-um",
        type=float,
        default=0.0,
        help="the measured target this far above the platform (µm; a 6-D probe: 60000)",
    )
    a = ap.parse_args(argv)
    controller = h811()
    nominal = Parameters.nominal(controller)
    rng = np.random.default_rng(12345)
    probe, lam = synthetic.simulate(
        nominal, synthetic.random_poses(a.poses, rng), controller, rng, SIGMA_POSE
    )
    free = identify(probe, lam, controller.zero_lengths, LADDER[a.model], nominal, sigma_pose=SIGMA_POSE).free
    t0 = time.perf_counter()
    hits, chi2, dropped = [], [], set()
    for seed in range(a.seeds):
        rng = np.random.default_rng(seed)
        truth = synthetic.perturbed(rng, nominal, only=free)
        truth = truth.replace(tool_z=truth.tool[2] + a.probe_z_um)
        measured, lam = synthetic.simulate(
            truth,
            synthetic.random_poses(a.poses, rng),
            controller,
            rng,
            SIGMA_POSE,
            sigma_leg_um=a.sigma_leg_um,
        )
        fit = identify(
            measured,
            lam,
            controller.zero_lengths,
            LADDER[a.model],
            nominal,
            sigma_pose=SIGMA_POSE,
            sigma_leg_um=a.sigma_leg_um,
        )
        dropped.update(fit.dropped)
        est, true = fit.parameters.as_dict(), truth.as_dict()
        hits.append([abs(est[n] - true[n]) <= Z95 * fit.std[n] for n in free])
        chi2.append(fit.chi2_dof)
    hits = np.asarray(hits, dtype=float)
    per = hits.mean(axis=0)
    out = {
        "model": a.model,
        "probe_z_um": a.probe_z_um,
        "seeds": a.seeds,
        "poses": a.poses,
        "free": len(free),
        "intervals": int(hits.size),
        "coverage_95": round(float(hits.mean()), 4),
        "target": [0.90, 0.99],
        "ok": bool(0.90 <= hits.mean() <= 0.99),
        "per_parameter_min": round(float(per.min()), 3),
        "per_parameter_max": round(float(per.max()), 3),
        "chi2_dof_mean": round(float(np.mean(chi2)), 4),
        "dropped": sorted(dropped),
        "seconds": round(time.perf_counter() - t0, 1),
        "load_average": [round(x, 2) for x in os.getloadavg()],
    }
    print_figures(out, a.json)
    return out


if __name__ == "__main__":
    main()
