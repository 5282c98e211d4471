"""The stage settings of the workflow configuration (``stages.<id>`` of config/config.yaml or
``--config 'stages=…'``), checked against the campaigns before anything runs.

Refused, in one line naming the file (or the command line), the key and what was expected:

* a stage id no campaign names (``stage: <id>``), neither among the configuration's campaigns
  nor in the campaign folder — a typo would otherwise be a setting nobody reads;
* ``model``: a model none of the stage's calibrations identifies (the due date would watch
  nothing).
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path

from calflow.errors import CalflowError, ConfigError


def _on_disk(folder: Path) -> dict[str, dict]:
    """Campaign name → its data, for the campaign files of ``folder`` that read as a mapping
    (a file that does not is refused where it is used, not here)."""
    from calflow.configuration.campaign import raw

    out = {}
    for path in sorted(folder.glob("*.yaml")) if folder.is_dir() else ():
        try:
            data = raw(path)
        except CalflowError:
            continue
        if isinstance(data, dict):
            out[path.stem] = data
    return out


def _models(campaign: Mapping) -> set[str]:
    """The models a calibration campaign identifies (none for an interim check)."""
    if "interim_check" in campaign:
        return set()
    models = campaign.get("models")
    if isinstance(models, Mapping):
        return {str(m) for m in models}
    try:  # a family that fills in its default models
        from calflow.family_workflow import hooks

        return set(hooks(dict(campaign)).models(dict(campaign)))
    except (CalflowError, KeyError, TypeError):
        return set()


def check_stage_settings(
    settings: Mapping[str, Mapping],
    campaigns: Mapping[str, Mapping],
    folder: str | Path,
    file: str | Path = "config/config.yaml",
) -> None:
    """Refuse stage settings that no campaign reads (module docstring). ``campaigns``: the
    configuration's loaded campaigns (name → data); ``folder``: the campaign folder, whose
    other files are read for their ``stage`` and ``models`` only."""
    if not settings:
        return
    everyone = {**_on_disk(Path(folder)), **campaigns}
    by_stage: dict[str, list[Mapping]] = {}
    for c in everyone.values():
        if isinstance(c.get("stage"), str):
            by_stage.setdefault(c["stage"], []).append(c)
    for stage, values in settings.items():
        if stage not in by_stage:
            close = difflib.get_close_matches(stage, list(by_stage), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ConfigError(
                f"{file}: key 'stages.{stage}': expected the id of a stage a campaign names "
                f"(stage: <id>) in the configuration or {folder}, one of {sorted(by_stage)}, "
                f"got {stage!r}{hint}"
            )
        model = (values or {}).get("model")
        if model is not None:
            known = set().union(*(_models(c) for c in by_stage[stage]))
            if model not in known:
                raise ConfigError(
                    f"{file}: key 'stages.{stage}.model': expected one of the models the stage's "
                    f"calibrations identify {sorted(known)}, got {model!r}"
                )
