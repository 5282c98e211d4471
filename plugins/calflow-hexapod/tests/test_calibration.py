"""An identified hexapod model: prediction, compensation and its netCDF file."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.data.runs import RunMetadata
from calflow_hexapod.models import synthetic
from calflow_hexapod.models.calibration import HexapodModel, command, predict
from calflow_hexapod.models.geometry import H811_TRAVEL, h811
from calflow_hexapod.models.identification import identify
from calflow_hexapod.models.ladder import LADDER, NAMES, Parameters

CONTROLLER = h811(pivot=(0.0, 0.0, 20_000.0))
NOMINAL = Parameters.nominal(CONTROLLER)
TRUTH = synthetic.perturbed(np.random.default_rng(21), NOMINAL).replace(alpha_T=11.5e-6)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-0.6, 0.6), min_size=6, max_size=6), st.floats(15.0, 25.0))
def test_command_inverts_predict(fraction, temperature):
    target = (np.asarray(fraction) * H811_TRAVEL)[None]
    found = predict(TRUTH, CONTROLLER, command(TRUTH, CONTROLLER, target, [temperature]), [temperature])
    np.testing.assert_allclose(found[:, :3], target[:, :3], atol=1e-6)
    np.testing.assert_allclose(found[:, 3:], target[:, 3:], atol=1e-9)


def test_predict_is_the_noise_free_simulation():
    rng = np.random.default_rng(22)
    commands = synthetic.random_poses(20, rng)
    measured, _ = synthetic.simulate(TRUTH, commands, CONTROLLER, rng)
    np.testing.assert_allclose(predict(TRUTH, CONTROLLER, commands), measured, atol=1e-9)
    assert np.max(np.abs(measured[:, :3] - commands[:, :3])) > 100.0  # the frames and joints show


def test_the_model_file_gives_back_the_model(tmp_path):
    rng = np.random.default_rng(23)
    measured, lam = synthetic.simulate(
        TRUTH, synthetic.random_poses(200, rng), CONTROLLER, rng, (0.5,) * 3 + (2e-5,) * 3
    )
    fit = identify(
        measured, lam, CONTROLLER.zero_lengths, LADDER["scale"], NOMINAL, sigma_pose=(0.5,) * 3 + (2e-5,) * 3
    )
    model = HexapodModel.from_identification("scale", fit, CONTROLLER)
    meta = RunMetadata(
        campaign="hexapod-test",
        robot="hexapod",
        source="simulated",
        plan="identification",
        config_sha256="0" * 64,
    )
    model.write(tmp_path / "scale.nc", meta)
    back = HexapodModel.read(tmp_path / "scale.nc")
    assert back.name == "scale" and back.free == fit.free and len(back.free) == 48
    np.testing.assert_array_equal(back.parameters.vector(), fit.parameters.vector())
    np.testing.assert_array_equal(back.controller.pivot, CONTROLLER.pivot)
    np.testing.assert_allclose(back.correlation, fit.correlation)
    assert back.std == fit.std and back.diagnostics["dropped"] == ",".join(fit.dropped)
    targets = synthetic.random_poses(5, rng)
    np.testing.assert_allclose(back.predict(back.command(targets)), targets, atol=1e-6)
    assert set(NAMES) <= set(back.to_dataset(meta).data_vars)
