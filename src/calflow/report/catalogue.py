"""The lab's catalogue of campaigns: every campaign whose results are on disk, whichever run
made them, for ``reports/index.html``.

A campaign is a folder ``results/<campaign>/``. It is *done* when it holds ``summary.json``
and no job log newer than it ends in an error; it is *failed* when it has no summary (its run
stopped before it) or a job log newer than the summary holds an error: calflow writes
``calflow: error: <file>: <field>: <what was expected>`` as one line (:func:`calflow.cli._error`),
and the catalogue shows that line. A done campaign's report is *current* unless one of the
inputs it was written from changed after it: the summary, a result file the summary lists
(``inputs``, SHA-256 compared when the file is newer than the report), the campaign file, or
calflow's version. Building the catalogue reads files only; it never reruns a campaign.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

from calflow import __version__
from calflow.configuration import layout
from calflow.configuration.campaign import raw as campaign_file
from calflow.errors import CalflowError

RESERVED = frozenset({"stages", "studies", "logs", "benchmarks"})  # results/ folders that are no campaign
ERROR_PREFIX = "calflow: error:"


def _mtime(path: Path) -> float | None:
    try:
        return path.stat().st_mtime
    except OSError:
        return None


def _logs(results: Path, name: str) -> list[Path]:
    """The job logs of a campaign (``results/<c>/logs/``, and ``results/logs/<c>/`` if any)."""
    found = []
    for folder in (results / name / "logs", results / "logs" / name):
        if folder.is_dir():
            found += [p for p in folder.rglob("*.log") if p.is_file()]
    return found


def error_line(log: Path) -> str | None:
    """The one line of a failed job's error in ``log``: calflow's last ``calflow: error:`` line, or
    the last line of a traceback (an unexpected failure); None when the log shows no error."""
    try:
        lines = [line.strip() for line in log.read_text(errors="replace").splitlines() if line.strip()]
    except OSError:
        return None
    ours = [line for line in lines if line.startswith(ERROR_PREFIX)]
    if ours:
        return ours[-1]
    if any(line.startswith("Traceback") for line in lines):
        return lines[-1]
    return None


def _failure(results: Path, name: str, summary_time: float | None) -> tuple[str, float] | None:
    """(error line, time) of the newest failed job log newer than the summary; without a summary,
    the newest log's error, or a line saying no summary was written."""
    logs = sorted(_logs(results, name), key=lambda p: _mtime(p) or 0.0, reverse=True)
    for log in logs:
        when = _mtime(log) or 0.0
        if summary_time is not None and when <= summary_time:
            break
        line = error_line(log)
        if line:
            return f"{log.name}: {line}", when
    if summary_time is None:
        when = max((_mtime(p) or 0.0 for p in logs), default=_mtime(results / name) or 0.0)
        return "no summary.json: the run stopped before its summary (see results/" + name + "/logs/)", when
    return None


def _resolve(recorded: str, results: Path) -> Path:
    """A path the summary recorded (relative to the workflow's folder, ``results/...``)."""
    p = Path(recorded)
    return p if p.is_absolute() else results.resolve().parent / p


def staleness(
    summary: dict, summary_path: Path, report: Path, campaign_file: Path | None, results: Path
) -> list[str]:
    """Why a campaign's report is not current (empty: it is): what changed after it was written."""
    from calflow.data.io import sha256_file

    written = _mtime(report)
    if written is None:
        return ["no report"]
    why = []
    if (_mtime(summary_path) or 0.0) > written:
        why.append("summary.json is newer than the report")
    for recorded, digest in (summary.get("inputs") or {}).items():
        path = _resolve(recorded, results)
        when = _mtime(path)
        if when is None:
            why.append(f"{recorded} is gone")
        elif when > written and sha256_file(path) != digest:
            why.append(f"{recorded} changed")
    if campaign_file is not None and (_mtime(campaign_file) or 0.0) > written:
        why.append(f"{campaign_file.name} was edited after the report")
    if summary.get("calflow_version") not in (None, __version__):
        why.append(f"made by calflow {summary['calflow_version']}, this is {__version__}")
    return why


def _headline(summary: dict) -> dict | None:
    """The family's headline of a summary with its value and the declared reference's value."""
    from calflow.configuration.campaign import dig
    from calflow.family import family_of, resolve

    try:
        target = family_of(summary.get("robot", "")).headline
    except CalflowError:  # a campaign of a family that is no longer installed
        return None
    head = resolve(target)(summary) if target else None
    if not head:
        return None
    ref = summary.get("reference") or {}
    return {**head, "value": dig(summary, head["key"]), "reference": dig(ref, head["key"]) if ref else None}


def _campaign_yaml(campaign_dir: Path | None, name: str) -> tuple[Path | None, dict]:
    if campaign_dir is None:
        return None, {}
    path = campaign_dir / f"{name}.yaml"
    if not path.is_file():
        return None, {}
    try:
        data = campaign_file(path)
    except CalflowError:  # the index lists what it can read; the config check names the fault
        data = None
    return path, data if isinstance(data, dict) else {}


def histories(results: Path) -> list[dict]:
    """Every stage history on disk (``results/stages/<id>/history.json``), by stage."""
    out = []
    for path in sorted((results / "stages").glob("*/history.json")):
        try:
            out.append(json.loads(path.read_text()))
        except (OSError, ValueError):
            continue
    return out


def _when(seconds: float) -> str:
    return dt.datetime.fromtimestamp(seconds, dt.UTC).strftime("%Y-%m-%d %H:%M UTC")


def entry(results: Path, reports: Path, name: str, campaign_dir: Path | None = None) -> dict | None:
    """One campaign of the catalogue, or None when ``results/<name>/`` holds no campaign."""
    folder = results / name
    summary_path = folder / "summary.json"
    summary_time = _mtime(summary_path)
    if summary_time is None and not _logs(results, name):
        return None
    campaign_file, spec = _campaign_yaml(campaign_dir, name)
    row = {
        "campaign": name,
        "robot": spec.get("robot"),
        "rig": (spec.get("rig") or {}).get("factory"),
        "stage": spec.get("stage"),
        "summary": None,
        "headline": None,
        "error": None,
        "stale": [],
    }
    failed = _failure(results, name, summary_time)
    if summary_time is not None:
        try:
            summary = json.loads(summary_path.read_text())
        except (OSError, ValueError) as exc:
            summary, failed = None, (f"summary.json does not parse: {exc}", summary_time)
        if summary is not None and not isinstance(summary, dict):
            summary, failed = None, ("summary.json: expected a mapping of keys", summary_time)
        if summary is not None:
            row.update(summary=summary, robot=summary.get("robot"), rig=summary.get("rig"))
            row["stage"] = summary.get("stage") or row["stage"]
            row["headline"] = _headline(summary)
            row["stale"] = staleness(
                summary, summary_path, reports / name / "report.html", campaign_file, results
            )
    row["status"] = "failed" if failed else "done"
    row["error"] = failed[0] if failed else None
    row["time"] = failed[1] if failed else summary_time
    row["written"] = _when(row["time"])
    start = (row["summary"] or {}).get("start") or spec.get("start")
    row["start"] = _start(start)
    # the campaign's date is its start on the rig (a stage's life in order); else when its results were written
    row["date"] = (
        dt.datetime.fromtimestamp(row["start"], dt.UTC).date().isoformat() if row["start"] else row["written"]
    )
    row["current"] = not failed and not row["stale"]
    row["footprint"] = footprint_of(folder)
    row["report"] = (reports / name / "report.html").is_file()
    row["certificate"] = (reports / name / "certificate.html").is_file()
    row["decision"] = ((row["summary"] or {}).get("certificate") or {}).get("decision")
    # as found and as left, each labelled, when the campaign decided both
    given = ((row["summary"] or {}).get("certificate") or {}).get("decisions") or {}
    row["decisions"] = {k: given[k] for k in ("as_found", "as_left") if given.get(k)}
    return row


def _start(value) -> float | None:
    """A campaign's ``start`` (ISO 8601) as POSIX seconds; None when absent or unreadable."""
    if value is None:
        return None
    try:
        when = dt.datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except ValueError:
        return None
    return (when if when.tzinfo else when.replace(tzinfo=dt.UTC)).timestamp()


def footprint_of(folder: Path) -> dict | None:
    """What a campaign's jobs measured of themselves (:mod:`calflow.footprint`): ``{jobs,
    peak_mb, step, cpu_s}`` — the largest peak resident set and its step, the CPU seconds of
    all the jobs — or None when none left a record."""
    from calflow.footprint import SUFFIX, records

    found = records(folder / "benchmarks") if (folder / "benchmarks").is_dir() else []
    if not found:
        return None
    top = max(found, key=lambda r: r["peak_rss_mb"])
    return {
        "jobs": len(found),
        "peak_mb": float(top["peak_rss_mb"]),
        "step": top["path"].rsplit("/", 1)[-1].removesuffix(SUFFIX),
        "cpu_s": float(sum(r.get("cpu_s", 0.0) for r in found)),
    }


def catalogue(
    results: str | Path = layout.RESULTS,
    reports: str | Path = layout.REPORTS,
    campaign_dir: str | Path | None = None,
) -> dict:
    """``{"groups": [{"stage", "history", "campaigns"}], "histories"}``: every campaign on disk,
    newest first (by its ``start``, else when its results were written), grouped by the stage it names (a stage's history on disk, or the campaign's
    ``stage`` key); campaigns of no stage last, in a group whose ``stage`` is None."""
    results, reports = Path(results), Path(reports)
    folder = Path(campaign_dir) if campaign_dir else None
    names = (
        sorted(p.name for p in results.iterdir() if p.is_dir() and p.name not in RESERVED)
        if results.is_dir()
        else []
    )
    rows = [r for r in (entry(results, reports, n, folder) for n in names) if r]
    hist = histories(results)
    of_stage = {c["campaign"]: h["stage"] for h in hist for c in h.get("campaigns") or []}
    for r in rows:
        r["stage"] = of_stage.get(r["campaign"], r["stage"])
    rows.sort(key=lambda r: (-(r["start"] or r["time"] or 0.0), r["campaign"]))
    groups: dict = {}
    for r in rows:
        groups.setdefault(r["stage"], []).append(r)
    staged = [s for s in groups if s is not None]  # ordered by their newest campaign
    known = {h["stage"] for h in hist}
    return {
        "groups": [{"stage": s, "history": s in known, "campaigns": groups[s]} for s in staged]
        + ([{"stage": None, "history": False, "campaigns": groups[None]}] if None in groups else []),
        "histories": hist,
    }


def listing_digest(results: str | Path = layout.RESULTS, exclude: tuple[str, ...] = ()) -> list:
    """What the index depends on beyond its inputs: the campaigns on disk other than ``exclude``
    (the run's own, which the index rule takes as inputs), each with the time of its summary
    and of its newest log — unchanged by a run that does nothing, changed by another run's
    campaign, a deletion or a failure."""
    results = Path(results)
    if not results.is_dir():
        return []
    out = []
    for p in sorted(results.iterdir()):
        if not p.is_dir() or p.name in RESERVED or p.name in exclude:
            continue
        logs = _logs(results, p.name)
        summary = _mtime(p / "summary.json")
        if summary is None and not logs:
            continue
        out.append([p.name, summary, max((_mtime(x) or 0.0 for x in logs), default=None)])
    return out
