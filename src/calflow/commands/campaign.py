"""``calflow identify``, ``metrics``, ``summarise`` and ``report``: the campaign's steps whose
science its robot family holds (``Family.steps``), and the summary's and report's files."""

from __future__ import annotations

import json
from pathlib import Path

from calflow.configuration.handed import campaign_of
from calflow.family import family_of


def _family(args):
    campaign = campaign_of(args)
    return campaign, family_of(campaign["robot"])


def identify(args) -> None:
    campaign, family = _family(args)
    family.step("identify")(campaign, args)


def metrics(args) -> None:
    campaign, family = _family(args)
    family.step("metrics")(campaign, args)


def summarise(args) -> None:
    from calflow.data.io import write_json

    campaign, family = _family(args)
    truth = json.loads(Path(args.truth).read_text()) if args.truth else None
    if args.budget:  # the error budget's replays on the simulated truth: reports only, like the truth
        truth = {**(truth or {}), "error_budget": json.loads(Path(args.budget).read_text())}
    from calflow.certificate.annotate import annotate, stage_settings_or_fail
    from calflow.commands.kept import iso230_2_uncertainty
    from calflow.summary_routing import opened_once

    settings = stage_settings_or_fail(args.settings)
    with opened_once():  # the family's summary and the certificate read the same files
        summary = family.step("summarise")(campaign, args.with_values(truth=truth))
        # a characterisation's ISO 230-2 U is kept between runs: a change of validation alone
        # does not compute it again
        summary = annotate(summary, campaign, args.files, settings, iso230_2=iso230_2_uncertainty)
    write_json(summary, args.out)


def report(args) -> None:
    from calflow.data.io import load_summary, write_bytes, write_text
    from calflow.report.render import render_campaign_pages, write_pdf

    campaign = campaign_of(args)
    summary = load_summary(args.summary)
    command = f"snakemake --cores 2 --config 'campaigns=[\"{campaign['name']}\"]'"
    html, printed = render_campaign_pages(summary, campaign, command, args.files or [])
    write_text(html, args.html)
    if args.pdf:
        write_bytes(write_pdf(printed, Path(args.html).parent), args.pdf)
