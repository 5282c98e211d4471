"""What a calflow process used: its peak resident memory and CPU time, measured by itself.

Snakemake's ``benchmark:`` samples a job's memory every few seconds and misses a short
peak (a summary job that peaked at 4.7 GB was recorded at 632 MB). The kernel keeps the
true peak of a process (``getrusage``'s ``ru_maxrss``, the largest resident set it ever
had) and of its children it has waited for, so a step that reads them when it ends misses
nothing. :func:`measure` reads them; :func:`finish` writes them, when the process runs as a
workflow job (its stderr is a file, the job's log), as one line at the end of the log and
as a small JSON record beside Snakemake's benchmark file:

``results/<campaign>/logs/<step>.log`` → ``results/<campaign>/benchmarks/<step>.footprint.json``

(stderr sent to a file in no ``logs`` folder gets the line only). ``CALFLOW_FOOTPRINT``
names the record's file instead (``-``: the log line only). :func:`records` reads them back,
for the index and ``benchmarks/bench_footprint.py``.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
from pathlib import Path

#: when the process started measuring (``calflow.cli`` imports this module first)
STARTED = time.monotonic()
SUFFIX = ".footprint.json"
#: ru_maxrss is in KiB on Linux, in bytes on macOS
_RSS_BYTES = 1 if sys.platform == "darwin" else 1024


def measure() -> dict[str, float]:
    """``{peak_rss_mb, self_rss_mb, children_rss_mb, cpu_s, user_s, system_s, wall_s}`` of
    this process so far (MB = 10⁶ bytes): its own peak resident set, the largest peak of the
    children it waited for (the kernel keeps the largest, not their sum), and ``peak_rss_mb``
    their sum — an upper bound of what the job held at once when one child ran at a time
    beside it (a job running k children at once may hold its own and k children's); CPU is
    user + system of both."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    self_mb = _own_peak_mb() or me.ru_maxrss * _RSS_BYTES / 1e6
    kids_mb = kids.ru_maxrss * _RSS_BYTES / 1e6
    user, system = me.ru_utime + kids.ru_utime, me.ru_stime + kids.ru_stime
    return {
        "peak_rss_mb": round(self_mb + kids_mb, 1),
        "self_rss_mb": round(self_mb, 1),
        "children_rss_mb": round(kids_mb, 1),
        "cpu_s": round(user + system, 3),
        "user_s": round(user, 3),
        "system_s": round(system, 3),
        "wall_s": round(time.monotonic() - STARTED, 3),
    }


def _own_peak_mb() -> float | None:
    """The peak resident set of this program since it started (Linux: ``VmHWM`` of
    /proc/self/status), or None. ``ru_maxrss`` keeps, across the ``exec`` that starts a job,
    the peak of the process that spawned it (Snakemake's own, ~150 MB): the job's is this."""
    try:
        with open("/proc/self/status") as fh:
            for text in fh:
                if text.startswith("VmHWM:"):
                    return int(text.split()[1]) * 1024 / 1e6
    except (OSError, ValueError, IndexError):
        return None
    return None


def _log_file() -> Path | None:
    """The regular file this process's stderr is written to (a workflow job's log), if any."""
    try:
        if not os.path.isfile(f"/proc/self/fd/{sys.stderr.fileno()}"):
            return None
        return Path(os.readlink(f"/proc/self/fd/{sys.stderr.fileno()}"))
    except (OSError, ValueError, AttributeError):  # no /proc (not Linux), stderr closed or replaced
        return None


def record_path(log: Path) -> Path:
    """Where the record of the job whose log is ``log`` goes (module notes)."""
    stem = log.name[: -len(".log")] if log.name.endswith(".log") else log.name
    folder = log.parent.parent / "benchmarks" if log.parent.name == "logs" else log.parent
    return folder / f"{stem}{SUFFIX}"


def line(command: str, found: dict[str, float]) -> str:
    """The log's closing line."""
    return (
        f"calflow: footprint: {command}: peak resident {found['peak_rss_mb']:.0f} MB, "
        f"CPU {found['cpu_s']:.2f} s (user {found['user_s']:.2f}, system {found['system_s']:.2f}), "
        f"wall {found['wall_s']:.2f} s"
    )


def finish(command: str, status: int) -> Path | None:
    """Write this process's footprint (module notes) when it runs as a workflow job; return
    the record's path (None when none was written). Never fails the step: a record that
    cannot be written is said so in the log."""
    target = os.environ.get("CALFLOW_FOOTPRINT", "")
    log = _log_file()
    if not target and log is None:
        return None
    found = measure()
    print(line(command, found), file=sys.stderr, flush=True)
    if target == "-" or (not target and log.parent.name != "logs"):
        return None  # a log outside a workflow's logs/ folder: the line only, no file beside it
    path = Path(target) if target else record_path(log)
    record = {"command": command, "status": int(status), "pid": os.getpid(), **found}
    if log is not None:
        record["log"] = str(log)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(record, sort_keys=True) + "\n")
        os.replace(tmp, path)
    except OSError as exc:
        print(f"calflow: footprint: {path}: not written ({exc.strerror or exc})", file=sys.stderr)
        return None
    return path


def records(root) -> list[dict]:
    """Every footprint record under ``root``, each with its ``path`` (relative to ``root``'s
    parent, as the rules name it: ``results/...``); unreadable ones are skipped."""
    root = Path(root)
    found = []
    for path in sorted(root.rglob(f"*{SUFFIX}")):
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(record, dict) and isinstance(record.get("peak_rss_mb"), (int, float)):
            record["path"] = path.relative_to(root.parent).as_posix()
            found.append(record)
    return found
