"""The instruments' own errors: thermocouples beyond noise, the interferometer beyond heat.

Lengths in um, temperatures in K, time in s of campaign time. Thermocouples (K type,
~40 uV/K near 20 degC, NIST ITS-90 tables, Monograph 175):

* ``thermocouple_calibration``: each channel's offset drifts linearly, at a rate drawn per
  channel from ``world_seed`` with spread ``thermocouple_drift_mk_per_day`` (0.1 uV/day of the
  measuring chain's offset is 2.5 mK/day; an assumption of that class, no datasheet given).
* ``reference_junction``: the data logger compensates the cold junction with a sensor in its
  terminal block; when the room changes, the terminals (lag ``cjc_terminal_tau_s``) and the
  sensor (a further ``cjc_lag_s``) differ, an error common to every channel (isothermal-block
  gradients are the dominant thermocouple error of such loggers: NI, "Taking thermocouple
  temperature measurements", application note). Computed as extra states of the network.
* ``junction_lag``: a junction glued or taped to its part lags it by ``junction_glue_tau_s``
  (the contact's thermal resistance times the junction's capacity); read error = lagged minus
  host. Also extra network states.

Interferometer (a counting interferometer zeroed at time 0 with the mirror at the dead path D):

* ``laser_wander``: the vacuum wavelength wanders slowly by eps(t) within the bound of Table 3.4
  (U1, 0.3 ppm: the white part is already a per-reading noise); the count of the whole optical
  path D + x then errs by -(eps(t) - eps(0)) (D + x). Periods 0.5-12 h, weights from ``world_seed``.
* ``periodic_nonlinearity``: polarisation mixing makes a periodic error of one fringe's period
  in the optical path (Bobroff, Meas. Sci. Technol. 4 (1993) 907; Cosijns et al., Precis. Eng.
  26 (2002) 448); amplitude the 3 nm that Table 3.4 (U3) took from the thesis's ref. [15].
* ``turbulence``: the air along the beam fluctuates by ``turbulence_mk`` rms (shielded path),
  -0.93 ppm/K of the path D + x (Edlen/Birch & Downs sensitivity), at 0.02-2 Hz (Bobroff,
  Appl. Opt. 26 (1987) 2676): a deterministic sum of sines of unit rms from ``world_seed``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Wander", "calibration_rates_c_per_s", "laser_wander_um", "periodic_um", "turbulence_um"]

_DN_DT = -0.93e-6  # 1/K, refractive index of air near 20 degC, 101 kPa (calflow.nano.stage.interferometer)


class Wander:
    """Sum of sines with fixed random phases, ``periods_s`` log-spaced, per channel.

    ``bound``: weights sum to one (|value| <= 1); else each sine has amplitude sqrt(2/n)
    (unit rms)."""

    def __init__(self, seed, n_channels: int, periods_s, *, bound: bool):
        rng = np.random.default_rng(np.random.SeedSequence(seed))
        self.omega = 2 * np.pi / np.asarray(periods_s, dtype=float)
        n = self.omega.size
        self.phase = rng.uniform(0, 2 * np.pi, (n_channels, n))
        self.amp = (
            rng.dirichlet(np.ones(n), n_channels) if bound else np.full((n_channels, n), np.sqrt(2.0 / n))
        )

    def __call__(self, t, k: int):
        t = np.asarray(t, dtype=float)[..., None]
        return np.sum(self.amp[k] * np.sin(self.omega * t + self.phase[k]), axis=-1)


def calibration_rates_c_per_s(world_seed: int, n_tc: int, mk_per_day: float) -> np.ndarray:
    """Each channel's calibration drift rate (K/s), drawn from ``world_seed``."""
    rng = np.random.default_rng(np.random.SeedSequence([int(world_seed), 29, 1]))
    return rng.standard_normal(n_tc) * mk_per_day * 1e-3 / 86400.0


def laser_wander_um(wander: Wander, k: int, t, path_um, ppm: float):
    """-(eps(t) - eps(0)) x optical path (um), eps within +-``ppm``."""
    return -ppm * 1e-6 * (wander(t, k) - wander(0.0, k)) * path_um


def periodic_um(path_um, deadpath_um: float, amplitude_nm: float, period_nm: float, phase: float):
    """First-order periodic error (um) at optical path ``path_um``, zero at the zeroing (path D)."""
    w = 2 * np.pi / (period_nm * 1e-3)
    return amplitude_nm * 1e-3 * (np.sin(w * np.asarray(path_um) + phase) - np.sin(w * deadpath_um + phase))


def turbulence_um(wander: Wander, k: int, t, path_um, mk: float):
    """Index fluctuation of the beam's air times the path (um), ``mk`` rms of temperature."""
    return _DN_DT * mk * 1e-3 * wander(t, k) * path_um
