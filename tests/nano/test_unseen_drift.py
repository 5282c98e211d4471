"""Drift the thermocouples do not see (calflow.nano.stage.unseen): each effect's physics
against its source's law, the thermocouples' own errors on and off, and the report's
extrapolation sentences."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.nano.stage.options import without
from calflow.nano.stage.rig import nano1d, nano2d
from calflow.nano.stage.unseen import heat, humidity, instruments
from calflow.nano.stage.unseen.options import TC_ERRORS, UNSEEN, UNSEEN_EFFECTS

T = np.linspace(0.0, 100 * 3600.0, 400)


# ------------------------------------------------------------------ the thermocouples' own errors
@pytest.mark.parametrize("factory", [nano1d, nano2d])
@pytest.mark.parametrize("effect", TC_ERRORS)
def test_each_thermocouple_error_is_present_and_switching_it_off_removes_it(factory, effect):
    on = factory(profile="lab5day")._unseen.thermocouples(T)
    assert np.max(np.abs(on[effect])) > 1e-4, effect  # > 0.1 mK somewhere over 100 h
    keys = UNSEEN_EFFECTS[effect]
    rig = factory(
        profile="lab5day", **{k: v for k, v in without(factory().options, effect).items() if k in keys}
    )
    off = rig._unseen.thermocouples(T)
    assert np.max(np.abs(off[effect])) == 0.0
    for other in TC_ERRORS:  # the others stay
        if other != effect:
            np.testing.assert_allclose(on[other], off[other], atol=1e-12)


def test_thermocouple_readings_carry_their_errors_and_unmodelled_false_removes_them():
    rig, plain = nano1d(profile="lab5day"), nano1d(profile="lab5day", unmodelled=False)
    t = 60 * 3600.0
    read = rig._state(t, rig._snapshot())[1]
    base = plain._state(t, plain._snapshot())[1]
    errs = rig._unseen.thermocouples(t)
    np.testing.assert_allclose(read - base, sum(errs.values()), atol=1e-9)
    assert not plain._unseen.active and np.all(plain._unseen.reading_c(T) == 0.0)


def test_reference_junction_error_is_common_and_follows_room_changes():
    rig = nano1d(profile="lab5day")
    e = rig._unseen.thermocouples(T)["reference_junction"]
    assert np.ptp(e, axis=1).max() == 0.0  # every channel shares the logger's terminal block
    assert np.abs(e).max() < 0.2  # tens of mK at most, for a room changing ~1 K over 12 h


def test_junction_lag_is_a_first_order_lag_of_its_host():
    """The glued junction reads its host through tau dG/dt = T - G (solved here by scipy)."""
    from scipy.integrate import solve_ivp

    quiet = dict(lighting_w=0.0, people_w=0.0, electronics_w=0.0)  # the host is then the room-driven node
    rig = nano1d(profile="lab5day", junction_glue_tau_s=300.0, **quiet)
    t0, t = 60 * 3600.0, np.arange(60 * 3600.0, 62 * 3600.0, 30.0)

    def host(tt):
        return rig._nodes(np.asarray(tt, dtype=float))[..., 3]

    g0 = host(t0) + rig._unseen.thermocouples(t0)["junction_lag"][0]
    sol = solve_ivp(
        lambda tt, g: (host(tt) - g) / 300.0, (t0, t[-1]), [g0], t_eval=t, rtol=1e-10, atol=1e-12, max_step=30
    )
    np.testing.assert_allclose(
        rig._unseen.thermocouples(t)["junction_lag"][:, 0], sol.y[0] - host(t), atol=2e-5
    )
    assert np.abs(sol.y[0] - host(t)).max() > 5e-4  # a mK-size error


# ------------------------------------------------------------------ heat off the thermocouples' paths
@settings(max_examples=40, deadline=None)
@given(st.floats(1.0, 500.0), st.floats(1e-3, 0.3), st.floats(0.1, 20.0))
def test_piezo_loss_of_a_full_cycle_is_the_application_note_power(u_pp, tan_d, c_uf):
    """Two moves of U_pp (out and back) per cycle dissipate pi/4 tan(delta) C U_pp^2 (P = that x f)."""
    o = {**UNSEEN, "piezo_loss_factor": tan_d, "piezo_capacitance_uf": c_uf, "piezo_drive_span_v": u_pp}
    per_cycle = 2 * heat.piezo_energy_j(100.0, 100.0, o)
    assert per_cycle == pytest.approx(math.pi / 4 * tan_d * c_uf * 1e-6 * u_pp**2, rel=1e-12)


def test_lighting_heats_the_stage_more_than_the_thermocouples_see():
    rig = nano1d(profile="constant")
    t = np.arange(0.0, 48 * 3600.0, 300.0)
    bank, _ = rig._unseen.heat.banks["lighting"]
    rise = bank(t)
    stage, tcs = rise[:, 0], rise[:, 3:7]
    assert 0.005 < np.ptp(stage) < 0.05  # ~8 mW into ~0.5 W/K: tens of mK
    assert np.ptp(stage) > 4 * np.ptp(tcs, axis=0).max()
    lit = heat.daily_window(t, 8.0, 19.0) > 0
    assert stage[lit].mean() > stage[~lit].mean()


def test_piezo_heat_is_microkelvin_for_quasi_static_stepping():
    rig = nano1d(profile="constant")
    mem = rig._unseen.rest()
    for i in range(500):  # the training's 30 um steps every 29 s, back and forth
        mem = rig._unseen.after_move(mem, 29.0 * i, [30.0 if (i // 16) % 2 == 0 else -30.0])
    cmds = (np.array([240.0]),)
    term = rig._unseen.terms(
        cmds, np.array([500 * 29.0]), np.array([500 * 29.0]), mem, [np.array([240.0])] * 2, 0.0
    )
    assert 0 < abs(term["piezo_heating"][0][0]) < 1e-4  # below 0.1 nm


# ------------------------------------------------------------------ mechanics and humidity
def test_move_settling_relaxes_about_its_rate_per_decade():
    rig = nano1d(profile="constant", move_settling_ppm_per_decade=100.0)
    mem = rig._unseen.after_move(rig._unseen.rest(), 0.0, [400.0])
    t = np.array([10.0, 100.0, 1000.0])
    out = rig._unseen.terms((np.full(3, 400.0),), t, t, mem, [np.full(3, 400.0)] * 2, np.zeros(3))
    s = out["move_settling"][0]
    per_decade = np.diff(s) / (100e-6 * 400.0)
    assert np.all(s < 0) and np.all((per_decade > 0.7) & (per_decade < 1.3))


def test_mount_settling_grows_with_log_time():
    rig = nano1d(profile="constant")
    age = rig.options["mounted_h_before"] * 3600.0
    t = np.array([0.0, 10 * age, 100 * age])
    out = rig._unseen.terms((np.zeros(3),), t, t, None, [np.zeros(3)] * 2, np.zeros(3))["mount_settling"][0]
    steps = np.diff(out) / (rig.options["mount_settling_nm_per_decade"] * 1e-3 * rig._unseen._mount_dir[0])
    np.testing.assert_allclose(steps, 1.0, atol=0.1)  # one decade each: ~10 nm


def test_lagged_humidity_matches_a_first_order_lag():
    from scipy.integrate import solve_ivp

    rig = nano1d()
    o, ph, tau = rig.options, rig._weather, 6 * 3600.0
    t = np.linspace(0.0, 10 * 86400.0, 2000)

    def rh(tt):
        return humidity.weather_at(o, ph, tt)[1]

    sol = solve_ivp(
        lambda tt, y: (rh(tt) - y) / tau, (-20 * tau, t[-1]), [o["humidity_pct"]], t_eval=t, rtol=1e-9
    )
    np.testing.assert_allclose(humidity.lagged_humidity(o, ph, t, tau), sol.y[0], atol=1e-3)


def test_permittivity_sensitivities_of_smith_weintraub():
    e0 = humidity.permittivity(20.0, 101325.0, 50.0)
    d_rh = humidity.permittivity(20.0, 101325.0, 51.0) / e0 - 1
    d_p = humidity.permittivity(20.0, 101425.0, 50.0) / e0 - 1
    d_t = humidity.permittivity(21.0, 101325.0, 0.0) / humidity.permittivity(20.0, 101325.0, 0.0) - 1
    assert (
        1.8e-6 < d_rh < 2.3e-6 and 0.45e-6 < d_p < 0.6e-6 and -2.0e-6 < d_t < -1.6e-6
    )  # dry air: -1.8 ppm/K


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 500.0), st.floats(0.0, 2 * np.pi))
def test_periodic_error_repeats_every_fringe_and_vanishes_at_the_zeroing(x, phase):
    d, per = 5e4, UNSEEN["periodic_period_nm"]
    a = instruments.periodic_um(d + x, d, 3.0, per, phase)
    b = instruments.periodic_um(d + x + per * 1e-3, d, 3.0, per, phase)
    assert abs(a - b) < 1e-9 and abs(a) <= 6e-3 + 1e-12
    assert instruments.periodic_um(d, d, 3.0, per, phase) == 0.0


def test_laser_wander_stays_within_its_bound_over_the_path():
    rig = nano1d()
    t = np.linspace(0.0, 5 * 86400.0, 3000)
    path = 5e4 + 480.0
    w = instruments.laser_wander_um(rig._unseen._laser, 0, t, path, 0.3)
    assert np.abs(w).max() <= 2 * 0.3e-6 * path + 1e-12 and np.ptp(w) > 0.1 * 0.3e-6 * path


# ------------------------------------------------------------------ extrapolation in words
def _metrics(t_lo, t_hi, hours):
    n = len(hours)
    return xr.Dataset(
        {
            "time_h": ("test", np.asarray(hours, float)),
            "time_start_h": ("test", np.asarray(hours, float) - 0.5),
            "time_end_h": ("test", np.asarray(hours, float) + 0.5),
            "temperature_min_c": ("test", np.asarray(t_lo, float)),
            "temperature_max_c": ("test", np.asarray(t_hi, float)),
            "mode": ("test", np.zeros(n, int)),
        },
        attrs={"start_time_h": 0.0, "end_time_h": float(max(hours)) + 0.5},
    )


def test_extrapolation_says_which_day_leaves_training_for_every_model():
    from calflow.nano.report.extrapolation import extrapolation_block

    m = _metrics([20.5, 20.5, 19.8], [20.6, 20.6, 20.6], [2.0, 30.0, 54.0])
    tests = {"single": {}, "adaptive_kmz": {}}
    hum = {"training_pct": [40.0, 50.0], "tests_pct": [[41, 49], [38, 45], [42, 44]]}
    out = extrapolation_block(m, (20.4, 20.7), tests, hum)
    words = [d["words"] for d in out["days"]]
    assert out["days"][0]["temperature_outside"] is False and out["days"][0]["humidity_outside"] is False
    assert "humidity" in words[1] and "beyond training's 40.0–50.0 %RH by up to 2.0 %RH" in words[1]
    assert "thermocouples 19.80–20.60 °C, beyond" in words[2] and "by up to 0.60 °C" in words[2]
    for t in tests.values():  # beside every model's day figures
        assert t["extrapolation_by_day"][0] is None and t["extrapolation_by_day"][2] == words[2]
    assert extrapolation_block(m, None, tests) is None
    recorded = extrapolation_block(m, (20.4, 20.7), tests)  # a recorded campaign: no humidity known
    assert recorded["training_humidity_pct"] is None and "humidity" not in recorded["days"][2]["words"]
    assert (
        tests["single"]["extrapolation_by_day"][1] is None and "temperature" in recorded["days"][2]["words"]
    )
