"""The linear stage's step hooks, each ``hook(c, args)`` (calflow.family_contract)."""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.commands.common import meta
from calflow.data.io import open_dataset, write_dataset
from calflow.errors import ConfigError
from calflow.metrics.iso9283 import iso9283
from calflow.summary_routing import route


def check(c, args) -> None:
    if c["validation"]["stroke_um"] > c["identification"]["stroke_um"]:
        raise ConfigError(
            f"{args.campaign}: key 'validation.stroke_um': expected at most identification.stroke_um"
        )


def identify(c, args) -> None:
    """meas_x = (1 + s) cmd_x + b by least squares; the model's s (ppm) and b (µm)."""
    run = open_dataset(args.run, kind="run")
    A = np.column_stack([run["cmd_x"].values, np.ones(run.sizes["sample"])])
    (gain, offset), *_ = np.linalg.lstsq(A, run["meas_x"].values, rcond=None)
    ds = xr.Dataset(
        {
            "scale": xr.Variable((), (gain - 1) * 1e6, {"units": "1e-6", "long_name": "scale error"}),
            "offset": xr.Variable((), offset, {"units": "um", "long_name": "offset"}),
        },
        attrs=meta(c, run.attrs["source"], "identification", args.model_name).attrs("model"),
    )
    write_dataset(ds, args.out)


def metrics(c, args) -> None:
    """ISO 9283 AP and RP (µm) of each pose of the run, as read."""
    run = open_dataset(args.run, kind="run")
    poses = np.unique(run["pose"].values)
    results = [
        iso9283(
            run["target_x"].values[run["pose"].values == k][0], run["meas_x"].values[run["pose"].values == k]
        )
        for k in poses
    ]
    ds = xr.Dataset(
        {
            "ap": xr.Variable(
                ("target",), [r.ap for r in results], {"units": "um", "long_name": "ISO 9283 AP"}
            ),
            "rp": xr.Variable(
                ("target",), [r.rp for r in results], {"units": "um", "long_name": "ISO 9283 RP"}
            ),
        },
        coords={"target": xr.Variable(("target",), poses, {"units": "1", "long_name": "pose"})},
        attrs=meta(c, run.attrs["source"], run.attrs["plan"]).attrs("metrics"),
    )
    write_dataset(ds, args.out)


def summarise(c, args) -> dict:
    found = route(args.files, {"model": "models", "metrics": "metrics", "run": "runs"}, "linear family")
    model = found["models"][0][1]
    m = found["metrics"][0][1]
    return {
        "campaign": c["name"],
        "robot": c["robot"],
        "model": {"scale_ppm": float(model["scale"]), "offset_um": float(model["offset"])},
        "accuracy_um": float(m["ap"].max()),
        "repeatability_um": float(m["rp"].max()),
        "truth": args.truth,
    }


def figures(c, args):
    return [], ["the linear stage draws no figure"]


def headline(summary):
    return {"label": "AP", "key": "accuracy_um", "unit": "µm"}
