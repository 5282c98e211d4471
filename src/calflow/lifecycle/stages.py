"""Which campaigns calibrated which physical stage, checked before anything runs.

A campaign may name its stage (``stage: <id>``, the stage's serial number). Refused, each
with one line naming the campaign file and the key: a stage whose campaigns are of
different robots; two campaigns of one stage with the same ``start`` (dates out of order
are fine: histories are sorted) — both over the run's campaigns and the stage's campaigns
whose results are on disk (:mod:`calflow.lifecycle.members`). A campaign that reads another
campaign's results (an interim check reads its reference's exported bundle,
``interim_check.reference``; a recalibration measured as found reads the exported bundle in
use, ``as_found.reference``) is refused when the other is itself, is no campaign file of the
folder, is itself such a campaign, is of another robot or stage, or starts after it
(:func:`check_reference`); and, when the other is not in the run, when its results are not
on disk (:func:`check_needs`: the line names the missing file and what to run first).
"""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Callable, Iterable
from pathlib import Path

from calflow.configuration import layout
from calflow.errors import ConfigError

STAGE_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")


def check_stage_id(stage: str, file: str | Path = "config") -> str:
    """``stage`` if it is safe as a folder name under results/stages/ and reports/stages/."""
    if not isinstance(stage, str) or not STAGE_ID.fullmatch(stage):
        raise ConfigError(
            f"{file}: key 'stage': expected letters, digits, '-' or '_' (at most 64), starting "
            f"with a letter or digit, got {stage!r}"
        )
    return stage


def parse_start(value) -> dt.datetime | None:
    """A campaign's ``start`` (ISO 8601; naive read as UTC) as an aware datetime, or None."""
    try:
        when = dt.datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except (TypeError, ValueError):
        return None
    return when if when.tzinfo else when.replace(tzinfo=dt.UTC)


def _start(campaign: dict) -> dt.datetime:
    when = parse_start(campaign["start"])
    if when is None:
        raise ValueError(f"not an ISO 8601 start: {campaign['start']!r}")
    return when


def _check_family(campaign: dict, file: Path) -> None:
    """The campaign's robot family can describe a campaign for a history."""
    from calflow.family import family_of

    family = family_of(campaign["robot"])
    if not family.history_entry:
        raise ConfigError(
            f"{file}: key 'stage': the {family.name} family does not take part in stage histories "
            "(no history_entry); remove the key"
        )


def takes_part(robot: str) -> bool:
    """Whether campaigns of ``robot`` can enter a stage's history (an installed family that
    describes its campaigns for one)."""
    from calflow.errors import CalflowError
    from calflow.family import family_of

    try:
        family = family_of(robot)
    except CalflowError:
        return False
    return bool(family.history_entry)


def check_reference(campaign: dict, file: str | Path, key: str, name: str) -> dict:
    """The raw configuration of campaign ``name``, which ``campaign`` (file ``file``) reads the
    results of through ``key`` (``interim_check.reference``), checked family-neutrally: another
    campaign of the same folder, not itself one that reads another (a chain, or a cycle of
    references, is refused here rather than loaded without end), of the same robot and stage,
    and starting before ``campaign`` (a check verifies a calibration made earlier)."""
    from calflow.configuration.campaign import raw
    from calflow.configuration.config import CAMPAIGN_NAME

    file = Path(file)
    if name == file.stem:
        raise ConfigError(
            f"{file}: key '{key}': expected another campaign (a calibration of the stage), got "
            f"{name!r}, this campaign itself"
        )
    if not isinstance(name, str) or not CAMPAIGN_NAME.fullmatch(name):
        raise ConfigError(
            f"{file}: key '{key}': expected a campaign of {file.parent} (letters, digits, '-' or '_'), "
            f"got {name!r}"
        )
    path = file.parent / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(
            f"{file}: key '{key}': expected a campaign of {file.parent}, got {name!r} (no {path.name})"
        )
    try:
        ref = raw(path)
    except ConfigError as exc:  # the reference's own line, after the key that reads it
        raise ConfigError(f"{file}: key '{key}': {exc}") from None
    if not isinstance(ref, dict):
        raise ConfigError(f"{file}: key '{key}': expected a campaign, got {name!r}, whose file is no mapping")
    if "interim_check" in ref:
        raise ConfigError(
            f"{file}: key '{key}': expected a calibration campaign, got {name!r}, itself an interim check"
        )
    if ref.get("robot") != campaign.get("robot"):
        raise ConfigError(
            f"{file}: key '{key}': expected a calibration of robot {campaign.get('robot')!r} (this "
            f"campaign's), got {name!r} of robot {ref.get('robot')!r}"
        )
    if ref.get("stage") != campaign.get("stage"):
        raise ConfigError(
            f"{file}: key '{key}': expected a calibration of stage {campaign.get('stage')!r}, got "
            f"{name!r} of stage {ref.get('stage')!r}"
        )
    if ref.get("start") is not None:
        check_after(campaign, file, name, ref["start"])
    return ref


def check_after(campaign: dict, file: str | Path, name: str, start) -> None:
    """``campaign`` starts after ``start``, that of campaign ``name`` whose results it reads."""
    mine, theirs = parse_start(campaign.get("start")), parse_start(start)
    if mine is not None and theirs is not None and mine <= theirs:
        raise ConfigError(
            f"{file}: key 'start': expected a start after that of its reference {name!r} "
            f"({start}), got {campaign.get('start')!r}"
        )


def check_needs(
    campaigns: dict[str, dict],
    folder: str | Path,
    needs: Callable[[dict], Iterable[tuple[str, str, list[str]]]],
    results: str | Path = layout.RESULTS,
) -> None:
    """Every campaign of the run that reads another campaign's results finds them: the other is
    in the run (the workflow makes them), or its files are on disk. ``needs(c)`` gives, per
    campaign, ``(key, other campaign, its files)`` (:meth:`calflow.family_workflow.FamilyWorkflow.needs`).
    Refused in one line naming the file, the key, the first missing file and what to run first."""
    for name, c in campaigns.items():
        for key, other, files in needs(c):
            if other in campaigns:
                continue
            missing = [f for f in files if not (Path(results).parent / f).is_file()]
            if missing:
                raise ConfigError(
                    f"{Path(folder) / f'{name}.yaml'}: key '{key}': expected the results of {other!r} "
                    f"on disk or {other!r} among this run's campaigns, {missing[0]} is missing: run it "
                    f"first (snakemake --cores 2 --config 'campaigns=[\"{other}\"]') or add it to the run"
                )


def stages_of(
    campaigns: dict[str, dict],
    folder: str | Path = "config/campaigns",
    disk: dict[str, dict] | None = None,
) -> dict[str, list[str]]:
    """Stage id → its campaign names in this run (in ``start`` order), checked as the module
    says. ``campaigns`` maps a campaign's name to its loaded configuration; ``disk`` the
    campaigns whose results are on disk and not in the run to what is known of them
    (:func:`calflow.lifecycle.members.on_disk`: ``stage``, ``robot``, ``start``), which the
    robot and start rules cover too."""
    groups: dict[str, list[str]] = {}
    for name, c in campaigns.items():
        stage = c.get("stage")
        if stage is not None:
            groups.setdefault(check_stage_id(stage, Path(folder) / f"{name}.yaml"), []).append(name)
    for name, c in campaigns.items():
        check = c.get("interim_check")
        ref = check.get("reference") if isinstance(check, dict) else None
        if ref is None or ref not in campaigns:
            continue  # not in the run: its file was checked at load (check_reference), its results by check_needs
        file = Path(folder) / f"{name}.yaml"
        if "interim_check" in campaigns[ref]:
            raise ConfigError(
                f"{file}: key 'interim_check.reference': expected a calibration campaign, got "
                f"{ref!r}, itself an interim check"
            )
        if campaigns[ref].get("stage") != c.get("stage"):
            raise ConfigError(
                f"{file}: key 'interim_check.reference': expected a calibration of stage "
                f"{c.get('stage')!r}, got {ref!r} of stage {campaigns[ref].get('stage')!r}"
            )
    others = {n: d for n, d in (disk or {}).items() if n not in campaigns}
    for stage, names in groups.items():
        _check_family(campaigns[names[0]], Path(folder) / f"{names[0]}.yaml")
        kept = {n: d for n, d in others.items() if d.get("stage") == stage}
        _check_robots(stage, names, campaigns, kept, Path(folder))
        _check_starts(stage, names, campaigns, kept, Path(folder))
        names.sort(key=lambda n: _start(campaigns[n]))
    return groups


def _check_robots(stage, names, campaigns, disk, folder: Path) -> None:
    """One robot per stage: the run's campaigns against each other and those on disk."""
    first = names[0]
    known = [(n, campaigns[n]["robot"], "") for n in names]
    known += [(n, d["robot"], ", on disk") for n, d in sorted(disk.items()) if d.get("robot")]
    if disk:  # the stage's robot is that of its results on disk, whatever the run adds
        first = next((n for n, _, where in known if where), first)
    robot = next(r for n, r, _ in known if n == first)
    where = ", on disk" if first in disk else ""
    for n in names:
        if campaigns[n]["robot"] != robot:
            raise ConfigError(
                f"{folder / f'{n}.yaml'}: key 'robot': expected {robot!r} as the other campaigns of "
                f"stage {stage!r} ({first}{where}), got {campaigns[n]['robot']!r}"
            )


def _check_starts(stage, names, campaigns, disk, folder: Path) -> None:
    """Distinct starts: the run's campaigns against each other and those on disk."""
    seen: dict[dt.datetime, str] = {}
    for n, d in sorted(disk.items()):
        t = parse_start(d.get("start"))
        if t is not None:
            seen.setdefault(t, f"{n}, on disk")
    for n in names:
        t = _start(campaigns[n])
        if t in seen:
            raise ConfigError(
                f"{folder / f'{n}.yaml'}: key 'start': expected a start different from every other "
                f"campaign of stage {stage!r}, got {campaigns[n]['start']!r} as {seen[t]}"
            )
        seen[t] = n
