"""Coverage of Model III's 95 % intervals on a rig whose only errors Model III represents.

Per seed: characterise X and Y (25 µm steps, 2 cycles), build the XY tables, identify
Model III on 200 random poses, and count whether estimate ± 1.96 σ holds each true
parameter. The rig keeps geometry, lead screw, backlash and coupling (what the XY tables
hold); `--with-slides` adds the guides' scale and straightness, whose linear part cannot
be told from α, β over a sweep.

    .venv/bin/python benchmarks/coverage_model_iii.py [--seeds 60] [--with-slides]
"""

from __future__ import annotations

import argparse
import time

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.xytheta.models import cost
from calflow.xytheta.models.identification import identify
from calflow.xytheta.models.kinematics import Parameters
from calflow.xytheta.models.ladder import joint_directions
from calflow.xytheta.plans import poses as plans
from calflow.xytheta.plans import sweeps
from calflow.xytheta.stage.physics import options_off
from calflow.xytheta.stage.rig import simulated_xytheta
from calflow.xytheta.tables.characterisation import characterise
from calflow.xytheta.tables.position import PositionLUT

PARAMETERS = (("x_R", "x_R_um"), ("y_R", "y_R_um"), ("alpha", "alpha_deg"), ("beta", "beta_deg"))


def meta(plan: str) -> RunMetadata:
    return RunMetadata(
        campaign="coverage", robot="xytheta", source="simulated", plan=plan, config_sha256="0" * 64
    )


def one_seed(seed: int, rig: dict) -> dict[str, bool]:
    runs = {}
    for axis, stop in (("x", 4400.0), ("y", 3200.0)):
        r = simulated_xytheta(seed=seed, stream=f"characterisation_{axis}", **rig)
        runs[axis] = acquire(
            sweeps.characterisation(axis, stop_um=stop, step_um=25.0, cycles=2, dwell_s=0.1),
            r,
            meta(f"characterisation_{axis}"),
        )
    lut = PositionLUT.from_dataset(characterise(runs["x"], runs["y"], meta("characterisation")))
    r = simulated_xytheta(seed=seed, stream="identification", **rig)
    run = acquire(
        plans.identification(200, (0, 4000), (800, 2800), (0, 5), seed=seed), r, meta("identification")
    )
    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(run["meas_x"].values, run["meas_y"].values, theta)
    X, Y = run["cmd_x"].values, run["cmd_y"].values
    ex, ey = lut.errors(X, Y, *joint_directions(X, Y), method="linear", trends=False)
    fit = identify(X, Y, theta, P_mx, P_my, initial=Parameters(10000.0, 8000.0, 180.0, 0.0), ex=ex, ey=ey)
    truth = r.truth()
    return {
        name: abs(getattr(fit.parameters, name) - truth[key]) <= 1.959964 * fit.std[name]
        for name, key in PARAMETERS
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=60)
    p.add_argument("--smoke", action="store_true", help="small sizes for CI: 2 seeds")
    p.add_argument("--with-slides", action="store_true")
    a = p.parse_args()
    if a.smoke:
        a.seeds = 2
    off = [
        "yaw",
        "expansion",
        "theta_scale",
        "theta_periodic",
        "theta_backlash",
        "axis_runout",
        "decode",
        "drift",
    ]
    if not a.with_slides:
        off += ["straightness", "scale"]
    rig = {**options_off(*off), "gross_error_rate": 0.0, "lost_motion": False, "room_swing_degC": 0.0}
    start = time.perf_counter()
    hits = [one_seed(seed, rig) for seed in range(a.seeds)]
    cover = {name: sum(h[name] for h in hits) / len(hits) for name, _ in PARAMETERS}
    print(
        f"Model III, {a.seeds} seeds{' with scale and straightness' if a.with_slides else ''}: "
        + ", ".join(f"{k} {v:.2f}" for k, v in cover.items())
        + f"  ({time.perf_counter() - start:.0f} s)"
    )


if __name__ == "__main__":
    main()
