"""The ``rig.options.aging`` checks every simulated stage shares (calflow.rigs.aging)."""

from __future__ import annotations

import pytest

from calflow.errors import OptionError
from calflow.nano.stage import aging as nano_aging
from calflow.rigs import aging
from calflow.xytheta.stage import aging as xy_aging


def test_off_on_and_defaults():
    d = {"since": "2026-01-05T08:00:00+00:00", "rate": 1.0}
    assert aging.options(False, d) is None
    assert aging.options(None, d) == aging.options(True, d) == d
    assert aging.options({"rate": 2.0}, d) == {**d, "rate": 2.0}
    with pytest.raises(OptionError, match=r"aging\.speed"):
        aging.options({"speed": 1}, d)
    with pytest.raises(OptionError, match="false or a mapping"):
        aging.options(3, d)


@pytest.mark.parametrize("family", [xy_aging, nano_aging])
def test_a_date_without_its_offset_is_refused_by_every_family(family):
    """A naive time cannot be subtracted from the stage's commissioning: one line, not a
    TypeError later (the XYΘ stage used to accept it at load)."""
    with pytest.raises(OptionError, match=r"aging\.since.*offset"):
        family.check({"since": "2026-01-05T08:00:00"})
    with pytest.raises(OptionError, match=r"aging\.events\.0\.date"):
        family.check({"events": [{"date": "2026-07-01"}]})


def test_events_and_numbers():
    aging.events([{"date": "2026-07-01T00:00:00Z", "a": 1.5}], ("a", "b"))
    with pytest.raises(OptionError, match=r"aging\.events\.0'?"):
        aging.events([{"date": "2026-07-01T00:00:00Z", "c": 1}], ("a", "b"))
    with pytest.raises(OptionError, match=r"aging\.events\.0\.b"):
        aging.events([{"date": "2026-07-01T00:00:00Z", "b": float("nan")}], ("a", "b"))
    with pytest.raises(OptionError, match=r"aging\.events"):
        aging.events({"date": "2026-07-01T00:00:00Z"}, ("a",))
    assert aging.number(0.5, "k", 0.0, 1.0) == 0.5
    for bad in (True, -0.1, 1.1, float("inf"), "1"):
        with pytest.raises(OptionError, match="k"):
            aging.number(bad, "k", 0.0, 1.0)


def test_season_peaks_on_its_day_and_is_opposite_half_a_year_on():
    assert aging.season(196, 196) == pytest.approx(1.0)
    assert aging.season(196 + aging.YEAR_D / 2, 196) == pytest.approx(-1.0)
