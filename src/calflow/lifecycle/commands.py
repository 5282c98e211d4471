"""``calflow history`` and ``calflow history-report``: a stage's history and its report."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from calflow import layout
from calflow.errors import ConfigError


def history_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--stage", required=True, help="the stage's id (campaign key 'stage')")
    p.add_argument("--campaigns", nargs="+", required=True, help="the stage's campaign files")
    p.add_argument("--summaries", nargs="+", required=True, help="their summary.json, in the same order")
    p.add_argument("--settings", default="{}", help="JSON: the stage's settings (config 'stages.<id>')")
    p.add_argument("--out", required=True)


def report_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--history", required=True)
    p.add_argument("--html", required=True)
    p.add_argument("--pdf")


def run_history(args) -> None:
    from calflow.config import load_campaign
    from calflow.data.io import jsonable, load_summary, write_json
    from calflow.lifecycle.history import build
    from calflow.lifecycle.stages import stages_of

    if len(args.campaigns) != len(args.summaries):
        raise ConfigError(
            f"calflow history: --campaigns gives {len(args.campaigns)} files, --summaries "
            f"{len(args.summaries)}; expected one summary per campaign"
        )
    try:
        settings = json.loads(args.settings)
    except json.JSONDecodeError as exc:
        raise ConfigError(
            f"calflow history: --settings: expected JSON, got {args.settings!r} ({exc})"
        ) from None
    from calflow.lifecycle.interval import check_settings

    if not isinstance(settings, dict):
        raise ConfigError(f"calflow history: --settings: expected a JSON object, got {args.settings!r}")
    try:  # before anything is read: a reliability outside (0, 1), a tolerance <= 0
        check_settings(settings.get("reliability", 0.95), settings.get("tolerance_um"), "stage settings")
    except ValueError as exc:
        raise ConfigError(f"calflow history: --settings: {exc}") from None
    campaigns = [load_campaign(f) for f in args.campaigns]
    folder = Path(args.campaigns[0]).parent
    groups = stages_of({c["name"]: c for c in campaigns}, folder)
    others = [c["name"] for c in campaigns if c.get("stage") != args.stage]
    if others or args.stage not in groups:
        raise ConfigError(
            f"{folder / (others[0] if others else campaigns[0]['name'])}.yaml: key 'stage': expected "
            f"{args.stage!r}, the stage whose history is asked for"
        )
    pairs = [(c, load_summary(s)) for c, s in zip(campaigns, args.summaries)]
    try:
        history = build(args.stage, pairs, settings)
    except ValueError as exc:  # a campaign's tolerance_um the schema would have refused
        raise ConfigError(f"calflow history: {exc}") from None
    write_json(jsonable(history), args.out)


def run_report(args) -> None:
    from calflow.data.io import write_bytes, write_text
    from calflow.lifecycle.report import render
    from calflow.report.render import write_pdf

    history = json.loads(Path(args.history).read_text())
    command = f"snakemake --cores 2 {layout.stage_history(history['stage'])}"
    html, printed = render(history, command, pdf=bool(args.pdf))
    write_text(html, args.html)
    if args.pdf:
        write_bytes(write_pdf(printed, Path(args.html).parent), args.pdf)
