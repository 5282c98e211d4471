"""A recording of Megarena frames (a lab's target) replayed: the pattern file the Vernier
library writes, a TIFF stack and its joints table decoded into a run dataset
(``calflow decode-run``, the workflow's ``decode_frames`` rule) and served by the replay rig
(``calflow acquire --decoded``). The pixel size comes from the camera when it says it, from
each frame when not. Frames are rendered by calflow's camera model: few and small."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from conftest import SMALL_XYTHETA

from calflow.cli import main
from calflow.data.io import open_dataset
from calflow.data.validate import validate_dataset
from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.megarena import MegarenaPattern
from calflow.instruments.readings import render_poses

CAMERA = {"width": 384, "height": 336, "sensor_pixel_um": 5.0, "magnification": 10.0}  # 0.5 µm pixels
POSES = np.array([[300.0, 400.0, 0.0], [310.5, 390.25, 0.4], [290.0, 450.0, -0.3], [350.0, 470.0, 1.0]])


def _campaign(tmp_path, camera: dict):
    import tifffile

    pattern = MegarenaPattern(4.0, 6)
    (tmp_path / "megarena.json").write_text(json.dumps(pattern.to_library_dict(), ensure_ascii=False))
    frames = Camera(**CAMERA).render_batch(pattern, render_poses(*POSES.T), np.random.default_rng(4))
    tifffile.imwrite(tmp_path / "ident.tif", frames, photometric="minisblack")
    lines = ["frame,time,cmd_x,cmd_y,cmd_theta,T1"]
    lines += [f"{k},{2.0 * k},{100.0 * k},{50.0 * k},{0.5 * k},{21.0 + 0.01 * k}" for k in range(len(POSES))]
    (tmp_path / "ident.csv").write_text("\n".join(lines) + "\n")
    c = yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))
    c["rig"] = {
        "factory": "replay",
        "options": {
            "recordings": {
                "identification": {
                    "file": str(tmp_path / "ident.tif"),
                    "format": "frames",
                    "table": str(tmp_path / "ident.csv"),
                    "pattern": str(tmp_path / "megarena.json"),
                    "camera": camera,
                }
            }
        },
    }
    path = tmp_path / "megarena-frames.yaml"
    path.write_text(yaml.safe_dump(c))
    return path


@pytest.mark.parametrize(
    "camera",
    [CAMERA, {"width": CAMERA["width"], "height": CAMERA["height"]}],
    ids=["pixel size given", "pixel size measured"],
)
def test_megarena_frames_decode_into_a_run_the_replay_rig_serves(tmp_path, camera):
    campaign = _campaign(tmp_path, camera)
    decoded = tmp_path / "decoded" / "identification.nc"
    args = ["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(decoded)]
    assert main(args) == 0
    ds = open_dataset(decoded, kind="run")
    assert validate_dataset(ds) == []
    assert np.all(ds["decode_status"].values == 0)
    assert np.max(np.abs(ds["meas_x"].values - POSES[:, 0])) < 0.01
    assert np.max(np.abs(ds["meas_y"].values - POSES[:, 1])) < 0.01
    assert np.max(np.abs(ds["meas_theta"].values - POSES[:, 2])) < 1e-3
    run = tmp_path / "runs" / "identification.nc"
    args = ["acquire", "--campaign", str(campaign), "--plan", "identification", "--decoded", str(decoded)]
    assert main([*args, "--out", str(run)]) == 0
    served = open_dataset(run, kind="run")
    assert np.array_equal(served["meas_x"].values, ds["meas_x"].values)


def test_the_workflow_replays_a_megarena_recording_end_to_end(tmp_path):
    """Snakemake: the decode_frames rule decodes the library's Megarena pattern file and the
    stack (pixel size measured from each frame), then the acquire rule's replay rig serves the
    run: the poses the frames were rendered at, every frame decoded."""
    from conftest import make_workdir, snakemake

    campaign = _campaign(tmp_path, {"width": CAMERA["width"], "height": CAMERA["height"]})
    work = make_workdir(tmp_path, {"rec": yaml.safe_load(campaign.read_text())})
    proc = snakemake(work, "results/rec/runs/identification.nc")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (work / "results/rec/logs/decode_frames_identification.log").exists()
    run = open_dataset(work / "results/rec/runs/identification.nc", kind="run")
    assert validate_dataset(run) == [] and np.all(run["decode_status"].values == 0)
    assert np.max(np.abs(run["meas_x"].values - POSES[:, 0])) < 0.01
    assert np.max(np.abs(run["meas_theta"].values - POSES[:, 2])) < 1e-3
