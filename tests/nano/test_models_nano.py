"""Tests of the nanopositioning models (thesis Sec. 5.2, 5.4.1; calflow.nano.models.geometric/kmz).

Synthetic physics generated here, richer than the models on purpose:
* geometry: the stage lands at x_clean with G(x_clean) = q, G a known cubic
  (gain 1.001, ~400 nm peak to valley over 0-500 um, Fig. 5.1);
* thermal drift D = -1 um/degC * (T_stage - T_ref), T_stage a 1.5 h lag of the room, seen
  only through four thermocouples with lags 0.5, 1, 2, 3 h (+ 2 mK noise);
* interferometer noise 10 nm (1 sigma).
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.nano.models.kmz import AdaptiveKMZModel, KMZReading
from calflow.nano.models.registry import GeometricModel, ModelInputError, model_from_dataset
from calflow.nano.models.thermal import SingleModel, ThermalDriftModel, TwoDoFModel

P = np.polynomial.Polynomial
NOISE = 0.010  # um
T_REF = 20.5
DT = 20.0  # s, simulation grid
HOUR = 3600.0
TAUS_H = (0.5, 1.0, 2.0, 3.0)
STAGE_TAU_H = 1.5
ALPHA = -1.0  # um/degC: drift grows as temperature falls (Fig. 5.2)


def true_inverse(offset=0.2, gain=1.001, amp=0.52):
    """G(x) = offset + gain x - amp (u^3 - u), u = (x - 250)/250: PV of G(x) - gain x ~ 400 nm."""
    u = P([-1.0, 1.0 / 250.0])
    return P([offset, gain]) - amp * (u**3 - u)


G_TRUE = true_inverse()


def land(q, G=G_TRUE):
    """x_clean with G(x_clean) = q (Newton; G is monotonic over the stroke)."""
    q = np.asarray(q, dtype=float)
    x, dG = q.copy(), G.deriv()
    for _ in range(30):
        x = x - (G(x) - q) / dG(x)
    return x


def lag(u, tau_s):
    y = np.empty_like(u)
    y[0] = u[0]
    k = 1.0 - np.exp(-DT / tau_s)
    for i in range(1, u.size):
        y[i] = y[i - 1] + k * (u[i] - y[i - 1])
    return y


def world(hours, excursion=0.0, excursion_start_h=np.inf, seed=0):
    """Room, thermocouples (n, 4) and the true drift (um) on the DT grid; warm start."""
    warm = 12 * HOUR
    t = np.arange(-warm, hours * HOUR + DT, DT)
    w = 2 * np.pi / HOUR
    room = T_REF + 0.12 * np.sin(w * t / 6) + 0.05 * np.sin(w * t / 2.3 + 1.0)
    room = room + excursion * np.clip((t - excursion_start_h * HOUR) / (6 * HOUR), 0, 1)
    rng = np.random.default_rng(seed)
    tc = np.column_stack([lag(room, h * HOUR) for h in TAUS_H]) + rng.normal(0, 0.002, (t.size, 4))
    drift = ALPHA * (lag(room, STAGE_TAU_H * HOUR) - T_REF)
    keep = t >= 0
    return t[keep], tc[keep], drift[keep]


def measure(q, idx, drift, rng, extra=0.0):
    return land(q) + drift[idx] + extra + rng.normal(0, NOISE, np.size(q))


@pytest.fixture(scope="module")
def training():
    """14 h of 0:30:480 forward/backward cycles, one settled pose every 20 s."""
    t, tc, drift = world(14)
    cycle = np.r_[np.arange(0, 481, 30.0), np.arange(480, -1, -30.0)[1:-1]]
    q = np.resize(cycle, t.size)
    idx = np.arange(t.size)
    x = measure(q, idx, drift, np.random.default_rng(1))
    return q, x, tc


@pytest.fixture(scope="module")
def single(training):
    return SingleModel.fit(*training)


# ----------------------------------------------------------------------------- Eq. (5.1)
def test_geometric_recovers_polynomial_at_constant_temperature():
    rng = np.random.default_rng(2)
    q = np.tile(np.arange(0, 481, 30.0), 20)
    x = land(q) + rng.normal(0, NOISE, q.size)
    model = GeometricModel.fit(q, x)
    table = model.coefficients.set_index("name")
    for i, true in enumerate(G_TRUE.coef):
        est, se = table.loc[f"a_{i}", ["value", "std_error"]]
        assert abs(est - true) < 5 * se, (i, est, true, se)
    assert table.loc["a_3", "unit"] == "um-2" and table.loc["a_0", "unit"] == "um"
    xs = np.linspace(0, 500, 101)
    assert np.max(np.abs(model.command_for(xs) - G_TRUE(xs))) < 0.005  # within 5 nm
    assert model.info["rmse_um"] == pytest.approx(NOISE, rel=0.2)


@settings(max_examples=40, deadline=None)
@given(
    gain=st.floats(0.98, 1.02),
    amp=st.floats(-0.6, 0.6),
    quad=st.floats(-0.3, 0.3),
    off=st.floats(-5, 5),
    probe=st.lists(st.floats(0, 500), min_size=1, max_size=20),
)
def test_geometric_inverse_of_forward_is_identity(gain, amp, quad, off, probe):
    u = P([-1.0, 1.0 / 250.0])
    forward = P([off, gain]) + amp * (u**3 - u) + quad * u**2  # x = f(q)
    q = np.linspace(0, 500, 51)
    model = GeometricModel.fit(q, forward(q))
    probe = np.asarray(probe)
    assert np.allclose(model.command_for(forward(probe)), probe, atol=0.005)  # q(f(q)) = q
    xs = forward(probe)
    assert np.allclose(model.position(model.command(xs)), xs, atol=1e-9, rtol=0)


# ----------------------------------------------------------------------------- Eq. (5.2)
def test_thermal_drift_model_on_a_stage_at_rest():
    t, tc, drift = world(48, seed=3)
    meas = drift + 0.7 + np.random.default_rng(4).normal(0, NOISE, t.size)  # frame zeroed anywhere
    model = ThermalDriftModel.fit(tc, meas, sensors=("T1", "T2", "T3", "T4"))
    b = model.thermal()
    # q_t = -drift; the static gain sum(b) is only loosely identified without slow swings
    assert b.sum() == pytest.approx(-ALPHA, abs=0.25)
    resid = model.drift(tc) - meas
    assert np.std(resid) < 3 * NOISE
    assert np.allclose(model.command([0.0, 250.0], tc[100]) - [0.0, 250.0], -model.drift(tc[100]))
    assert model.info["stepwise_history"].startswith("Step 1, added column")
    table = model.coefficients
    assert list(table["name"]) == ["b_1", "b_2", "b_3", "b_4", "b_0"]
    assert (table["unit"][:4] == "um degC-1").all()


# ----------------------------------------------------------------------------- Eq. (5.3)-(5.5)
def test_single_model_identification(single):
    table = single.coefficients.set_index("name")
    assert list(table.index) == ["a_1", "a_2", "a_3", "b_1", "b_2", "b_3", "b_4", "lambda"]
    for i in (1, 2, 3):  # geometry recovered despite the drift, within 5 standard errors
        est, se = table.loc[f"a_{i}", ["value", "std_error"]]
        assert abs(est - G_TRUE.coef[i]) < 5 * se, (i, est, G_TRUE.coef[i], se)
    assert single.thermal().sum() == pytest.approx(-ALPHA * G_TRUE.coef[1], abs=0.1)
    assert table.loc["a_3", "p_value"] < 1e-6 and table.loc["a_1", "in_model"]
    assert single.info["rmse_um"] < 2 * NOISE


def test_single_model_commands_to_target_at_training_temperatures(single):
    t, tc, drift = world(20)
    later = t >= 14 * HOUR  # 6 h after training, same thermal regime
    t, tc, drift = t[later], tc[later], drift[later]
    assert single.in_training_range(tc, margin=0.02).mean() > 0.9
    rng = np.random.default_rng(5)
    targets = np.resize(np.arange(0, 481, 80.0), t.size)
    x = measure(single.command(targets, tc), np.arange(t.size), drift, rng)
    err = x - targets
    assert np.sqrt(np.mean(err**2)) < 2.5 * NOISE
    assert np.max(np.abs(err)) < 6 * NOISE
    raw = measure(targets, np.arange(t.size), drift, rng) - targets  # uncalibrated
    assert np.max(np.abs(raw)) > 10 * np.max(np.abs(err))
    # predict_error foresees the uncalibrated error (up to noise)
    assert np.sqrt(np.mean((single.predict_error(targets, tc) - raw) ** 2)) < 3 * NOISE


# ----------------------------------------------------------------------------- Eq. (5.6)-(5.7)
def kmz_visit(model, idx, tc, drift, rng, extra):
    q_k = model.command(0.0, tc[idx], reference=0.0)[0]
    x_k = measure(q_k, idx, drift, rng, extra)[0]
    return KMZReading(command=q_k, measured=x_k, temperatures=tc[idx], time=idx * DT)


@pytest.mark.parametrize("variant", ["5.6", "5.7"])
def test_kmz_removes_constant_offset_single_model_cannot(single, variant):
    t, tc, drift = world(20)
    sl = slice(int(14 * HOUR / DT), int(15.25 * HOUR / DT))  # one 1.25 h test
    idx = np.arange(t.size)[sl]
    offset = 0.5  # um: unexplained (e.g. a knock on the interferometer mount)
    rng = np.random.default_rng(6)
    kmz = AdaptiveKMZModel.from_single(single, variant)
    ref = kmz_visit(kmz, idx[0], tc, drift, rng, offset)  # visit at the start of the test
    targets = np.resize(np.arange(0, 481, 80.0), idx.size)
    e_single = measure(single.command(targets, tc[idx]), idx, drift, rng, offset) - targets
    e_kmz = measure(kmz.command(targets, tc[idx], reference=ref), idx, drift, rng, offset) - targets
    assert np.mean(e_single) == pytest.approx(offset, abs=0.05)
    assert np.max(np.abs(e_kmz)) < 0.2 * np.max(np.abs(e_single))
    assert np.sqrt(np.mean(e_kmz**2)) < 4 * NOISE


def test_kmz_tracks_temperature_excursion_and_slow_drift(single):
    """1.3 degC excursion (outside training, Fig. 5.19) + 60 nm/h unexplained creep."""
    t, tc, drift = world(30, excursion=1.3, excursion_start_h=16)
    creep = 0.06 * np.clip(t - 14 * HOUR, 0, None) / HOUR
    idx = np.arange(t.size)[t >= 16 * HOUR]
    assert not single.in_training_range(tc[idx[-1]], margin=0.2)[0]
    rng = np.random.default_rng(7)
    kmz = AdaptiveKMZModel.from_single(single)  # Eq. (5.6), as the thesis experiments
    visits = [kmz_visit(kmz, i, tc, drift, rng, creep[i]) for i in idx[::15]]  # every 5 min
    lam = kmz.offsets_at(t[idx], visits)
    targets = np.resize(np.arange(0, 481, 80.0), idx.size)
    e_single = measure(single.command(targets, tc[idx]), idx, drift, rng, creep[idx]) - targets
    e_kmz = measure(kmz.command(targets, reference=lam), idx, drift, rng, creep[idx]) - targets
    assert np.max(np.abs(e_single)) > 0.5
    assert np.max(np.abs(e_kmz)) < 0.1 * np.max(np.abs(e_single))
    assert np.sqrt(np.mean(e_kmz**2)) < 3 * NOISE


def test_kmz_lambda_is_minus_the_drift_seen_at_the_kmz(single):
    kmz = AdaptiveKMZModel.from_single(single)
    q_k = kmz.command(0.0, reference=0.0)[0]
    seen = kmz.position(q_k, reference=0.0)[0] + 0.3  # stage found 0.3 um further
    lam = kmz.lambda_kmz(KMZReading(q_k, seen))
    assert lam == pytest.approx(-0.3 * single.value("a_1"), abs=1e-3)
    # lambda_KMZ is a command offset: position-independent to first order (slope ~ 1 +- 0.5 %)
    landed = kmz.position(kmz.command(123.0, reference=lam), reference=0.0)[0] + 0.3
    assert landed == pytest.approx(123.0, abs=0.003)
    with pytest.raises(ModelInputError, match="reference"):
        kmz.command(10.0)
    with pytest.raises(ModelInputError, match="precedes"):
        kmz.offsets_at([0.0], [KMZReading(q_k, seen, time=10.0)])


# ----------------------------------------------------------------------------- Eq. (5.10)
def test_two_dof_model_reduces_cross_coupled_error():
    rng = np.random.default_rng(8)
    t, tc, drift = world(6, seed=9)

    def stage(q, i):  # forward physics: cubic + cross-coupling + a small x*y term + drift
        qx, qy = q[:, 0], q[:, 1]
        ux, uy = (qx - 40) / 40, (qy - 40) / 40
        x = qx + 0.25 * (ux**3 - ux) + 0.012 * qy + 1e-5 * qx * qy + drift[i]
        y = qy - 0.15 * (uy**3 - uy) - 0.008 * qx + 0.1 * ux**2 + 0.6 * drift[i]
        return np.column_stack([x, y]) + rng.normal(0, NOISE, q.shape)

    grid = np.array([(a, b) for a in np.arange(0, 81, 10.0) for b in np.arange(0, 81, 10.0)])
    q = np.resize(grid, (t.size, 2))
    i = np.arange(t.size)
    model = TwoDoFModel.fit(q, stage(q, i), tc)
    assert {"a_1x", "b_1x", "a_1y", "b_1y", "lambda_x", "c_1x"} <= set(model.coefficients["name"])
    assert model.value("b_1x") == pytest.approx(-0.012, abs=2e-3)  # X joint undoes Y coupling
    targets = np.array([(0, 0), (45, 45), (75, 15), (75, 75), (15, 75), (15, 15)], float)
    targets = np.resize(targets, (t.size, 2))
    raw = np.linalg.norm(stage(targets, i) - targets, axis=1)
    cal = np.linalg.norm(stage(model.command(targets, tc), i) - targets, axis=1)
    assert raw.max() > 5 * cal.max(), (raw.max(), cal.max())
    pred = model.predict_error(targets[:50], tc[:50])
    assert np.allclose(pred, stage(targets[:50], i[:50]) - targets[:50], atol=0.1)
    back = model.position(model.command(targets[:20], tc[:20]), tc[:20])
    assert np.allclose(back, targets[:20], atol=1e-9)


# ----------------------------------------------------------------------------- I/O, errors
def all_models(training, single):
    q, x, tc = training
    geo = GeometricModel.fit(q[:500], x[:500])
    therm = ThermalDriftModel.fit(tc, x - land(q))
    xy = np.column_stack([x, 0.5 * x])
    return [
        geo,
        therm,
        single,
        AdaptiveKMZModel.from_single(single),
        AdaptiveKMZModel.from_single(single, "5.7"),
        AdaptiveKMZModel.from_geometric(geo),
        TwoDoFModel.fit(np.column_stack([q, 0.5 * q]), xy, tc, order=(3, 1)),
    ]


def test_dataset_round_trip(training, single, tmp_path):
    tc = training[2][:7]
    for k, model in enumerate(all_models(training, single)):
        ds = model.to_dataset()
        assert ds.attrs["calflow_kind"] == "model" and ds.attrs["model"] == model.kind
        for name, var in ds.variables.items():
            assert "long_name" in var.attrs, name
            assert "units" in var.attrs or name == "sensor", name
        path = tmp_path / f"m{k}.nc"
        ds.to_netcdf(path)
        with xr.open_dataset(path) as opened:
            back = model_from_dataset(opened.load())
        assert type(back) is type(model)
        assert back.coefficients.equals(model.coefficients)
        target = np.arange(7.0) * 60
        if k == 6:
            target = np.column_stack([target / 6, target / 12])
        ref = {} if k < 3 or k == 6 else {"reference": 0.1}
        assert np.array_equal(back.command(target, tc, **ref), model.command(target, tc, **ref))
    with pytest.raises(ModelInputError, match="not a 'single' model"):
        SingleModel.from_dataset(all_models(training, single)[0].to_dataset())


def test_nan_handling(training, single):
    q, x, tc = training
    x = x.copy()
    x[[3, 50]] = np.nan
    model = SingleModel.fit(q, x, tc)
    assert model.info["n_dropped"] == 2
    assert np.isnan(model.residuals(q, x, tc)[3]) and np.isfinite(model.residuals(q, x, tc)[4])
    with pytest.raises(ModelInputError, match="target is not finite at index"):
        single.command([1.0, np.nan], tc[0])
    with pytest.raises(ModelInputError, match="needs temperatures"):
        single.command(10.0)
    with pytest.raises(ModelInputError, match="temperatures must have shape"):
        single.command(10.0, tc[0, :3])
    with pytest.raises(ModelInputError, match="not finite in row"):
        single.command(10.0, [20.0, np.nan, 20.0, 20.0])
    with pytest.raises(ModelInputError, match="free of NaN"):
        GeometricModel.fit([1.0, 2.0, np.nan, 4.0], [1.0, 2.0, 3.0, np.nan])
    assert isinstance(ModelInputError("x"), ValueError)
