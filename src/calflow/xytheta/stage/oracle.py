"""The rig's own floor at the held-out targets: a validation through the simulated truth.

Test and report use only (the summary step, like its truth block): the held-out targets
are commanded through the simulated rig's *exact* inverse (:meth:`XYThetaTruth.exact_inverse`),
so what remains is what no calibration can remove — stage repeatability, sensor noise
(from rendered frames and the decoder when the rig reads through images), the
approach-dependent effects the exact inverse does not know. Its ISO 9283 RP is the
floor a model's held-out accuracy is compared with. Analysis code never imports this.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.xytheta.tables.position import infer_directions


def oracle_validation(truth: dict, run: xr.Dataset, seed: int) -> dict:
    """ISO 9283 AP and RP (µm, maxima over targets) of the held-out targets of ``run``
    commanded through the exact inverse of the rig whose truth dict is ``truth``."""
    from dataclasses import fields

    from calflow.acquisition.runner import acquire
    from calflow.data.runs import RunMetadata
    from calflow.xytheta.evaluation import xytheta_validation_metrics
    from calflow.xytheta.models.kinematics import inverse as nominal_inverse
    from calflow.xytheta.plans.poses import validation
    from calflow.xytheta.stage.physics import XYThetaTruth
    from calflow.xytheta.stage.rig import simulated_xytheta

    physics = {f.name: truth[f.name] for f in fields(XYThetaTruth) if f.name in truth}
    sensor = {
        k: v for k, v in (truth.get("sensor") or {}).items() if v is not None
    }  # images: the same camera
    rig = simulated_xytheta(seed=seed, stream="validation_oracle", **physics, **sensor)
    t = rig.truth_model
    visits = run["pose"].values > 0
    poses = run["pose"].values[visits]
    first = np.unique(poses, return_index=True)[1]
    targets = np.column_stack([run[f"target_{a}"].values[visits][first] for a in ("x", "y", "theta")])
    cycles = int(np.bincount(poses).max())
    x0, y0, _ = t.tool_point(0.0, 0.0, 0.0, 1, 1)  # the world frame is the home pose's (Eq. 4.27)

    def exact(x, y, theta):
        X0, Y0 = nominal_inverse(x, y, theta, t.parameters)
        return t.exact_inverse(
            x + x0, y + y0, theta, infer_directions(X0), infer_directions(Y0), infer_directions(theta)
        )

    meta = RunMetadata(
        campaign="oracle", robot="xytheta", source="simulated", plan="validation", config_sha256="0" * 64
    )
    try:
        result = acquire(validation(exact, targets, cycles, dwell_s=0.0), rig, meta)
    finally:
        rig.close()
    m = xytheta_validation_metrics(result, meta)
    return {
        "accuracy_um": float(m.attrs["accuracy_um"]),
        "floor_um": float(m.attrs["repeatability_um"]),
        "cycles": cycles,
        "n_targets": int(len(targets)),
    }
