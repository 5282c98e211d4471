"""A hexapod calibration through the C-887 emulator (``rig: gcs``) against the simulated rig.

The same small campaign — identification, the models ``nominal``, ``offsets`` and
``geometric``, held-out validation — is run twice with the same seed and streams: on the
simulated rig in-process (:func:`calflow_hexapod.stage.error_budget.replay_heldout`) and through
the ``gcs`` rig driving a C-887 emulator (:mod:`calflow_hexapod.stage.emulate`) whose tracker sensor
carries the same physics. The run-to-run spread is that of the simulated campaign over
``--spread`` other noise seeds on the same rig (same ``geometry_seed``): the per-model standard
deviation of the RMS held-out AP. The emulated run agrees when |gcs − simulated| is within
twice that spread. ``--json`` prints one JSON line last.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from calflow_hexapod.models.geometry import AXES
from calflow_hexapod.stage import error_budget
from calflow_hexapod.stage.emulate import campaign_emulator, rig_options
from calflow_hexapod.stage.run_options import rig_options as run_rig_options


def campaign(seed: int, poses: int) -> dict:
    return {
        "name": "hexapod-agreement",
        "seed": seed,
        "rig": {"factory": "simulated", "options": {}},
        "identification": {
            "plan": "random",
            "poses": poses,
            "fraction": 0.6,
            "dwell_s": 1.0,
            "initial": {"tool": [0, 0, 60000, 0, 0, 0]},
        },
        "models": {"nominal": {}, "offsets": {}, "geometric": {}},
        "validation": {"dwell_s": 1.0, "heldout": {"targets": 6, "cycles": 3}},
    }


def gcs_acquire(address, time_scale: float):
    """``acquire(campaign, overrides, acquisition)`` through the gcs rig at ``address``."""
    from calflow.gcs.rig import gcs

    def acquire(c: dict, overrides: dict, acquisition) -> dict:
        opts = run_rig_options(
            c, "gcs", acquisition.run_id, rig_options(address, c, time_scale=time_scale), 0.0
        )
        rig = gcs(**opts)
        plan, rows = acquisition.plan, []
        try:
            for i in range(len(plan)):
                rig.move(plan.row(i))
                rig.wait(plan.dwell_s)
                rows.append(rig.read())
        finally:
            rig.close()
        out = {k: np.array([r[k] for r in rows]) for k in rows[0]}
        return {**out, **{f"cmd_{a}": np.asarray(plan.commands[a], dtype=float) for a in AXES}}

    return acquire


def rms(ap: dict) -> dict:
    return {m: float(np.sqrt(np.mean(np.square(v["ap_um"])))) for m, v in ap.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--poses", type=int, default=80)
    p.add_argument("--spread", type=int, default=8, help="other noise seeds for the run-to-run spread")
    p.add_argument("--time-scale", type=float, default=200.0)
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    c = campaign(a.seed, a.poses)
    sim = rms(error_budget.replay_heldout(c, {}))
    others = [rms(error_budget.replay_heldout(c, {"seed": a.seed + 1000 + k})) for k in range(a.spread)]
    spread = {m: float(np.std([o[m] for o in others], ddof=1)) for m in sim}
    emu = campaign_emulator(c, time_scale=a.time_scale).start()
    t0 = time.time()
    try:
        got = rms(error_budget.replay_heldout(c, {}, gcs_acquire(emu.address, a.time_scale)))
    finally:
        emu.stop()
    out = {
        "rms_ap_um": {"simulated": sim, "gcs": got},
        "run_to_run_sd_um": spread,
        "agree": all(abs(got[m] - sim[m]) <= 2 * spread[m] for m in sim),
        "gcs_wall_s": time.time() - t0,
        "machine": "shared two-core machine",
    }
    print(json.dumps(out) if a.json else json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
