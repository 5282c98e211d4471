"""What a run adds to a hexapod campaign's rig options (the family's ``rig_options`` hook).

``rig_options(campaign, factory, run_id, options, start_s)``: the simulated rig draws its
noise from (seed, run id) and reads the room profile from the run's campaign time
(``start_offset_s``), so every run of a campaign is reproducible to the byte and sees the
room as it was when the run started; through the ``gcs`` rig the simulated tracker sensor
gets the same seed, stream and start. Kept free of numerical imports.
"""

from __future__ import annotations

from calflow.rigs.simulated.campaign import simulated_options

SENSORS = ("simulated_tracker", "calflow_hexapod.stage.sensor:simulated_tracker")
#: Run ids of the closed-loop runs through an exported bundle, and of the held-out runs.
CLOSED_LOOP, HELDOUT = "closed_loop_", "validation_heldout_"


def noise_stream(run_id: str) -> str:
    """The noise stream of a run on a simulated hexapod: a closed-loop run through a model's
    exported bundle draws the noise of that model's held-out run (common random numbers: the
    two differ only by what the export changes, :mod:`calflow_hexapod.export.verification`);
    every other run draws its own, named by its id."""
    if run_id.startswith(CLOSED_LOOP):
        return HELDOUT + run_id[len(CLOSED_LOOP) :]
    return run_id


def simulated_physics(campaign: dict) -> dict | None:
    """The :class:`~calflow_hexapod.stage.physics.HexapodTruth` overrides of a campaign whose
    hexapod is simulated — the simulated rig's options, or the tracker sensor's options of a
    ``gcs`` rig (an emulated controller) — without seed, stream and pivot; None for a real rig."""
    return simulated_options(campaign, SENSORS, ("seed", "stream", "pivot_um", "start_offset_s"))


def rig_options(c: dict, factory: str, run_id: str, options: dict, start_s: float) -> dict:
    """Per-run options of the simulated hexapod, or of the tracker sensor of a ``gcs`` rig."""
    if factory == "simulated":
        options.setdefault("seed", c["seed"])
        options["stream"] = noise_stream(run_id)
        options.setdefault("start_offset_s", float(start_s))
    elif factory == "gcs":
        sensor = dict(options.get("sensor") or {})
        if sensor.get("factory") in SENSORS:
            sensor["options"] = {
                "seed": c["seed"],
                "start_offset_s": float(start_s),
                **(sensor.get("options") or {}),
                "stream": noise_stream(run_id),
            }
            options["sensor"] = sensor
    return options
