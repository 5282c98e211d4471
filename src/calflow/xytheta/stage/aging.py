"""A simulated XYΘ stage that ages with the campaign's ``start``.

``rig.options.aging`` (on by default, ``false`` turns it off) describes the stage's life
since ``since`` (its commissioning; default the default campaign start, so a campaign that
starts then sees the rig of :class:`calflow.xytheta.stage.physics.XYThetaTruth` unchanged).
The campaign loader resolves it, for the campaign's ``start``, into the rig's physics
options (:func:`resolve`); every consumer of the options (the rig, the oracle, the error
budget's replays, the designed plans) then sees the same aged stage.

Each effect, with where its rate comes from, and how it combines with the rig's options
(an effect switched off in the options stays off: wear and the season scale it):

* ``wear_per_year`` (default 0.05): relative growth per year of the lead-screw errors and
  the backlash (``lead_fwd_um``, ``lead_bwd_um``, ``backlash_um``), linear in time at a
  constant duty. *Assumed*: wear of a lead-screw nut raises its backlash and periodic error
  with travel (ISO 3408-3 classifies lead deviations, it gives no ageing rate; PI quotes
  none for the M-111); 5 %/year is an order-of-magnitude placeholder a lab replaces by
  its own stage's record.
* ``seasonal_degC`` (default 1.0) with ``seasonal_peak_day`` (default 196, mid-July): the
  room's mean temperature follows a yearly sine of that amplitude (an air-conditioned lab
  held within ±1 °C over the year, ISO 230-3 Annex A / ASME B5.54 Sec. 5); the aluminium
  stage's scale moves by ``expansion_ppm_per_degC`` per °C of the difference to ``since``
  (added to ``scale_ppm`` unless the scale error is off).
* ``sensor_drift_um_per_year`` (default [0.5, 0.5]): creep of the microscope's mount,
  moving the camera offsets ``camera_x_um``, ``camera_y_um``. *Assumed* order of
  magnitude of long-term creep of a bolted optical mount (sub-µm per month).
* ``events``: step changes at a date — a re-mount or a crash moving the geometry, e.g.
  ``{date: "2026-07-01T00:00:00+00:00", alpha_deg: 0.02, x_R_um: 20}``; every field of
  the geometry (``x_R_um``, ``y_R_um``, ``alpha_deg``, ``beta_deg``) may move; applied to
  campaigns that start at or after the date.
"""

from __future__ import annotations

from calflow.errors import OptionError
from calflow.rigs.aging import YEAR_D, checked, date, defaults, number, season, split

GEOMETRY = ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")
DEFAULTS = defaults(wear_per_year=0.05, sensor_drift_um_per_year=[0.5, 0.5])
DEFAULT_SINCE = DEFAULTS["since"]  # the commissioning when a campaign gives none


def check(aging) -> dict | None:
    """The ``aging`` option checked, with its defaults; None when ageing is off."""
    a = checked(aging, DEFAULTS, GEOMETRY)
    if a is None:
        return None
    number(a["wear_per_year"], "aging.wear_per_year")
    drift = a["sensor_drift_um_per_year"]
    if not isinstance(drift, (list, tuple)) or len(drift) != 2:
        raise OptionError("aging.sensor_drift_um_per_year", "a list of 2 numbers (µm/year, x and y)", drift)
    for v in drift:
        number(v, "aging.sensor_drift_um_per_year", None)
    return a


def resolve(physics: dict, start: str, base=None) -> dict:
    """The rig's physics options for a campaign starting at ``start``: ``physics`` without
    ``aging``, with the aged values of the fields ageing moves (only those that differ).
    ``base``: the rig's defaults (an :class:`~calflow.xytheta.stage.physics.XYThetaTruth`)."""
    physics, a = split(physics, start, check)
    if a is None:
        return physics
    t, t0 = date(start, "start"), date(a["since"], "aging.since")
    years = (t - t0).total_seconds() / (YEAR_D * 86400.0)
    if base is None:
        raise ValueError("aging.resolve: the rig's defaults (base) are needed")
    get = lambda k: physics.get(k, getattr(base, k))  # noqa: E731
    out = dict(physics)
    growth = 1.0 + a["wear_per_year"] * max(years, 0.0)
    if growth != 1.0:
        for k in ("lead_fwd_um", "lead_bwd_um"):
            out[k] = [v * growth for v in get(k)]
        out["backlash_um"] = get("backlash_um") * growth
    amp, peak = a["seasonal_degC"], a["seasonal_peak_day"]
    dT = amp * (season(t.timetuple().tm_yday, peak) - season(t0.timetuple().tm_yday, peak))
    if dT != 0.0 and get("expansion_ppm_per_degC") != 0.0 and any(get("scale_ppm")):
        out["scale_ppm"] = [v + get("expansion_ppm_per_degC") * dT for v in get("scale_ppm")]
    drift = a["sensor_drift_um_per_year"]
    if years != 0.0 and any(drift):
        out["camera_x_um"] = get("camera_x_um") + drift[0] * years
        out["camera_y_um"] = get("camera_y_um") + drift[1] * years
    for e in a["events"]:
        if t >= date(e["date"], "aging.events.date"):
            for k in GEOMETRY:
                if k in e:
                    out[k] = out.get(k, get(k)) + e[k]
    return out
