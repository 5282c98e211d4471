"""Identification of the hexapod's model ladder from synthetic poses with only the model's errors."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.errors import CalflowError
from calflow.identification.robust import Robust
from calflow_hexapod.models import synthetic
from calflow_hexapod.models.geometry import compose, h811, pose_of, transform
from calflow_hexapod.models.identification import _Data, identifiable, identify, prediction_rms, run_inputs
from calflow_hexapod.models.ladder import LADDER, NAMES, Parameters
from calflow_hexapod.models.loop import closure

CONTROLLER = h811()
NOMINAL = Parameters.nominal(CONTROLLER)
SIGMA = (0.5, 0.5, 0.5, 2e-5, 2e-5, 2e-5)  # µm, degree


def _data(truth, n, seed, sigma=SIGMA, temperature=None):
    rng = np.random.default_rng(seed)
    commands = synthetic.random_poses(n, rng)
    return synthetic.simulate(truth, commands, CONTROLLER, rng, sigma, temperature=temperature)


@functools.cache
def _free(model="geometric"):
    measured, lam = _data(NOMINAL, 200, 99)
    J = _Data(measured, lam, CONTROLLER.zero_lengths, None, SIGMA, 0.0, NOMINAL).J0.reshape(-1, len(NAMES))
    return identifiable(J, LADDER[model])


def _fit(measured, lam, model, sigma_pose=SIGMA, **options):
    """The identification of a ladder model from the nominal start, the readings' σ SIGMA."""
    return identify(
        measured, lam, CONTROLLER.zero_lengths, LADDER[model], NOMINAL, sigma_pose=sigma_pose, **options
    )


def _z(fit, truth):
    est, true = fit.parameters.as_dict(), truth.as_dict()
    return np.array([(est[n] - true[n]) / fit.std[n] for n in fit.free])


@settings(max_examples=6, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_noiseless_poses_give_back_the_geometry(seed):
    kept, _, _ = _free()
    truth = synthetic.perturbed(np.random.default_rng(seed), NOMINAL, only=kept)
    measured, lam = _data(truth, 100, seed + 1, sigma=(0.0,) * 6)
    fit = _fit(measured, lam, "geometric")
    assert fit.free == kept and fit.success
    error = fit.parameters.vector() - truth.vector()
    lengths = [k for k, name in enumerate(NAMES) if not name.endswith(("_u", "_v", "_w"))]
    assert np.max(np.abs(error[lengths])) < 1e-4  # µm, against errors of tens of µm to mm
    # degree: 1e-7° over the ~100 mm joint radii is ~2e-4 µm, the same round-off as the lengths
    assert np.max(np.abs(np.delete(error, lengths))) < 1e-7
    assert fit.residual_rms_um < 1e-5


@pytest.mark.parametrize("model", ["offsets", "geometric", "scale"])
def test_noisy_poses_give_the_geometry_within_its_stated_sigma(model):
    kept, _, _ = _free(model)
    truth = synthetic.perturbed(np.random.default_rng(3), NOMINAL, only=kept)
    measured, lam = _data(truth, 400, 4)
    fit = _fit(measured, lam, model)
    z = _z(fit, truth)
    assert np.max(np.abs(z)) < 4.5, dict(zip(fit.free, np.round(z, 1)))
    assert 0.9 < fit.chi2_dof < 1.1  # the residuals are the stated noise
    assert max(fit.std[n] for n in fit.free if n[0] in "bpd") < 20.0  # µm: the joints are actually determined
    np.testing.assert_allclose(np.diag(fit.correlation), 1.0)


def _base_motion(phi: Parameters, E) -> Parameters:
    """The same hexapod described in a work frame moved by E: base joints and measurement frame move."""
    RE, tE = E
    frame = pose_of(*compose(RE, tE, *transform(phi.frame)))
    return Parameters(frame, phi.tool, phi.base @ RE.T + tE, phi.platform, phi.offset, phi.scale, phi.thermal)


def _platform_motion(phi: Parameters, H) -> Parameters:
    """The same hexapod described in a platform frame moved by H: platform joints and tool frame move."""
    RH, tH = H
    tool = pose_of(*compose(RH, tH, *transform(phi.tool)))
    return Parameters(phi.frame, tool, phi.base, phi.platform @ RH.T + tH, phi.offset, phi.scale, phi.thermal)


def test_the_reduction_drops_exactly_the_two_frame_freedoms():
    kept, dropped, _ = _free()
    assert len(kept) == 42 and len(dropped) == 12  # 54 - two rigid motions of 6
    measured, lam = _data(NOMINAL, 200, 5)
    r0 = closure(NOMINAL, measured, lam, CONTROLLER.zero_lengths, derivatives=False)
    # moving the work frame or the platform frame together with its joints changes no residual ...
    null = []
    for move in (_base_motion, _platform_motion):
        for j in range(6):
            step = np.zeros(6)
            step[j] = 1e-3
            moved = move(NOMINAL, transform(step))
            r = closure(moved, measured, lam, CONTROLLER.zero_lengths, derivatives=False)
            assert np.max(np.abs(r - r0)) < 1e-8
            null.append((moved.vector() - NOMINAL.vector()) / 1e-3)
    null = np.asarray(null)  # (12, 61): the non-identifiable directions
    # ... so the dropped columns are those that pin these 12 directions down (a unique gauge) ...
    assert np.linalg.matrix_rank(null[:, [NAMES.index(n) for n in dropped]], tol=1e-6) == 12
    # ... and every combination of the kept columns is seen by the readings
    J = _Data(measured, lam, CONTROLLER.zero_lengths, None, SIGMA, 0.0, NOMINAL).J0.reshape(-1, len(NAMES))
    A = J[:, [NAMES.index(n) for n in kept]]
    s = np.linalg.svd(A / np.linalg.norm(A, axis=0), compute_uv=False)
    assert s[-1] / s[0] > 1e-6
    full = J[:, [NAMES.index(n) for n in LADDER["geometric"]]]
    assert np.linalg.matrix_rank(full / np.linalg.norm(full, axis=0), tol=1e-8) == 42


def test_a_thermal_term_needs_a_temperature_that_changes():
    kept, _, _ = _free("scale")
    truth = synthetic.perturbed(np.random.default_rng(6), NOMINAL, only=kept).replace(alpha_T=11.5e-6)
    measured, lam = _data(truth, 400, 7, temperature=np.full(400, 23.0))
    fit = _fit(measured, lam, "thermal", temperature=np.full(400, 23.0))
    assert "alpha_T" in fit.dropped  # a constant temperature only looks like offsets and scales
    T = 20.0 + np.linspace(0.0, 4.0, 400)
    measured, lam = _data(truth, 400, 7, temperature=T)
    fit = _fit(measured, lam, "thermal", temperature=T)
    assert "alpha_T" in fit.free
    assert abs(fit.parameters.thermal - 11.5e-6) < 4.5 * fit.std["alpha_T"]
    assert fit.std["alpha_T"] < 2e-6  # 1/K


def test_a_model_that_lacks_an_error_predicts_held_out_poses_worse():
    kept, _, _ = _free("scale")
    truth = synthetic.perturbed(np.random.default_rng(8), NOMINAL, only=kept)
    measured, lam = _data(truth, 400, 9)
    held_measured, held_lam = _data(truth, 200, 10)
    rms = {}
    for model in ("nominal", "offsets", "geometric", "scale"):
        fit = _fit(measured, lam, model)
        rms[model] = prediction_rms(fit, held_measured, held_lam, CONTROLLER.zero_lengths)
    assert rms["nominal"] > rms["offsets"] > rms["geometric"] > rms["scale"]
    assert rms["scale"] < 1.5  # µm of leg length: the instrument's noise seen through the legs


def test_robust_identification_rejects_the_gross_errors():
    kept, _, _ = _free()
    truth = synthetic.perturbed(np.random.default_rng(11), NOMINAL, only=kept)
    measured, lam = _data(truth, 400, 12)
    bad = np.array([5, 50, 123, 300])
    measured[bad, 0] += 200.0  # µm: a misread of the instrument
    plain = _fit(measured, lam, "geometric")
    fit = _fit(measured, lam, "geometric", robust=Robust())
    assert fit.rejected == tuple(bad) and fit.n_poses == 396 and fit.loss == "soft_l1"
    assert np.max(np.abs(_z(fit, truth))) < 4.5
    assert plain.chi2_dof > 10 * fit.chi2_dof


def test_rows_with_a_nan_are_dropped():
    measured, lam = _data(NOMINAL, 60, 13)
    measured[3, 2] = np.nan
    fit = _fit(measured, lam, "offsets")
    assert fit.n_poses == 59


def test_bad_input_is_one_line_naming_what_was_expected():
    measured, lam = _data(NOMINAL, 10, 14)
    with pytest.raises(CalflowError, match=r"must both be \(n, 6\)"):
        identify(measured[:, :5], lam, CONTROLLER.zero_lengths)
    with pytest.raises(CalflowError, match="unknown parameters"):
        identify(measured, lam, CONTROLLER.zero_lengths, free=("b1_x", "q7"))
    with pytest.raises(CalflowError, match="needs more than"):
        identify(measured[:5], lam[:5], CONTROLLER.zero_lengths, LADDER["geometric"])


def test_a_run_dataset_gives_the_identification_its_inputs():
    import xarray as xr

    rng = np.random.default_rng(15)
    commands = synthetic.random_poses(30, rng)
    measured, lam = synthetic.simulate(NOMINAL, commands, CONTROLLER, rng, SIGMA)
    data = {f"cmd_{a}": ("sample", commands[:, k]) for k, a in enumerate("xyzuvw")}
    data |= {f"meas_{a}": ("sample", measured[:, k]) for k, a in enumerate("xyzuvw")}
    data["temperature"] = (
        ("sample", "sensor"),
        np.column_stack([np.full(30, 21.0), np.linspace(20, 21, 30)]),
    )
    run = xr.Dataset(data, coords={"sensor": ["T1", "T2"]})
    M, L, T = run_inputs(run, CONTROLLER)
    np.testing.assert_array_equal(M, measured)
    np.testing.assert_allclose(L, lam, rtol=1e-15)
    np.testing.assert_array_equal(T, np.linspace(20, 21, 30))
    assert run_inputs(run.drop_vars("temperature"), CONTROLLER)[2] is None
    with pytest.raises(CalflowError, match=r"run.nc: missing variables \['meas_w'\]"):
        run_inputs(run.drop_vars("meas_w"), CONTROLLER, source="run.nc")


def test_a_probe_far_from_the_platform_is_weighted_at_the_estimate_not_at_the_start():
    kept, _, _ = _free()
    truth = synthetic.perturbed(np.random.default_rng(16), NOMINAL, only=kept)
    truth = truth.replace(tool_z=60_000.0, tool_w=1.0)  # a 6-D probe 60 mm above the platform, turned 1°
    measured, lam = _data(truth, 400, 17)
    fit = _fit(measured, lam, "geometric")
    assert 0.9 < fit.chi2_dof < 1.1  # weights at the nominal probe (on the platform) would misstate the noise
    assert np.max(np.abs(_z(fit, truth))) < 4.5


def test_a_covariance_of_the_readings_weights_like_the_sigmas_it_holds():
    measured, lam = _data(NOMINAL, 100, 18)
    by_sigma = _fit(measured, lam, "offsets")
    by_cov = _fit(measured, lam, "offsets", sigma_pose=np.diag(np.square(SIGMA)))
    np.testing.assert_allclose(by_cov.parameters.vector(), by_sigma.parameters.vector(), rtol=0, atol=1e-9)
    assert by_cov.chi2_dof == pytest.approx(by_sigma.chi2_dof, rel=1e-9)


def test_the_fit_keeps_its_whitened_jacobian_for_the_observability_indices():
    from calflow.identification.diagnostics import observability

    measured, lam = _data(NOMINAL, 150, 19)
    fit = _fit(measured, lam, "geometric")
    assert fit.jacobian.shape == (6 * 150, 42)
    # the covariance is the inverse information of that Jacobian, scaled by chi2/dof
    d = np.sqrt(np.diag(fit.covariance))
    inverse = fit.chi2_dof * np.linalg.inv(fit.jacobian.T @ fit.jacobian)
    np.testing.assert_allclose(inverse / np.outer(d, d), fit.covariance / np.outer(d, d), atol=1e-6)
    assert observability(fit.jacobian)["O3"] > 0
