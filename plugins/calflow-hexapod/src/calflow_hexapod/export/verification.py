"""``calflow hexapod-export`` and the closed-loop run through the exported bundle.

The export (:func:`export_command`) writes a model's ``geometry.nc``, ``bundle.json`` and a
``README.md`` into its folder. The closed-loop run (:func:`validation_export`, plan
``validation_export``, run ``closed_loop_<model>``) commands the campaign's held-out targets
(``validation_heldout``: the same targets, order and cycles) through the :class:`Compensator`
*loaded from the folder*, not through the in-process model; its ISO 9283 metrics are the
family's ``metrics`` step, and the summary puts its AP beside the in-process held-out AP
(:func:`calflow_hexapod.report.summary.export_entry`).

On a simulated rig (and on the tracker sensor of an emulated controller) the closed-loop run
draws its noise from the held-out run's stream (:func:`calflow_hexapod.stage.run_options.noise_stream`: common random numbers,
the same virtual clock): the two runs differ only by what the export changes, so their AP
must agree to numerical precision. Through a real controller the noise is the rig's, and the
two agree within its repeatability RP.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calflow.errors import CalflowError
from calflow.plan import Acquisition
from calflow_hexapod.stage.run_options import CLOSED_LOOP

RUN_PREFIX = CLOSED_LOOP

README = """# calflow export of hexapod model {model}

Campaign `{campaign}`, configuration SHA-256 `{config}`, model file `{file}` (SHA-256 `{sha}`),
calflow {version}.

* `bundle.json`: the identified geometry — base and platform joints (um), leg offsets (um),
  scales, thermal expansion (1/K), measurement and tool frames (um, degree) — with every
  parameter's sigma, units and correlation, the controller's nominal geometry and pivot, and
  the conventions. `geometry.nc`: the same as netCDF with CF units.
* Compensation from your own code (numpy and the calflow-hexapod package, no workflow):

      from calflow_hexapod.export import Compensator
      comp = Compensator.load("<this folder>")
      pose = comp.command(target)   # (n, 6): x y z um, u v w degree -> the MOV pose (um, degree)

  Send `pose` with `MOV X Y Z U V W` (mm and degree: divide x y z by 1000) with the
  controller's pivot at `controller.pivot_um` (`SPI R S T`, mm).
* Controller file: none. A C-887 keeps its leg geometry in factory parameters that PI does
  not document for users; its coordinate-system commands move the work and tool frames, not
  the joints. The identified joints therefore reach the hexapod through the Compensator.
"""


def export_command(args) -> None:
    """``calflow hexapod-export --campaign FILE --model M.nc --out DIR``: the model's bundle."""
    from calflow.commands.common import campaign_of, meta
    from calflow.data.io import write_text
    from calflow_hexapod.export.bundle import provenance, write_bundle
    from calflow_hexapod.models.calibration import HexapodModel

    c = campaign_of(args)
    model = HexapodModel.read(args.model)
    prov = provenance(args.model)
    folder = Path(args.out).parent if Path(args.out).suffix == ".json" else Path(args.out)
    folder.mkdir(parents=True, exist_ok=True)
    text = README.format(
        model=model.name,
        campaign=prov["campaign"],
        config=prov["config_sha256"],
        file=prov["model_file"],
        sha=prov["model_sha256"],
        version=prov["export_calflow_version"],
    )
    write_text(text, folder / "README.md")
    write_bundle(model, folder, prov, meta(c, str(prov.get("source") or "simulated"), "export", model.name))


def validation_export(c: dict, args) -> Acquisition:
    """``calflow acquire --plan validation_export --model M.nc --bundle DIR``: the held-out
    targets through the Compensator of DIR. Records the largest difference between its
    commands and the in-process model's (``command_difference_um``, µm and degree)."""
    from calflow_hexapod.export.compensator import Compensator
    from calflow_hexapod.models.calibration import HexapodModel
    from calflow_hexapod.plans import poses as plans
    from calflow_hexapod.plans.campaign import heldout_targets

    if not getattr(args, "bundle", None) or not getattr(args, "model", None):
        raise CalflowError(
            "calflow acquire --plan validation_export: --bundle DIR (the model's export folder) "
            "and --model M.nc are required"
        )
    comp = Compensator.load(args.bundle)
    inproc = HexapodModel.read(args.model[0])
    if comp.model.name != inproc.name:
        raise CalflowError(
            f"{args.bundle}: field 'model': expected {inproc.name!r} (the --model), got {comp.model.name!r}"
        )
    h = c["validation"]["heldout"]
    targets = heldout_targets(c)
    try:
        plan = plans.validation(
            comp.command, targets, h["cycles"], c["validation"]["dwell_s"], name="validation_export"
        )
    except ValueError as exc:
        raise CalflowError(f"campaign {c['name']}: {exc}") from None
    diff = float(np.max(np.abs(comp.command(targets) - inproc.command(targets))))
    return Acquisition(
        plan,
        RUN_PREFIX + comp.model.name,
        comp.model.name,
        attrs={"bundle": str(args.bundle), "command_difference": diff},
    )
