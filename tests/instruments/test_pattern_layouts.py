"""Pattern layouts are contributions: a lab's own encoding registers a Layout through the
``calflow.pattern_layouts`` entry points and calflow reads and decodes its files without a
change to the core; a bad registration is refused in one line."""

from __future__ import annotations

import json
import sys
import types
from importlib.metadata import EntryPoint

import numpy as np
import pytest

from calflow.errors import CalflowError
from calflow.instruments.pattern import layouts as registry
from calflow.instruments.pattern.decode import Decoded


@pytest.fixture
def lab_layout(monkeypatch):
    """A module ``lab_layout`` of a lab's package with a Layout whose file key is ``LabGrid``."""
    mod = types.ModuleType("lab_layout")

    class LabPattern:
        layout = "labgrid"

        def __init__(self, period):
            self.period_um = period

    def read(data, where):
        body = data.get("LabGrid", data)
        if not isinstance(body.get("period"), (int, float)):
            raise CalflowError(f"{where}: LabGrid.period: expected a number")
        return LabPattern(float(body["period"]))

    def decode(frames, pattern, **options):
        n = len(np.atleast_3d(frames)) if np.ndim(frames) == 3 else 1
        full = np.full(n, pattern.period_um)
        return Decoded(full, full, full, full, full, full, np.array(["ok"] * n), np.array(["decoded"] * n))

    mod.read, mod.decode = read, decode
    mod.LAYOUT = registry.Layout("labgrid", "a lab's grid", read, decode, ("LabGrid",))
    mod.NAMED = registry.Layout("named", "hooks named, not given", "lab_layout:read", "lab_layout:decode")
    mod.NOT_A_LAYOUT = object()
    mod.TWIN = registry.Layout("megarena", "a second megarena", read, decode)
    monkeypatch.setitem(sys.modules, "lab_layout", mod)
    real = registry.entry_points

    def with_lab(names=("LAYOUT",)):
        def fake(group):
            eps = list(real(group=group))
            eps += [EntryPoint(f"lab{k}", f"lab_layout:{n}", group) for k, n in enumerate(names)]
            return eps

        monkeypatch.setattr(registry, "entry_points", fake)
        registry.layouts.cache_clear()

    yield with_lab
    registry.layouts.cache_clear()


def test_a_labs_layout_plugs_in_without_a_core_edit(tmp_path, lab_layout):
    lab_layout()
    assert {"cell2x2", "megarena", "labgrid"} <= set(registry.layouts())
    path = tmp_path / "lab.json"
    path.write_text(json.dumps({"LabGrid": {"period": 7.5}}))
    pattern = registry.load_pattern(path)
    assert pattern.layout == "labgrid" and pattern.period_um == 7.5
    result = registry.decode_frames(np.zeros((2, 32, 32)), pattern)
    assert list(result.x_um) == [7.5, 7.5]
    with pytest.raises(CalflowError, match="LabGrid.period"):
        registry.read_pattern({"LabGrid": {}}, "lab.json")


@pytest.mark.parametrize(
    "names, said",
    [
        (("NOT_A_LAYOUT",), "is not a calflow pattern Layout"),
        (("TWIN",), "a second layout named 'megarena'"),
        (("NAMED",), "read and decode: expected functions"),
    ],
)
def test_a_bad_registration_is_refused_in_one_line(lab_layout, names, said):
    lab_layout(names)
    with pytest.raises(CalflowError) as err:
        registry.layouts()
    assert (
        said in str(err.value) and "\n" not in str(err.value) and "calflow.pattern_layouts:" in str(err.value)
    )
