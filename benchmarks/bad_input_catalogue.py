"""Run the bad-input catalogue of campaign and workflow files (tests/bad_input/test_bad_input_campaigns.py)
case by case in subprocesses, with a time limit, and count how many are refused at load —
before any job — in one line naming the file and what the catalogue expects.

    .venv/bin/python benchmarks/bad_input_catalogue.py [--json] [--src OTHER/src ...] [--timeout 20]

``--src`` puts another calflow source tree first on the path (e.g. an older checkout's
``src`` and ``plugins/calflow-hexapod/src``), to measure it on the same catalogue. Each case
reads ``refused`` (one line naming the file, every expected part), ``refused-other`` (refused
at load, but the line lacks a part), ``accepted`` (loaded: it would fail in a job or never),
``traceback`` or ``timeout``; the alias-bomb case also reports its load time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

LOAD = (
    "import sys\n"
    "from calflow.configuration.campaign import load as load_campaign\n"
    "from calflow.errors import ConfigError\n"
    "try:\n"
    "    load_campaign(sys.argv[1], [])\n"
    "except ConfigError as exc:\n"
    "    print(str(exc)); sys.exit(2)\n"
    "print('ACCEPTED')\n"
)


def _run(argv, cwd, env, timeout):
    t = time.perf_counter()
    try:
        proc = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", "", time.perf_counter() - t
    return proc, proc.stdout + proc.stderr, time.perf_counter() - t


def _named(expected) -> str:
    """The file a campaign case's line names: the campaign, or the reference file at fault."""
    return "ref.yaml" if any(p.startswith("ref.yaml") for p in expected) else "bad.yaml"


def _outcome(proc, out: str, named: str, expected) -> str:
    if proc == "timeout":
        return "timeout"
    lines = [line for line in out.splitlines() if line.strip()]
    if proc.returncode == 0:
        return "accepted"
    if "Traceback" in out:
        return "traceback"
    if len(lines) == 1 and named in lines[0] and all(p in lines[0] for p in expected):
        return "refused"
    return "refused-other"


BOMB_TIMER = (
    "import sys, time\n"
    "from calflow.configuration.campaign import load as load_campaign\n"
    "from calflow.errors import ConfigError\n"
    "best = float('inf')\n"
    "for _ in range(5):\n"
    "    t = time.perf_counter()\n"
    "    try:\n"
    "        load_campaign(sys.argv[1])\n"
    "    except ConfigError:\n"
    "        pass\n"
    "    best = min(best, time.perf_counter() - t)\n"
    "print(best)\n"
)


def _bomb_in_process(env, timeout) -> float | None:
    """Seconds to load (and refuse) a campaign with the alias bomb, in process, best of 5;
    None on timeout."""
    from bad_input.test_bad_input_campaigns import BOMB

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bomb.yaml"
        path.write_text((ROOT / "config" / "campaigns" / "demo-sn0042-2026-01.yaml").read_text() + BOMB)
        proc, out, _ = _run([sys.executable, "-c", BOMB_TIMER, str(path)], tmp, env, timeout)
    return None if proc == "timeout" else float(out.split()[-1])


def main(argv=None) -> int:
    import pytest
    from bad_input.test_bad_input_campaigns import CAMPAIGNS, CONFIGS, _project, write_case  # noqa: F401

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", action="append", default=[], help="a source tree put first on the path")
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument(
        "--smoke", action="store_true", help="the first three campaign cases and config cases only, for CI"
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    cases, configs = (CAMPAIGNS[:3], CONFIGS[:3]) if args.smoke else (CAMPAIGNS, CONFIGS)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([*map(str, args.src), os.environ.get("PYTHONPATH", "")]),
    }
    env.pop("CALFLOW_RIG_PLUGINS", None)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for param in cases:
            base, old, new, expected, files = param.values
            work = Path(tmp) / f"c{len(results)}"
            mp = pytest.MonkeyPatch()
            try:
                folder = _project(work, mp)
                path = write_case(folder, base, old, new, files)
            finally:
                mp.undo()
            proc, out, dt = _run([sys.executable, "-c", LOAD, str(path)], work, env, args.timeout)
            results.append(
                {
                    "case": param.id,
                    "kind": "campaign",
                    "outcome": _outcome(proc, out, _named(expected), expected),
                    "s": round(dt, 3),
                }
            )
        for param in configs:
            text, expected = param.values
            work = Path(tmp) / f"c{len(results)}"
            mp = pytest.MonkeyPatch()
            try:
                _project(work, mp)
            finally:
                mp.undo()
            (work / "config" / "config.yaml").write_text(text, encoding="utf-8")
            cmd = [sys.executable, "-m", "calflow", "check-config", "config/config.yaml"]
            proc, out, dt = _run(cmd, work, env, args.timeout)
            lines = "\n".join(line.removeprefix("calflow: error: ") for line in out.splitlines())
            results.append(
                {
                    "case": param.id,
                    "kind": "config",
                    "outcome": _outcome(proc, lines, "config/config.yaml", expected),
                    "s": round(dt, 3),
                }
            )
    counts: dict[str, int] = {}
    for r in results:
        counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
    at_load = counts.get("refused", 0) + counts.get("refused-other", 0)
    bomb = next(r["s"] for r in results if r["case"] == "alias bomb")  # with the interpreter's start
    summary = {
        "cases": len(results),
        "refused_in_one_line": counts.get("refused", 0),
        "refused_at_load": at_load,
        "share_refused_at_load": round(at_load / len(results), 3),
        "outcomes": counts,
        "alias_bomb_subprocess_s": bomb,
        "alias_bomb_load_s": _bomb_in_process(env, args.timeout),
        "src": args.src,
    }
    if args.json:
        print(json.dumps({"summary": summary, "cases": results}))
    else:
        for r in results:
            print(f"{r['outcome']:>14}  {r['s']:7.2f} s  {r['kind']:8} {r['case']}")
        print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
