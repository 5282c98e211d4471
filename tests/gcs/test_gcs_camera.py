"""The ``gcs`` rig's camera sensor: frames grabbed from a frame source and decoded. Tested
with the XYΘ family's emulated camera, which renders the pattern where the emulated stages
put it, through the GCS emulator; the GenICam driver's missing producer and package are one
line each. Small frames, few poses.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SMALL_XYTHETA

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.errors import RigError
from calflow.gcs.camera import CameraSensor, FrameSource, genicam
from calflow.gcs.rig import gcs
from calflow.plan import Plan
from calflow.xytheta.stage.emulate import emulated_rig_options
from calflow.xytheta.stage.rig import simulated_xytheta

CAMERA = {"width": 352, "height": 272, "magnification": 5.0}
PHYSICS = {"pattern_range_um": [1500.0, 1500.0], "camera_x_um": 750.0, "camera_y_um": 750.0}
META = RunMetadata(campaign="t", robot="xytheta", source="gcs", plan="identification", config_sha256="0" * 64)
PLAN = Plan(
    name="identification",
    commands={
        "x": np.array([0.0, 40.0, 80.0, 20.0]),
        "y": np.array([0.0, 30.0, -20.0, 60.0]),
        "theta": np.array([0.0, 0.3, 0.6, -0.4]),
    },
    targets={},
    pose=np.arange(4),
    cycle=np.zeros(4, int),
    direction=np.zeros(4, int),
    dwell_s=0.5,
)


@pytest.fixture
def pattern_file(tmp_path):
    from calflow.instruments.pattern import Pattern

    return str(Pattern.make(range_um=(1500.0, 1500.0)).save(tmp_path / "pattern.json"))


def test_emulated_camera_through_the_gcs_emulator():
    """A campaign whose simulated rig reads through images, served by the GCS emulator: the
    rig section it prints reads the pattern through the emulated camera and the decoder, and
    gives the readings of the simulated rig reading through images, within the stage's
    repeatability, with uncertainties and status."""
    options = {"sensor": "images", "camera": CAMERA, **PHYSICS}
    campaign = {**SMALL_XYTHETA, "rig": {"factory": "simulated", "options": options}}
    emu, rig_options = emulated_rig_options(campaign, time_scale=100.0, timeout=1.0)
    try:
        assert rig_options["sensor"]["factory"] == "camera"
        assert rig_options["sensor"]["options"]["source"]["factory"] == "simulated_camera"
        rig = gcs(**rig_options)
        try:
            ds = acquire(PLAN, rig, META)
        finally:
            rig.close()
    finally:
        emu.stop()
    assert validate_dataset(ds) == []
    assert np.all(ds["decode_status"].values == 0) and np.all(ds["u_meas_x"].values > 0)
    sim = acquire(
        PLAN,
        simulated_xytheta(seed=7, stream="identification", sensor="images", camera=CAMERA, **PHYSICS),
        META,
    )
    for name in ("meas_x", "meas_y"):  # same physics; the stage repeatability draws differ (0.5 µm)
        assert np.max(np.abs(ds[name].values - sim[name].values)) < 3.0, name
    assert np.max(np.abs(ds["meas_theta"].values - sim["meas_theta"].values)) < 0.01


class Frames:
    """A frame source serving given frames."""

    def __init__(self, frames):
        self.frames, self.closed = list(frames), False

    def grab(self):
        return self.frames.pop(0)

    def close(self):
        self.closed = True


def test_a_frame_of_the_wrong_size_or_type_is_one_line(pattern_file):
    from calflow.instruments.pattern import Pattern
    from calflow.instruments.readings import camera_of

    pattern, camera = Pattern.load(pattern_file), camera_of(CAMERA, "camera")
    source = Frames([np.zeros((100, 100), np.uint8), np.zeros((272, 352, 3), np.uint8)])
    assert isinstance(source, FrameSource)
    sensor = CameraSensor(source, pattern, camera)
    with pytest.raises(RigError, match=r"frame 1: expected 352 × 272 pixels.*got 100 × 100"):
        sensor.read({}, 0.0)
    with pytest.raises(RigError, match="frame 2: expected a monochrome frame"):
        sensor.read({}, 0.0)
    sensor.close()
    assert source.closed


def test_genicam_without_a_producer_file_names_what_to_set(monkeypatch):
    monkeypatch.delenv("GENICAM_GENTL64_PATH", raising=False)
    with pytest.raises(RigError) as err:
        genicam()
    assert "GenTL producer (.cti)" in str(err.value) and "GENICAM_GENTL64_PATH" in str(err.value)
    assert len(str(err.value).splitlines()) == 1


def test_genicam_without_harvesters_names_what_to_install(tmp_path, monkeypatch):
    import sys

    producer = tmp_path / "vendor.cti"
    producer.write_bytes(b"\0")
    monkeypatch.setitem(sys.modules, "harvesters", None)  # as if not installed
    monkeypatch.setitem(sys.modules, "harvesters.core", None)
    monkeypatch.setenv("GENICAM_GENTL64_PATH", str(tmp_path))
    with pytest.raises(
        RigError, match=r"harvesters package is not installed: pip install 'calflow\[genicam\]'"
    ):
        genicam()


def blank_source():
    """A frame source that knows no pattern (a plug-in of the tests)."""
    return Frames([])


def test_camera_sensor_options_are_checked(pattern_file, monkeypatch):
    from calflow.gcs.camera import camera_sensor

    with pytest.raises(RigError, match="sensor.options.source"):
        camera_sensor(source=None, pattern=pattern_file)
    with pytest.raises(RigError, match="sensor.options.pattern"):
        camera_sensor(source={"factory": "genicam"}, pattern="no/such.json")
    with pytest.raises(RigError, match="not allowed to run"):
        camera_sensor(source={"factory": "os:getcwd"}, pattern=pattern_file)
    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_gcs_camera")
    with pytest.raises(RigError, match="expected the pattern file the camera looks at"):
        camera_sensor(source={"factory": "test_gcs_camera:blank_source"}, pattern=None)
    emulated = {"factory": "simulated_camera", "options": {"camera": CAMERA, **PHYSICS}}
    sensor = camera_sensor(source=emulated, pattern=pattern_file, camera=CAMERA)
    assert sensor.pattern.range_um == (1500.0, 1500.0) and sensor.camera.width == 352


MEGARENA_CAMERA = {"width": 384, "height": 336, "sensor_pixel_um": 5.0, "magnification": 10.0}  # 0.5 µm
MEGARENA_POSES = np.array([[300.0, 400.0, 0.0], [310.5, 390.25, 0.4]])  # camera point µm, degree


def megarena_source():
    """A frame source serving frames of a Megarena target at known poses (a plug-in of the tests)."""
    from calflow.instruments.pattern import Camera
    from calflow.instruments.pattern.megarena import MegarenaPattern
    from calflow.instruments.readings import render_poses

    poses = render_poses(*MEGARENA_POSES.T)
    camera = Camera(**MEGARENA_CAMERA)
    return Frames(camera.render_batch(MegarenaPattern(4.0, 6), poses, np.random.default_rng(3)))


@pytest.mark.parametrize("given", [True, False], ids=["pixel size given", "pixel size measured"])
def test_the_camera_sensor_reads_a_megarena_target(tmp_path, monkeypatch, given):
    import json

    from calflow.gcs.camera import camera_sensor
    from calflow.instruments.pattern.megarena import MegarenaPattern

    path = tmp_path / "megarena.json"  # the Vernier library's file, as a lab has it
    path.write_text(json.dumps(MegarenaPattern(4.0, 6).to_library_dict()))
    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_gcs_camera")
    camera = MEGARENA_CAMERA if given else {"width": 384, "height": 336}
    sensor = camera_sensor(
        source={"factory": "test_gcs_camera:megarena_source"}, pattern=str(path), camera=camera
    )
    assert sensor.pattern.layout == "megarena" and sensor.measure_pixel is not given
    for x, y, theta in MEGARENA_POSES:
        r = sensor.read({}, 0.0)
        assert r["decode_status"] == 0
        assert (
            abs(r["meas_x"] - x) < 0.01
            and abs(r["meas_y"] - y) < 0.01
            and abs(r["meas_theta"] - theta) < 1e-3
        )
    sensor.close()


HPCODE_CAMERA = {"width": 640, "height": 560}  # 0.375 µm pixels (the default optics)
#: per frame: the fixed marker 0 and the moving marker 1, (number, x, y, Θ) as the renderer takes them
HPCODE_TRUTH = [
    [(0, 60.0, 50.0, 0.0), (1, -55.0, -40.0, 10.0)],
    [(0, 60.0, 50.0, 0.0), (1, -52.5, -41.0, 10.3)],
]


def hpcode_source():
    """A frame source serving frames of two HP-code markers (a plug-in of the tests)."""
    from calflow.instruments.pattern import Camera
    from calflow.instruments.pattern.hpcode import HPCodePattern
    from calflow.instruments.pattern.hpcode.render import render

    camera = Camera(**HPCODE_CAMERA)
    return Frames([render(camera, HPCodePattern(4.0, 17), t, rng=k) for k, t in enumerate(HPCODE_TRUTH)])


@pytest.mark.parametrize(
    "marker, reference", [(1, None), (None, 0)], ids=["the marker named", "against a reference"]
)
def test_the_camera_sensor_reads_hp_code_markers(tmp_path, monkeypatch, marker, reference):
    import json

    from calflow.gcs.camera import camera_sensor
    from calflow.instruments.pattern.hpcode import HPCodePattern, decode_markers, relative
    from calflow.instruments.readings import readings_of

    pattern = HPCodePattern(4.0, 17)
    path = tmp_path / "markers.json"  # the Vernier library's file, as a lab has it
    path.write_text(json.dumps(pattern.to_library_dict()))
    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_gcs_camera")
    sensor = camera_sensor(
        source={"factory": "test_gcs_camera:hpcode_source"},
        pattern=str(path),
        camera=HPCODE_CAMERA,
        marker=marker,
        reference_marker=reference,
    )
    frames = hpcode_source().frames
    for k, truth in enumerate(HPCODE_TRUTH):
        r = sensor.read({}, 0.0)
        assert r["decode_status"] == 0 and sensor.marker == 1  # named, or the lowest but the reference
        if reference is None:  # the marker's own pose (Eq. 4.26: the reading's angle is −Θ)
            _, x, y, theta = truth[1]
            assert abs(r["meas_x"] - x) < 0.05 and abs(r["meas_y"] - y) < 0.05
            assert abs(r["meas_theta"] + theta) < 0.01
        else:  # the relative pose a frames recording's replay gives
            want = readings_of(relative(decode_markers(frames[k], pattern), 1, 0, pattern.period_um))
            for key in ("meas_x", "meas_y", "meas_theta"):
                assert r[key] == pytest.approx(float(want[key][0]), abs=1e-9)
    sensor.close()


@pytest.mark.parametrize(
    "options, words",
    [
        ({"marker": 1}, "only for HP-code markers"),
        ({"reference_marker": 0}, "only for HP-code markers"),
    ],
)
def test_markers_named_for_another_layout_are_one_line(pattern_file, monkeypatch, options, words):
    from calflow.gcs.camera import camera_sensor

    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_gcs_camera")
    with pytest.raises(RigError) as err:
        camera_sensor(source={"factory": "test_gcs_camera:blank_source"}, pattern=pattern_file, **options)
    assert "\n" not in str(err.value) and words in str(err.value) and pattern_file in str(err.value)


@pytest.mark.parametrize(
    "options",
    [{"marker": -1}, {"marker": True}, {"reference_marker": "0"}, {"marker": 2, "reference_marker": 2}],
)
def test_bad_marker_numbers_are_one_line(tmp_path, monkeypatch, options):
    import json

    from calflow.gcs.camera import camera_sensor

    path = tmp_path / "markers.json"
    path.write_text(json.dumps({"HPCodePattern": {"period": 15.5, "size": 17}}))
    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_gcs_camera")
    with pytest.raises(RigError) as err:
        camera_sensor(source={"factory": "test_gcs_camera:blank_source"}, pattern=str(path), **options)
    assert "\n" not in str(err.value) and "sensor.options." in str(err.value) and str(path) in str(err.value)
