"""The ``calflow export`` and ``calflow export-verify`` subcommands."""

from __future__ import annotations


def export(args) -> None:
    """Bundle and controller files of one model (``--model M.nc``) into ``--out DIR``."""
    from calflow.commands.common import campaign as load
    from calflow.xytheta.export.writer import export_model

    load(args.campaign)  # refuse a bad campaign before writing
    export_model(args.model, args.out)


def verify(args) -> None:
    """Export paths' accuracy beside the in-process model's, from a validation_export run."""
    from calflow.commands.common import campaign as load, meta
    from calflow.data.io import open_dataset, write_dataset
    from calflow.errors import CalflowError
    from calflow.xytheta.export.verification import compare

    c = load(args.campaign)
    run = open_dataset(args.run, kind="run")
    if run.attrs.get("plan") != "validation_export":
        raise CalflowError(f"{args.run}: attribute 'plan': expected 'validation_export', got {run.attrs.get('plan')!r}")
    heldout = open_dataset(args.heldout, kind="metrics")
    write_dataset(compare(run, heldout, meta(c, run.attrs["source"], "validation_export", run.attrs.get("model"))),
                  args.out)
