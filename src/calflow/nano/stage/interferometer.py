"""Errors of a displacement interferometer in air (thesis Sec. 3.5.2, Table 3.4).

Lengths in um unless a name says otherwise, temperatures in degC, pressure in Pa,
relative humidity in %. The SP-S 120 counts optical path: a reading is the change of
``n * (dead path + x)`` divided by the refractive index its compensation unit computes
from its own temperature, pressure and humidity sensors; the zero is set at the start
(Sec. 5.3.1). So a reading's error is

    (e(t) - e(0)) D   dead-path error once the dead path D is corrected (Table 3.4, U6),
    e(t) x            wavelength-compensation error over the measured distance (U4),
    with e = n_air - n_compensation;

without dead-path correction the first line is (n(t) - n(0)) D. Beside these, the beam's
angle to the axis gives the cosine error (U8) and the stage's pitch at the Abbe offset the
Abbe error (U7).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "HENE_VACUUM_UM",
    "refractive_index",
    "saturation_vapour_pressure_pa",
    "reading_error_um",
    "cosine_error_um",
    "abbe_error_um",
]

HENE_VACUUM_UM = 0.632991  # He-Ne vacuum wavelength (um), the SP-S 120's ~633 nm (Table 3.4)


def saturation_vapour_pressure_pa(t_c):
    """Saturation vapour pressure over water (Pa) at ``t_c`` degC, Magnus form with the
    coefficients of Sonntag (1990), within 0.1 % from 0 to 40 degC."""
    return 611.2 * np.exp(17.62 * t_c / (243.12 + t_c))


def refractive_index(t_c, p_pa, rh_pct, wavelength_um: float = HENE_VACUUM_UM):
    """Refractive index of air, the updated Edlén equation of Birch & Downs (Metrologia 30,
    155 (1993); correction Metrologia 31, 315 (1994)), vectorised:

        (n-1)_s  1e8 = 8342.54 + 2406147 / (130 - s^2) + 15998 / (38.9 - s^2)
        (n-1)_tp     = p (n-1)_s [1 + 1e-8 (0.601 - 0.00972 t) p] / (96095.43 (1 + 0.003661 t))
        n_tpf - n_tp = -f (3.7345 - 0.0401 s^2) 1e-10

    with s = 1 / wavelength (um^-1), t in degC, p and the water-vapour pressure f in Pa
    (f = rh/100 x saturation pressure). About -0.93 ppm/K, +2.7 ppm/kPa and -0.009 ppm/%RH
    at 20 degC, 101.3 kPa, 50 %RH (Table 3.4's 1 ppm per 1 degC, 2.5 mmHg, 80 %RH).
    """
    t, p = t_c, p_pa
    s2 = 1.0 / wavelength_um**2
    n_s = 1e-8 * (8342.54 + 2406147.0 / (130.0 - s2) + 15998.0 / (38.9 - s2))
    n_tp = p * n_s * (1.0 + 1e-8 * (0.601 - 0.00972 * t) * p) / (96095.43 * (1.0 + 0.003661 * t))
    f = rh_pct / 100.0 * saturation_vapour_pressure_pa(t)
    return 1.0 + n_tp - f * (3.7345 - 0.0401 * s2) * 1e-10


def reading_error_um(x_um, n_air, n_comp, n_air0, n_comp0, deadpath_um: float, corrected: bool = True):
    """Dead-path and compensation error of a reading (um) at displacement ``x_um`` (module docstring):
    ``n_air``/``n_comp`` now, ``n_air0``/``n_comp0`` at the zeroing. Returns ``(deadpath, path)``."""
    e, e0 = n_air - n_comp, n_air0 - n_comp0
    dead = ((e - e0) if corrected else (n_air - n_air0)) * deadpath_um
    return dead, e * x_um


def cosine_error_um(x_um, angle_deg: float):
    """Cosine error (um): a beam at ``angle_deg`` to the axis reads x cos(angle) (Table 3.4, U8)."""
    return -np.asarray(x_um, dtype=float) * (1.0 - np.cos(np.radians(angle_deg)))


def abbe_error_um(s, offset_mm: float, pitch_urad: float):
    """Abbe error (um): the stage's pitch, growing linearly from -pitch to +pitch over the
    normalised stroke ``s`` (flexure guidance), at ``offset_mm`` from the beam (Table 3.4, U7)."""
    return offset_mm * 1e3 * np.tan(pitch_urad * 1e-6 * (2.0 * np.asarray(s, dtype=float) - 1.0))
