"""An acquisition killed with SIGKILL and run again resumes: nothing lost, nothing duplicated."""

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT, SMALL_XYTHETA

from calflow.data.io import open_dataset

VARS = ("time", "cmd_x", "cmd_y", "cmd_theta", "meas_x", "meas_y", "meas_theta", "pose", "cycle", "direction")


def _campaign(tmp_path: Path, factory: str) -> Path:
    c = yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))
    c["identification"]["poses"] = 400
    c["rig"] = {"factory": factory, "options": {"seconds": 0.004}}
    path = tmp_path / "resumable.yaml"
    path.write_text(yaml.safe_dump(c))
    return path


def _acquire(campaign: Path, out: Path, kill_after: float | None = None) -> int:
    # toyrigs from tests/, before whatever calflow PYTHONPATH already names (a worktree's src)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "tests"), os.environ.get("PYTHONPATH")])),
    }
    cmd = [
        sys.executable,
        "-m",
        "calflow",
        "acquire",
        "--campaign",
        str(campaign),
        "--plan",
        "identification",
        "--out",
        str(out),
        "--rig-plugins",
        "toyrigs",
    ]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    if kill_after is None:
        proc.wait(timeout=300)
        return proc.returncode
    journal = Path(f"{out}.journal")
    deadline = time.monotonic() + 60
    while not journal.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(kill_after)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    return proc.returncode


@pytest.mark.process  # SIGKILLs a `calflow acquire` process on a slowed rig
@pytest.mark.parametrize("factory", ["toyrigs:slow_simulated", "toyrigs:slow_toy"])
def test_killed_acquisition_resumes_to_the_uninterrupted_dataset(tmp_path, factory):
    campaign = _campaign(tmp_path, factory)
    reference = tmp_path / "reference.nc"
    assert _acquire(campaign, reference) == 0
    out = tmp_path / "killed.nc"
    assert _acquire(campaign, out, kill_after=random.uniform(0.2, 1.0)) == -signal.SIGKILL
    assert not out.exists(), "a killed acquisition leaves no output under the final name"
    done = len(Path(f"{out}.journal").read_text().splitlines()) - 1
    assert 0 < done < 401, "the kill landed mid-run"
    assert _acquire(campaign, out) == 0
    assert not Path(f"{out}.journal").exists()
    a, b = open_dataset(reference), open_dataset(out)
    assert a.sizes["sample"] == b.sizes["sample"] == 401
    replayable = factory.endswith("simulated")
    for name in VARS:
        if name == "time" and not replayable:
            continue
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name
    if not replayable:
        # a real rig is continued, not replayed: its time axis carries on past the interruption
        t = b["time"].values
        assert np.all(np.diff(t) > 0)
        assert np.array_equal(t[:done], a["time"].values[:done])
