"""Physics of the simulated nano rigs, effect by effect: each is present by default and
switching it off in the rig's options removes it."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.nano.stage import interferometer as ifm
from calflow.nano.stage.options import EFFECTS, NOISE, UNMODELLED, without
from calflow.nano.stage.piezo import PlayHysteresis, residual_creep_um, sensor_nonlinearity_um
from calflow.nano.stage.rig import nano1d, nano2d
from calflow.nano.stage.thermal_network import ThermalNetwork, network_bank, network_matrices
from calflow.nano.stage.unseen.options import HEAT_SOURCES, TC_ERRORS
from calflow.rigs.thermal import room_profile

X = np.linspace(0.0, 480.0, 25)
T = np.linspace(0.0, 110 * 3600.0, 25)
DETERMINISTIC = [e for e in EFFECTS if e not in NOISE and e not in TC_ERRORS]
PATH = ("laser_wander", "periodic_nonlinearity", "turbulence")  # the optical path holds every other term


def _busy_memory(rig, n=2000, dwell=29.0):
    """The moves' memory after n full-stroke moves, every ``dwell`` s, the last just before time 0."""
    mem, stroke = rig._unseen.rest(), rig.options["stroke_um"]
    for i in range(n):
        mem = rig._unseen.after_move(mem, -dwell * (n - i), [stroke * 0.96 * (-1) ** i] * len(rig.joints))
    return mem


def _terms(rig, direction=1):
    """Every deterministic term on a grid of positions x times, after a long approach."""
    cmds, z = rig._long_approach(
        {j: np.meshgrid(X, T)[0] if j == "x" else np.meshgrid(X, T)[0][::-1] * 80 / 480 for j in rig.joints},
        direction,
    )
    t = np.meshgrid(X, T)[1]
    steps = tuple(np.full(t.shape, 80.0) for _ in rig.joints)
    return rig.effect_terms(cmds, t, z, steps=steps, since_s=np.full(t.shape, 26.5), memory=_busy_memory(rig))


@functools.cache
def _default_terms(factory):
    """:func:`_terms` of ``factory``'s default lab5day rig, computed once per factory: the
    same for every effect below (the tests only read it)."""
    return _terms(factory(profile="lab5day"))


def _size(terms, name):
    return max(float(np.max(np.abs(v))) for v in terms[name])


# ------------------------------------------------------------- each effect: present, and off when switched off
@pytest.mark.parametrize("factory", [nano1d, nano2d])
@pytest.mark.parametrize("effect", [e for e in DETERMINISTIC if e != "walk"])
def test_each_effect_is_present_and_switching_it_off_removes_it(factory, effect):
    on = _default_terms(factory)
    assert _size(on, effect) > 1e-5, effect  # > 0.01 nm somewhere on the grid
    off = _terms(
        factory(
            profile="lab5day",
            **{k: v for k, v in without(factory().options, effect).items() if k in EFFECTS[effect]},
        )
    )
    assert _size(off, effect) == 0.0
    shared = ("deadpath", "compensation", *PATH, *(("sensor_air",) if effect in HEAT_SOURCES else ()))
    if effect in (
        "stage_drift",
        "optics_drift",
        "expansion",
    ):  # a heat source's drift uses their coefficients
        shared += HEAT_SOURCES
    others = [e for e in DETERMINISTIC if e != effect and e not in shared]
    for name in others:  # the others do not change (refraction terms share the air, the path all terms)
        for a, b in zip(on[name], off[name]):
            np.testing.assert_allclose(a, b, atol=1e-12)


def test_walk_is_off_by_default_and_on_when_given():
    assert _size(_terms(nano1d(profile="lab5day")), "walk") == 0.0
    assert _size(_terms(nano1d(profile="lab5day", drift_walk_nm_per_sqrt_day=15.0)), "walk") > 1e-3


def test_unmodelled_false_switches_off_exactly_the_unmodelled_effects():
    on = _terms(nano1d(profile="lab5day", drift_walk_nm_per_sqrt_day=15.0))
    off = _terms(nano1d(profile="lab5day", drift_walk_nm_per_sqrt_day=15.0, unmodelled=False))
    for name in DETERMINISTIC:
        if name in UNMODELLED:
            assert _size(on, name) > 0 and _size(off, name) == 0.0, name
        else:
            assert _size(off, name) == pytest.approx(_size(on, name), rel=1e-12), name


@pytest.mark.parametrize(
    "effect,key", [("interferometer_noise", "interferometer_noise_nm"), ("repeatability", "repeatability_nm")]
)
def test_noise_effects_switch_off(effect, key):
    def spread(**o):
        rig = nano1d(profile="constant", **o)
        xs = []
        for _ in range(20):
            rig.move({"x": 0.0})
            rig.move({"x": 240.0})
            rig.wait(25.0)
            xs.append(rig.read()["meas_x"])
        return np.std(xs)

    assert spread() > 2e-3
    o = without(nano1d().options, effect)
    assert spread(**{k: o[k] for k in EFFECTS[effect]}) < spread()


def test_without_rejects_unknown_effects():
    with pytest.raises(ValueError, match="unknown nano effect"):
        without(nano1d().options, "gremlins")


# ------------------------------------------------------------- thermal network
def test_network_discretisation_agrees_with_solve_ivp():
    """The exact FOH discretisation agrees with scipy's ODE solver on the full network."""
    from scipy.integrate import solve_ivp

    o = nano1d().options
    net = ThermalNetwork.from_options(o)
    A, b = network_matrices(net)
    room = room_profile("lab5day", base_c=20.5, seed=1)
    bank = network_bank(net, room)
    t0, t1 = 10 * 3600.0, 30 * 3600.0
    sol = solve_ivp(
        lambda t, x: A @ x + b * room(t),
        (t0, t1),
        bank.at(t0),
        method="Radau",
        jac=lambda t, x: A,
        rtol=1e-9,
        atol=1e-9,
        t_eval=[t1],
    )
    np.testing.assert_allclose(bank.at(t1), sol.y[:, -1], atol=2e-5)


def test_network_equilibrium_and_ordering_of_lags():
    """In a constant room every node sits at the room; after a step, air leads and the base lags."""
    net = ThermalNetwork.from_options(nano1d().options)
    bank = network_bank(net, lambda t: 20.0 + 1.0 * (np.asarray(t) > 0))
    np.testing.assert_allclose(bank.at(-1.0), 20.0, atol=1e-9)
    air, base, stage = (bank.at(1800.0)[i] for i in (2, 1, 0))
    assert air > stage > 20.0 and air > base > 20.0
    np.testing.assert_allclose(bank.at(20 * 86400.0), 21.0, atol=1e-6)


# ------------------------------------------------------------- interferometer
def test_refractive_index_matches_birch_downs_reference_values():
    """Birch & Downs (1994) Table: n - 1 = 2.71800e-4 at 20 degC, 101325 Pa, dry, 633 nm;
    sensitivities of Table 3.4's order (1 ppm per degC, per 2.5 mmHg, per 80 %RH)."""
    n = ifm.refractive_index(20.0, 101325.0, 0.0)
    assert (n - 1) == pytest.approx(2.71800e-4, rel=2e-4)
    dT = ifm.refractive_index(21.0, 101325.0, 50.0) - ifm.refractive_index(20.0, 101325.0, 50.0)
    dp = ifm.refractive_index(20.0, 101325.0 + 333.3, 50.0) - ifm.refractive_index(20.0, 101325.0, 50.0)
    dh = ifm.refractive_index(20.0, 101325.0, 90.0) - ifm.refractive_index(20.0, 101325.0, 10.0)
    assert -1.0e-6 < dT < -0.85e-6 and 0.85e-6 < dp < 1.0e-6 and -1.0e-6 < dh < -0.5e-6


@settings(max_examples=40, deadline=None)
@given(st.floats(0, 500), st.floats(0, 0.2))
def test_cosine_error_is_never_positive_and_grows_with_angle(x, angle):
    e1, e2 = ifm.cosine_error_um(x, angle), ifm.cosine_error_um(x, angle * 1.5)
    assert e1 <= 0 and e2 <= e1 + 1e-15


def test_deadpath_error_uncorrected_is_index_change_times_deadpath():
    dead, path = ifm.reading_error_um(100.0, 1.000271, 1.000271, 1.000272, 1.000272, 5e4, corrected=False)
    assert dead == pytest.approx(-1e-6 * 5e4) and path == 0.0
    dead, _ = ifm.reading_error_um(100.0, 1.000271, 1.000271, 1.000272, 1.000272, 5e4, corrected=True)
    assert dead == 0.0


# ------------------------------------------------------------- piezo
def test_play_hysteresis_long_approach_gives_the_set_difference_and_short_steps_less():
    h = PlayHysteresis(500.0, 10.0)
    up = h.error(h.long_approach(240.0, 1), 240.0)
    down = h.error(h.long_approach(240.0, -1), 240.0)
    assert (down - up) * 1e3 == pytest.approx(10.0)
    z_long = h.sequence([0.0, 240.0])[-1]
    z_short = h.sequence([480.0, 200.0, 240.0])[-1]  # up by 40 um only: the widest play not reversed
    assert h.error(z_long, 240.0) == pytest.approx(up)
    assert up < h.error(z_short, 240.0) < down  # the approach distance matters, not only its direction


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0, 500), min_size=1, max_size=20))
def test_play_error_is_bounded_by_half_the_long_approach_difference(xs):
    h = PlayHysteresis(500.0, 10.0)
    z = h.sequence(xs)
    assert np.all(np.abs(h.error(z, np.array(xs))) <= 5e-3 + 1e-12)


def test_creep_grows_with_log_time_and_step_and_sensor_nonlinearity_vanishes_at_the_ends():
    c1, c2 = residual_creep_um(80.0, [2.5, 25.0], 1.0, 1e-3)
    assert 0 < c1 < c2
    assert residual_creep_um(160.0, 25.0, 1.0, 1e-3) == pytest.approx(2 * c2)
    e = sensor_nonlinearity_um(np.linspace(0, 1, 101), 500.0, 0.02)
    assert e[0] == pytest.approx(0.0, abs=1e-12) and e[-1] == pytest.approx(0.0, abs=1e-12)
    assert np.ptp(e) == pytest.approx(0.1, rel=1e-3)  # 0.02 % of 500 um


# ------------------------------------------------------------- error budget and ordering (summary step)
def test_effect_samples_replay_the_rig_exactly():
    """The budget's replay of a run (same commands, times, move history) gives the rig's readings."""
    import xarray as xr

    from calflow.nano.stage.error_budget import effect_samples

    quiet = dict(
        interferometer_noise_nm=0.0,
        repeatability_nm=0.0,
        settle_fraction=0.0,
        wavelength_stability_ppm=0.0,
        thermocouple_noise_mk=0.0,
        profile="lab5day",
        start_offset_s=3600.0,
    )
    rig = nano1d(**quiet)
    cmds = [0.0, 80.0, 160.0, 40.0, 200.0, 190.0, 480.0, 0.0, 240.0]
    times, meas = [], []
    for q in cmds:
        rig.move({"x": q})
        rig.wait(19.0)
        r = rig.read()
        times.append(r["time"] + 3600.0)
        meas.append(r["meas_x"])
    run = xr.Dataset({"cmd_x": ("sample", cmds), "time": ("sample", times)})
    terms = effect_samples(nano1d(**{**quiet, "start_offset_s": 0.0}), run, since_s=23.0)[
        "samples"
    ]  # campaign time
    rebuilt = np.array(cmds) + sum(v[:, 0] for v in terms.values())
    np.testing.assert_allclose(rebuilt, meas, atol=0.3e-3)
    assert np.ptp(terms["hysteresis"][:, 0]) > 5e-3 and np.ptp(terms["creep"][:, 0]) > 0


def test_budget_combination_adds_in_quadrature_when_uncorrelated():
    from calflow.nano.stage.error_budget import _combine

    rng = np.random.default_rng(1)
    a, b = rng.standard_normal((4000, 1)) * 0.02, rng.standard_normal((4000, 1)) * 0.01
    noise = rng.standard_normal((4000, 1)) * 0.005
    out = _combine({"a": a, "b": b}, a + b + noise)
    assert out["a"] == pytest.approx(20.0, rel=0.05) and out["b"] == pytest.approx(10.0, rel=0.05)
    assert out["noise_and_estimation"] == pytest.approx(5.0, rel=0.05)
    assert abs(out["interaction"]) < 0.3 * out["b"]
    same = _combine({"a": a, "b": a}, 2 * a)  # fully correlated: the interaction is large and positive
    assert same["interaction"] > same["a"]


def test_ordering_paragraph_follows_the_numbers_not_the_thesis():
    from calflow.nano.report.ordering import ordering_block

    ref = {
        "tests": {
            "no_calibration": {"max_accuracy_nm": 1000.0},
            "single": {"max_accuracy_nm": 400.0},
            "adaptive_kmz": {"max_accuracy_nm": 200.0},
        }
    }

    def tests(single, kmz):
        return {
            "no_calibration": {"max_accuracy_nm": 1500.0},
            "single": {"max_accuracy_nm": single},
            "adaptive_kmz": {"max_accuracy_nm": kmz},
        }

    a = ordering_block(tests(30.0, 80.0), {}, ref)
    assert a["order"] == ["single", "adaptive_kmz", "no_calibration"] and a["agrees"] is False
    assert "different" in a["statement"] and "30 nm" in a["statement"]
    b = ordering_block(tests(300.0, 80.0), {}, ref)
    assert b["order"] == ["adaptive_kmz", "single", "no_calibration"] and b["agrees"] is True
