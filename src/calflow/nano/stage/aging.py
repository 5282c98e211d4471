"""A simulated nano stage (1-DoF, 2-DoF piezo stages) that ages with the campaign's ``start``.

``rig.options.aging`` (on by default, ``false`` turns it off) describes the stage's life
since ``since`` (its commissioning; default the default campaign start, so a campaign that
starts then sees the rig of :mod:`calflow.nano.stage.rig` unchanged). The campaign loader
resolves it, for the campaign's ``start``, into the rig's options (:func:`resolve`, called
by :func:`calflow.nano.checks.check_campaign`); every consumer of the options (the rig, the
error budget's replays of the rig's truth, the designed plans) then sees the same aged
stage. Ageing is constant within a campaign (a campaign lasts days, ageing takes months).
Time Δt in days since ``since`` (an earlier campaign sees the commissioned stage, in
its season).

Each effect, where its law and size come from, and the rig option it moves:

* ``piezo_pct_per_decade`` (default 1.0) with ``poled_days_before`` (default 365): the
  piezo's gain (stroke per volt, d33) falls logarithmically with the time since poling,
  loss = r · lg((t_p + Δt) / t_p) %, t_p the stack's age at commissioning (PI Ceramic's
  material data and Physik Instrumente's *Piezo Mechanics Design Tutorial* give ageing as a
  change per time decade after poling; Jaffe, Cook & Jaffe, *Piezoelectric Ceramics*, 1971,
  and APC International, *Piezoelectric Ceramics: Principles and Applications*, 2011, tabulate
  ageing rates per decade of soft PZT's coupling and permittivity of a fraction of a % to
  ~2 %). The size 1 %/decade and the one-year age at commissioning are *assumed*.
* ``depolarisation_pct_per_year`` (default 0.1): a further loss of gain, linear in the time
  driven at the rig's voltage (0-120 V of a PICMA stack) and temperature (20 °C, far below
  the Curie point). *Assumed* size: no datasheet gives a rate at these conditions.
  ``events`` with ``gain_pct`` add a dated step (an overheat: ``gain_pct: -1``).
* ``gain_seen`` (default 1.0): the fraction of the piezo's loss of gain that reaches the
  measured position, as in an open loop or a loop on a strain gauge on the stack. *Assumed*:
  a loop on a capacitive sensor that measures the platform (the P-625.1CD's) holds the
  position and asks for more voltage instead, so 0 is the better figure for such a stage
  (its loss then shows only as a smaller stroke reserve, not simulated). The resolved loss,
  ``gain_seen`` × (ageing + depolarisation + events), goes to the rig's ``gain_pct``: the
  stage moves (1 + gain_pct/100) × the command along each axis, the actuator gain the
  calibration identifies (``a_1`` of Eq. (5.1), the linear terms of Eq. (5.3), (5.10)).
* ``sensor_drift_nm_per_month`` (default 2.0): the stage's capacitive sensor's zero drifts
  with calendar time, moving the stage along each axis (rig option ``offset_nm``; one month
  = 365.25/12 days). PI gives the long-term stability of its capacitive sensors over hours
  only (sub-nm over 3 h); the monthly rate is *assumed*. The thesis sees such a shift: its
  stage's error curve "has been moved in parallel which is due to long term use" (Sec. 5.2,
  Fig. 5.1 a).
* ``seasonal_degC`` (default 1.0) with ``seasonal_peak_day`` (default 196, mid-July): the
  room's mean temperature follows a yearly sine of that amplitude (an air-conditioned lab
  held within ±1 °C over the year, ISO 230-3 Annex A / ASME B5.54 Sec. 5); it shifts the
  rig's ``base_temperature_c`` by the difference to ``since``.
* ``events``: step changes at a date, applied to campaigns that start at or after it — a
  re-mount moving the stage's zero (``offset_nm`` along each axis) and its installation
  (``cosine_deg``, ``abbe_offset_mm``: Table 3.4, U7, U8), or a depolarising ``gain_pct``,
  e.g. ``{date: "2026-07-01T00:00:00+00:00", offset_nm: 50, cosine_deg: 0.05}``.
"""

from __future__ import annotations

import math

from calflow.errors import OptionError
from calflow.rigs.aging import YEAR_D, checked, date, defaults, number, season, split

#: what an event may move, and the rig option it adds to
EVENT_KEYS = ("gain_pct", "offset_nm", "cosine_deg", "abbe_offset_mm")
DEFAULTS = defaults(
    piezo_pct_per_decade=1.0,
    poled_days_before=365.0,
    depolarisation_pct_per_year=0.1,
    gain_seen=1.0,
    sensor_drift_nm_per_month=2.0,
)
_MONTH_D = YEAR_D / 12.0
DEFAULT_SINCE = DEFAULTS["since"]  # the commissioning when a campaign gives none


def check(aging) -> dict | None:
    """The ``aging`` option checked, with its defaults; None when ageing is off. Raises
    :class:`~calflow.errors.OptionError` naming the field (``aging.<field>``)."""
    a = checked(aging, DEFAULTS, EVENT_KEYS)
    if a is None:
        return None
    for key in ("piezo_pct_per_decade", "depolarisation_pct_per_year"):
        number(a[key], f"aging.{key}")
    if number(a["poled_days_before"], "aging.poled_days_before") <= 0:
        raise OptionError("aging.poled_days_before", "a finite number > 0", a["poled_days_before"])
    number(a["gain_seen"], "aging.gain_seen", 0.0, 1.0)
    number(a["sensor_drift_nm_per_month"], "aging.sensor_drift_nm_per_month", None)
    return a


def piezo_loss_pct(days: float, rate_pct_per_decade: float, poled_days_before: float) -> float:
    """Loss of the piezo's gain (%, ≥ 0) ``days`` after commissioning by logarithmic ageing
    since poling: r · lg((t_p + Δt) / t_p) (module docstring)."""
    return rate_pct_per_decade * math.log10((poled_days_before + max(days, 0.0)) / poled_days_before)


def effects(aging: dict, start: str) -> dict:
    """Each effect of a checked ``aging`` at ``start``: ``piezo_pct``, ``depolarisation_pct``
    (losses, %), ``events_gain_pct``, ``gain_pct`` (what the stage's gain changes by, %),
    ``drift_nm``, ``events_offset_nm``, ``room_degC`` and the installation's steps."""
    t, t0 = date(start, "start"), date(aging["since"], "aging.since")
    days = max((t - t0).total_seconds() / 86400.0, 0.0)
    piezo = piezo_loss_pct(days, aging["piezo_pct_per_decade"], aging["poled_days_before"])
    depol = aging["depolarisation_pct_per_year"] * days / YEAR_D
    past = [e for e in aging["events"] if t >= date(e["date"], "aging.events.date")]
    steps = {k: sum(e.get(k, 0.0) for e in past) for k in EVENT_KEYS}
    peak = aging["seasonal_peak_day"]
    swing = season(t.timetuple().tm_yday, peak) - season(t0.timetuple().tm_yday, peak)
    return {
        "days": days,
        "piezo_pct": piezo,
        "depolarisation_pct": depol,
        "events_gain_pct": steps["gain_pct"],
        "gain_pct": aging["gain_seen"] * (steps["gain_pct"] - piezo - depol),
        "drift_nm": aging["sensor_drift_nm_per_month"] * days / _MONTH_D,
        "events_offset_nm": steps["offset_nm"],
        "room_degC": aging["seasonal_degC"] * swing,
        "cosine_deg": steps["cosine_deg"],
        "abbe_offset_mm": steps["abbe_offset_mm"],
    }


def resolve(options: dict, start: str, defaults: dict, axes: tuple) -> dict:
    """The rig's options for a campaign starting at ``start``: ``options`` without ``aging``,
    with the aged values of the options ageing moves (only those that differ from the
    unaged rig). ``defaults``: the rig's own option defaults; ``axes``: the joint each sensor
    measures along (None: across; the drift and a re-mount's offset move the on-axis ones)."""
    options, a = split(options, start, check)
    if a is None:
        return options
    e = effects(a, start)
    get = lambda k: options.get(k, defaults[k])  # noqa: E731
    out = dict(options)
    if e["gain_pct"] != 0.0:
        out["gain_pct"] = get("gain_pct") + e["gain_pct"]
    offset = e["drift_nm"] + e["events_offset_nm"]
    if offset != 0.0:
        out["offset_nm"] = [
            v + (offset if axis is not None else 0.0) for v, axis in zip(get("offset_nm"), axes)
        ]
    if e["room_degC"] != 0.0:
        out["base_temperature_c"] = get("base_temperature_c") + e["room_degC"]
    for k in ("cosine_deg", "abbe_offset_mm"):
        if e[k] != 0.0:
            out[k] = get(k) + e[k]
    return out
