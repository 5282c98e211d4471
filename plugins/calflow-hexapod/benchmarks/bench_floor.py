"""Held-out accuracy of the ladder's first models on the simulated hexapod, against its floor.

For the default rig and for ``unmodelled: false``: the calibration replayed in-process
(:func:`calflow_hexapod.stage.error_budget.replay`, 150 random poses, 10 held-out targets × 5 cycles,
seed 1) and the floor through the rig's true parameters. ``--json`` prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import time

from calflow_hexapod.stage import error_budget


def campaign(options: dict, poses: int, seed: int) -> dict:
    return {
        "name": "hexapod-floor",
        "seed": seed,
        "rig": {"factory": "simulated", "options": options},
        "identification": {
            "plan": "random",
            "poses": poses,
            "fraction": 0.7,
            "dwell_s": 1.0,
            "initial": {"tool": [0, 0, 60000, 0, 0, 0]},
        },
        "models": {"nominal": {}, "offsets": {}, "geometric": {}},
        "validation": {"dwell_s": 1.0, "heldout": {"targets": 10, "cycles": 5}},
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--poses", type=int, default=150)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    out, t0 = {}, time.process_time()
    for label, options in (("defaults", {}), ("unmodelled_false", {"unmodelled": False})):
        c = campaign(options, a.poses, a.seed)
        ap = error_budget.replay(c, "none")["ap"]
        out[label] = {
            "max_ap_um": {m: max(v["ap_um"]) for m, v in ap.items()},
            "max_ap_deg": {m: max(v["ap_deg"]) for m, v in ap.items()},
            "floor": error_budget.floor(c),
        }
    out["cpu_s"] = time.process_time() - t0
    print(json.dumps(out) if a.json else json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
