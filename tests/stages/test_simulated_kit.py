"""The simulated-stage kit (calflow.rigs.simulated) on a stage of its own, no family's."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.data.bundle import Compensator, read_bundle
from calflow.errors import DataError, OptionError, UnknownOptionError
from calflow.rigs.simulated.budget import Replays, decompose, effects_of, require_simulated, signed_root
from calflow.rigs.simulated.campaign import simulated_options
from calflow.rigs.simulated.checks import Bounds, check_physics
from calflow.rigs.simulated.effects import Effect, Effects, SwitchedTruth

TABLE = Effects(
    {
        "tilt": Effect(("tilt_urad",), "a datasheet"),
        "wobble": Effect(("wobble_um", "wobble_period_um"), "a standard", modelled=False),
        "lost": Effect(("lost",), "a thesis table", modelled=False),
    },
    kind="toy",
)


class ToyTruth(SwitchedTruth, effects=TABLE):
    tilt_urad: float = 5.0
    wobble_um: tuple[float, float] = (1.0, -2.0)
    wobble_period_um: float = 400.0
    lost: bool = True
    noise_um: float = 0.1
    offset_um: float = -3.0
    profile: str = "flat"
    geometry_seed: int = 7
    unmodelled: bool = True


BOUNDS = Bounds(
    positive=("wobble_period_um",),
    signed=("offset_um", "wobble_um"),
    default=">=",
    choices={"profile": ("flat", "daily")},
)


def test_the_table_is_a_mapping_of_fields_with_sources():
    assert dict(TABLE) == {
        "tilt": ("tilt_urad",),
        "wobble": ("wobble_um", "wobble_period_um"),
        "lost": ("lost",),
    }
    assert TABLE.source("wobble") == "a standard" and TABLE.modelled("tilt") and not TABLE.modelled("lost")
    assert TABLE.unmodelled == ("wobble", "lost")
    assert TABLE.unmodelled_fields == ("wobble_um", "wobble_period_um", "lost")


def test_one_key_switches_off_the_unmodelled_effects_of_a_truth_and_of_options():
    t = ToyTruth(unmodelled=False)
    assert (t.wobble_um, t.wobble_period_um, t.lost, t.tilt_urad) == ((0.0, 0.0), 0.0, False, 5.0)
    assert ToyTruth().wobble_um == (1.0, -2.0)
    o = TABLE.unmodelled_off(
        {"unmodelled": False, "tilt_urad": 5.0, "wobble_um": (1.0, 2.0), "noise_um": 1.0}
    )
    assert o == {"unmodelled": False, "tilt_urad": 5.0, "wobble_um": (0.0, 0.0), "noise_um": 1.0}
    assert TABLE.unmodelled_off({"unmodelled": True, "lost": True}) == {"unmodelled": True, "lost": True}


def test_options_off_and_active_effects():
    defaults = ToyTruth().as_dict()
    assert TABLE.options_off(defaults, "wobble") == {"wobble_um": [0.0, 0.0], "wobble_period_um": 0.0}
    everything = TABLE.options_off(defaults)
    assert set(everything) == {"tilt_urad", "wobble_um", "wobble_period_um", "lost"}
    assert TABLE.active(ToyTruth()) == ["tilt", "wobble", "lost"]
    assert (
        TABLE.active(ToyTruth(**{k: tuple(v) if isinstance(v, list) else v for k, v in everything.items()}))
        == []
    )
    assert TABLE.active({**defaults, "tilt_urad": 0.0}) == ["wobble", "lost"]
    assert ToyTruth().without("tilt_urad").tilt_urad == 0.0
    with pytest.raises(ValueError, match=r"unknown toy effect\(s\) \['spin'\]"):
        TABLE.without(defaults, "spin")


def test_options_are_checked_against_the_declaration():
    o = check_physics(ToyTruth, BOUNDS, 3, "run", {"tilt_urad": 1, "wobble_um": [1, -1], "profile": "daily"})
    assert o == {"seed": 3, "stream": "run", "tilt_urad": 1.0, "wobble_um": (1.0, -1.0), "profile": "daily"}
    cases = [
        ({"tilt_urad": -1.0}, "tilt_urad", "a finite number >= 0"),
        ({"wobble_period_um": 0.0}, "wobble_period_um", "a finite number > 0"),
        ({"offset_um": float("nan")}, "offset_um", "a finite number"),
        ({"wobble_um": [1.0]}, "wobble_um", "a list of 2 numbers"),
        ({"wobble_um": [1.0, "a"]}, "wobble_um", "a list of 2 numbers, each finite"),
        ({"lost": 1}, "lost", "true or false"),
        ({"profile": "weekly"}, "profile", "one of flat, daily"),
        ({"geometry_seed": 1.5}, "geometry_seed", "an integer >= 0"),
    ]
    for physics, key, expected in cases:
        with pytest.raises(OptionError) as err:
            check_physics(ToyTruth, BOUNDS, 0, "", physics)
        assert key in str(err.value) and expected in str(err.value), (physics, str(err.value))
    with pytest.raises(UnknownOptionError, match="expected one of: seed, stream, camera, geometry_seed"):
        check_physics(ToyTruth, BOUNDS, 0, "", {"tilt": 1.0}, also=("camera",))
    with pytest.raises(OptionError, match="seed"):
        check_physics(ToyTruth, BOUNDS, -1, "", {})


@settings(max_examples=60, deadline=None)
@given(
    full=st.lists(st.floats(0.0, 100.0), min_size=1, max_size=6),
    data=st.data(),
)
def test_the_budget_adds_up_in_signed_quadrature(full, data):
    n = len(full)
    aps = st.lists(st.floats(0.0, 100.0), min_size=n, max_size=n)
    base = data.draw(aps)
    without = {f"e{i}": data.draw(aps) for i in range(data.draw(st.integers(0, 4)))}
    rms, budget = decompose(full, base, without)
    assert np.isclose(rms**2, np.mean(np.square(full)))
    total = sum(np.sign(v) * v**2 for v in budget.values())
    assert np.isclose(total, np.mean(np.square(full)), rtol=1e-9, atol=1e-9)
    for e, w in without.items():
        assert np.isclose(
            np.sign(budget[e]) * budget[e] ** 2, np.mean(np.square(full)) - np.mean(np.square(w))
        )
    assert list(budget) == ["baseline", *without, "interaction"]


@given(st.floats(-1e6, 1e6))
def test_signed_root_keeps_the_sign(v):
    r = signed_root(v)
    assert np.sign(r) == np.sign(v) and np.isclose(r * abs(r), v)


def test_replays_skip_what_the_rig_has_off_already():
    calls = []
    replays = Replays(
        options=lambda name: {} if name == "none" else {f"{name}_off": True},
        active=lambda c: ["tilt"],
        heldout=lambda c, options: calls.append(options) or {"M": [1.0]},
    )
    records = replays.run({"name": "toy"}, ["baseline", "tilt", "wobble", "none"])
    assert [r["active"] for r in records] == [True, True, False, True]
    assert records[1] == {"replay": "tilt", "active": True, "options": {"tilt_off": True}, "ap": {"M": [1.0]}}
    assert calls == [{"baseline_off": True}, {"tilt_off": True}, {}]
    by, effects = effects_of(records)
    assert effects == ["tilt"] and set(by) == {"baseline", "tilt", "none"}
    with pytest.raises(Exception, match="campaign toy: key 'rig.factory'.*got 'gcs'"):
        require_simulated({"rig": {"factory": "gcs"}}, "campaign toy")


def test_the_physics_options_of_a_simulated_stage_direct_or_behind_a_controller():
    direct = {"rig": {"factory": "simulated", "options": {"seed": 1, "a": 2}, "runs": {"r": {"a": 3}}}}
    assert simulated_options(direct, ("toy_sensor",)) == {"a": 2}
    assert simulated_options(direct, ("toy_sensor",), run="r") == {"a": 3}
    behind = {
        "rig": {"factory": "gcs", "options": {"sensor": {"factory": "toy_sensor", "options": {"b": 1}}}}
    }
    assert simulated_options(behind, ("toy_sensor",)) == {"b": 1}
    assert simulated_options(behind, ("other",)) is None
    assert simulated_options({}, ("toy_sensor",)) == {}


def test_a_bundle_read_back_names_file_and_field(tmp_path):
    path = tmp_path / "bundle.json"
    with pytest.raises(DataError, match="file not found"):
        read_bundle(tmp_path, "toy", 1, ("a",))
    path.write_text("{")
    with pytest.raises(DataError, match="not JSON"):
        read_bundle(path, "toy", 1, ("a",))
    path.write_text(json.dumps({"format": "toy", "version": 2}))
    with pytest.raises(DataError, match="fields 'format', 'version': expected 'toy' 1, got 'toy' 2"):
        read_bundle(path, "toy", 1, ("a",))
    path.write_text(json.dumps({"format": "toy", "version": 1, "parameters": {"a": {"value": "x"}}}))
    with pytest.raises(DataError, match=r"field 'parameters.a.value': expected a number"):
        read_bundle(tmp_path, "toy", 1, ("a",))
    doc = {"format": "toy", "version": 1, "parameters": {"a": {"value": 2.5}}}
    path.write_text(json.dumps(doc))
    assert read_bundle(tmp_path, "toy", 1, ("a",)) == (path, doc)

    class Params:
        def __init__(self, a):
            self.a = a

        def as_dict(self):
            return {"a": self.a}

    class Model:
        def __init__(self, doc):
            self.parameters = Params(doc["parameters"]["a"]["value"])

    class ToyCompensator(Compensator):
        read_model = staticmethod(lambda p: Model(read_bundle(p, "toy", 1, ("a",))[1]))

    assert ToyCompensator.load(tmp_path).parameters == {"a": 2.5}


def test_joint_commands_of_move_and_visit_name_the_rig():
    from calflow.errors import RigError
    from calflow.rigs.simulated.commands import joint_commands

    assert joint_commands("toy rig", "move", False, ("x", "y"), {"x": 1, "y": 2.5, "z": 9}).tolist() == [
        1.0,
        2.5,
    ]
    rows = joint_commands("toy rig", "visit", False, ("x", "y"), {"x": [1, 2], "y": [3, 4]})
    assert rows.shape == (2, 2) and rows[1].tolist() == [2.0, 4.0]
    with pytest.raises(RigError, match=r"^toy rig: command lacks joint 'y'$"):
        joint_commands("toy rig", "visit", False, ("x", "y"), {"x": [1.0]})
    with pytest.raises(RigError, match=r"^toy rig: move\(\) after close\(\)$"):
        joint_commands("toy rig", "move", True, ("x",), {"x": 1.0})
