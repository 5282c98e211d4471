#!/usr/bin/env python
"""Wall time of a Monte-Carlo study (issue 8) through Snakemake with 1 and 2 cores.

Each run starts from a clean scratch copy of the project (Snakefile, workflow/, config/),
so nothing under the repository's results/ is touched, and builds only the study's page
``reports/studies/<study>.html``. Prints the machine, the wall time per core count, the
CPU time of snakemake and its jobs, the number of jobs and the sum of the jobs' own
times (Snakemake benchmark files), and the load average before each run: on a machine
busy with other work, wall times overstate; CPU time does not.

    .venv/bin/python benchmarks/bench_montecarlo.py                  # default study, 1 and 2 cores
    .venv/bin/python benchmarks/bench_montecarlo.py --seeds-per-job 8 --cores 1 2 4
    .venv/bin/python benchmarks/bench_montecarlo.py --smoke    # CI: 2 seeds x 1 noise x 2 pose counts
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def machine() -> str:
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        model = platform.processor() or model
    snake = subprocess.run(
        [str(BIN / "snakemake"), "--version"], capture_output=True, text=True
    ).stdout.strip()
    return (
        f"nproc={os.cpu_count()} (usable {len(os.sched_getaffinity(0))}), CPU: {model}, "
        f"Python {platform.python_version()}, Snakemake {snake}, {platform.system()} {platform.release()}"
    )


#: ``--smoke``: the study shrunk to two point jobs (the same rules, aggregate and page)
SMOKE = {"seeds": 2, "seeds_per_job": 1, "noise_um": [0.5], "poses": [5, 20], "validation_cycles": 2}


def run(
    study: str, cores: int, seeds_per_job: int | None, tmp: Path, smoke: bool = False
) -> tuple[float, int, float, float]:
    work = tmp / f"cores{cores}"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow")
    shutil.copytree(ROOT / "config", work / "config")
    if seeds_per_job or smoke:
        path = work / "config/studies" / f"{study}.yaml"
        body = yaml.safe_load(path.read_text())
        body.update(SMOKE if smoke else {})
        body["seeds_per_job"] = seeds_per_job or body["seeds_per_job"]
        path.write_text(yaml.safe_dump(body))
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    cmd = [
        str(BIN / "snakemake"),
        "--cores",
        str(cores),
        "--config",
        f"studies=[{study}]",
        "--quiet",
        "all",
        "--",
        f"reports/studies/{study}.html",
    ]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode:
        sys.exit(f"snakemake failed ({cores} cores):\n{proc.stderr[-3000:]}")
    tsvs = list((work / "results/studies" / study / "benchmarks").glob("*.tsv"))
    job_s = sum(float(next(csv.DictReader(t.open(), delimiter="\t"))["s"]) for t in tsvs)
    return wall, len(tsvs), job_s, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="montecarlo-xytheta")
    ap.add_argument("--cores", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--seeds-per-job", type=int, help="override the study's seeds_per_job")
    ap.add_argument("--smoke", action="store_true", help="CI: the study shrunk to a few points")
    args = ap.parse_args()
    print(f"machine: {machine()}")
    body = yaml.safe_load((ROOT / "config/studies" / f"{args.study}.yaml").read_text())
    body.update(SMOKE if args.smoke else {})
    spj = args.seeds_per_job or body.get("seeds_per_job", 1)
    print(
        f"study {args.study}: {body['seeds']} seeds x noise {body['noise_um']} um x poses {body['poses']}, "
        f"seeds_per_job {spj}"
    )
    walls = {}
    for cores in args.cores:
        load = os.getloadavg()[0]
        with tempfile.TemporaryDirectory(prefix="calflow-bench-") as tmp:
            wall, jobs, job_s, cpu = run(args.study, cores, args.seeds_per_job, Path(tmp), args.smoke)
        walls[cores] = wall
        print(
            f"--cores {cores}: wall {wall:6.1f} s, CPU {cpu:6.1f} s, {jobs} jobs (sum of their times "
            f"{job_s:6.1f} s), load average before {load:.2f} (other work on the machine slows the figures)"
            + (f", speed-up {walls[args.cores[0]] / wall:.2f}x" if cores != args.cores[0] else "")
        )


if __name__ == "__main__":
    main()
