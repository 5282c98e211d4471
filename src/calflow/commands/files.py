"""The subcommands around the workflow's steps that read and check files: the report index
(``calflow index``), run datasets imported from a CSV or a recording (``calflow import-csv``,
``calflow import-recording``), the data contract (``calflow validate``) and the configuration
(``calflow check-config``). Each takes the parsed arguments of its subcommand
(:func:`calflow.cli.parser`).
"""

from __future__ import annotations

import sys
from pathlib import Path

from calflow.errors import CalflowError


def index(args) -> None:
    from calflow.data.io import write_text
    from calflow.lifecycle.fleet import fleets
    from calflow.report import render_index
    from calflow.report.catalogue import catalogue

    out = Path(args.out or Path(args.reports) / "index.html")
    found = catalogue(args.results, args.reports, args.campaign_dir)
    write_text(render_index(found, fleets=fleets(found.get("histories") or [])), out)
    done = sum(c["status"] == "done" for g in found["groups"] for c in g["campaigns"])
    failed = sum(c["status"] == "failed" for g in found["groups"] for c in g["campaigns"])
    print(f"{out}: {done} campaigns, {failed} failed")


def import_csv(args) -> None:
    from calflow.commands.common import campaign_of, meta
    from calflow.data.importing import import_csv, load_mapping
    from calflow.data.io import write_dataset

    c = campaign_of(args)
    mapping = load_mapping(args.mapping)
    write_dataset(
        import_csv(args.csv, mapping, meta(c, "replay", mapping["plan"], mapping.get("model"))), args.out
    )


def import_recording(args) -> None:
    from calflow.commands.common import campaign_of, meta
    from calflow.data.io import write_dataset
    from calflow.data.recordings import in_campaign_time, load

    c = campaign_of(args)
    spec = {"file": args.file, "format": args.format, **({"mapping": args.mapping} if args.mapping else {})}
    path, ds, _ = load(spec, args.plan, "calflow import-recording")
    ds = in_campaign_time(ds, c["start"])
    if ds.attrs["robot"] != c["robot"]:
        raise CalflowError(
            f"{path}: holds a {ds.attrs['robot']} recording; campaign {args.campaign} is {c['robot']!r}"
        )
    kept = {k: ds.attrs[k] for k in ("imported_from", "z_range_um", "recording_start") if k in ds.attrs}
    ds.attrs = {**meta(c, "replay", args.plan).attrs("run"), **kept}
    write_dataset(ds, args.out)


def validate(args) -> int:
    from calflow.data.validate import validate_file

    status = 0
    for path in args.files:
        problems = validate_file(path)
        for problem in problems:
            print(problem, file=sys.stderr)
        if problems:
            status = 1
        else:
            print(f"{path}: ok")
    return status


def check_config(args) -> None:
    from calflow.configuration.campaign import load as load_campaign
    from calflow.configuration.config import check_campaign_name, load_yaml
    from calflow.configuration.workflow_config import load as load_config
    from calflow.lifecycle.settings import check_stage_settings
    from calflow.lifecycle.stages import stages_of

    cfg = load_config(load_yaml(args.config) or {}, [args.config])

    folder = Path(args.campaign_dir or cfg["campaign_dir"])
    campaigns = {}
    for name in cfg["campaigns"]:
        campaigns[name] = load_campaign(folder / f"{check_campaign_name(name)}.yaml", cfg["rig_plugins"])
    groups = stages_of(
        campaigns, folder
    )  # the campaigns of each stage agree (robot, distinct starts, interim references)
    check_stage_settings(cfg["stages"], campaigns, folder, args.config)
    from calflow.certificate.annotate import check_stages

    check_stages(cfg.get("stages", {}), campaigns, groups, args.config)  # specifications and rules
    print(f"{args.config}: ok ({len(cfg['campaigns'])} campaigns)")
