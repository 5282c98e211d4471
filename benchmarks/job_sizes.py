"""Per-rule job sizes (mem_mb, runtime, threads) from a run's Snakemake benchmark files.

Every rule writes a benchmark file (``benchmark:``; columns of Snakemake's benchmark
record: wall seconds ``s``, peak resident set ``max_rss`` in MB, ``cpu_time`` in s). This
script matches each file under ``results/`` to its rule through the rules' benchmark
patterns, and proposes what docs/cluster.md ("Job sizes") states:

* ``mem_mb``  = twice the largest peak resident set of the rule's jobs, rounded up to 100 MB;
* ``runtime`` = ten times the longest wall time, in whole minutes, at least 1;
* ``threads`` = the largest CPU time / wall time, rounded, at least 1.

Usage (after a local run, e.g. ``make run``)::

    .venv/bin/python benchmarks/job_sizes.py [RESULTS_DIR] [--check]

``--check`` exits 1 if a rule's declared ``mem_mb`` or ``runtime`` is below the measured
peak (``max_rss``) or wall time: the declared sizes no longer cover what the jobs use.
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RULE = re.compile(r"^rule (\w+):", re.MULTILINE)
BENCH = re.compile(r"^\s+benchmark:\s*\n\s+\"([^\"]+)\"", re.MULTILINE)
RESOURCE = re.compile(r"^\s+(mem_mb|runtime)=(\d+),", re.MULTILINE)
THREADS = re.compile(r"^\s+threads: (\d+)", re.MULTILINE)
CONSTRAINT = re.compile(r"^[ \t]+(\w+)=(r?\"[^\"]*\"|\w+),", re.MULTILINE)


def wildcard_constraints(texts: list[str]) -> dict[str, str]:
    """The global ``wildcard_constraints:`` of the rule files, names resolved to their
    string constants (``run=OPEN_LOOP_RUNS``), so ``acquire_{run}`` and ``acquire_{test}_{comp}``
    are told apart as Snakemake does."""
    joined = "\n".join(texts)
    constants = {
        m.group(1): "".join(re.findall(r"\"([^\"]*)\"", m.group(2)))
        for m in re.finditer(r"^(\w+) = (\(?\s*(?:r?\"[^\"]*\"\s*)+\)?)", joined, re.MULTILINE)
    }
    found = {}
    for block in re.findall(r"^wildcard_constraints:\n((?:[ \t]+.+\n)+)", joined, re.MULTILINE):
        for name, value in CONSTRAINT.findall(block):
            found[name] = constants.get(value, value.lstrip("r").strip('"'))
    return found


def rule_files(root: Path = ROOT) -> list[Path]:
    """The workflow's rule files: the core's (workflow/rules) and each family's (a ``rules``
    folder of a package under src/ or plugins/)."""
    found = sorted((root / "workflow" / "rules").glob("*.smk"))
    for base in ("src", "plugins"):
        found += sorted(p for p in (root / base).rglob("rules/*.smk") if p.is_file())
    return found


def rule_patterns(files: list[Path]) -> dict[str, dict]:
    """``{rule: {"regex": compiled benchmark path, "mem_mb": declared, "runtime": declared,
    "threads": declared}}`` from the rule files' text."""
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
            pattern = re.sub(
                r"\\\{(\w+)\\\}",
                lambda m: f"(?:{constraints.get(m.group(1), '.+')})",
                re.escape(bench.group(1)),
            )
            declared = {k: int(v) for k, v in RESOURCE.findall(body)}
            threads = THREADS.search(body)
            rules[name] = {
                "regex": re.compile(f"^{pattern}$"),
                **declared,
                "threads": int(threads.group(1)) if threads else 1,
            }
    return rules


def measured(results: Path, rules: dict[str, dict]) -> dict[str, list[dict]]:
    """The benchmark records under ``results``, grouped by rule."""
    runs: dict[str, list[dict]] = {}
    for tsv in sorted(results.rglob("benchmarks/*.tsv")):
        rel = tsv.relative_to(results.parent).as_posix()
        # rules whose pattern matches; the most specific (longest literal) wins
        matches = [r for r, spec in rules.items() if spec["regex"].match(rel)]
        if not matches:
            continue
        rule = max(
            matches,
            key=lambda r: len(re.sub(r"\(\?:.*?\)", "", rules[r]["regex"].pattern)),
        )
        with tsv.open() as fh:
            rows = list(csv.DictReader(fh, delimiter="\t"))
        runs.setdefault(rule, []).extend(rows)
    return runs


def proposal(rows: list[dict]) -> dict:
    """The sizes of the module docstring from one rule's benchmark records."""
    wall = max(float(r["s"]) for r in rows)
    rss = max(float(r["max_rss"]) if r["max_rss"] not in ("", "NA", "-") else 0.0 for r in rows)
    cpu = max(float(r["cpu_time"]) / max(float(r["s"]), 1e-9) for r in rows)
    return {
        "jobs": len(rows),
        "max_s": wall,
        "max_rss_mb": rss,
        "cores_used": cpu,
        "mem_mb": 100 * math.ceil(2 * rss / 100),
        "runtime": max(1, math.ceil(10 * wall / 60)),
        "threads": max(1, round(cpu)),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="?", default="results", type=Path)
    ap.add_argument(
        "--rules", nargs="*", type=Path, help="rule files (default: the workflow's and the families')"
    )
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args(argv)
    rules = rule_patterns(args.rules or rule_files())
    runs = measured(args.results.resolve(), rules)
    if not runs:
        sys.stderr.write(f"job_sizes: error: {args.results}: no benchmark file of a known rule\n")
        return 2
    short = []
    print(
        "| rule | jobs | longest s | peak RSS MB | cores used | mem_mb | runtime min | threads | declared |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for rule in sorted(runs):
        p, spec = proposal(runs[rule]), rules[rule]
        declared = f"{spec.get('mem_mb', '-')} MB, {spec.get('runtime', '-')} min, {spec['threads']}"
        print(
            f"| {rule} | {p['jobs']} | {p['max_s']:.1f} | {p['max_rss_mb']:.0f} | {p['cores_used']:.1f}"
            f" | {p['mem_mb']} | {p['runtime']} | {p['threads']} | {declared} |"
        )
        if spec.get("mem_mb", 0) < p["max_rss_mb"] or 60 * spec.get("runtime", 0) < p["max_s"]:
            short.append(rule)
    if args.check and short:
        sys.stderr.write(f"job_sizes: declared mem_mb/runtime below the measured use: {', '.join(short)}\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
