"""Recorded camera frames replayed: a TIFF stack (or a folder of images) and its joints table
decoded into a run dataset (``calflow decode-run``, the workflow's ``decode_frames`` rule),
served by the replay rig (``calflow acquire --decoded``); bad inputs in one line, nothing
written. Frames are rendered by the camera model in the test: few and small.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import yaml
from conftest import SMALL_XYTHETA

from calflow.cli import main
from calflow.data.io import open_dataset
from calflow.data.validate import validate_dataset
from calflow.instruments.pattern import Camera, Pattern
from calflow.instruments.readings import render_poses

CAMERA = {"width": 352, "height": 272, "magnification": 5.0}
POSES = np.array([[700.0, 650.0, 0.0], [710.5, 640.25, 0.4], [690.0, 700.0, -0.3], [750.0, 720.0, 1.0]])


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A pattern file and four frames rendered at POSES (camera point and Θ, pattern frame)."""
    folder = tmp_path_factory.mktemp("frames")
    pattern = Pattern.make(range_um=(1500.0, 1500.0))
    pattern.save(folder / "pattern.json")
    frames = Camera(**CAMERA).render_batch(pattern, render_poses(*POSES.T), np.random.default_rng(4))
    return folder, frames


def _recording(tmp_path, rendered, frames=None, rows=None, camera=CAMERA, fmt="stack"):
    """A campaign replaying an identification run recorded as frames; returns its path."""
    import tifffile

    folder, all_frames = rendered
    frames = all_frames if frames is None else frames
    n = len(POSES) if rows is None else rows
    if fmt == "stack":
        source = tmp_path / "ident.tif"
        tifffile.imwrite(source, frames, photometric="minisblack")
        names = [str(k) for k in range(n)]
    else:
        from PIL import Image

        source = tmp_path / "ident"
        source.mkdir()
        names = []
        for k, frame in enumerate(frames):
            Image.fromarray(frame).save(source / f"f{k:03d}.png")
            names.append(f"f{k:03d}.png")
    lines = ["frame,time,cmd_x,cmd_y,cmd_theta,T1"]
    lines += [f"{names[k]},{2.0 * k},{100.0 * k},{50.0 * k},{0.5 * k},{21.0 + 0.01 * k}" for k in range(n)]
    (tmp_path / "ident.csv").write_text("\n".join(lines) + "\n")
    c = yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))
    c["rig"] = {
        "factory": "replay",
        "options": {
            "recordings": {
                "identification": {
                    "file": str(source),
                    "format": "frames",
                    "table": str(tmp_path / "ident.csv"),
                    "pattern": str(folder / "pattern.json"),
                    "camera": dict(camera),
                }
            }
        },
    }
    path = tmp_path / "recorded-frames.yaml"
    path.write_text(yaml.safe_dump(c))
    return path, source


def test_a_tiff_stack_decodes_into_a_run_the_replay_rig_serves(tmp_path, rendered):
    campaign, stack = _recording(tmp_path, rendered)
    decoded = tmp_path / "decoded" / "identification.nc"
    assert (
        main(["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(decoded)])
        == 0
    )
    ds = open_dataset(decoded, kind="run")
    assert validate_dataset(ds) == []
    assert np.all(ds["decode_status"].values == 0)
    assert np.max(np.abs(ds["meas_x"].values - POSES[:, 0])) < 0.01
    assert np.max(np.abs(ds["meas_y"].values - POSES[:, 1])) < 0.01
    assert np.max(np.abs(ds["meas_theta"].values - POSES[:, 2])) < 1e-3  # Eq. (4.26)'s Θ, sign included
    assert np.all(ds["u_meas_x"].values > 0)
    assert list(ds["cmd_x"].values) == [0.0, 100.0, 200.0, 300.0]
    assert list(ds["temperature"].sel(sensor="T1").values) == pytest.approx([21.0, 21.01, 21.02, 21.03])
    # frames stay in their file: its digest and each page's
    assert ds.attrs["frames_sha256"] == hashlib.sha256(stack.read_bytes()).hexdigest()
    pages = [hashlib.sha256(np.ascontiguousarray(f).tobytes()).hexdigest() for f in rendered[1]]
    assert list(ds["frame_sha256"].values) == pages
    run = tmp_path / "runs" / "identification.nc"
    args = ["acquire", "--campaign", str(campaign), "--plan", "identification", "--decoded", str(decoded)]
    assert main([*args, "--out", str(run)]) == 0
    served = open_dataset(run, kind="run")
    for name in ("meas_x", "meas_y", "meas_theta", "u_meas_x", "decode_status"):
        assert np.array_equal(served[name].values, ds[name].values), name
    assert served.attrs["imported_from"] == "ident.csv"


def test_a_folder_of_png_frames_decodes_too(tmp_path, rendered):
    campaign, folder = _recording(tmp_path, rendered, fmt="folder")
    out = tmp_path / "decoded.nc"
    assert (
        main(["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(out)]) == 0
    )
    ds = open_dataset(out, kind="run")
    assert np.max(np.abs(ds["meas_x"].values - POSES[:, 0])) < 0.01
    shas = [hashlib.sha256((folder / f"f{k:03d}.png").read_bytes()).hexdigest() for k in range(len(POSES))]
    assert list(ds["frame_sha256"].values) == shas


def test_frames_without_their_decoded_run_are_refused(tmp_path, rendered, capsys):
    campaign, _ = _recording(tmp_path, rendered)
    out = tmp_path / "run.nc"
    assert main(["acquire", "--campaign", str(campaign), "--plan", "identification", "--out", str(out)]) != 0
    assert "calflow decode-run" in capsys.readouterr().err and not out.exists()


def _fails(campaign, tmp_path, capsys) -> str:
    out = tmp_path / "decoded.nc"
    assert (
        main(["decode-run", "--campaign", str(campaign), "--run", "identification", "--out", str(out)]) != 0
    )
    assert not out.exists() and not list(tmp_path.glob("*.tmp*"))
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_a_stack_whose_frame_count_is_not_the_tables(tmp_path, rendered, capsys):
    campaign, stack = _recording(tmp_path, rendered, frames=rendered[1][:3])
    err = _fails(campaign, tmp_path, capsys)
    assert str(stack) in err and "3 frames" in err and "4 rows" in err


def test_a_truncated_stack(tmp_path, rendered, capsys):
    campaign, stack = _recording(tmp_path, rendered)
    data = stack.read_bytes()
    stack.write_bytes(data[: len(data) // 2])
    err = _fails(campaign, tmp_path, capsys)
    assert str(stack) in err and "not a readable" in err


def test_a_truncated_image_in_a_folder(tmp_path, rendered, capsys):
    """Refused even after WeasyPrint (the reports) made Pillow lenient in this process."""
    import weasyprint  # noqa: F401  (sets PIL.ImageFile.LOAD_TRUNCATED_IMAGES)

    campaign, folder = _recording(tmp_path, rendered, fmt="folder")
    bad = folder / "f002.png"
    bad.write_bytes(bad.read_bytes()[:200])
    err = _fails(campaign, tmp_path, capsys)
    assert str(bad) in err and "not a readable" in err


def test_frames_of_another_size_than_the_camera(tmp_path, rendered, capsys):
    campaign, stack = _recording(tmp_path, rendered, camera={**CAMERA, "width": 400})
    err = _fails(campaign, tmp_path, capsys)
    assert str(stack) in err and "400 × 272" in err and "352 × 272" in err


def test_a_table_without_a_joint(tmp_path, rendered, capsys):
    campaign, _ = _recording(tmp_path, rendered)
    table = tmp_path / "ident.csv"
    table.write_text(table.read_text().replace("cmd_theta", "theta"))
    err = _fails(campaign, tmp_path, capsys)
    assert str(table) in err and "'cmd_theta'" in err


def test_the_workflow_decodes_before_it_replays(tmp_path, rendered):
    """Snakemake: the decode_frames rule decodes the recording into decoded/<run>.nc from the
    stack, the table and the pattern file, then the acquire rule's replay rig serves it; a
    changed table decodes again."""
    from conftest import make_workdir, snakemake

    campaign, stack = _recording(tmp_path, rendered)
    work = make_workdir(tmp_path, {"rec": yaml.safe_load(campaign.read_text())})
    proc = snakemake(work, "results/rec/runs/identification.nc")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (work / "results/rec/logs/decode_frames_identification.log").exists()
    decoded = open_dataset(work / "results/rec/decoded/identification.nc", kind="run")
    run = open_dataset(work / "results/rec/runs/identification.nc", kind="run")
    assert np.array_equal(run["meas_x"].values, decoded["meas_x"].values)
    assert np.array_equal(run["decode_status"].values, decoded["decode_status"].values)
    table = tmp_path / "ident.csv"
    table.write_text(table.read_text().replace("21.03", "21.04"))  # a corrected thermometer reading
    proc = snakemake(work, "-n", "results/rec/runs/identification.nc")
    assert proc.returncode == 0 and "rule decode_frames" in proc.stdout and "rule acquire" in proc.stdout


def test_a_truncated_stack_even_when_tifffile_is_silenced(tmp_path, rendered, capsys):
    """The cut is found from the file's chain of pages, not from tifffile's log (which other
    code in the same process may have silenced)."""
    import logging

    log = logging.getLogger("tifffile")
    level = log.level
    log.setLevel(logging.CRITICAL)
    logging.disable(logging.CRITICAL)
    try:
        campaign, stack = _recording(tmp_path, rendered)
        data = stack.read_bytes()
        stack.write_bytes(data[: len(data) // 2])
        err = _fails(campaign, tmp_path, capsys)
    finally:
        logging.disable(logging.NOTSET)
        log.setLevel(level)
    assert str(stack) in err and "truncated or corrupt" in err
