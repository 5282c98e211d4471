"""``calflow export``: a model's bundle, controller files and README in one folder."""

from __future__ import annotations

from pathlib import Path

from calflow.data.bundle import provenance
from calflow.data.io import write_text
from calflow.xytheta.export import controllers as ctl
from calflow.xytheta.export.bundle import write_bundle
from calflow.xytheta.export.verification import LINUXCNC, TWINCAT

AXIS_NUMBER = {"x": 1, "y": 2}  # TwinCAT logical axis numbers (kopf.achs_nr) written by default

NOT_EXPRESSED = (
    "cross-axis terms of the position table (x error while Y moves, f_yx/b_yx; y error while X moves, "
    "f_xy/b_xy)",
    "the kinematic parameters x_R, y_R, alpha, beta (the controller's kinematics)",
    "the angle table f_ax, f_ay (errors of the tool point against the rotation angle)",
)


def export_model(model_path, folder) -> dict:
    """Write the bundle of the model at ``model_path`` and, when it has a position table, its
    LinuxCNC and TwinCAT files into ``folder``; returns what the controller files hold."""
    from calflow.xytheta.models.ladder import MicroModel

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    model = MicroModel.read(model_path)
    prov = provenance(model_path)
    files = {}
    if model.position is not None:
        header = (
            f"calflow {prov['export_calflow_version']} export of model {model.name}, campaign {prov['campaign']}\n"
            f"config_sha256 {prov['config_sha256']}\nmodel_sha256 {prov['model_sha256']}"
        )
        for axis in ("x", "y"):
            comp, info = ctl.from_position_table(model.position, axis, model.method, ctl.LINUXCNC_MAX_ENTRIES)
            ctl.write_linuxcnc(comp, folder / LINUXCNC[axis])
            files[LINUXCNC[axis]] = {"axis": axis, "entries": int(comp.nominal.size), **info}
            comp, info = ctl.from_position_table(model.position, axis, model.method, ctl.TWINCAT_MAX_ENTRIES)
            ctl.write_twincat(comp, folder / TWINCAT[axis], AXIS_NUMBER[axis], header)
            files[TWINCAT[axis]] = {
                "axis": axis,
                "entries": int(comp.nominal.size),
                "axis_number": AXIS_NUMBER[axis],
                **info,
            }
    controllers = {"files": files, "not_expressed": list(NOT_EXPRESSED) if files else []}
    write_text(readme(model.name, prov, files), folder / "README.md")
    write_bundle(model, folder, prov, controllers)  # last: the workflow's marker of a complete export
    return controllers


def readme(name: str, prov: dict, files: dict) -> str:
    lines = [
        f"# calflow export of model {name}",
        "",
        f"Campaign `{prov['campaign']}`, configuration SHA-256 `{prov['config_sha256']}`, model file "
        f"`{prov['model_file']}` (SHA-256 `{prov['model_sha256']}`), calflow {prov['export_calflow_version']}.",
        "",
        "* `bundle.json` + `*.csv`: the whole model (parameters with sigma and units, every table). Load it with "
        "`calflow.xytheta.export.Compensator.load(<this folder>)`; `.joints(x_T, y_T, theta_T)` gives the joint "
        "commands (um, degree) as calflow's in-process model does.",
    ]
    if files:
        lines += [
            "* `linuxcnc_x.comp`, `linuxcnc_y.comp`: `[JOINT_n] COMP_FILE = linuxcnc_x.comp`, `COMP_FILE_TYPE = 1`; "
            "lines `nominal forward_trim reverse_trim` in mm (set `LINEAR_UNITS = mm`), at most 256 lines.",
            "* `twincat_x_ssfk.lis`, `twincat_y_ssfk.lis`: TwinCAT CNC double-sided leadscrew error compensation "
            "(`kw.ssfk.*`, 0.1 um, `kopf.achs_nr` 1 and 2 — edit to your logical axis numbers; activate with "
            "`lr_param.ssfk 1`).",
            "",
            "The controller files hold the own-axis errors of the X and Y stages only. They cannot express: "
            + "; ".join(NOT_EXPRESSED)
            + ". A controller using them needs a kinematics module with the bundle's "
            "parameters (and angle table); the bundle's `Compensator` applies everything.",
            "",
            "Entries and interpolation error of the resampling to the controllers' table sizes (um):",
            "",
        ]
        for file, info in files.items():
            e = info["resampling_error_um"]
            lines.append(
                f"* `{file}`: {info['entries']} entries, forward {e['forward']:.3f}, reverse {e['reverse']:.3f}"
            )
    else:
        lines += [
            "",
            "This model has no position table: there are no controller files (a per-axis compensation would "
            "be zero); use the bundle.",
        ]
    return "\n".join(lines) + "\n"
