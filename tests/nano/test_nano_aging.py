"""Simulated nano stages that age with the campaign's start (rig.options.aging)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError, OptionError
from calflow.lifecycle import history
from calflow.nano.checks import check_campaign
from calflow.nano.models.geometric import GeometricModel
from calflow.nano.stage.aging import DEFAULT_SINCE, check, piezo_loss_pct
from calflow.nano.stage.aging import resolve as _resolve
from calflow.nano.stage.error_budget import rig_from_truth
from calflow.nano.stage.options import _COMMON
from calflow.nano.stage.rig import Nano1DRig, Nano2DRig, nano1d, nano2d

ROOT = Path(__file__).resolve().parents[2]
YEAR_LATER = "2027-01-05T14:00:00+00:00"  # 365.25 days after DEFAULT_SINCE, same day of the year
QUIET = {"profile": "constant", "world_seed": 3}
ONLY_GAIN = {"sensor_drift_nm_per_month": 0, "seasonal_degC": 0}


def resolve(options, start, cls=Nano1DRig):
    return _resolve(options, start, {**_COMMON, **cls._EXTRA}, cls._AXIS)


def _readings(rig, commands):
    out = []
    for q in commands:
        rig.move({j: q for j in rig.joints})
        rig.wait(2.0)
        r = rig.read()
        out.append([r[s] for s in rig.sensors] + [r[t] for t in rig.thermometers])
    return np.array(out)


def test_off_or_at_commissioning_reads_todays_stage_bit_for_bit():
    assert resolve({"aging": False, **QUIET}, YEAR_LATER) == QUIET
    assert resolve(dict(QUIET), DEFAULT_SINCE) == QUIET
    commands = [0.0, 480.0, 120.0, 300.5]
    today = _readings(nano1d(seed=4, **QUIET), commands)
    assert np.array_equal(
        today, _readings(nano1d(seed=4, **resolve({"aging": False, **QUIET}, YEAR_LATER)), commands)
    )
    assert np.array_equal(today, _readings(nano1d(seed=4, **resolve(dict(QUIET), DEFAULT_SINCE)), commands))
    assert not np.array_equal(today, _readings(nano1d(seed=4, **resolve(dict(QUIET), YEAR_LATER)), commands))


def test_a_year_on_the_gain_is_lower_by_the_documented_ageing():
    days = 365.25
    expected = -(
        1.0 * math.log10((365.0 + days) / 365.0) + 0.1 * days / 365.25
    )  # docstring: r lg(..) + rate t
    aged = resolve({"aging": ONLY_GAIN}, YEAR_LATER)
    assert aged == {"gain_pct": pytest.approx(expected, rel=1e-12)}
    # unmodelled: false, as the interferometer's periodic error depends on where the stage is
    young, old = nano1d(**QUIET, unmodelled=False), nano1d(**QUIET, unmodelled=False, **aged)
    for x in (100.0, 400.0):
        shift = (
            old.true_position(x, time=0.0, direction=1)["meas_x"] - young.true_position(x, 0.0, 1)["meas_x"]
        )
        assert shift == pytest.approx(expected * 1e-2 * x, rel=1e-9)
    assert (
        old.true_position(400.0, 0.0)["meas_y"] == young.true_position(400.0, 0.0)["meas_y"]
    )  # across: no gain


@given(
    rate=st.floats(0.0, 5.0),
    poled=st.floats(1.0, 1e4),
    days=st.floats(0.0, 1e5),
    more=st.floats(0.0, 1e5),
)
def test_piezo_loss_is_logarithmic_since_poling(rate, poled, days, more):
    assert piezo_loss_pct(0.0, rate, poled) == 0.0
    assert piezo_loss_pct(9.0 * poled, rate, poled) == pytest.approx(rate, rel=1e-9, abs=1e-12)  # one decade
    assert piezo_loss_pct(days + more, rate, poled) >= piezo_loss_pct(days, rate, poled) - 1e-12
    assert piezo_loss_pct(-days, rate, poled) == 0.0  # before commissioning: the commissioned stage


def test_sensor_drift_moves_the_on_axis_zero_by_its_rate():
    aged = resolve(
        {"aging": {"piezo_pct_per_decade": 0, "depolarisation_pct_per_year": 0, "seasonal_degC": 0}},
        YEAR_LATER,
    )
    assert aged == {"offset_nm": [pytest.approx(2.0 * 12.0), 0.0]}  # 2 nm per month, 12 months
    two = resolve(
        {"aging": {"piezo_pct_per_decade": 0, "depolarisation_pct_per_year": 0}}, YEAR_LATER, Nano2DRig
    )
    assert two["offset_nm"] == [pytest.approx(24.0), pytest.approx(24.0)]
    young, old = nano2d(**QUIET, unmodelled=False), nano2d(**QUIET, unmodelled=False, **two)
    moved = old.true_position({"x": 40.0, "y": 10.0}, 0.0)
    still = young.true_position({"x": 40.0, "y": 10.0}, 0.0)
    assert moved["meas_x"] - still["meas_x"] == pytest.approx(0.024, abs=1e-12)


def test_the_room_is_warmer_in_july_and_unchanged_a_year_on():
    a = {
        "aging": {"piezo_pct_per_decade": 0, "depolarisation_pct_per_year": 0, "sensor_drift_nm_per_month": 0}
    }
    july = resolve(a, "2026-07-15T08:00:00+00:00")["base_temperature_c"]
    two_pi = 2 * math.pi / 365.25
    assert july - _COMMON["base_temperature_c"] == pytest.approx(
        math.cos(two_pi * (196 - 196)) - math.cos(two_pi * (5 - 196)), rel=1e-12
    )
    assert "base_temperature_c" not in resolve(a, YEAR_LATER)


@pytest.mark.parametrize(
    ("switch", "moved"),
    [
        ("piezo_pct_per_decade", "gain_pct"),
        ("depolarisation_pct_per_year", "gain_pct"),
        ("sensor_drift_nm_per_month", "offset_nm"),
        ("seasonal_degC", "base_temperature_c"),
    ],
)
def test_each_effect_on_alone_and_off(switch, moved):
    rates = {
        k: 0
        for k in (
            "piezo_pct_per_decade",
            "depolarisation_pct_per_year",
            "sensor_drift_nm_per_month",
            "seasonal_degC",
        )
    }
    start = "2026-10-05T08:00:00+00:00"
    assert set(resolve({"aging": {**rates, switch: check({})[switch]}}, start)) == {moved}
    assert resolve({"aging": rates}, start) == {}


def test_gain_seen_scales_what_reaches_the_position():
    full = resolve({"aging": ONLY_GAIN}, YEAR_LATER)["gain_pct"]
    assert resolve({"aging": {**ONLY_GAIN, "gain_seen": 0.25}}, YEAR_LATER)["gain_pct"] == pytest.approx(
        full / 4
    )
    assert resolve({"aging": {**ONLY_GAIN, "gain_seen": 0}}, YEAR_LATER) == {}


def test_dated_events_from_their_date_on():
    event = {"date": "2026-07-01T00:00:00+00:00", "gain_pct": -1.0, "offset_nm": 50, "cosine_deg": 0.05}
    a = {
        "aging": {
            "piezo_pct_per_decade": 0,
            "depolarisation_pct_per_year": 0,
            "sensor_drift_nm_per_month": 0,
            "seasonal_degC": 0,
            "events": [event],
        }
    }
    assert resolve(a, "2026-06-30T23:59:59+00:00") == {}
    after = resolve(a, "2026-07-01T00:00:00+00:00")
    assert after == {
        "gain_pct": pytest.approx(-1.0),
        "offset_nm": [pytest.approx(50.0), 0.0],
        "cosine_deg": pytest.approx(_COMMON["cosine_deg"] + 0.05),
    }


def _campaign(tmp_path, options, start=YEAR_LATER, name="stage1d-aged", runs=None):
    data = yaml.safe_load((ROOT / "config/campaigns/nano1d-thesis.yaml").read_text())
    data["rig"]["options"] = options
    data["start"] = start
    if runs is not None:
        data["rig"]["runs"] = runs
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_the_loader_resolves_once_and_the_budget_replays_the_aged_stage(tmp_path):
    c = load_campaign(_campaign(tmp_path, {"profile": "constant"}))
    options = c["rig"]["options"]
    assert options["gain_pct"] < 0 and options["offset_nm"][0] > 0 and "aging" not in options
    default = load_campaign(ROOT / "config/campaigns/nano1d-thesis.yaml")
    assert (
        default["rig"]["options"]
        == yaml.safe_load((ROOT / "config/campaigns/nano1d-thesis.yaml").read_text())["rig"]["options"]
    )
    rig = nano1d(**options)
    replay = rig_from_truth(rig.truth())  # the error budget's replays
    assert replay.options["gain_pct"] == options["gain_pct"]
    assert replay.true_position(300.0, 0.0) == rig.true_position(300.0, 0.0)


@pytest.mark.parametrize(
    ("aging", "key"),
    [
        ({"piezo_pct_per_decade": -1}, "rig.options.aging.piezo_pct_per_decade"),
        ({"since": "last spring"}, "rig.options.aging.since"),
        ({"gain_seen": 1.5}, "rig.options.aging.gain_seen"),
        ({"poled_days_before": 0}, "rig.options.aging.poled_days_before"),
        ({"events": [{"date": "2026-07-01T00:00:00+00:00", "alpha_deg": 1}]}, "rig.options.aging.events.0"),
        (
            {"events": [{"date": "2026-07-01T00:00:00+00:00", "offset_nm": "far"}]},
            "rig.options.aging.events.0.offset_nm",
        ),
        ({"wear_per_year": 0.1}, "rig.options.aging.wear_per_year"),
        (3, "rig.options.aging"),
    ],
)
def test_bad_ageing_refused_in_one_line_naming_the_field(tmp_path, aging, key):
    with pytest.raises(ConfigError) as err:
        load_campaign(_campaign(tmp_path, {"aging": aging}))
    msg = str(err.value)
    assert "\n" not in msg and f"'{key}'" in msg and "stage1d-aged.yaml" in msg


def test_the_world_behind_an_emulated_controller_ages_too(tmp_path):
    sensor = {"factory": "simulated_interferometer", "options": {"aging": {"seasonal_degC": 0}}}
    c = {"robot": "stage2d", "start": YEAR_LATER, "rig": {"factory": "gcs", "options": {"sensor": sensor}}}
    aged = check_campaign(c, tmp_path / "gcs.yaml").rig["options"]["sensor"]["options"]
    assert c["rig"]["options"]["sensor"] == sensor  # resolved, not changed in place
    assert aged == resolve({"aging": {"seasonal_degC": 0}}, YEAR_LATER, Nano2DRig) and aged["gain_pct"] < 0
    bad = {"factory": "simulated_interferometer", "options": {"aging": {"since": "soon"}}}
    c["rig"]["options"]["sensor"] = bad
    with pytest.raises(ConfigError, match=r"gcs\.yaml: key 'rig\.options\.sensor\.options\.aging\.since'"):
        check_campaign(c, tmp_path / "gcs.yaml")


def test_ageing_per_run_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"'rig\.runs\.metrology\.aging'"):
        load_campaign(_campaign(tmp_path, {}, runs={"metrology": {"aging": False}}))


def test_unknown_field_raises_option_error_naming_it():
    with pytest.raises(OptionError, match="aging.bogus"):
        check({"bogus": 1})


# ---------------------------------------------------------------- a stage's history
def _calibration(options, seed):
    """Eq. (5.1) fitted to a small 1-DoF plan (0..480 um, 3 cycles) on the simulated stage,
    as a nano summary's ``models`` and ``tests`` blocks (what the history reads)."""
    rig = nano1d(seed=seed, **QUIET, **options)
    commands = np.tile(np.arange(0.0, 481.0, 30.0), 3)
    x = _readings(rig, commands)[:, 0]
    model = GeometricModel.fit(commands, x, order=3)
    residual = np.abs(model.residuals(commands, x))
    return model, {
        "models": {"single": model.coefficients.to_dict("records")},
        "tests": {"single": {"heldout_max_accuracy_nm": 1e3 * float(residual.max())}},
    }


def test_a_history_a_year_apart_sees_the_gain_change():
    def campaign(name, start):
        return {"name": name, "start": start, "robot": "stage1d"}

    first, s1 = _calibration(resolve({}, DEFAULT_SINCE), seed=1)
    again, s2 = _calibration(resolve({"aging": False}, "2026-01-19T08:00:00+00:00"), seed=2)
    later, s3 = _calibration(resolve({"aging": ONLY_GAIN}, YEAR_LATER), seed=3)
    gain = resolve({"aging": ONLY_GAIN}, YEAR_LATER)["gain_pct"] * 1e-2
    # q = a_1 x + ...: a stage that moves (1 + g) per command needs 1/(1 + g) the command
    assert later.value("a_1") / first.value("a_1") == pytest.approx(1.0 / (1.0 + gain), abs=0.05 * abs(gain))
    h = history.build(
        "SN-P625",
        [
            (campaign("p625-a", DEFAULT_SINCE), s1),
            (campaign("p625-b", "2026-01-19T08:00:00+00:00"), s2),
            (campaign("p625-c", YEAR_LATER), s3),
        ],
    )
    unchanged, aged = (c["models"]["single"] for c in h["changes"])
    assert not unchanged["significant"]
    assert aged["significant"] and aged["p_value"] < 1e-6
