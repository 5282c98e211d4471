"""Options and slow-drift helpers of the simulated nanopositioning rigs (:mod:`calflow.nano.rig`)."""

from __future__ import annotations

import math

import numpy as np

from calflow.errors import OptionError, UnknownOptionError

_DAY = 86400.0

_COMMON = {
    "seed": 0,  # noise seed: interferometer/thermocouple noise, per-move repeatability
    "world_seed": 0,  # fixes the room profile's phases and the slow random walk
    "profile": "metrology",  # "constant" | "metrology" | "lab5day"
    "profile_params": {},  # overrides, see calflow.rigs.thermal
    "base_temperature_c": 20.5,  # room temperature the profile starts from
    "reference_offset_c": 0.0,  # T_ref - base: the structure's drift-free temperature
    "start_offset_s": 0.0,  # campaign time (s) of the rig's time 0
    "rise_time_s": 4.0,  # virtual time taken by a move (Fig. 5.8)
    "stream_rate_hz": 10.0,  # default rate of stream()
    "interferometer_noise_nm": 3.0,  # white noise, 1 sigma per sample (Table 3.4, U3)
    "interferometer_resolution_nm": 0.3,  # quantisation (Sec. 3.5.2)
    "repeatability_nm": 12.0,  # 1 sigma per visit along the moving axis -> RP ~ 35 nm
    "repeatability_correlation": 0.2,  # AR(1) correlation of successive visits
    "thermocouple_noise_mk": 5.0,
    "thermocouple_resolution_mk": 1.0,
    "thermocouple_tau_h": (0.5, 1.0, 2.0, 3.0),
    "thermocouple_gain": (1.0, 0.97, 1.03, 0.99),
    "thermocouple_offset_c": (0.02, -0.03, 0.01, -0.015),
    "stage_tau_h": 1.5,  # lag of the stage structure behind the room
    "frame_tau_h": 8.0,  # lag of the frame / base plate / interferometer mount
    "position_thermal_gain": 0.05,  # stage coefficient grows by 5 % over the stroke
    "drift_walk_nm_per_sqrt_day": 15.0,  # random walk no thermocouple explains
    "creep_nm": 20.0,  # deterministic slow creep, 1 - exp(-t / creep_tau)
    "creep_tau_h": 48.0,
    "hysteresis_nm": 10.0,  # forward/backward difference (Sec. 5.3.3: ~10 nm)
    "settle_fraction": 1e-3,  # overshoot as a fraction of the step, decaying ...
    "settle_tau_s": 0.7,  # ... with this time constant from the start of the move
    "geometric_scale": 1.0,  # multiplies the geometric errors
    "stroke_margin_um": 5.0,  # commands may exceed the stroke by this much
}
_POSITIVE = ("rise_time_s", "stream_rate_hz", "stage_tau_h", "frame_tau_h", "creep_tau_h",
             "settle_tau_s", "interferometer_resolution_nm", "thermocouple_resolution_mk",
             "stroke_um")
_NON_NEGATIVE = ("seed", "world_seed", "interferometer_noise_nm", "repeatability_nm",
                 "thermocouple_noise_mk", "drift_walk_nm_per_sqrt_day", "creep_nm",
                 "settle_fraction", "stroke_margin_um")


class _Walk:
    """Brownian slow drift (um) per sensor on a 600 s grid, linear in between; 0 at t <= 0.

    Generated lazily in whole days from ``world_seed`` so values do not depend on the
    order of queries. ``sigma_um_per_sqrt_day`` is the standard deviation after one day.
    """

    _DT, _BLOCK = 600.0, 144

    def __init__(self, world_seed: int, sigma_um_per_sqrt_day: np.ndarray):
        self._rng = np.random.default_rng(np.random.SeedSequence([int(world_seed), 5_2_4]))
        self._step = np.asarray(sigma_um_per_sqrt_day) * math.sqrt(self._DT / _DAY)
        self._w = np.zeros((1, self._step.size))

    def __call__(self, t):
        if np.ndim(t) == 0:
            pos = max(float(t), 0.0) / self._DT
            while self._w.shape[0] - 2 < pos:
                self._extend()
            i = int(pos)
            return self._w[i] + (pos - i) * (self._w[i + 1] - self._w[i])
        pos = np.maximum(np.asarray(t, dtype=float), 0.0) / self._DT
        while self._w.shape[0] - 2 < np.max(pos):
            self._extend()
        i = pos.astype(np.int64)
        w = (pos - i)[..., None]
        return self._w[i] * (1.0 - w) + self._w[i + 1] * w

    def _extend(self):
        inc = self._rng.standard_normal((self._BLOCK, self._w.shape[1])) * self._step
        self._w = np.concatenate((self._w, self._w[-1] + np.cumsum(inc, axis=0)))


def _coerce(rig, key, value, default):
    """Convert a config value to the type of its default; errors name the option."""
    try:
        if isinstance(default, tuple):
            if isinstance(value, (str, bytes)):
                raise TypeError
            out = tuple(float(v) for v in value)
            if not all(math.isfinite(v) for v in out):
                raise ValueError
            return out
        if isinstance(default, dict):
            return dict(value)
        if isinstance(default, str):
            if not isinstance(value, str):
                raise TypeError
            return value
        if isinstance(default, int) and not isinstance(default, bool):
            if isinstance(value, bool) or int(value) != value:
                raise TypeError
            return int(value)
        if isinstance(value, (bool, str)):
            raise TypeError
        out = float(value)
        if not math.isfinite(out):
            raise ValueError
        return out
    except (TypeError, ValueError, OverflowError):
        kind = ("a list of finite numbers" if isinstance(default, tuple) else "a mapping" if isinstance(default, dict)
                else "a string" if isinstance(default, str) else "an integer"
                if isinstance(default, int) and not isinstance(default, bool) else "a finite number")
        raise OptionError(key, f"{kind} (like {default!r})", value) from None


def check_options(name: str, defaults: dict, n_sensors: int, options: dict) -> dict:
    """The options of nano rig ``name`` (``defaults`` are its own), checked and converted;
    raises :class:`~calflow.errors.OptionError` naming the option."""
    for key in options:
        if key not in defaults:
            raise UnknownOptionError(key, f"expected one of: {', '.join(sorted(defaults))}")
    o = {**defaults, **options}
    for key, default in defaults.items():
        o[key] = _coerce(name, key, o[key], default)
    for key in ("stage_coeff_um_per_c", "frame_coeff_um_per_c"):
        if len(o[key]) != n_sensors:
            raise OptionError(key, f"{n_sensors} values, one per sensor", o[key])
    n_tc = len(o["thermocouple_tau_h"])
    for key in ("thermocouple_gain", "thermocouple_offset_c"):
        if len(o[key]) != n_tc:
            raise OptionError(key, f"{n_tc} values, as many as 'thermocouple_tau_h'", o[key])
    for key in _POSITIVE:
        if key in o and not o[key] > 0:
            raise OptionError(key, "a value > 0", o[key])
    for key in _NON_NEGATIVE:
        if key in o and o[key] < 0:
            raise OptionError(key, "a value >= 0", o[key])
    if not all(v > 0 for v in o["thermocouple_tau_h"]):
        raise OptionError("thermocouple_tau_h", "values > 0", o["thermocouple_tau_h"])
    from calflow.rigs.thermal import _DEFAULTS, PROFILES

    if o["profile"] not in PROFILES:
        raise OptionError("profile", f"one of {list(PROFILES)}", o["profile"])
    for key, value in o["profile_params"].items():
        if key not in _DEFAULTS[o["profile"]]:
            raise OptionError("profile_params", f"parameters of profile {o['profile']!r} "
                              f"({', '.join(sorted(_DEFAULTS[o['profile']]))})", {key: value})
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise OptionError("profile_params", "finite numbers", {key: value})
    if not -1.0 < o["repeatability_correlation"] < 1.0:
        raise OptionError("repeatability_correlation", "a value in (-1, 1)", o["repeatability_correlation"])
    return o
