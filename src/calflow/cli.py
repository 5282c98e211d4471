"""The ``calflow`` command line: one subcommand per workflow step.

Every rule of the Snakemake workflow calls one subcommand. Errors the user can fix are
printed as one line (``calflow: error: <file>: <field>: <what was expected>``) with a
non-zero exit status; outputs are written atomically, so a failed step leaves none.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from functools import cache
from pathlib import Path

from calflow import __version__, footprint
from calflow.configuration import layout
from calflow.errors import CalflowError


def cmd_acquire(args) -> None:
    from calflow.commands import acquire

    acquire.run(args)


def _family(args):
    from calflow.commands.common import campaign_of
    from calflow.family import family_of

    campaign = campaign_of(args)
    return campaign, family_of(campaign["robot"])


def cmd_identify(args) -> None:
    campaign, family = _family(args)
    family.step("identify")(campaign, args)


def cmd_metrics(args) -> None:
    campaign, family = _family(args)
    family.step("metrics")(campaign, args)


def cmd_summarise(args) -> None:
    from calflow.data.io import write_json

    campaign, family = _family(args)
    truth = json.loads(Path(args.truth).read_text()) if args.truth else None
    if args.budget:  # the error budget's replays on the simulated truth: reports only, like the truth
        truth = {**(truth or {}), "error_budget": json.loads(Path(args.budget).read_text())}
    summary = family.step("summarise")(campaign, argparse.Namespace(**{**vars(args), "truth": truth}))
    from calflow.certificate.annotate import annotate, stage_settings_or_fail

    summary = annotate(summary, campaign, args.files, stage_settings_or_fail(args.settings))
    write_json(summary, args.out)


def cmd_report(args) -> None:
    from calflow.commands.common import campaign_of
    from calflow.data.io import load_summary, write_bytes, write_text
    from calflow.report.render import render_campaign_pages, write_pdf

    campaign = campaign_of(args)
    summary = load_summary(args.summary)
    command = f"snakemake --cores 2 --config 'campaigns=[\"{campaign['name']}\"]'"
    html, printed = render_campaign_pages(summary, campaign, command, args.files or [])
    write_text(html, args.html)
    if args.pdf:
        write_bytes(write_pdf(printed, Path(args.html).parent), args.pdf)


def _run(target: str):
    """A subcommand function that imports ``"module:function"`` only when it runs."""

    def run(args):
        from calflow.family import resolve

        return resolve(target)(args)

    run.target = target
    return run


def _sub(sub, name, func, help_):
    p = sub.add_parser(name, help=help_)
    p.set_defaults(func=func)
    return p


def _required(p, *options: str) -> None:
    """Options ``p`` cannot run without (each one value)."""
    for option in options:
        p.add_argument(option, required=True)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calflow", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"calflow {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    a = _sub(sub, "acquire", cmd_acquire, "run a plan on the campaign's rig and write the run dataset")
    _required(a, "--campaign", "--plan")
    a.add_argument("--model", action="append", help="model file(s) whose inverse commands the run")
    a.add_argument("--out", required=True)
    a.add_argument("--truth", help="where to write the rig's truth (simulated rigs), for tests and reports")
    a.add_argument("--decoded", help="a frame recording's decoded run (calflow decode-run), for a replay rig")
    a.add_argument(
        "--rig-plugins",
        metavar="MODULES",
        help="comma-separated modules whose 'module:callable' rig factories may run "
        "(default: $CALFLOW_RIG_PLUGINS; the workflow passes config rig_plugins)",
    )

    i = _sub(sub, "identify", cmd_identify, "identify one calibration model")
    _required(i, "--campaign", "--model-name")
    i.add_argument("--run", help="the run the model is identified from (its family's identification run)")
    i.add_argument("--out", required=True)

    m = _sub(sub, "metrics", cmd_metrics, "ISO 9283 accuracy and repeatability of a run")
    _required(m, "--campaign", "--run", "--out")

    s = _sub(sub, "summarise", cmd_summarise, "write the campaign's summary.json")
    s.add_argument("--campaign", required=True)
    s.add_argument("--files", nargs="+", required=True, help="the campaign's model, metrics and table files")
    s.add_argument("--truth")
    s.add_argument("--budget", help="the error budget's replays (calflow error-budget), simulated rigs")
    s.add_argument(
        "--settings", help="JSON: the stage's settings (config 'stages.<id>'): specification, decision rule"
    )
    s.add_argument("--out", required=True)
    s.add_argument(
        "--sections",
        help=SECTIONS_HELP,
    )

    r = _sub(sub, "report", cmd_report, "render the campaign report (HTML and PDF)")
    _required(r, "--campaign", "--summary")
    r.add_argument("--files", nargs="*", help="run, table and metrics files the figures draw on")
    r.add_argument("--html", required=True)
    r.add_argument("--pdf")

    x = _sub(
        sub,
        "index",
        _run("calflow.commands.files:index"),
        "render reports/index.html over every campaign on disk (reruns none)",
    )
    x.add_argument("--results", default=layout.RESULTS, help="the results folder (default: results)")
    x.add_argument("--reports", default=layout.REPORTS, help="the reports folder (default: reports)")
    x.add_argument(
        "--campaign-dir",
        default="config/campaigns",
        help="campaign files, to tell whether a report is current (default: config/campaigns)",
    )
    x.add_argument("--out", help="default: <reports>/index.html")

    from calflow.lifecycle.commands import history_arguments, report_arguments

    history_arguments(
        _sub(sub, "history", _run("calflow.lifecycle.commands:run_history"), "write a stage's history.json")
    )
    report_arguments(
        _sub(
            sub,
            "history-report",
            _run("calflow.lifecycle.commands:run_report"),
            "render a stage's history report (HTML and PDF)",
        )
    )

    ce = _sub(
        sub,
        "certificate",
        _run("calflow.certificate.page:run"),
        "render a campaign's certificate (HTML and PDF): U, decisions, as found and as left",
    )
    _required(ce, "--campaign", "--summary", "--html")
    ce.add_argument("--pdf")
    ce.add_argument("--xml", help="the Digital Calibration Certificate (DCC, PTB's XML schema)")
    ce.add_argument(
        "--laboratory", help="JSON: config 'laboratory' (name, address, accreditation, approver, signing_key)"
    )
    ce.add_argument(
        "--item", help="JSON: config 'stages.<id>.item' (customer, manufacturer, model, serial_number)"
    )
    ce.add_argument(
        "--sections",
        help=SECTIONS_HELP,
    )

    vc = _sub(
        sub,
        "verify-certificate",
        _run("calflow.certificate.verify:run"),
        "check a certificate (PDF or DCC): its signature and chain, and that its values equal the results on disk",
    )
    vc.add_argument("file", help="the certificate's PDF or DCC (reports/<campaign>/certificate.pdf or .xml)")
    vc.add_argument("--trust", help="PEM file of the CA certificate(s) the signer's chain must reach")
    vc.add_argument("--summary", help="the results it certifies (default: results/<campaign>/summary.json)")

    ic = _sub(
        sub,
        "import-csv",
        _run("calflow.commands.files:import_csv"),
        "turn a CSV recording into a run dataset with a column mapping",
    )
    ic.add_argument("csv")
    ic.add_argument(
        "--mapping", required=True, help="YAML file: which column gives which run variable (docs/data.md)"
    )
    _required(ic, "--campaign", "--out")

    ir = _sub(
        sub,
        "import-recording",
        _run("calflow.commands.files:import_recording"),
        "turn an instrument's file (ISO 230-2 .dat, laser-tracker CSV) into a run dataset",
    )
    ir.add_argument("file")
    ir.add_argument(
        "--format",
        required=True,
        choices=["ecmc_iso230", "laser_tracker", "csv"],
        help="docs/data.md, 'Recorded campaigns'",
    )
    ir.add_argument("--mapping", help="column mapping of a csv recording")
    ir.add_argument("--plan", required=True, help="the run's plan (e.g. metrology, training)")
    _required(ir, "--campaign", "--out")

    dr = _sub(
        sub,
        "decode-run",
        _run("calflow.commands.decode_run:run"),
        "decode a replay campaign's recorded camera frames into the run dataset of one run",
    )
    dr.add_argument("--campaign", required=True)
    dr.add_argument("--run", required=True, help="the run id of the frame recording (rig.options.recordings)")
    dr.add_argument("--out", required=True)

    v = _sub(
        sub,
        "validate",
        _run("calflow.commands.files:validate"),
        "check netCDF files against the calflow data contract",
    )
    v.add_argument("files", nargs="+")

    k = _sub(
        sub,
        "check-config",
        _run("calflow.commands.files:check_config"),
        "validate config/config.yaml and its campaign files",
    )
    k.add_argument("config", nargs="?", default="config/config.yaml")
    k.add_argument("--campaign-dir")

    e = _sub(
        sub,
        "emulate",
        _run("calflow.gcs.emulation.campaign_server:emulate_command"),
        "serve a campaign's stages as a PI GCS 2.0 controller on 127.0.0.1, with the emulator "
        "its robot family registers (docs/gcs.md)",
    )
    e.add_argument("kind", choices=["gcs"])
    e.add_argument(
        "rest",
        nargs=argparse.REMAINDER,
        help="--campaign FILE [--port 50000] [--time-scale 1] [--duration S]",
    )

    from calflow.instruments.pattern.commands import decode_arguments, pattern_arguments

    pattern_arguments(
        _sub(
            sub,
            "pattern",
            _run("calflow.instruments.pattern.commands:run_pattern"),
            "an encoded dot pattern: its file, GDSII and preview (docs/instruments.md)",
        )
    )
    decode_arguments(
        _sub(
            sub,
            "decode",
            _run("calflow.instruments.pattern.commands:run_decode"),
            "decode frames of an encoded pattern into x, y, Θ (docs/instruments.md)",
        )
    )

    from calflow.family import families

    for family in families():
        if family.acquire_arguments is not None:
            family.acquire_arguments(a)
        if family.identify_arguments is not None:
            family.identify_arguments(i)
        for command in family.commands:
            command.arguments(_sub(sub, command.name, _run(command.run), command.help))
    for q in sub.choices.values():  # a step that reads a campaign reads only what its rule hands it
        options = {o for action in q._actions for o in action.option_strings}
        if "--campaign" in options and "--sections" not in options:
            q.add_argument("--sections", help=SECTIONS_HELP)
    return p


SECTIONS_HELP = (
    "the campaign sections this step reads, comma-separated (its rule hands them and digests the "
    "same); reading another is an error; '*': all of them. Default: all"
)


@cache
def entry_points() -> dict[str, str]:
    """Subcommand → the ``"module:function"`` it runs (what its rerun digest covers,
    :func:`calflow.provenance.code_digest`)."""
    sub = next(a for a in parser()._actions if isinstance(a, argparse._SubParsersAction))
    found = {}
    for name, p in sub.choices.items():
        func = p.get_default("func")
        found[name] = getattr(func, "target", None) or f"{func.__module__}:{func.__qualname__}"
    return found


def entry_point(command: str) -> str:
    """``"module:function"`` that ``calflow <command>`` runs."""
    found = entry_points()
    if command not in found:
        raise CalflowError(f"calflow: no subcommand {command!r}; expected one of {', '.join(found)}")
    return found[command]


def _error(message: str) -> int:
    """Print ``calflow: error: <message>`` on stderr, and on the file descriptor named by
    ``CALFLOW_ERROR_FD`` too: the workflow's jobs send stderr to their log, and pass the
    terminal's stderr as that descriptor so the one line reaches the user (common.smk)."""
    line = f"calflow: error: {message}"
    print(line, file=sys.stderr)
    fd = os.environ.get("CALFLOW_ERROR_FD", "")
    if fd.isdigit():
        try:
            os.write(int(fd), (line + "\n").encode())
        except OSError:  # not open in this process: stderr has it
            pass
    return 2


def _step(args) -> int:
    try:
        status = args.func(args)
    except (CalflowError, ValueError) as exc:  # library ValueErrors are worded for users
        return _error(str(exc))
    except OSError as exc:  # a file or folder the system refused: name it, no traceback
        return _error(f"{exc.filename}: {exc.strerror or exc}" if exc.filename else str(exc.strerror or exc))
    except KeyboardInterrupt:
        print("calflow: interrupted; no output was written", file=sys.stderr)
        return 130
    return int(status or 0)


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; a workflow job then records its own peak memory and CPU time
    (:mod:`calflow.footprint`)."""
    args = parser().parse_args(argv)
    status = 1  # an uncaught exception (a traceback) is recorded as a failure
    try:
        status = _step(args)
    finally:
        footprint.finish(args.command, status)
    return status


if __name__ == "__main__":
    sys.exit(main())
