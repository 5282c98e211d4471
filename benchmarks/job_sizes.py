"""Per-rule job sizes (mem_mb, runtime, threads) from what a run's jobs measured of themselves.

Every calflow step records its own peak resident set and CPU time when it ends
(``calflow.footprint``: ``results/<campaign>/benchmarks/<step>.footprint.json``, the kernel's
peak, which no sampling misses), beside Snakemake's benchmark file (``<step>.tsv``: wall
seconds ``s``, a *sampled* ``max_rss``, ``cpu_time``). This script matches each file to its
rule through the rules' ``benchmark:`` paths, and proposes what docs/cluster.md ("Job
sizes") states:

* ``mem_mb``  = the largest measured peak times 1.5, rounded up to 100 MB, at least 200; a
  job's peak is its own plus, for each of the rule's threads, its largest child's (the
  footprint's; Snakemake's sample where a job has none);
* ``runtime`` = ten times the largest CPU time, in whole minutes, at least 1 (a job of one
  thread takes its CPU time of wall time on a quiet machine; a loaded one stretches wall
  times by any factor, so they are not the measure);
* ``threads`` = the largest CPU time / wall time, rounded, at least 1.

Usage (after a local run, e.g. ``make run``)::

    .venv/bin/python benchmarks/job_sizes.py [RESULTS_DIR] [--check] [--json]

``--check`` exits 1 if a rule's declared ``mem_mb`` is below a job's measured peak or its
``runtime`` below a job's CPU time: the declared sizes no longer cover what the jobs use.
``--json`` prints the table as one JSON line (the largest peak per rule first).
"""

from __future__ import annotations

import argparse
import ast
import csv
import json
import math
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RULE = re.compile(r"^rule (\w+):", re.MULTILINE)
BENCH = re.compile(r"^\s+benchmark:\s*\n\s+(\"[^\"]+\"|layout\.\w+\([^)]*\))", re.MULTILINE)
RESOURCE = re.compile(r"^\s+(mem_mb|runtime)=(\d+),", re.MULTILINE)
THREADS = re.compile(r"^\s+threads: (\d+)", re.MULTILINE)
CONSTRAINT = re.compile(r"^[ \t]+(\w+)=(r?\"[^\"]*\"|\w+),", re.MULTILINE)
MARGIN = 1.5  #: declared memory over the largest measured peak
FOOTPRINT = ".footprint.json"


def wildcard_constraints(texts: list[str]) -> dict[str, str]:
    """The global ``wildcard_constraints:`` of the rule files, names resolved to their
    string constants (``run=OPEN_LOOP_RUNS``), so ``acquire_{run}`` and ``acquire_{test}_{comp}``
    are told apart as Snakemake does (a constant computed at load matches anything)."""
    joined = "\n".join(texts)
    constants = {
        m.group(1): "".join(re.findall(r"\"([^\"]*)\"", m.group(2)))
        for m in re.finditer(r"^(\w+) = (\(?\s*(?:r?\"[^\"]*\"\s*)+\)?)[ \t]*$", joined, re.MULTILINE)
    }
    found = {}
    for block in re.findall(r"^wildcard_constraints:\n((?:[ \t]+.+\n)+)", joined, re.MULTILINE):
        for name, value in CONSTRAINT.findall(block):
            if value.startswith(('r"', '"')) or value in constants:
                found[name] = constants.get(value, value.lstrip("r").strip('"'))
    return found


def rule_files(root: Path = ROOT) -> list[Path]:
    """The workflow's rule files: the core's (workflow/rules) and each family's (a ``rules``
    folder of a package under src/ or plugins/)."""
    found = sorted((root / "workflow" / "rules").glob("*.smk"))
    for base in ("src", "plugins"):
        found += sorted(p for p in (root / base).rglob("rules/*.smk") if p.is_file())
    return found


def benchmark_path(expression: str) -> str:
    """A rule's ``benchmark:`` as a path: a string, or a call of calflow's layout with literal
    arguments (``layout.benchmark("{campaign}", "summarise")``), called, never evaluated."""
    if expression.startswith('"'):
        return ast.literal_eval(expression)
    from calflow.configuration import layout

    call = ast.parse(expression, mode="eval").body
    if not isinstance(call, ast.Call) or not isinstance(call.func, ast.Attribute):
        raise ValueError(f"benchmark: {expression}: expected layout.<function>(literals)")
    return getattr(layout, call.func.attr)(*(ast.literal_eval(a) for a in call.args))


def rule_patterns(files: list[Path]) -> dict[str, dict]:
    """``{rule: {"regex": compiled benchmark path without its suffix, "mem_mb": declared,
    "runtime": declared, "threads": declared}}`` from the rule files' text."""
    rules = {}
    texts = [smk.read_text() for smk in files]
    constraints = wildcard_constraints(texts)
    for text in texts:
        starts = [(m.start(), m.group(1)) for m in RULE.finditer(text)] + [(len(text), None)]
        for (start, name), (end, _) in zip(starts, starts[1:]):
            body = text[start:end]
            bench = BENCH.search(body)
            if not bench:
                continue
            path = benchmark_path(bench.group(1)).removesuffix(".tsv")
            pattern = re.sub(
                r"\\\{(\w+)\\\}", lambda m: f"(?:{constraints.get(m.group(1), '.+')})", re.escape(path)
            )
            declared = {k: int(v) for k, v in RESOURCE.findall(body)}
            threads = THREADS.search(body)
            rules[name] = {
                "regex": re.compile(f"^{pattern}$"),
                "literal": len(re.sub(r"\{\w+\}", "", path)),
                **declared,
                "threads": int(threads.group(1)) if threads else 1,
            }
    return rules


def rule_of(stem: str, rules: dict[str, dict]) -> str | None:
    """The rule whose benchmark path (without suffix) matches ``stem``; the most specific wins."""
    matches = [r for r, spec in rules.items() if spec["regex"].match(stem)]
    return max(matches, key=lambda r: rules[r]["literal"]) if matches else None


def measured(results: Path, rules: dict[str, dict]) -> dict[str, list[dict]]:
    """Per rule, one row per job: ``{job, s, peak_mb, cpu_s, source}`` from its footprint
    record (the kernel's peak) and Snakemake's benchmark file (wall time; its sampled peak
    where the job left no footprint)."""
    jobs: dict[str, dict] = {}
    for path in sorted(results.rglob("benchmarks/*")):
        name = path.name
        if name.endswith(".tsv"):
            stem = path.relative_to(results.parent).as_posix().removesuffix(".tsv")
            with path.open() as fh:
                rows = list(csv.DictReader(fh, delimiter="\t"))
            if rows:
                row = jobs.setdefault(stem, {})
                row["s"] = max(float(r["s"]) for r in rows)
                rss = [float(r["max_rss"]) for r in rows if r.get("max_rss") not in (None, "", "NA", "-")]
                row["sampled_mb"] = max(rss) if rss else 0.0
                row.setdefault("cpu_s", max(float(r["cpu_time"]) for r in rows))
        elif name.endswith(FOOTPRINT):
            stem = path.relative_to(results.parent).as_posix().removesuffix(FOOTPRINT)
            try:
                record = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            row = jobs.setdefault(stem, {})
            own, kids = (
                float(record.get("self_rss_mb", record["peak_rss_mb"])),
                float(record.get("children_rss_mb", 0)),
            )
            row.update(own_mb=own, children_mb=kids, cpu_s=float(record["cpu_s"]))
            row.setdefault("s", float(record.get("wall_s", 0.0)))
    runs: dict[str, list[dict]] = {}
    for stem, row in jobs.items():
        rule = rule_of(stem, rules)
        if rule is None:
            continue
        source = "footprint" if "own_mb" in row else "sampled"
        # its own peak and, beside it, as many children at their peak as the rule has threads
        peak = (
            row["own_mb"] + rules[rule]["threads"] * row["children_mb"]
            if "own_mb" in row
            else row.get("sampled_mb", 0.0)
        )
        runs.setdefault(rule, []).append(
            {
                "job": stem,
                "s": row.get("s", 0.0),
                "peak_mb": peak,
                "cpu_s": row.get("cpu_s", 0.0),
                "source": source,
            }
        )
    return runs


def proposal(rows: list[dict]) -> dict:
    """The sizes of the module docstring from one rule's jobs."""
    wall = max(r["s"] for r in rows)
    peak = max(r["peak_mb"] for r in rows)
    cores = max(r["cpu_s"] / max(r["s"], 1e-9) for r in rows)
    return {
        "jobs": len(rows),
        "max_s": wall,
        "peak_mb": peak,
        "largest": max(rows, key=lambda r: r["peak_mb"])["job"],
        "all_footprints": all(r["source"] == "footprint" for r in rows),
        "cores_used": cores,
        "mem_mb": max(200, 100 * math.ceil(MARGIN * peak / 100)),
        "max_cpu_s": max(r["cpu_s"] for r in rows),
        "runtime": max(1, math.ceil(10 * max(r["cpu_s"] for r in rows) / 60)),
        "threads": max(1, round(cores)),
    }


def short_of(runs: dict[str, list[dict]], rules: dict[str, dict]) -> list[str]:
    """``"rule: job peak X MB > declared Y MB"`` for every job over its rule's declaration."""
    out = []
    for rule, rows in sorted(runs.items()):
        spec = rules[rule]
        for r in rows:
            if "mem_mb" in spec and r["peak_mb"] > spec["mem_mb"]:
                out.append(
                    f"{rule}: {r['job']} peaked at {r['peak_mb']:.0f} MB > declared mem_mb={spec['mem_mb']}"
                )
            if "runtime" in spec and r["cpu_s"] > 60 * spec["runtime"]:
                out.append(
                    f"{rule}: {r['job']} took {r['cpu_s']:.0f} s of CPU > declared runtime={spec['runtime']} min"
                )
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="?", default="results", type=Path)
    ap.add_argument(
        "--rules", nargs="*", type=Path, help="rule files (default: the workflow's and the families')"
    )
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--json", action="store_true", help="one JSON line: per rule, its jobs' largest peak")
    args = ap.parse_args(argv)
    rules = rule_patterns(args.rules or rule_files())
    runs = measured(args.results.resolve(), rules)
    if not runs:
        sys.stderr.write(f"job_sizes: error: {args.results}: no benchmark file of a known rule\n")
        return 2
    table = {rule: proposal(rows) for rule, rows in runs.items()}
    if args.json:
        order = sorted(table, key=lambda r: -table[r]["peak_mb"])
        print(
            json.dumps({"rules": {r: {**table[r], "declared_mem_mb": rules[r].get("mem_mb")} for r in order}})
        )
    else:
        print(
            "| rule | jobs | longest s | peak RSS MB | cores used | mem_mb | runtime min | threads | declared |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for rule in sorted(table):
            p, spec = table[rule], rules[rule]
            declared = f"{spec.get('mem_mb', '-')} MB, {spec.get('runtime', '-')} min, {spec['threads']}"
            sampled = "" if p["all_footprints"] else " (sampled)"
            print(
                f"| {rule} | {p['jobs']} | {p['max_cpu_s']:.1f} | {p['peak_mb']:.0f}{sampled} | {p['cores_used']:.1f}"
                f" | {p['mem_mb']} | {p['runtime']} | {p['threads']} | {declared} |"
            )
    short = short_of(runs, rules)
    if args.check and short:
        sys.stderr.write("job_sizes: declared sizes below what jobs used:\n  " + "\n  ".join(short) + "\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
