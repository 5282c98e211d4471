"""A stage's campaigns on disk: what its history is built from, whichever run made them.

The history of a stage (``results/stages/<id>/history.json``) holds every campaign of the
stage whose results are on disk — a folder ``results/<campaign>/`` with its
``summary.json`` — not only the campaigns of the run that rebuilds it, as the index
(:mod:`calflow.report.catalogue`) lists every campaign on disk. What is known of a campaign
on disk (:func:`describe`), first found wins:

1. its campaign file ``<campaign dir>/<campaign>.yaml`` (key ``stage``, ``robot``,
   ``start``, ``tolerance_um``), read without running anything;
2. else the stage's history on disk, which listed it (its ``start``; the history's robot);
3. else its summary, when it recorded its ``stage`` and ``start`` (an interim check's does).

The second and third are said in the history (the entry's ``note``). A campaign the history
listed whose results are gone, or whose campaign file now names another stage, leaves the
history with the reason (:func:`departed`); a run of one campaign never shrinks a history.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

from calflow.configuration import layout
from calflow.errors import CalflowError
from calflow.lifecycle.stages import STAGE_ID, takes_part


def previous(path: str | Path) -> dict:
    """A stage's history on disk (``results/stages/<id>/history.json``; ``{}`` when none, or
    when it does not parse)."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _yaml(path: Path) -> dict | None:
    from calflow.configuration.campaign import raw

    try:
        data = raw(path)
    except CalflowError:
        return None
    return data if isinstance(data, dict) else None


def _summary(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _record(stage, robot, start, tolerance, note) -> dict:
    """Plain values (a date YAML read unquoted as its ISO text): they enter the rule's digest."""
    if isinstance(start, (dt.date, dt.datetime)):
        start = start.isoformat()
    number = isinstance(tolerance, (int, float)) and not isinstance(tolerance, bool)
    return {
        "stage": stage,
        "robot": robot if isinstance(robot, str) else None,
        "start": start if isinstance(start, str) else None,
        "tolerance_um": tolerance if number else None,
        "note": note,
    }


def describe(
    name: str, results: str | Path, campaign_dir: str | Path, histories: dict[str, dict]
) -> dict | None:
    """What is known of campaign ``name`` on disk: ``{stage, robot, start, tolerance_um, note}``
    (``note`` None when its campaign file says it), or None when it names no stage.
    ``histories``: stage id → that stage's history on disk (:func:`previous`)."""
    results, folder = Path(results), Path(campaign_dir)
    file = folder / f"{name}.yaml"
    spec = _yaml(file) if file.is_file() else None
    if spec is not None:
        if spec.get("stage") is None:
            return None
        return _record(spec["stage"], spec.get("robot"), spec.get("start"), spec.get("tolerance_um"), None)
    why = f"{file} does not load" if file.is_file() else f"no campaign file {file}"
    for stage, h in sorted(histories.items()):
        for e in h.get("campaigns") or []:
            if e.get("campaign") == name:
                note = f"{why}: its start and stage are those of the stage's earlier history"
                return _record(stage, h.get("robot"), e.get("start"), e.get("tolerance_um"), note)
    summary = _summary(results / name / "summary.json")
    if summary.get("stage") is not None and summary.get("start") is not None:
        note = f"{why}: its start and stage are those its summary.json recorded"
        return _record(summary["stage"], summary.get("robot"), summary["start"], None, note)
    return None


def on_disk(
    results: str | Path = layout.RESULTS,
    campaign_dir: str | Path = "config/campaigns",
    exclude: tuple[str, ...] | frozenset = (),
) -> dict[str, dict]:
    """Every campaign with a ``summary.json`` under ``results`` (other than ``exclude``, the
    run's own) that names a stage: name → :func:`describe`."""
    # results/ folders that are no campaign (imported here: the workflow's load needs no jinja2)
    from calflow.report.catalogue import RESERVED

    results = Path(results)
    if not results.is_dir():
        return {}
    stages_dir = results / "stages"
    histories = {}
    if stages_dir.is_dir():
        histories = {p.name: h for p in sorted(stages_dir.iterdir()) if (h := previous(p / "history.json"))}
    out = {}
    for p in sorted(results.iterdir()):
        if p.name in RESERVED or p.name in exclude or not (p / "summary.json").is_file():
            continue
        d = describe(p.name, results, campaign_dir, histories)
        if d is not None and isinstance(d.get("stage"), str) and STAGE_ID.fullmatch(d["stage"]):
            out[p.name] = d  # (a stage id that is no safe folder name: its own load refuses it)
    return out


def histories_on_disk(results: str | Path, disk: dict[str, dict]) -> dict[str, str]:
    """Stage id → robot of every stage a run keeps current besides its own: the stages of the
    campaigns on disk (``disk``, :func:`on_disk`) and those with a history on disk — whose
    campaigns may all have gone — when their robot's family takes part in histories."""
    robots: dict[str, str] = {}
    for d in disk.values():
        if d.get("robot"):
            robots.setdefault(d["stage"], d["robot"])
    folder = Path(results) / "stages"
    if folder.is_dir():
        for p in sorted(folder.iterdir()):
            robot = previous(p / "history.json").get("robot")
            if STAGE_ID.fullmatch(p.name) and isinstance(robot, str):
                robots.setdefault(p.name, robot)
    return {stage: robot for stage, robot in sorted(robots.items()) if takes_part(robot)}


def departed(
    stage: str, names: list[str], results: str | Path, campaign_dir: str | Path, earlier: dict
) -> list[dict]:
    """The campaigns the stage's earlier history (``earlier``) listed, or said had left, that
    are not among ``names`` (the history's campaigns now): ``{campaign, start, kind, reason}``."""
    results, folder = Path(results), Path(campaign_dir)
    gone = [dict(e) for e in earlier.get("departed") or [] if isinstance(e, dict)]
    gone += [
        {"campaign": e.get("campaign"), "start": e.get("start"), "kind": e.get("kind")}
        for e in earlier.get("campaigns") or []
        if isinstance(e, dict)
    ]
    out, seen = [], set(names)
    for e in gone:
        name = e.get("campaign")
        if not isinstance(name, str) or name in seen:
            continue
        seen.add(name)
        summary = results / name / "summary.json"
        spec = _yaml(folder / f"{name}.yaml") if (folder / f"{name}.yaml").is_file() else None
        if not summary.is_file():
            reason = f"{summary} is no longer on disk (its results were deleted)"
        elif spec is not None and spec.get("stage") != stage:
            reason = f"{folder / f'{name}.yaml'} now names stage {spec.get('stage')!r}"
        else:
            reason = f"{summary} is on disk but no longer read as a campaign of stage {stage!r}"
        out.append({"campaign": name, "start": e.get("start"), "kind": e.get("kind"), "reason": reason})
    return sorted(out, key=lambda e: (str(e["start"]), e["campaign"]))
