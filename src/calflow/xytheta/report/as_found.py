"""As found and as left in an XYΘ calibration's summary (docs/lifecycle.md, "As found, as left").

* ``models.<M>.as_left = {accuracy_um, repeatability_um, date}`` for every model with a
  held-out validation: ISO 9283 AP and RP (max over the held-out targets, Sec. 7.2.1 and
  7.2.2 of ISO 9283) through the model this campaign identified — what the stage is left
  with — dated at the end of that run;
* ``models.<M>.as_found = {accuracy_um, repeatability_um, date, reference}`` for the model in
  use, when the campaign has an ``as_found`` section: the same targets through the earlier
  calibration's (``reference``) exported bundle of ``M``, dated at the start of that run —
  before anything was adjusted (:mod:`calflow.xytheta.plans.as_found`). The same block is
  the summary's top-level ``as_found`` with its ``model``, so it is there when this
  campaign does not identify ``M`` again.

Dates are ISO 8601 instants: the campaign's ``start`` plus the run's time axis (seconds of
rig time since the start).
"""

from __future__ import annotations

import datetime as dt

import numpy as np

from calflow.data.io import jsonable


def _date(campaign: dict, run, last: bool) -> str:
    """ISO instant of a run's first (or last) reading: the campaign start plus its time."""
    t0 = dt.datetime.fromisoformat(str(campaign["start"]).replace("Z", "+00:00"))
    if run is None or "time" not in run:
        return t0.isoformat()
    t = np.asarray(run["time"].values)
    if np.issubdtype(t.dtype, np.datetime64):
        t = (t - t.min()).astype("timedelta64[ns]").astype(float) / 1e9
    t = t.astype(float)
    t = t[np.isfinite(t)]
    if t.size == 0:
        return t0.isoformat()
    return (t0 + dt.timedelta(seconds=float(t.max() if last else t.min()))).isoformat()


def add(summary: dict, campaign: dict, found: dict) -> None:
    """Write ``as_left`` per model and ``as_found`` (module docstring) into ``summary``;
    ``found`` is the campaign's result files routed by section."""
    runs = {ds.attrs.get("model"): ds for _, ds in found.get("heldout_runs", [])}
    for name, m in summary["models"].items():
        if m.get("protocol") == "heldout" and m.get("accuracy_um") is not None:
            m["as_left"] = {
                "accuracy_um": m["accuracy_um"],
                "repeatability_um": m.get("repeatability_um"),
                "date": _date(campaign, runs.get(name), last=True),
            }
    spec = campaign.get("as_found")
    metrics = [ds for _, ds in found.get("as_found", [])]
    if not spec or not metrics:
        return
    run = next((ds for _, ds in found.get("as_found_runs", [])), None)
    ds = metrics[0]
    block = {
        "accuracy_um": jsonable(float(ds.attrs["accuracy_um"])),
        "repeatability_um": jsonable(float(ds.attrs["repeatability_um"])),
        "date": _date(campaign, run, last=False),
        "reference": spec["reference"],
    }
    summary["as_found"] = {
        "model": spec["model"],
        **block,
        "targets": int(ds.sizes.get("target", 0)),
        "definition": (
            "ISO 9283 AP and RP (max over the campaign's held-out targets) through the exported bundle "
            "of the reference calibration's model, measured before this calibration adjusted anything"
        ),
    }
    if spec["model"] in summary["models"]:
        summary["models"][spec["model"]]["as_found"] = block
