"""What the hexapod's certificate figures are measured from, and its laser tracker's budget.

Each model's held-out position AP and RP (ISO 9283, max over the held-out targets, µm).
The tracker's declared terms, from its specification under ISO 10360-10:2021 (Leica
AT960 manual; the MPEs in :mod:`calflow_hexapod.stage.tracker`), at the station distance D
the campaign states (rig option ``tracker_distance_m``, 1.5 m when it states none):

* the ADM's random error along the beam, (10 µm + 0.3 µm/m · D)/4, and the transverse
  random error, (15 µm + 6 µm/m · D)/4, per reading (in the observed scatter), and the
  0.1 µm display resolution;
* the angle encoders' systematic error, the same at every visit of a point but different
  between points: the specification does not split the transverse MPE into random and
  systematic parts, so its whole MPE/4 is taken as systematic per target — a conservative
  reading, said so on the certificate.

The orientation figures (``accuracy_u_deg`` …) are stated without U.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.certificate import Measurement
from calflow.metrics.uncertainty import Term

AXES = ("x", "y", "z")
DISTANCE_M = 1.5  # station distance when the campaign states none


def tracker_terms(distance_m: float) -> tuple[Term, ...]:
    """The tracker's terms (µm) at station distance ``distance_m``."""
    adm = (10.0 + 0.3 * distance_m) / 4.0
    transverse = (15.0 + 6.0 * distance_m) / 4.0
    return (
        Term("tracker ADM, random", adm, scope="reading"),
        Term("tracker transverse, random", transverse, scope="reading"),
        Term("tracker resolution", 0.1 / math.sqrt(12.0), scope="reading"),
        Term("tracker angle encoders, systematic (transverse MPE/4)", transverse, scope="target"),
    )


#: The tracker's chain to the SI metre (the certificate's traceability statement).
TRACEABILITY = (
    "the laser tracker's length measurement, verified to ISO 10360-10:2021 (its verification certificate: "
    "not recorded in the campaign)",
)
NOTES = (
    "the tracker's transverse MPE is not split into random and systematic parts: its whole MPE/4 "
    "enters as a systematic error per target (conservative)",
)


def measurements(campaign: dict, files: list[str]) -> list[Measurement]:
    """Each model's held-out position figures with the tracker's terms."""
    from calflow.summary_routing import route
    from calflow_hexapod.family import FAMILY

    options = (campaign.get("rig") or {}).get("options") or {}
    distance = float(options.get("tracker_distance_m", DISTANCE_M))
    out = []
    for _, run in route(files, FAMILY.summary_sections, "hexapod family").get("heldout_runs", []):
        pose = np.asarray(run["pose"].values, dtype=int)
        meas = np.stack([np.asarray(run[f"meas_{a}"].values, float) for a in AXES], axis=-1)
        target = np.stack([np.asarray(run[f"target_{a}"].values, float) for a in AXES], axis=-1)
        cmd, att = [], []
        for k in sorted(set(pose[pose > 0])):
            sel = (pose == k) & np.all(np.isfinite(meas), axis=1)
            if sel.sum() >= 2:
                cmd.append(target[pose == k][0])
                att.append(meas[sel])
        if not att:
            continue
        model = run.attrs.get("model")
        out.append(
            Measurement(
                path=("models", str(model), "heldout"),
                keys={"accuracy": "accuracy_um", "repeatability": "repeatability_um"},
                data={"command": np.array(cmd), "attained": att},
                terms=tracker_terms(distance),
                label=f"Model {model}, held-out targets (position)",
                notes=NOTES,
                state="as_left",
                traceability=TRACEABILITY,
            )
        )
    return out
