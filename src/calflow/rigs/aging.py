"""What the ``rig.options.aging`` option of every simulated stage shares.

Each family's simulated stage says what ages and how fast (its ``stage/aging.py``); the
checks of the option's shape, its dates and numbers, the dated events and the yearly season
are the same for all of them and live here. Errors are
:class:`~calflow.errors.OptionError` naming the field (``aging.<field>``).
"""

from __future__ import annotations

import datetime as dt
import math

from calflow.errors import OptionError

YEAR_D = 365.25  # days in a year (Julian year)
DEFAULT_SINCE = "2026-01-05T08:00:00+00:00"  # the stages' commissioning when a campaign gives none


def defaults(**stage) -> dict:
    """The defaults of a stage's ``aging`` option: the commissioning date (``since``), what
    the stage's ``stage`` fields age, a yearly room season of ±1 °C peaking mid-July (day
    196: an air-conditioned lab, ISO 230-3 Annex A), no events."""
    return {"since": DEFAULT_SINCE, **stage, "seasonal_degC": 1.0, "seasonal_peak_day": 196, "events": []}


def checked(aging, defaults: dict, event_keys: tuple[str, ...]) -> dict | None:
    """The ``aging`` option with its ``defaults`` (:func:`options`), its shared fields checked
    (``since``, the season, ``events`` moving some of ``event_keys``); None when ageing is off.
    The stage checks its own fields."""
    a = options(aging, defaults)
    if a is None:
        return None
    date(a["since"], "aging.since")
    number(a["seasonal_degC"], "aging.seasonal_degC")
    number(a["seasonal_peak_day"], "aging.seasonal_peak_day", None)
    events(a["events"], event_keys)
    return a


def split(options: dict, start: str, check) -> tuple[dict, dict | None]:
    """A rig's ``options`` without ``aging``, and that option checked (``check(aging)``, the
    stage's) against the campaign's ``start`` (:func:`lifetime`); None when ageing is off."""
    options = dict(options)
    given = options.pop("aging", None)
    a = check(given)
    if a is not None:
        lifetime(a, given, start)
    return options, a


def options(aging, defaults: dict) -> dict | None:
    """The ``aging`` option with its ``defaults``: None when it is ``false`` (ageing off);
    ``true`` or absent give the defaults; unknown fields are refused."""
    if aging is False:
        return None
    if aging is None or aging is True:
        aging = {}
    if not isinstance(aging, dict):
        raise OptionError("aging", f"false or a mapping ({', '.join(defaults)})", aging)
    unknown = sorted(set(aging) - set(defaults))
    if unknown:
        raise OptionError(f"aging.{unknown[0]}", f"one of {', '.join(defaults)}", unknown=True)
    return {**defaults, **aging}


def date(value, key: str) -> dt.datetime:
    """An ISO 8601 date and time with its UTC offset (naive times are refused: the stage's
    age is a difference of two instants)."""
    try:
        t = dt.datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except ValueError:
        raise OptionError(key, "an ISO 8601 date and time with its offset", value) from None
    if t.tzinfo is None:
        raise OptionError(key, "an ISO 8601 date and time with its offset", value)
    return t


def number(value, key: str, low: float | None = 0.0, high: float | None = None) -> float:
    """A finite number within [low, high] (either bound None: open)."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and (low is None or value >= low) and (high is None or value <= high)
    if not ok:
        bounds = (f" >= {low:g}" if low is not None else "") + (
            f" and <= {high:g}" if high is not None else ""
        )
        raise OptionError(key, "a finite number" + bounds, value)
    return float(value)


def events(items, keys: tuple[str, ...]) -> None:
    """``aging.events``: a list of mappings with a ``date`` and some of ``keys`` (numbers)."""
    if not isinstance(items, list):
        raise OptionError("aging.events", f"a list of {{date, {', '.join(keys)}}}", items)
    for i, e in enumerate(items):
        if not isinstance(e, dict) or "date" not in e or set(e) - {"date", *keys}:
            raise OptionError(f"aging.events.{i}", f"a mapping with 'date' and some of {', '.join(keys)}", e)
        date(e["date"], f"aging.events.{i}.date")
        for k in keys:
            if k in e:
                number(e[k], f"aging.events.{i}.{k}", None)


def lifetime(aging: dict, given, start) -> None:
    """The dates of a checked ``aging`` against the campaign's ``start``: a ``since`` the
    campaign gives (the stage's commissioning) lies at or before ``start`` — else the stage
    would age backwards — and every event lies at or after ``since`` (an event before the
    commissioning would be applied to every campaign of the stage)."""
    t0, t = date(aging["since"], "aging.since"), date(start, "start")
    if isinstance(given, dict) and "since" in given and t0 > t:
        raise OptionError(
            "aging.since",
            f"the stage's commissioning at or before the campaign's start ({start})",
            given["since"],
        )
    for i, e in enumerate(aging["events"]):
        if date(e["date"], f"aging.events.{i}.date") < t0:
            given_since = isinstance(given, dict) and "since" in given
            raise OptionError(
                f"aging.events.{i}.date",
                f"a date at or after the stage's commissioning (aging.since, {aging['since']}"
                f"{'' if given_since else ', its default'})",
                e["date"],
            )


def season(day_of_year: float, peak_day: float) -> float:
    """The yearly season, cos(2π (day − peak)/year): 1 on the peak day, −1 half a year on."""
    return math.cos(2 * math.pi * (day_of_year - peak_day) / YEAR_D)
