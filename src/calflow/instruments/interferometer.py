"""GUM uncertainty budget of the laser interferometer (thesis Sec. 3.5.2, Table 3.4).

The SIOS SP-S 120 budget has eight standard uncertainties U_1 ... U_8 in three groups:
intrinsic (laser wavelength, electronics, optics nonlinearity), environmental (atmospheric
wavelength compensation, optics thermal drift) and installation (deadpath, Abbe, cosine).
They are combined as in Table 3.4, with U_4 and U_6 added linearly because both come from
the same atmospheric wavelength uncertainty U_W:

    u_c = sqrt(U_1^2 + U_2^2 + U_3^2 + U_5^2 + U_7^2 + U_8^2 + (U_4 + U_6)^2).

Every U_k is in nanometres.  ``DEFAULT_INPUTS`` holds the thesis inputs; a campaign config
overrides any of them by name: ``interferometer_budget(**{**DEFAULT_INPUTS, **overrides})``
or simply ``interferometer_budget(**overrides)``.

Notes on Table 3.4 (what we found while reproducing it):

* U_2 = (0.0003 µm / 2) / sqrt(3) = 0.0866 nm; the table prints 0.08 (truncated).
* U_3 = 0.0042 µm / sqrt(2) = 2.97 nm, printed 3 nm (a 4.2 nm peak nonlinearity with
  a sinusoidal, arcsine-distributed error: standard uncertainty = amplitude / sqrt(2)).
* U_5 = 0.1 °C x 0.5 µm/°C / sqrt(3) = 28.87 nm, printed 29 nm.
* U_7 is printed as "1 cm x tan(6 µrad) = 10 nm", but 1 cm x tan(6 µrad) = 60 nm.  The
  10 nm value is the one the thesis combines into 40.6 nm, so the default Abbe angle
  here is 1 µrad (1 cm x tan(1 µrad) = 10 nm); set ``abbe_angle_urad=6`` for the other
  reading (U_7 = 60 nm, u_c ≈ 71.7 nm).
* The thesis's 40.6 nm combines the *rounded* components (its formula line shows 3 and
  29).  Combining the unrounded components of the same inputs gives 40.51 nm, which is
  what ``combined_nm`` returns; ``combine(0.087, 0.08, 3, 0.262, 29, 26.2, 10, 0.76)``
  reproduces the printed 40.6 nm.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = [
    "DEFAULT_INPUTS",
    "InterferometerBudget",
    "atmospheric_ppm",
    "combine",
    "interferometer_budget",
]

#: Thesis inputs of Table 3.4 (read-only; copy with ``dict(DEFAULT_INPUTS)`` to edit).
DEFAULT_INPUTS: Mapping[str, float] = MappingProxyType(
    {
        "measured_distance_um": 500.0,  # L, measured distance, µm
        "wavelength_stability_ppm": 0.3,  # laser wavelength stability, ppm (3e-7)
        "resolution_nm": 0.3,  # interferometer resolution, nm
        "nonlinearity_nm": 4.2,  # optics nonlinearity, peak amplitude, nm
        "temperature_ppm": 0.1,  # air temperature uncertainty 0.1 K x 1 ppm/K, ppm
        "pressure_ppm": 0.9,  # air pressure uncertainty 2.25 mmHg / 2.5 mmHg/ppm, ppm
        "humidity_ppm": 0.0375,  # humidity uncertainty 3 %RH / 80 %RH/ppm, ppm
        "optics_drift_um_per_degC": 0.5,  # optics thermal drift coefficient, µm/°C
        "optics_temperature_uncertainty_degC": 0.1,  # temperature uncertainty at the optics, °C
        "deadpath_mm": 50.0,  # deadpath length, mm
        "abbe_offset_mm": 10.0,  # Abbe offset, mm
        "abbe_angle_urad": 1.0,  # Abbe angle, µrad (thesis prints 6 µrad, but 10 nm; see module doc)
        "cosine_angle_deg": 0.1,  # beam misalignment angle, degree
    }
)

_SQRT3 = math.sqrt(3.0)


def atmospheric_ppm(
    temperature_K: float = 0.1,
    pressure_mmHg: float = 2.25,
    humidity_percent: float = 3.0,
) -> dict[str, float]:
    """Convert air-sensor uncertainties to refractive-index ppm-equivalents (Sec. 3.5.2).

    1 ppm of wavelength error results from 1 °C of air temperature, 2.5 mmHg of pressure,
    or 80 % of relative humidity.  Thesis values: 0.1 K, 300 Pa = 2.25 mmHg, 3 %.

    Returns ``{"temperature_ppm", "pressure_ppm", "humidity_ppm"}`` for
    :func:`interferometer_budget`.
    """
    return {
        "temperature_ppm": temperature_K / 1.0,
        "pressure_ppm": pressure_mmHg / 2.5,
        "humidity_ppm": humidity_percent / 80.0,
    }


def combine(u1: float, u2: float, u3: float, u4: float, u5: float, u6: float, u7: float, u8: float) -> float:
    """Combined standard uncertainty of Table 3.4, same unit as the U_k (nm).

    u_c = sqrt(U1^2 + U2^2 + U3^2 + U5^2 + U7^2 + U8^2 + (U4 + U6)^2): U_4 and U_6 share the
    atmospheric uncertainty U_W and are fully correlated, so they add linearly.
    """
    return math.sqrt(u1**2 + u2**2 + u3**2 + u5**2 + u7**2 + u8**2 + (u4 + u6) ** 2)


@dataclass(frozen=True)
class InterferometerBudget:
    """Table 3.4 budget: each U_k in nm, U_W in ppm, the combined uncertainty in nm."""

    U_1: float
    U_2: float
    U_3: float
    U_4: float
    U_5: float
    U_6: float
    U_7: float
    U_8: float
    U_W_ppm: float
    combined_nm: float
    inputs: Mapping[str, float] = field(repr=False)

    @property
    def components_nm(self) -> tuple[float, ...]:
        """(U_1, ..., U_8) in nm."""
        return (self.U_1, self.U_2, self.U_3, self.U_4, self.U_5, self.U_6, self.U_7, self.U_8)

    def table(self) -> list[tuple[str, str, str, float]]:
        """Rows (name, category, formula text, value_nm) for reports, in Table 3.4 order."""
        return [
            ("U_1 laser wavelength", "intrinsic", "L x wavelength stability / sqrt(3)", self.U_1),
            ("U_2 electronics", "intrinsic", "(resolution / 2) / sqrt(3)", self.U_2),
            ("U_3 optics nonlinearity", "intrinsic", "nonlinearity / sqrt(2)", self.U_3),
            (
                "U_4 atmospheric compensation",
                "environmental",
                "U_W x L, U_W = sqrt(sum (ppm_k / sqrt(3))^2) over temperature, pressure, humidity",
                self.U_4,
            ),
            ("U_5 optics thermal drift", "environmental", "dT x drift coefficient / sqrt(3)", self.U_5),
            ("U_6 deadpath", "installation", "U_W x deadpath length", self.U_6),
            ("U_7 Abbe", "installation", "Abbe offset x tan(Abbe angle)", self.U_7),
            ("U_8 cosine", "installation", "L x (1 - cos(angle))", self.U_8),
            (
                "combined standard uncertainty",
                "combined",
                "sqrt(U_1^2 + U_2^2 + U_3^2 + U_5^2 + U_7^2 + U_8^2 + (U_4 + U_6)^2)",
                self.combined_nm,
            ),
        ]


def interferometer_budget(**inputs: float) -> InterferometerBudget:
    """GUM uncertainty budget of the interferometer, Table 3.4 (Sec. 3.5.2).

    Keyword inputs (defaults in ``DEFAULT_INPUTS``, the thesis values):

    ``measured_distance_um`` (L, µm, 500), ``wavelength_stability_ppm`` (ppm, 0.3),
    ``resolution_nm`` (nm, 0.3), ``nonlinearity_nm`` (peak optics nonlinearity, nm, 4.2),
    ``temperature_ppm``, ``pressure_ppm``, ``humidity_ppm`` (air-sensor uncertainties as
    ppm-equivalents, 0.1, 0.9, 0.0375; see :func:`atmospheric_ppm`),
    ``optics_drift_um_per_degC`` (µm/°C, 0.5), ``optics_temperature_uncertainty_degC``
    (°C, 0.1), ``deadpath_mm`` (mm, 50), ``abbe_offset_mm`` (mm, 10), ``abbe_angle_urad``
    (µrad, 1; see the module notes), ``cosine_angle_deg`` (degree, 0.1).

    Formulas (all results in nm):

    * U_1 = L x stability / sqrt(3)                 (rectangular distribution)
    * U_2 = (resolution / 2) / sqrt(3)              (quantisation, rectangular)
    * U_3 = nonlinearity / sqrt(2)                  (sinusoidal, arcsine distribution)
    * U_W = sqrt((T/sqrt3)^2 + (P/sqrt3)^2 + (H/sqrt3)^2)  in ppm
    * U_4 = U_W x L,  U_6 = U_W x deadpath
    * U_5 = dT x drift coefficient / sqrt(3)
    * U_7 = Abbe offset x tan(Abbe angle),  U_8 = L x (1 - cos(angle))
    * combined_nm from :func:`combine` (U_4 + U_6 linearly).

    With the defaults: U_1..U_8 = 0.087, 0.087, 2.97, 0.262, 28.9, 26.2, 10, 0.76 nm and
    combined_nm = 40.51 nm (thesis prints 40.6 nm from rounded components; module doc).

    Raises
    ------
    ValueError
        Unknown input names, or negative / non-finite values.
    """
    unknown = sorted(set(inputs) - set(DEFAULT_INPUTS))
    if unknown:
        raise ValueError(
            f"unknown interferometer budget input(s) {unknown}; expected some of {sorted(DEFAULT_INPUTS)}"
        )
    p = {**DEFAULT_INPUTS, **{k: float(v) for k, v in inputs.items()}}
    for k, v in p.items():
        if not math.isfinite(v) or v < 0:
            raise ValueError(f"interferometer budget input {k} must be finite and >= 0; got {v!r}")

    length_nm = p["measured_distance_um"] * 1e3
    u1 = length_nm * p["wavelength_stability_ppm"] * 1e-6 / _SQRT3
    u2 = (p["resolution_nm"] / 2.0) / _SQRT3
    u3 = p["nonlinearity_nm"] / math.sqrt(2.0)
    u_w_ppm = math.sqrt(
        sum((p[k] / _SQRT3) ** 2 for k in ("temperature_ppm", "pressure_ppm", "humidity_ppm"))
    )
    u4 = u_w_ppm * 1e-6 * length_nm
    u5 = p["optics_temperature_uncertainty_degC"] * p["optics_drift_um_per_degC"] * 1e3 / _SQRT3
    u6 = u_w_ppm * 1e-6 * p["deadpath_mm"] * 1e6
    u7 = p["abbe_offset_mm"] * 1e6 * math.tan(p["abbe_angle_urad"] * 1e-6)
    u8 = length_nm * (1.0 - math.cos(math.radians(p["cosine_angle_deg"])))
    return InterferometerBudget(
        U_1=u1,
        U_2=u2,
        U_3=u3,
        U_4=u4,
        U_5=u5,
        U_6=u6,
        U_7=u7,
        U_8=u8,
        U_W_ppm=u_w_ppm,
        combined_nm=combine(u1, u2, u3, u4, u5, u6, u7, u8),
        inputs=MappingProxyType(p),
    )
