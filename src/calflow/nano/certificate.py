"""What the nano family's certificate figures are measured from, and its interferometer's budget.

The 1-DoF stage's intrinsic AP and RP (metrology run) and training AP and RP (ISO 9283,
max over the run's poses; thesis Sec. 5.3.3) and ISO 230-2 of its training run (or of a
recorded ISO 230-2 test). The interferometer's terms are its Table 3.4 budget
(:func:`calflow.instruments.interferometer.interferometer_budget`, with the campaign's ``uncertainty``
inputs), each given the way it acts on a mean reading:

* U_1 laser wavelength, U_4 atmospheric compensation, U_8 cosine: proportional to the
  measured length (relative, in ppm of the position from the interferometer's zero);
* U_6 deadpath: one offset for the whole run (it cancels in E, M, B, A, R and RP);
* U_3 optics nonlinearity, U_5 optics thermal drift, U_7 Abbe: independent between
  targets (the nonlinearity is periodic in the position, the drift and the Abbe angle vary
  over the run);
* U_2 electronics (resolution): per reading, in the observed scatter.

U_4 and U_6 share the atmospheric uncertainty U_W; here they are independent (one scales,
one is an offset), which the certificate notes. The 2-DoF stage's figures are maxima over
a validation period (``max_accuracy_nm``): calflow states them without U.
"""

from __future__ import annotations

import numpy as np

from calflow.certificate import Measurement
from calflow.metrics.uncertainty import Term

#: The interferometer's chain to the SI metre (the certificate's traceability statement).
TRACEABILITY = (
    "the laser wavelength of the interferometer (Table 3.4, U_1; its calibration: not recorded in the campaign)",
    "the atmospheric compensation's air sensors (U_4; their calibration: not recorded)",
)
NOTES = ("U_4 (atmospheric, relative) and U_6 (deadpath, offset) share U_W but enter as independent terms",)


def interferometer_terms(budget) -> tuple[Term, ...]:
    """Table 3.4 as :class:`Term` in µm (relative terms in ppm of the position)."""
    length_nm = budget.inputs["measured_distance_um"] * 1e3
    ppm = (lambda u_nm: u_nm / length_nm * 1e6) if length_nm > 0 else (lambda u_nm: 0.0)
    return (
        Term("U_1 laser wavelength", ppm(budget.U_1), relative=True),
        Term("U_2 electronics (resolution)", budget.U_2 / 1e3, scope="reading"),
        Term("U_3 optics nonlinearity", budget.U_3 / 1e3, scope="target"),
        Term("U_4 atmospheric compensation", budget.U_W_ppm, relative=True),
        Term("U_5 optics thermal drift", budget.U_5 / 1e3, scope="target"),
        Term("U_6 deadpath", budget.U_6 / 1e3),
        Term("U_7 Abbe", budget.U_7 / 1e3, scope="target"),
        Term("U_8 cosine", ppm(budget.U_8), relative=True),
    )


def _cells(run):
    """Targets (T, 1) and the readings (µm) of each (test, pose) of a 1-DoF run."""
    from calflow.nano.evaluation import run_columns

    meas, tgt, pose, _cycle, _direction, test, _mode, _hours = run_columns(run, ("x",))
    cmd, att = [], []
    for t in np.unique(test):
        for p in np.unique(pose):
            sel = (
                (test == t)
                & (pose == p)
                & np.all(np.isfinite(meas), axis=1)
                & np.all(np.isfinite(tgt), axis=1)
            )
            if sel.sum() >= 2:
                cmd.append(tgt[sel][0])
                att.append(meas[sel])
    return np.array(cmd), att


def measurements(campaign: dict, files: list[str]) -> list[Measurement]:
    """The stage1d figures with a U (:class:`calflow.certificate.Measurement`)."""
    from calflow.instruments.interferometer import interferometer_budget
    from calflow.metrics.iso230_2_runs import tables_of_run
    from calflow.nano.family import FAMILY
    from calflow.summary_routing import route

    if campaign["robot"] != "stage1d":
        return []
    runs = {
        ds.attrs["plan"]: ds for _, ds in route(files, FAMILY.summary_sections, "nano family").get("runs", [])
    }
    recorded = campaign["rig"]["factory"] == "replay" and isinstance(
        campaign["rig"].get("options", {}).get("recordings"), dict
    )
    notes = list(NOTES)
    if recorded and not campaign.get("uncertainty"):
        terms: tuple[Term, ...] = ()
        notes = [
            "the instrument's uncertainty inputs are not given (campaign key 'uncertainty'): the sample only"
        ]
    else:
        terms = interferometer_terms(interferometer_budget(**campaign.get("uncertainty", {})))
    out = []
    for plan, path in (("metrology", ("intrinsic",)), ("training", ("training",))):
        if plan in runs:
            cmd, att = _cells(runs[plan])
            if len(att):
                out.append(
                    Measurement(
                        path=path,
                        keys={"accuracy": "accuracy_nm", "repeatability": "repeatability_nm"},
                        data={"command": cmd, "attained": att},
                        terms=terms,
                        scale=1000.0,
                        label=f"{plan} run, every pose",
                        notes=tuple(notes),
                        traceability=TRACEABILITY if terms else (),
                    )
                )
    iso_run = runs.get("training", runs.get("metrology"))
    if iso_run is not None:
        targets, fwd, bwd, *_ = tables_of_run(iso_run)
        out.append(
            Measurement(
                path=("iso230_2",),
                keys={k: f"{k}_nm" for k in ("E", "M", "B", "A", "R")},
                kind="iso230_2",
                data={"targets": targets, "forward": fwd, "backward": bwd},
                terms=terms,
                scale=1000.0,
                label=f"ISO 230-2, {iso_run.attrs['plan']} run",
                notes=tuple(notes),
                traceability=TRACEABILITY if terms else (),
            )
        )
    return out
