#!/usr/bin/env python
"""Every benchmark of benchmarks/ at its small ``--smoke`` size, so none rots unseen (CI:
``make bench-smoke``). The workflow's own benchmark runs first (nano2d-thesis alone,
``bench_footprint.py --smoke``, kept in a scratch folder) and the benchmarks that read a
finished run read that one. Those that run the workflow themselves do it on shortened
campaigns (a nano2d-thesis of 2 training cycles, an xytheta-thesis of 120 poses, a study of
four points), those that kill acquisitions kill each rig once. Prints one line per benchmark
(its exit status and seconds) and exits 1 if any failed.

    .venv/bin/python benchmarks/smoke.py [--only NAME ...]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PY = sys.executable

#: benchmark → its smoke arguments; ``{run}``: the smoke run's project folder
SMOKE = {
    "bench_footprint.py": ["--smoke", "--json", "--keep", "{run}"],
    "job_sizes.py": ["{run}/results", "--check"],
    "compare_summaries.py": ["--smoke", "{run}/results"],
    "bench_report.py": ["{run}", "--smoke", "--out", "{run}/bench-report"],
    "bench_identification.py": ["--smoke", "--json"],
    "bench_certificate.py": ["--smoke", "--json"],
    "bench_interval.py": ["--smoke", "--json"],
    "bench_lifecycle.py": ["--smoke", "--json"],
    "coverage_model_iii.py": ["--smoke"],
    "bad_input_catalogue.py": ["--smoke", "--json"],
    "bench_pattern.py": ["--smoke", "--json"],
    "bench_nano.py": ["--smoke"],
    "bench_max_coverage.py": ["--seeds", "4", "--trials", "500", "--json"],
    "bench_megarena_vernier.py": ["--smoke", "--json"],
    "bench_megarena_witness.py": ["--smoke", "--json"],
    "bench_megarena_residual.py": ["--smoke", "--json"],
    "make_distorted_megarena.py": ["--smoke", "{run}/distorted"],
    "bench_hpcode_vernier.py": ["--smoke", "--json"],
    "reliability_sigkill.py": ["--smoke", "--json", "--workdir", "{run}/sigkill"],
    "reliability_gcs_campaign.py": ["--smoke", "--json"],
    "bench_montecarlo.py": ["--smoke"],
    "bench_design.py": ["--smoke", "--json"],
    "bench_design_nano.py": ["--smoke", "--json"],
    "bench_workflow.sh": ["--smoke"],
    "bench_workflow_pair.sh": ["--smoke", str(HERE.parent)],  # this tree against itself
}

#: modules the benchmarks import, run through them (not on their own): module → a benchmark above
MODULES = {
    "megarena_estimand.py": "bench_megarena_witness.py",
    "megarena_realmap.py": "make_distorted_megarena.py",
    "megarena_dots.py": "bench_megarena_witness.py",
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="run these benchmarks only")
    args = ap.parse_args(argv)
    known = set(SMOKE) | set(MODULES) | {"smoke.py"}
    unknown = sorted(p.name for p in HERE.iterdir() if p.suffix in (".py", ".sh") and p.name not in known)
    if unknown:
        print(f"smoke: no smoke size for {', '.join(unknown)}: add it to benchmarks/smoke.py")
        return 1
    failed = []
    with tempfile.TemporaryDirectory(prefix="calflow-smoke-") as tmp:
        run = Path(tmp) / "project"
        for name, arguments in SMOKE.items():
            if args.only and name not in args.only and name != "bench_footprint.py":
                continue
            runner = ["bash"] if name.endswith(".sh") else [PY]
            cmd = [*runner, str(HERE / name), *(a.format(run=run) for a in arguments)]
            start = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True)
            took = time.perf_counter() - start
            print(f"{'ok' if proc.returncode == 0 else 'FAILED'}  {name} ({took:.0f} s)", flush=True)
            if proc.returncode:
                failed.append(name)
                print((proc.stdout + proc.stderr)[-2000:])
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
