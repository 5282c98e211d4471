"""The ``calflow`` command line: one subcommand per workflow step.

Every rule of the Snakemake workflow calls one subcommand. Errors the user can fix are
printed as one line (``calflow: error: <file>: <field>: <what was expected>``) with a
non-zero exit status; outputs are written atomically, so a failed step leaves none.
"""

from __future__ import annotations

import argparse
import json
import shlex
import zlib
import sys
from pathlib import Path

from calflow import __version__
from calflow.errors import CalflowError


def _campaign(path: str) -> dict:
    from calflow.config import load_campaign

    return load_campaign(path)


def _meta(campaign: dict, source: str, plan: str, model: str | None = None):
    from calflow.config import campaign_digest
    from calflow.data.runs import RunMetadata

    return RunMetadata(
        campaign=campaign["name"], robot=campaign["robot"], source=source, plan=plan,
        config_sha256=campaign_digest(campaign), start=campaign["start"], model=model,
        history=f"calflow {__version__}: {' '.join(shlex.quote(a) for a in sys.argv[1:])}",
    )


def _open_rig(campaign: dict, run_id: str):
    from calflow.rigs import load_rig

    rig_cfg = campaign["rig"]
    options = dict(rig_cfg.get("options", {}))
    if rig_cfg["factory"] == "simulated" and campaign["robot"] == "xytheta":
        options.setdefault("seed", campaign["seed"])
        options["stream"] = run_id
    elif rig_cfg["factory"] == "simulated":
        # one world (room, slow drift) per campaign; independent noise per run
        options.setdefault("world_seed", campaign["seed"])
        options["seed"] = zlib.crc32(f"{campaign['seed']}:{run_id}".encode())
    elif rig_cfg["factory"] == "replay":
        options["stream"] = run_id
    return load_rig(rig_cfg["factory"], campaign["robot"], options)


def cmd_acquire(args) -> None:
    from calflow.acquisition import acquire, terminal_progress
    from calflow.checkpoint import Journal, plan_digest
    from calflow.data.io import open_dataset, write_dataset, write_json
    from calflow.plans import xytheta as plans

    campaign = _campaign(args.campaign)
    model_name = None
    if args.plan == "identification":
        c = campaign["identification"]
        plan = plans.identification(c["poses"], c["x_um"], c["y_um"], c["theta_deg"],
                                    seed=campaign["seed"], dwell_s=c["dwell_s"])
    elif args.plan == "validation":
        from calflow.models.micro import MicroModel

        if not args.model:
            raise CalflowError("calflow acquire --plan validation: --model MODEL.nc is required")
        model = MicroModel.from_dataset(open_dataset(args.model, kind="model"))
        model_name = model.name
        c = campaign["validation"]
        plan = plans.validation(model.inverse, c.get("targets"), c["cycles"], c["dwell_s"])
    else:
        raise CalflowError(f"calflow acquire: --plan: unknown plan {args.plan!r}")
    run_id = args.plan if model_name is None else f"{args.plan}_{model_name}"
    rig, source = _open_rig(campaign, run_id)
    journal = Journal(f"{args.out}.journal", plan_digest(plan))
    try:
        ds = acquire(plan, rig, _meta(campaign, source, args.plan, model_name), journal,
                     terminal_progress(f"{campaign['name']} {run_id}"))
        truth = rig.truth() if hasattr(rig, "truth") else {"available": False}
    finally:
        rig.close()
    if args.truth:
        write_json(truth, args.truth)
    write_dataset(ds, args.out)
    journal.close(remove=True)


def cmd_identify(args) -> None:
    import numpy as np

    from calflow.data.io import open_dataset, write_dataset
    from calflow.identification import cost, diagnostics
    from calflow.identification.least_squares import identify
    from calflow.kinematics.xytheta import Parameters
    from calflow.models.micro import MicroModel

    campaign = _campaign(args.campaign)
    spec = campaign["models"].get(args.model_name)
    if spec is None:
        raise CalflowError(f"{args.campaign}: key 'models.{args.model_name}': missing")
    run = open_dataset(args.run, kind="run")
    initial = {**campaign["identification"]["initial"], **spec.get("fixed", {})}
    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(run["meas_x"].values, run["meas_y"].values, theta)
    result = identify(run["cmd_x"].values, run["cmd_y"].values, theta, P_mx, P_my,
                      free=tuple(spec["free"]), initial=Parameters(**initial))
    r_diag, not_identifiable = diagnostics.identifiability(result.jacobian, result.free)
    diag = {
        "r_diag": r_diag,
        "not_identifiable": ", ".join(not_identifiable),
        "residual_rms_um": result.residual_rms_um,
        "n_poses": result.n_poses,
        "dof": result.dof,
        "optimizer": f"scipy.optimize.least_squares(method='lm'), nfev={result.nfev}: {result.message}",
        **diagnostics.observability(result.jacobian),
    }
    if not result.success or not np.all(np.isfinite(result.parameters.as_array())):
        raise CalflowError(f"{args.run}: identification of model {args.model_name} failed ({result.message})")
    model = MicroModel(args.model_name, result.parameters, result.free, result.std, result.correlation, diag)
    write_dataset(model.to_dataset(_meta(campaign, run.attrs["source"], "identification", args.model_name)), args.out)


def cmd_metrics(args) -> None:
    from calflow.data.io import open_dataset, write_dataset
    from calflow.evaluation import xytheta_validation_metrics

    campaign = _campaign(args.campaign)
    run = open_dataset(args.run, kind="run")
    meta = _meta(campaign, run.attrs["source"], run.attrs["plan"], run.attrs.get("model"))
    write_dataset(xytheta_validation_metrics(run, meta), args.out)


def _pairs(items: list[str], flag: str) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep:
            raise CalflowError(f"calflow: {flag}: expected NAME=PATH, got {item!r}")
        out[name] = path
    return out


def cmd_summarise(args) -> None:
    from calflow.data.io import open_dataset, write_json
    from calflow.summary import xytheta_summary

    campaign = _campaign(args.campaign)
    models = {k: open_dataset(v, kind="model") for k, v in _pairs(args.models, "--models").items()}
    metrics = {k: open_dataset(v, kind="metrics") for k, v in _pairs(args.metrics, "--metrics").items()}
    truth = json.loads(Path(args.truth).read_text()) if args.truth else None
    inputs = [*_pairs(args.models, "--models").values(), *_pairs(args.metrics, "--metrics").values()]
    write_json(xytheta_summary(campaign, models, metrics, truth, inputs), args.out)


def cmd_report(args) -> None:
    from calflow.data.io import write_bytes, write_text
    from calflow.report import render_campaign, write_pdf
    from calflow.summary import load_summary

    campaign = _campaign(args.campaign)
    summary = load_summary(args.summary)
    command = f"snakemake --cores 2 --config 'campaigns=[\"{campaign['name']}\"]'"
    html = render_campaign(summary, campaign, command)
    write_text(html, args.html)
    if args.pdf:
        write_bytes(write_pdf(html, Path(args.html).parent), args.pdf)


def cmd_index(args) -> None:
    from calflow.data.io import write_text
    from calflow.report import render_index
    from calflow.summary import load_summary

    write_text(render_index([load_summary(p) for p in args.summaries]), args.out)


def cmd_import_csv(args) -> None:
    from calflow.data.io import write_dataset
    from calflow.importing import import_csv, load_mapping

    campaign = _campaign(args.campaign)
    mapping = load_mapping(args.mapping)
    meta = _meta(campaign, "replay", mapping["plan"], mapping.get("model"))
    write_dataset(import_csv(args.csv, mapping, meta), args.out)


def cmd_validate(args) -> int:
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


def cmd_check_config(args) -> None:
    from calflow.config import check_campaign_name, load_campaign, load_workflow_config, load_yaml

    cfg = load_workflow_config(load_yaml(args.config) or {}, args.config)
    folder = Path(args.campaign_dir or cfg["campaign_dir"])
    for name in cfg["campaigns"]:
        load_campaign(folder / f"{check_campaign_name(name)}.yaml")
    print(f"{args.config}: ok ({len(cfg['campaigns'])} campaigns)")


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calflow", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"calflow {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    a = sub.add_parser("acquire", help="run a plan on the campaign's rig and write the run dataset")
    a.add_argument("--campaign", required=True)
    a.add_argument("--plan", required=True, choices=["identification", "validation"])
    a.add_argument("--model", help="model file whose inverse commands the validation")
    a.add_argument("--out", required=True)
    a.add_argument("--truth", help="where to write the rig's truth (simulated rigs), for tests and reports")
    a.set_defaults(func=cmd_acquire)

    i = sub.add_parser("identify", help="identify one calibration model from an identification run")
    i.add_argument("--campaign", required=True)
    i.add_argument("--model-name", required=True)
    i.add_argument("--run", required=True)
    i.add_argument("--out", required=True)
    i.set_defaults(func=cmd_identify)

    m = sub.add_parser("metrics", help="ISO 9283 accuracy and repeatability of a validation run")
    m.add_argument("--campaign", required=True)
    m.add_argument("--run", required=True)
    m.add_argument("--out", required=True)
    m.set_defaults(func=cmd_metrics)

    s = sub.add_parser("summarise", help="write the campaign's summary.json")
    s.add_argument("--campaign", required=True)
    s.add_argument("--models", nargs="+", required=True, metavar="NAME=MODEL.nc")
    s.add_argument("--metrics", nargs="+", required=True, metavar="NAME=METRICS.nc")
    s.add_argument("--truth")
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_summarise)

    r = sub.add_parser("report", help="render the campaign report (HTML and PDF)")
    r.add_argument("--campaign", required=True)
    r.add_argument("--summary", required=True)
    r.add_argument("--html", required=True)
    r.add_argument("--pdf")
    r.set_defaults(func=cmd_report)

    x = sub.add_parser("index", help="render reports/index.html over all campaigns")
    x.add_argument("--summaries", nargs="+", required=True)
    x.add_argument("--out", required=True)
    x.set_defaults(func=cmd_index)

    ic = sub.add_parser("import-csv", help="turn a CSV recording into a run dataset with a column mapping")
    ic.add_argument("csv")
    ic.add_argument("--mapping", required=True, help="YAML file: which column gives which run variable (docs/data.md)")
    ic.add_argument("--campaign", required=True)
    ic.add_argument("--out", required=True)
    ic.set_defaults(func=cmd_import_csv)

    v = sub.add_parser("validate", help="check netCDF files against the calflow data contract")
    v.add_argument("files", nargs="+")
    v.set_defaults(func=cmd_validate)

    c = sub.add_parser("check-config", help="validate config/config.yaml and its campaign files")
    c.add_argument("config", nargs="?", default="config/config.yaml")
    c.add_argument("--campaign-dir")
    c.set_defaults(func=cmd_check_config)
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        status = args.func(args)
    except CalflowError as exc:
        print(f"calflow: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("calflow: interrupted; no output was written", file=sys.stderr)
        return 130
    return int(status or 0)


if __name__ == "__main__":
    sys.exit(main())
