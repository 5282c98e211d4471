"""Nano benchmarks: five-day validation simulated and reduced at 10 Hz, training and
evaluation times, and the peak memory of a 14 h run streamed at 1 kHz.

    .venv/bin/python benchmarks/bench_nano.py [--rate-hz 1000]

Prints one line per figure and the machine; figures are recorded in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "config" / "campaigns" / "nano1d-thesis.yaml"


def calflow(*args: str, cwd: Path) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "calflow", *args], cwd=cwd, check=True)
    return time.perf_counter() - start


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def stream_peak_memory(rate_hz: float) -> tuple[float, float, int]:
    """Acquire the 14 h training plan streamed at ``rate_hz``; wall time, peak RSS (MiB), samples."""
    code = f"""
import resource, time
from calflow.acquisition.runner import acquire
from calflow.configuration.campaign import load as load_campaign
from calflow.commands.common import meta
from calflow.nano.plans import sequences as nano
from calflow.nano.stage.rig import nano1d
import numpy as np
c = load_campaign({str(CAMPAIGN)!r})
t = c["training"]
plan = nano.training_1d(np.arange(t["start_um"], t["stop_um"] + 1e-9, t["step_um"]), t["cycles"], t["dwell_s"],
                        t["average_last_s"])
rig = nano1d(**{{**c["rig"]["options"], "stream_rate_hz": {rate_hz}, "world_seed": c["seed"], "seed": 1}})
start = time.perf_counter()
ds = acquire(plan, rig, meta(c, "simulated", "training"))
wall = time.perf_counter() - start
samples = int(len(plan) * t["dwell_s"] * {rate_hz})
print(wall, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, samples, ds.sizes["sample"])
"""
    out = subprocess.run(
        [sys.executable, "-c", code], check=True, capture_output=True, text=True
    ).stdout.split()
    return float(out[0]), float(out[1]), int(out[2])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rate-hz", type=float, default=1000.0, help="stream rate of the memory benchmark")
    p.add_argument(
        "--smoke", action="store_true", help="the streamed run at 10 Hz instead of 1000 Hz, for CI"
    )
    args = p.parse_args()
    if args.smoke:
        args.rate_hz = 10.0
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        c = str(CAMPAIGN)
        t_train = calflow("acquire", "--campaign", c, "--plan", "training", "--out", "training.nc", cwd=d)
        t_single = calflow(
            "identify",
            "--campaign",
            c,
            "--model-name",
            "single",
            "--run",
            "training.nc",
            "--out",
            "single.nc",
            cwd=d,
        )
        t_kmz = calflow(
            "identify",
            "--campaign",
            c,
            "--model-name",
            "adaptive_kmz",
            "--run",
            "training.nc",
            "--out",
            "kmz.nc",
            cwd=d,
        )
        t_val = calflow(
            "acquire",
            "--campaign",
            c,
            "--plan",
            "validation",
            "--model",
            "single.nc",
            "--model",
            "kmz.nc",
            "--out",
            "validation.nc",
            cwd=d,
        )
        t_metrics = calflow(
            "metrics", "--campaign", c, "--run", "validation.nc", "--out", "metrics.nc", cwd=d
        )
    print(f"training run (17.8 h virtual, 10 Hz streams reduced): {t_train:.1f} s")
    print(f"single model trained by stepwise regression on it: {t_single:.1f} s (process incl. imports)")
    print(f"KMZ model: {t_kmz:.1f} s")
    print(f"five-day validation, 96 tests, simulated at 10 Hz and reduced: {t_val:.1f} s")
    print(f"five-day validation metrics: {t_metrics:.1f} s")
    wall, rss, samples = stream_peak_memory(args.rate_hz)
    print(
        f"training run streamed at {args.rate_hz:g} Hz ({samples / 1e6:.1f} M samples reduced): "
        f"{wall:.1f} s, peak RSS {rss:.0f} MiB"
    )
    print(f"(process baseline: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB)")


if __name__ == "__main__":
    main()
