"""The hexapod's export: the bundle gives the model back, its Compensator commands as calflow's
in-process model does, and a closed-loop run through the exported files on the simulated rig
reaches the in-process held-out accuracy."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from calflow.cli import main
from calflow.data.io import open_dataset
from calflow.data.runs import RunMetadata
from calflow.errors import DataError
from calflow_hexapod.export import Compensator
from calflow_hexapod.export.bundle import NETCDF, provenance, read_model, write_bundle
from calflow_hexapod.models import synthetic
from calflow_hexapod.models.calibration import HexapodModel, command
from calflow_hexapod.models.geometry import H811_TRAVEL, h811
from calflow_hexapod.models.identification import identify
from calflow_hexapod.models.ladder import LADDER, Parameters
from calflow_hexapod.stage.run_options import noise_stream

CONTROLLER = h811(pivot=(0.0, 0.0, 15_000.0))
NOMINAL = Parameters.nominal(CONTROLLER, tool=(0, 0, 60_000, 0, 0, 0))
TRUTH = synthetic.perturbed(np.random.default_rng(31), NOMINAL).replace(alpha_T=11.5e-6)
META = RunMetadata(
    campaign="hexapod-export", robot="hexapod", source="simulated", plan="export", config_sha256="0" * 64
)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A scale model identified from simulated readings, its model file and its export folder."""
    tmp = tmp_path_factory.mktemp("export")
    rng = np.random.default_rng(32)
    sigma = (0.5,) * 3 + (2e-5,) * 3
    measured, lam = synthetic.simulate(TRUTH, synthetic.random_poses(200, rng), CONTROLLER, rng, sigma)
    fit = identify(measured, lam, CONTROLLER.zero_lengths, LADDER["scale"], NOMINAL, sigma_pose=sigma)
    model = HexapodModel.from_identification("scale", fit, CONTROLLER)
    model.write(tmp / "scale.nc", META)
    write_bundle(model, tmp / "bundle", provenance(tmp / "scale.nc"), META)
    return model, tmp


def test_bundle_gives_back_the_model_to_the_bit(exported):
    model, tmp = exported
    back = read_model(tmp / "bundle")
    np.testing.assert_array_equal(back.parameters.vector(), model.parameters.vector())
    np.testing.assert_array_equal(back.controller.base, CONTROLLER.base)
    np.testing.assert_array_equal(back.controller.pivot, CONTROLLER.pivot)
    assert back.free == model.free and len(back.free) == 48
    assert back.std == model.std
    np.testing.assert_allclose(back.correlation, model.correlation, rtol=0, atol=0)
    netcdf = HexapodModel.read(tmp / "bundle" / NETCDF)
    np.testing.assert_array_equal(netcdf.parameters.vector(), model.parameters.vector())
    doc = json.loads((tmp / "bundle" / "bundle.json").read_text())
    np.testing.assert_array_equal(doc["geometry"]["base_joints_um"], model.parameters.base)
    assert doc["parameters"]["s1"]["units"] == "1" and doc["parameters"]["b1_x"]["units"] == "um"
    assert doc["provenance"]["model_file"] == "scale.nc" and len(doc["provenance"]["model_sha256"]) == 64
    ds = open_dataset(tmp / "bundle" / NETCDF, kind="model")
    assert ds["b1_x"].attrs["units"] == "um" and ds["tool_u"].attrs["units"] == "degree"


def test_bundle_of_another_format_is_refused_in_one_line(exported, tmp_path):
    _, tmp = exported
    doc = json.loads((tmp / "bundle" / "bundle.json").read_text())
    (tmp_path / "bundle.json").write_text(json.dumps({**doc, "version": 99}))
    with pytest.raises(DataError, match="'format', 'version'"):
        Compensator.load(tmp_path)
    del doc["parameters"]["p3_z"]
    (tmp_path / "bundle.json").write_text(json.dumps(doc))
    with pytest.raises(DataError, match="parameters.p3_z.value"):
        Compensator.load(tmp_path)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-0.6, 0.6), min_size=6, max_size=6))
def test_compensator_commands_as_the_in_process_model(exported, fraction):
    model, tmp = exported
    comp = Compensator.load(tmp / "bundle" / "bundle.json")
    target = (np.asarray(fraction) * H811_TRAVEL)[None]
    got = comp.command(target)
    np.testing.assert_allclose(got, command(model.parameters, CONTROLLER, target), rtol=0, atol=1e-9)
    np.testing.assert_allclose(comp.predict(got), target, rtol=0, atol=1e-6)  # the true pose lands on target
    assert np.max(np.abs(got - target)) > 1.0  # the compensation is not the identity


def test_closed_loop_runs_draw_the_held_out_runs_noise():
    assert noise_stream("closed_loop_geometric") == "validation_heldout_geometric"
    assert noise_stream("validation_heldout_geometric") == "validation_heldout_geometric"
    assert noise_stream("identification") == "identification"


def test_closed_loop_through_the_export_reaches_the_in_process_accuracy(tmp_path):
    """On a small simulated rig: identify, validate in process, export, command the held-out
    targets through the exported bundle; the two AP agree to numerical precision."""
    campaign = {
        "robot": "hexapod",
        "seed": 5,
        "rig": {"factory": "simulated"},
        "identification": {
            "plan": "random",
            "poses": 60,
            "fraction": 0.6,
            "dwell_s": 1.0,
            "initial": {"tool": [0, 0, 60000, 0, 0, 0]},
        },
        "models": {"geometric": {}},
        "validation": {"dwell_s": 1.0, "heldout": {"targets": 4, "cycles": 3}},
    }
    cfile = tmp_path / "hexapod-closed.yaml"
    cfile.write_text(yaml.safe_dump(campaign))
    runs, c = tmp_path / "runs", ["--campaign", str(cfile)]

    def cli(*argv):
        assert main(list(argv)) == 0, argv

    cli("acquire", *c, "--plan", "identification", "--out", str(runs / "identification.nc"))
    cli("identify", *c, "--model-name", "geometric", "--run", str(runs / "identification.nc"), "--out", str(tmp_path / "geometric.nc"))  # fmt: skip
    model = ["--model", str(tmp_path / "geometric.nc")]
    cli("acquire", *c, "--plan", "validation_heldout", *model, "--out", str(runs / "heldout.nc"))
    cli("hexapod-export", *c, *model, "--out", str(tmp_path / "export"))
    cli("acquire", *c, "--plan", "validation_export", *model, "--bundle", str(tmp_path / "export"), "--out", str(runs / "closed.nc"))  # fmt: skip
    for name in ("heldout", "closed"):
        cli("metrics", *c, "--run", str(runs / f"{name}.nc"), "--out", str(tmp_path / f"{name}_metrics.nc"))
    inproc = open_dataset(tmp_path / "heldout_metrics.nc", kind="metrics")
    closed = open_dataset(tmp_path / "closed_metrics.nc", kind="metrics")
    assert closed.attrs["plan"] == "validation_export" and closed.attrs["command_difference"] <= 1e-9
    assert closed.attrs["accuracy_um"] == pytest.approx(inproc.attrs["accuracy_um"], abs=1e-6)
    np.testing.assert_allclose(closed["ap"].values, inproc["ap"].values, rtol=0, atol=1e-6)
    np.testing.assert_allclose(closed["ap_c"].values, inproc["ap_c"].values, rtol=0, atol=1e-9)
    assert inproc.attrs["accuracy_um"] > 0.1  # a real accuracy, not a vacuous zero
    run = open_dataset(runs / "closed.nc", kind="run")
    assert run.attrs["bundle"] == str(tmp_path / "export")


@settings(max_examples=30, deadline=None)
@given(st.floats(0.1, 50.0), st.floats(-5.0, 5.0), st.floats(0.5, 20.0))
def test_summary_entry_says_whether_the_export_reproduces_the_model(ap, shift, rp):
    from calflow_hexapod.report.summary import NUMERICAL_UM, export_entry

    def iso(a):
        return {"accuracy_um": a, "repeatability_um": rp, **{f"accuracy_{x}_deg": 0.001 for x in "abc"}}

    # a shift within rounding of a threshold is on the edge: (ap + shift) - ap need not be shift
    assume(abs(abs(shift) - rp) > 1e-9 and abs(abs(shift) - NUMERICAL_UM) > 1e-9)
    e = export_entry(iso(ap + shift), iso(ap), 0.0)
    assert e["difference_um"] == pytest.approx(shift)
    assert e["numerically_equal"] == (abs(shift) <= NUMERICAL_UM)
    assert e["verified"] == (abs(shift) <= rp)
    assert export_entry(iso(ap), iso(ap), 0.0)["numerically_equal"]
