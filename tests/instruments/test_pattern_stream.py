"""``calflow decode`` reads and decodes a recording chunk by chunk on every core: the same
poses as the whole stack decoded at once, whatever the chunks and processes; bad files and
frames of another size in one line."""

from __future__ import annotations

import numpy as np
import pytest

from calflow.errors import DataError
from calflow.instruments.pattern import Camera
from calflow.instruments.pattern.megarena import MegarenaPattern, decode
from calflow.instruments.pattern.stream import decode_stream

CAMERA = Camera(width=256, height=224, sensor_pixel_um=5.0, magnification=10.0)
PATTERN = MegarenaPattern(4.0, 6)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    import tifffile
    from PIL import Image

    folder = tmp_path_factory.mktemp("stream")
    poses = [(300.0 + 7.3 * k, 400.0 - 5.1 * k, 3.0 * k - 9.0) for k in range(7)]
    frames = np.stack([CAMERA.render(PATTERN, *pose, rng=k) for k, pose in enumerate(poses)])
    frames[3] = 0  # a blank frame among them
    tifffile.imwrite(folder / "stack.tif", frames[:6], photometric="minisblack")
    Image.fromarray(frames[6]).save(folder / "last.png")
    return folder, frames


@pytest.mark.parametrize("jobs, chunk", [(1, 16), (2, 2), (2, 5)])
def test_the_stream_gives_the_whole_stacks_poses(recording, jobs, chunk):
    folder, frames = recording
    result, origin = decode_stream([folder / "stack.tif", folder / "last.png"], PATTERN, jobs, chunk)
    whole = decode(frames, PATTERN, workers=1)
    assert origin == [(str(folder / "stack.tif"), k) for k in range(6)] + [(str(folder / "last.png"), 0)]
    assert result.status.tolist() == whole.status.tolist() and result.status[3] == "bad_frame"
    assert (result.status == "ok").sum() == 6
    for key in ("x_um", "y_um", "theta_deg", "u_x_um", "pixel_um"):
        assert np.array_equal(getattr(result, key), getattr(whole, key), equal_nan=True), key


def test_bad_files_are_refused_in_one_line(recording, tmp_path):
    folder, _ = recording
    cut = tmp_path / "cut.tif"
    cut.write_bytes((folder / "stack.tif").read_bytes()[:-5000])
    with pytest.raises(DataError, match="cut.tif: not a readable TIFF"):
        decode_stream([cut], PATTERN, 1)
    other = tmp_path / "small.tif"
    import tifffile

    tifffile.imwrite(other, np.zeros((100, 120), np.uint8))
    with pytest.raises(DataError, match=r"small.tif: frame 0 is 120 × 100 pixels; expected 256 × 224"):
        decode_stream([folder / "stack.tif", other], PATTERN, 2, 4)


def test_a_chunk_across_files_reads_each_frame_from_its_own(recording, tmp_path):
    from calflow.instruments.pattern.stream import read_chunk

    folder, frames = recording
    import tifffile

    tifffile.imwrite(tmp_path / "reversed.tif", frames[:6][::-1], photometric="minisblack")
    units = [
        (str(folder / "stack.tif"), 4),
        (str(folder / "stack.tif"), 1),
        (str(tmp_path / "reversed.tif"), 0),
    ]
    units += [
        (str(folder / "last.png"), 0),
        (str(folder / "stack.tif"), 5),
        (str(tmp_path / "reversed.tif"), 2),
    ]
    got = read_chunk(units, frames.shape[1:])
    assert np.array_equal(got, frames[[4, 1, 5, 6, 5, 3]])
    with pytest.raises(DataError, match=r"stack.tif: frame 9: not readable"):
        read_chunk([(str(folder / "stack.tif"), 0), (str(folder / "stack.tif"), 9)])


def test_a_cell2x2_recording_streams_too(tmp_path):
    """calflow's own layout goes the same way: chunk by chunk on two processes, the whole
    stack's poses."""
    import tifffile

    from calflow.instruments.pattern import Pattern
    from calflow.instruments.pattern.decode import decode as decode_cell2x2

    camera = Camera(width=224, height=192, sensor_pixel_um=12.0)
    pattern = Pattern.make(range_um=(2000, 1500))
    poses = np.array([[500.0 + 90 * k, 400.0 + 70 * k, 20.0 * k] for k in range(5)])
    frames = camera.render_batch(pattern, poses, rng=3)
    tifffile.imwrite(tmp_path / "cell.tif", frames, photometric="minisblack")
    result, origin = decode_stream([tmp_path / "cell.tif"], pattern, 2, 2, pixel_um=camera.pixel_um)
    whole = decode_cell2x2(frames, pattern, pixel_um=camera.pixel_um)
    assert len(origin) == 5 and (result.status == "ok").all()
    for key in ("x_um", "y_um", "theta_deg", "u_x_um"):
        np.testing.assert_allclose(getattr(result, key), getattr(whole, key), rtol=0, atol=1e-9, err_msg=key)


def test_hp_code_markers_stream_as_the_whole_stacks(tmp_path):
    """HP-code recordings stream too: every marker of every frame, numbered by its frame in the
    whole recording, as the whole stack decoded at once gives them."""
    import tifffile

    from calflow.instruments.pattern.hpcode import HPCodePattern, decode_markers
    from calflow.instruments.pattern.hpcode.render import render
    from calflow.instruments.pattern.stream import markers_stream

    pattern, camera = HPCodePattern(4.0, 17), Camera(width=640, height=560)
    frames = []
    for k in range(5):
        t = 10.0 * k
        truth = [(7, 60.0 - k, -3.0, t), (300, -55.0, -5.0 + k, t + 2.0)] if k != 2 else [(9, 0.0, 0.0, t)]
        frames.append(render(camera, pattern, truth, rng=k))
    frames[3] = np.zeros_like(frames[3])  # no marker: a status, not a row lost
    frames = np.stack(frames)
    tifffile.imwrite(tmp_path / "markers.tif", frames, photometric="minisblack")
    found, origin = markers_stream([tmp_path / "markers.tif"], pattern, 2, 2)
    whole = decode_markers(frames, pattern)
    assert len(origin) == 5 and found.n_frames == 5
    assert found.frame.tolist() == whole.frame.tolist() and found.number.tolist() == whole.number.tolist()
    assert found.status.tolist() == whole.status.tolist() and (found.status == "ok").sum() == 7
    for key in whole.columns:
        np.testing.assert_allclose(found.columns[key], whole.columns[key], rtol=0, atol=1e-9, err_msg=key)
