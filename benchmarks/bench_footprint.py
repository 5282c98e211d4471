#!/usr/bin/env python
"""Memory and CPU of every job of the default campaigns and the study, as each job measured
itself (``calflow.footprint``: the kernel's peak resident set, which Snakemake's sampling
misses), and the largest peak per rule beside its declared ``mem_mb``.

A clean scratch copy of the project (Snakefile, workflow/, config/) runs
``snakemake --cores 2 --resources mem_mb=3000`` (the memory a lab PC with 4 GB free can
give), so nothing under the repository's results/ is touched. Prints, per rule, the largest
peak, the job that reached it, its CPU time and the declared size; then the largest peak of
any job, the xytheta-thesis summary's CPU time, and whether every job stayed within its
declaration. ``--smoke``: the small nano2d-thesis campaign alone, no study (a minute), for CI.

    .venv/bin/python benchmarks/bench_footprint.py --json            # the default run and study
    .venv/bin/python benchmarks/bench_footprint.py --smoke --json    # CI
    .venv/bin/python benchmarks/bench_footprint.py --results results  # a finished run, not run again
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_montecarlo import machine  # noqa: E402


def _job_sizes():
    spec = importlib.util.spec_from_file_location("job_sizes", Path(__file__).with_name("job_sizes.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(work: Path, smoke: bool, mem_mb: int) -> dict:
    """The workflow in a scratch copy ``work``: wall and CPU seconds of Snakemake and its jobs."""
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow")
    shutil.copytree(ROOT / "config", work / "config")
    env = {
        **os.environ,
        "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}",
        "SOURCE_DATE_EPOCH": "1767225600",
        # an empty cache: every job computes what it would on a first run (its largest footprint)
        "CALFLOW_CACHE_DIR": str(work / "cache"),
    }
    cmd = [str(BIN / "snakemake"), "--cores", "2", "--resources", f"mem_mb={mem_mb}", "--quiet", "all"]
    if smoke:
        cmd += ["--config", 'campaigns=["nano2d-thesis"]', "studies=[]"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        sys.exit(f"bench_footprint: snakemake failed:\n{proc.stderr[-3000:]}")
    return {
        "wall_s": round(wall, 1),
        "cpu_s": round(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, 1),
    }


def figures(results: Path) -> dict:
    """Per rule the largest peak (MB), its job and CPU time and the declared mem_mb; the largest
    of all; the jobs over their declaration."""
    js = _job_sizes()
    rules = js.rule_patterns(js.rule_files())
    runs = js.measured(results.resolve(), rules)
    per_rule = {}
    for rule, rows in sorted(runs.items(), key=lambda kv: -max(r["peak_mb"] for r in kv[1])):
        top = max(rows, key=lambda r: r["peak_mb"])
        per_rule[rule] = {
            "jobs": len(rows),
            "peak_mb": top["peak_mb"],
            "job": top["job"],
            "cpu_s": round(max(r["cpu_s"] for r in rows), 2),
            "declared_mem_mb": rules[rule].get("mem_mb"),
            "measured_by": "footprint"
            if all(r["source"] == "footprint" for r in rows)
            else "snakemake sample",
        }
    summary = [r for r in runs.get("summarise", []) if "xytheta-thesis/" in r["job"]]
    return {
        "largest_peak_mb": max((v["peak_mb"] for v in per_rule.values()), default=None),
        "xytheta_thesis_summary_cpu_s": summary[0]["cpu_s"] if summary else None,
        "jobs": sum(v["jobs"] for v in per_rule.values()),
        "over_declared": js.short_of(runs, rules),
        "per_rule": per_rule,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="nano2d-thesis alone, no study (CI)")
    ap.add_argument("--results", type=Path, help="a finished run's results folder: read it, run nothing")
    ap.add_argument("--mem-mb", type=int, default=3000, help="snakemake --resources mem_mb (default 3000)")
    ap.add_argument("--keep", type=Path, help="run in this folder and keep it")
    ap.add_argument("--json", action="store_true", help="one JSON line")
    a = ap.parse_args()
    out: dict = {"load_average_before": [round(v, 1) for v in os.getloadavg()]}
    if a.results:
        out.update(figures(a.results))
    else:
        with tempfile.TemporaryDirectory(prefix="calflow-footprint-") as tmp:
            work = a.keep or Path(tmp)
            work.mkdir(parents=True, exist_ok=True)
            out["run"] = run(work, a.smoke, a.mem_mb)
            out.update(figures(work / "results"))
    out["machine"] = machine()
    if a.json:
        print(json.dumps(out))
    else:
        for rule, v in out.pop("per_rule").items():
            print(
                f"{rule:32s} {v['peak_mb']:7.0f} MB  (declared {v['declared_mem_mb']})  {v['cpu_s']:7.1f} s CPU  {v['job']}"
            )
        for k, v in out.items():
            print(f"{k}: {v}")
    return 1 if out.get("over_declared") else 0


if __name__ == "__main__":
    sys.exit(main())
