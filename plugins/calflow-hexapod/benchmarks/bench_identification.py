#!/usr/bin/env python
"""Cost of the hexapod identification: the full geometric model from 1 000 poses.

``geometric_1000_ms``: :func:`calflow_hexapod.models.identification.identify` of the ``geometric``
model (frames, joints and leg offsets, reduced to its identifiable set by the QR analysis —
included in the time) from 1 000 poses of a simulated H-811-class hexapod with only the
model's errors and instrument noise (0.5 µm, 2·10⁻⁵ degree per axis); ``scale_1000_ms``
the same with the leg scales. Minimum over ``--repeats`` of the wall clock, and (``*_cpu_ms``)
of the process's CPU time, which a shared machine inflates less; the load average is printed.
BLAS runs single-threaded unless ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` say otherwise:
at this size threads only contend (on a loaded two-core machine a threaded QR of the
6 000 × 54 Jacobian took a second). ``--json`` prints one JSON line.

    .venv/bin/python plugins/calflow-hexapod/benchmarks/bench_identification.py --json
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


def _best(fn, repeats: int) -> tuple[float, float, object]:
    """Minimum wall and CPU time (ms) of ``fn`` over ``repeats`` calls, and its last result."""
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return 1e3 * min(wall), 1e3 * min(cpu), out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--poses", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    controller = h811()
    nominal = Parameters.nominal(controller)
    truth = synthetic.perturbed(rng, nominal)
    measured, lam = synthetic.simulate(
        truth, synthetic.random_poses(a.poses, rng), controller, rng, SIGMA_POSE
    )
    out = {"poses": a.poses, "repeats": a.repeats, "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}
    for model in ("geometric", "scale"):
        wall, cpu, fit = _best(
            lambda m=model: identify(
                measured, lam, controller.zero_lengths, LADDER[m], nominal, sigma_pose=SIGMA_POSE
            ),
            a.repeats,
        )
        out[f"{model}_{a.poses}_ms"] = round(wall, 1)
        out[f"{model}_{a.poses}_cpu_ms"] = round(cpu, 1)
        out[f"{model}_free"] = len(fit.free)
        out[f"{model}_nfev"] = fit.nfev
    out["load_average"] = [round(x, 2) for x in os.getloadavg()]
    out["cpus"] = os.cpu_count()
    print_figures(out, a.json)
    return out


if __name__ == "__main__":
    main()
