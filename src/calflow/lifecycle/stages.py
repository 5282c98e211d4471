"""Which campaigns calibrated which physical stage, checked before anything runs.

A campaign may name its stage (``stage: <id>``, the stage's serial number). Refused, each
with one line naming the campaign file and the key: a stage whose campaigns are of
different robots; two campaigns of one stage with the same ``start`` (dates out of order
are fine: histories are sorted); an interim check whose reference campaign is not in the
configuration, is not a calibration, or belongs to another stage; an as-found step whose
reference is not in the configuration.
"""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

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


def _start(campaign: dict) -> dt.datetime:
    return dt.datetime.fromisoformat(str(campaign["start"]).replace("Z", "+00:00"))


def _check_family(campaign: dict, file: Path) -> None:
    """The campaign's robot family can describe a campaign for a history."""
    from calflow.family import family_of

    family = family_of(campaign["robot"])
    if not family.history_entry:
        raise ConfigError(
            f"{file}: key 'stage': the {family.name} family does not take part in stage histories "
            "(no history_entry); remove the key"
        )


def stages_of(campaigns: dict[str, dict], folder: str | Path = "config/campaigns") -> dict[str, list[str]]:
    """Stage id → its campaign names (in ``start`` order), checked as the module says.
    ``campaigns`` maps a campaign's name to its loaded configuration."""
    groups: dict[str, list[str]] = {}
    for name, c in campaigns.items():
        stage = c.get("stage")
        if stage is not None:
            groups.setdefault(check_stage_id(stage, Path(folder) / f"{name}.yaml"), []).append(name)
    for name, c in campaigns.items():
        check = c.get("interim_check")
        if check is None:
            continue
        file = Path(folder) / f"{name}.yaml"
        ref = check.get("reference")
        if ref not in campaigns:
            raise ConfigError(
                f"{file}: key 'interim_check.reference': expected a calibration campaign of this "
                f"run, got {ref!r} (not among the configuration's campaigns)"
            )
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
    for name, c in campaigns.items():
        ref = (c.get("as_found") or {}).get("reference")
        if ref is not None and ref not in campaigns:
            raise ConfigError(
                f"{Path(folder) / f'{name}.yaml'}: key 'as_found.reference': expected a calibration "
                f"campaign of this run, got {ref!r} (not among the configuration's campaigns)"
            )
    for stage, names in groups.items():
        _check_family(campaigns[names[0]], Path(folder) / f"{names[0]}.yaml")
        robots = {campaigns[n]["robot"] for n in names}
        if len(robots) > 1:
            first = names[0]
            other = next(n for n in names if campaigns[n]["robot"] != campaigns[first]["robot"])
            raise ConfigError(
                f"{Path(folder) / f'{other}.yaml'}: key 'robot': expected "
                f"{campaigns[first]['robot']!r} as the other campaigns of stage {stage!r} "
                f"({first}), got {campaigns[other]['robot']!r}"
            )
        seen: dict[dt.datetime, str] = {}
        for n in names:
            t = _start(campaigns[n])
            if t in seen:
                raise ConfigError(
                    f"{Path(folder) / f'{n}.yaml'}: key 'start': expected a start different from "
                    f"every other campaign of stage {stage!r}, got {campaigns[n]['start']!r} "
                    f"as {seen[t]}"
                )
            seen[t] = n
        names.sort(key=lambda n: _start(campaigns[n]))
    return groups
