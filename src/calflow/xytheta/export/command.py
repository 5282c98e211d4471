"""The ``calflow export`` and ``calflow export-verify`` subcommands.

Both take every model of a campaign in one call (one process, not one per model: the
imports are most of a call's time)."""

from __future__ import annotations

from pathlib import Path


def export(args) -> None:
    """Bundle and controller files of each ``--model M.nc`` into ``--out DIR/<model file's stem>``,
    then ``DIR/manifest.json`` (model → its files; written last: the export is complete)."""
    from calflow.commands.common import campaign_of
    from calflow.data.io import write_json
    from calflow.xytheta.export.writer import export_model

    campaign_of(args)  # refuse a bad campaign before writing
    manifest = {}
    for path in args.model:
        folder = Path(args.out) / Path(path).stem
        export_model(path, folder)
        manifest[Path(path).stem] = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
    write_json(manifest, Path(args.out) / "manifest.json")


def verify(args) -> None:
    """Export paths' accuracy beside the in-process model's: each ``--run`` (a validation_export
    run) against the ``--heldout`` metrics of its model, into the ``--out`` at its position."""
    from calflow.commands.common import campaign_of, meta
    from calflow.data.io import open_dataset, write_dataset
    from calflow.errors import CalflowError
    from calflow.xytheta.export.verification import compare

    c = campaign_of(args)
    if len(args.out) != len(args.run):
        raise CalflowError(
            f"calflow export-verify: --out: expected one file per --run ({len(args.run)}), "
            f"got {len(args.out)}"
        )
    heldout = {}
    for path in args.heldout:
        ds = open_dataset(path, kind="metrics")
        heldout[ds.attrs.get("model")] = ds
    for run_path, out in zip(args.run, args.out):
        run = open_dataset(run_path, kind="run")
        if run.attrs.get("plan") != "validation_export":
            raise CalflowError(
                f"{run_path}: attribute 'plan': expected 'validation_export', got {run.attrs.get('plan')!r}"
            )
        model = run.attrs.get("model")
        if model not in heldout:
            raise CalflowError(f"{run_path}: model {model!r}: no --heldout metrics of that model")
        write_dataset(
            compare(run, heldout[model], meta(c, run.attrs["source"], "validation_export", model)), out
        )
