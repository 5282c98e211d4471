"""Every calflow step measures itself (calflow.footprint): the kernel's peak resident set and
CPU time, in the job's log and in a record beside Snakemake's benchmark file."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from calflow import footprint


def test_record_goes_beside_the_benchmark_of_the_log():
    assert footprint.record_path(Path("results/c/logs/summarise.log")) == Path(
        "results/c/benchmarks/summarise.footprint.json"
    )
    assert footprint.record_path(Path("/x/elsewhere/job.txt")) == Path("/x/elsewhere/job.txt.footprint.json")


def test_stderr_to_a_file_outside_logs_gets_the_line_and_no_file(tmp_path):
    log = tmp_path / "err.txt"
    code = "import sys; from calflow.cli import main; sys.exit(main(['check-config', sys.argv[1]]))"
    with log.open("w") as fh:
        subprocess.run([sys.executable, "-c", code, str(tmp_path / "missing.yaml")], stderr=fh, check=False)
    assert "calflow: footprint: check-config" in log.read_text()
    assert not list(tmp_path.rglob("*.footprint.json"))


def test_measure_sees_an_allocation_it_no_longer_holds():
    """ru_maxrss is the peak: 200 MB touched then freed still count (what sampling misses).
    In a fresh process, whose peak so far is its imports'."""
    code = (
        "import json; from calflow import footprint\n"
        "before = footprint.measure()\n"
        "block = bytearray(200_000_000); block[::4096] = b'x' * len(block[::4096]); del block\n"
        "print(json.dumps([before, footprint.measure()]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    before, after = json.loads(out)
    assert after["self_rss_mb"] >= before["self_rss_mb"] + 150
    assert after["peak_rss_mb"] >= after["self_rss_mb"]
    assert after["cpu_s"] >= after["user_s"] >= 0


def test_a_step_whose_stderr_is_a_log_writes_its_line_and_record(tmp_path):
    logs = tmp_path / "results" / "c" / "logs"
    logs.mkdir(parents=True)
    log = logs / "check.log"
    code = "import sys; from calflow.cli import main; sys.exit(main(['check-config', sys.argv[1]]))"
    with log.open("w") as fh:
        done = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path / "missing.yaml")], stderr=fh, check=False
        )
    assert done.returncode != 0  # a failed step is measured too
    last = log.read_text().strip().splitlines()[-1]
    assert last.startswith("calflow: footprint: check-config: peak resident ")
    record = json.loads((tmp_path / "results" / "c" / "benchmarks" / "check.footprint.json").read_text())
    assert record["command"] == "check-config" and record["status"] == done.returncode
    assert 10 < record["peak_rss_mb"] < 2000 and record["cpu_s"] > 0
    found = footprint.records(tmp_path / "results")
    assert [r["path"] for r in found] == ["results/c/benchmarks/check.footprint.json"]


def test_a_step_on_a_terminal_or_pipe_writes_nothing(tmp_path):
    code = "import sys; from calflow.cli import main; sys.exit(main(['check-config', sys.argv[1]]))"
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "missing.yaml")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert "footprint" not in done.stderr
    assert not list(tmp_path.rglob("*.footprint.json"))
