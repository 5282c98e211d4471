"""The weather under the shield and what humidity does to the stage (lengths um, time s).

Weather at campaign time t (s): pressure p = p0 + dp sin(2 pi h/79 + phi_p), a 3.3-day
weather swing, and relative humidity

    rh = rh0 + a_day sin(2 pi h/24 + phi_d) + a_wx sin(2 pi h/79 + phi_w),   h = t / 3600,

a daily swing and a slow weather swing of its own phase (indoor humidity follows the
outdoor air's over days; ``humidity_weather_pct``). Two effects follow from it:

* ``humidity_swelling``: epoxy bond lines in the measuring loop (a mirror glued to the stage,
  the stack's bonded end pieces) take up moisture and swell. Hygroscopic swelling of epoxies
  is ~0.2-0.4 strain per unit moisture concentration with ~1-2 wt% uptake at 50 %RH (E.H.
  Wong et al., hygroscopic swelling of epoxy compounds, IEEE Trans. Compon. Packag.
  Technol., 2003), ~1e-4 strain per %RH:
  a ~20 um bond line gives ~2 nm per %RH, following rh through a diffusion lag (hours). The
  thesis measured humidity beside its drift record and saw no correlation (Sec. 5.2.2):
  a few nm against its hundreds.
* ``sensor_air``: the stage's capacitive sensor holds C = eps A / d, so the closed loop holds
  the gap d in proportion to the air's permittivity. eps - 1 = 2 N 1e-6 with the refractivity
  N = 77.6 (P / T) + 3.73e5 (e / T^2) (P, e in hPa, T in K; Smith & Weintraub, Proc. IRE 41
  (1953) 1035): ~2 ppm of the gap per %RH at 20 degC, 0.5 ppm per hPa, -1.8 ppm per K.
"""

from __future__ import annotations

import numpy as np

from calflow.nano.stage.interferometer import saturation_vapour_pressure_pa

__all__ = ["weather_at", "lagged_humidity", "permittivity"]

_WEATHER_H, _DAY_H = 79.0, 24.0


def _components(o: dict, phases) -> list[tuple[float, float, float]]:
    """(amplitude %, period h, phase) of the humidity's swings."""
    return [
        (o["humidity_swing_pct"], _DAY_H, phases[1]),
        (o.get("humidity_weather_pct", 0.0), _WEATHER_H, phases[2]),
    ]


def weather_at(o: dict, phases, t_campaign):
    """Air pressure (Pa) and relative humidity (%) at campaign time (s), module docstring;
    ``phases`` (pressure, daily humidity, weather humidity) come from ``world_seed``."""
    h = np.asarray(t_campaign, dtype=float) / 3600.0
    p = o["pressure_pa"] + o["pressure_swing_pa"] * np.sin(2 * np.pi * h / _WEATHER_H + phases[0])
    rh = o["humidity_pct"] + sum(
        a * np.sin(2 * np.pi * h / per + ph) for a, per, ph in _components(o, phases) if a
    )
    return p, rh


def lagged_humidity(o: dict, phases, t_campaign, tau_s: float):
    """Relative humidity (%) seen through a first-order lag ``tau_s`` (a bond line's moisture):
    exact for the sinusoidal swings, each attenuated by 1/sqrt(1 + (w tau)^2) and delayed."""
    h = np.asarray(t_campaign, dtype=float) / 3600.0
    out = o["humidity_pct"] + 0.0 * h
    for a, per, ph in _components(o, phases):
        if a:
            wt = 2 * np.pi / (per * 3600.0) * tau_s
            out = out + a / np.sqrt(1 + wt * wt) * np.sin(2 * np.pi * h / per + ph - np.arctan(wt))
    return out


def permittivity(t_c, p_pa, rh_pct):
    """Relative permittivity of moist air (Smith & Weintraub 1953, module docstring)."""
    t_k = np.asarray(t_c, dtype=float) + 273.15
    e_hpa = np.asarray(rh_pct, dtype=float) / 100.0 * saturation_vapour_pressure_pa(t_c) / 100.0
    n = 77.6 / t_k * (np.asarray(p_pa, dtype=float) / 100.0 + 4810.0 * e_hpa / t_k)
    return 1.0 + 2.0 * n * 1e-6
