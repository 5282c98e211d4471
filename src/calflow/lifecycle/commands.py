"""``calflow history`` and ``calflow history-report``: a stage's history and its report."""

from __future__ import annotations

import json
from pathlib import Path

from calflow.configuration import layout
from calflow.errors import ConfigError


def run_history(args) -> None:
    from calflow.data.io import jsonable, load_summary, write_json
    from calflow.lifecycle.history import build
    from calflow.lifecycle.members import departed, previous

    files = args.campaigns or [
        str(Path(args.campaign_dir) / f"{Path(s).parent.name}.yaml") for s in args.summaries
    ]
    if len(files) != len(args.summaries):
        raise ConfigError(
            f"calflow history: --campaigns gives {len(files)} files, --summaries "
            f"{len(args.summaries)}; expected one summary per campaign"
        )
    try:
        settings = json.loads(args.settings)
    except json.JSONDecodeError as exc:
        raise ConfigError(
            f"calflow history: --settings: expected JSON, got {args.settings!r} ({exc})"
        ) from None
    from calflow.lifecycle.decisions.interval import check_settings

    if not isinstance(settings, dict):
        raise ConfigError(f"calflow history: --settings: expected a JSON object, got {args.settings!r}")
    try:  # before anything is read: a reliability outside (0, 1), a tolerance <= 0
        check_settings(settings.get("reliability", 0.95), settings.get("tolerance_um"), "stage settings")
    except ValueError as exc:
        raise ConfigError(f"calflow history: --settings: {exc}") from None
    results = Path(args.results)
    earlier = previous(Path(args.out))
    campaigns = [
        _campaign(Path(f), Path(s), args.stage, results, earlier) for f, s in zip(files, args.summaries)
    ]
    _same_robot(campaigns, args.stage)
    pairs = [(c, _summary(s, load_summary)) for c, s in zip(campaigns, args.summaries)]
    gone = departed(args.stage, [c["name"] for c in campaigns], results, Path(args.campaign_dir), earlier)
    try:
        history = build(args.stage, pairs, settings, gone)
    except ValueError as exc:  # a campaign's tolerance_um the schema would have refused
        raise ConfigError(f"calflow history: {exc}") from None
    if history["robot"] is None:  # every campaign gone: the stage's robot is still the history's
        history["robot"] = earlier.get("robot")
    write_json(jsonable(history), args.out)


def _summary(path: str, load) -> dict:
    """A member's summary.json, or one line naming it: the job fails and the workflow keeps the
    earlier history (its outputs are updated in place) rather than one without the campaign."""
    try:
        data = load(path)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: expected a campaign's summary (JSON), got {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(
            f"{path}: expected a campaign's summary (a JSON mapping), got {type(data).__name__}"
        )
    return data


def _campaign(file: Path, summary: Path, stage: str, results: Path, earlier: dict) -> dict:
    """A member of the stage's history: its campaign file, loaded and checked; else what is
    known of it on disk (calflow.lifecycle.members.describe), with a note saying whence."""
    from calflow.configuration.campaign import load as load_campaign
    from calflow.lifecycle.members import describe
    from calflow.lifecycle.stages import check_stage_id

    name = summary.parent.name
    why = None
    if file.is_file():
        try:
            c = load_campaign(file)
        except ConfigError as exc:
            why = f"{file} does not load now ({exc})"
        else:
            if c.get("stage") != stage:
                raise ConfigError(
                    f"{file}: key 'stage': expected {stage!r}, the stage whose history is asked for"
                )
            return c
    known = describe(name, results, file.parent, {stage: earlier}) if why is None else None
    if why is not None:  # the file is there but no longer valid: what it says, read as it is
        known = describe(name, results, file.parent, {})
        if known is not None:
            known["note"] = f"{why}: its start and stage read from the file as it is"
    if known is None or known.get("stage") != stage or known.get("start") is None:
        raise ConfigError(
            f"{file}: key 'stage': expected a campaign file of stage {stage!r} for {summary} (or "
            "the stage's earlier history listing it, or a summary recording stage and start), found none"
        )
    check_stage_id(known["stage"], file)
    robot = known.get("robot") or _summary(str(summary), lambda p: json.loads(Path(p).read_text())).get(
        "robot"
    )
    return {
        "name": name,
        "stage": stage,
        "robot": robot,
        "start": known["start"],
        "tolerance_um": known.get("tolerance_um"),
        "note": known["note"],
    }


def _same_robot(campaigns: list[dict], stage: str) -> None:
    robots = {c["robot"] for c in campaigns}
    if len(robots) > 1:
        first = campaigns[0]
        other = next(c for c in campaigns if c["robot"] != first["robot"])
        raise ConfigError(
            f"{other['name']}.yaml: key 'robot': expected {first['robot']!r} as the other campaigns "
            f"of stage {stage!r} ({first['name']}), got {other['robot']!r}"
        )


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
