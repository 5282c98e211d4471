"""The run dataset contract, atomic writes and `calflow validate`."""

import subprocess
import sys

import numpy as np
import pytest

from calflow.acquisition.runner import acquire
from calflow.cli import main
from calflow.data.io import atomic_path, open_dataset, write_dataset
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset, validate_file
from calflow.errors import DataError
from calflow.xytheta.plans import poses as plans
from calflow.xytheta.stage.rig import simulated_xytheta


@pytest.fixture
def run():
    plan = plans.identification(20, seed=3)
    meta = RunMetadata(
        campaign="t", robot="xytheta", source="simulated", plan="identification", config_sha256="0" * 64
    )
    return acquire(plan, simulated_xytheta(seed=1, stream="id"), meta)


def test_run_dataset_follows_the_contract(run, tmp_path):
    assert validate_dataset(run) == []
    for name in (
        "time",
        "cmd_x",
        "cmd_y",
        "cmd_theta",
        "meas_x",
        "meas_y",
        "meas_theta",
        "pose",
        "cycle",
        "direction",
    ):
        assert name in run and run[name].dims == ("sample",)
        assert "units" in run[name].attrs and "long_name" in run[name].attrs
    assert run["temperature"].dims == ("sample", "sensor")
    assert run["time"].attrs["units"].startswith("seconds since ")
    assert run["cmd_theta"].attrs["units"] == "degree" and run["meas_x"].attrs["units"] == "um"
    for attr in (
        "calflow_kind",
        "calflow_version",
        "campaign",
        "robot",
        "source",
        "created",
        "config_sha256",
        "history",
    ):
        assert attr in run.attrs
    path = write_dataset(run, tmp_path / "run.nc")
    assert validate_file(path) == []
    back = open_dataset(path, kind="run")
    assert np.array_equal(back["meas_x"].values, run["meas_x"].values, equal_nan=True)


def test_validate_reports_each_problem_on_one_line(run, tmp_path):
    bad = run.drop_vars("meas_y")
    bad["cmd_x"].attrs["units"] = "mm"
    del bad.attrs["config_sha256"]
    path = write_dataset(bad, tmp_path / "bad.nc")
    problems = validate_file(path)
    assert any("'meas_y': missing" in p for p in problems)
    assert any("'cmd_x': units expected 'um', got 'mm'" in p for p in problems)
    assert any("'config_sha256': missing" in p for p in problems)
    assert all(p.startswith(str(path)) and "\n" not in p for p in problems)


def test_validate_cli_on_corrupt_and_truncated_files(run, tmp_path, capsys):
    good = write_dataset(run, tmp_path / "good.nc")
    corrupt = tmp_path / "corrupt.nc"
    corrupt.write_bytes(b"this is not netCDF at all")
    truncated = tmp_path / "truncated.nc"
    truncated.write_bytes(good.read_bytes()[:600])
    assert main(["validate", str(good)]) == 0
    for path in (corrupt, truncated):
        capsys.readouterr()
        assert main(["validate", str(path)]) != 0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(str(path))
    proc = subprocess.run(
        [sys.executable, "-m", "calflow", "validate", str(corrupt)], capture_output=True, text=True
    )
    assert proc.returncode != 0 and str(corrupt) in proc.stderr


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.nc"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []


def test_open_dataset_checks_kind(run, tmp_path):
    path = write_dataset(run, tmp_path / "run.nc")
    with pytest.raises(DataError, match="calflow_kind"):
        open_dataset(path, kind="model")


@pytest.mark.process  # three `calflow acquire` processes: the same bytes across processes
@pytest.mark.parametrize("name,plan", [("xy", "identification"), ("n1", "training")])
def test_same_seed_gives_identical_bytes(tmp_path, name, plan):
    """Two acquisitions of the same campaign and seed write byte-identical files
    (`created` follows SOURCE_DATE_EPOCH); another seed gives other noise."""
    import hashlib
    import os

    import yaml
    from conftest import SMALL_NANO1D, SMALL_XYTHETA

    campaign = SMALL_XYTHETA if name == "xy" else SMALL_NANO1D
    if name == "n1":  # 2 of its 6 training cycles: the same code path, a third of the samples to write
        campaign = {**campaign, "training": {**campaign["training"], "cycles": 2}}
    digests = []
    for k, seed in enumerate((5, 5, 6)):
        d = tmp_path / str(k)
        d.mkdir()
        (d / "c.yaml").write_text(yaml.safe_dump({**campaign, "seed": seed}))
        env = {**os.environ, "SOURCE_DATE_EPOCH": "1767225600"}
        subprocess.run(
            [
                sys.executable,
                "-m",
                "calflow",
                "acquire",
                "--campaign",
                "c.yaml",
                "--plan",
                plan,
                "--out",
                "run.nc",
            ],
            cwd=d,
            env=env,
            check=True,
        )
        digests.append(hashlib.sha256((d / "run.nc").read_bytes()).hexdigest())
    assert digests[0] == digests[1]
    a, c = open_dataset(tmp_path / "0" / "run.nc"), open_dataset(tmp_path / "2" / "run.nc")
    assert not np.allclose(a["meas_x"].values, c["meas_x"].values, equal_nan=True)  # other noise
