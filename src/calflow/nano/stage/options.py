"""Options and slow-drift helpers of the simulated nanopositioning rigs (:mod:`calflow.nano.stage.rig`)."""

from __future__ import annotations

import math

import numpy as np

from calflow.errors import OptionError, UnknownOptionError
from calflow.nano.stage.aging import check as check_aging
from calflow.nano.stage.unseen.options import UNSEEN, UNSEEN_EFFECTS, UNSEEN_NON_NEGATIVE, UNSEEN_POSITIVE
from calflow.rigs.simulated.effects import Effect, Effects

_DAY = 86400.0

_COMMON = {
    "seed": 0,  # noise seed: interferometer/thermocouple noise, per-move repeatability
    "world_seed": 0,  # fixes the room profile's phases, the weather and the slow random walk
    "profile": "metrology",  # "constant" | "metrology" | "lab5day"
    "profile_params": {},  # overrides, see calflow.rigs.thermal
    "base_temperature_c": 20.5,  # room temperature the profile starts from
    "start_offset_s": 0.0,  # campaign time (s) of the rig's time 0
    "rise_time_s": 4.0,  # virtual time taken by a move (Fig. 5.8)
    "stream_rate_hz": 10.0,  # default rate of stream()
    # interferometer (Sec. 3.5.2, Table 3.4)
    "interferometer_noise_nm": 3.0,  # white noise, 1 sigma per sample (Table 3.4, U3)
    "interferometer_resolution_nm": 0.3,  # quantisation (Table 3.4, U2)
    "wavelength_stability_ppm": 0.3,  # laser wavelength stability, uniform bound (Table 3.4, U1)
    "deadpath_m": 0.05,  # dead path (Table 3.4)
    "deadpath_corrected": True,  # built-in dead-path correction (Sec. 3.5.2, 5.3.1)
    "compensation_bias_k": 0.0577,  # compensation sensors' errors: Table 3.4 bounds / sqrt(3)
    "compensation_bias_pa": 173.0,  # (0.1 K, 300 Pa, 3 %RH)
    "compensation_bias_pct": 1.73,
    "compensation_sensor_tau_s": 300.0,  # its Pt100's lag behind the beam's air (0: reads it exactly)
    "cosine_deg": 0.1,  # beam-to-axis angle (Table 3.4, U8)
    "abbe_offset_mm": 10.0,  # Abbe offset (Table 3.4, U7) ...
    "abbe_pitch_urad": 6.0,  # ... and the stage's pitch over the stroke
    "pressure_pa": 101325.0,  # air pressure and its weather swing (amplitude) ...
    "pressure_swing_pa": 800.0,
    "humidity_pct": 45.0,  # relative humidity and its daily swing (amplitude)
    "humidity_swing_pct": 5.0,
    # closed-loop piezo stage (calflow.nano.stage.piezo)
    "repeatability_nm": 12.0,  # 1 sigma per visit along the moving axis -> RP ~ 35 nm (Sec. 5.3.3)
    "repeatability_correlation": 0.2,  # AR(1) correlation of successive visits
    "hysteresis_nm": 10.0,  # forward/backward difference after the loop (Sec. 5.3.3: ~10 nm)
    "creep_pct_per_decade": 1.0,  # open-loop log creep per time decade (1-2 %)
    "sensor_linearity_pct": 0.02,  # capacitive sensor nonlinearity, of the stroke
    "settle_fraction": 1e-3,  # overshoot as a fraction of the step, decaying ...
    "settle_tau_s": 0.7,  # ... with this time constant from the start of the move
    "step_natural_hz": 100.0,  # closed-loop step response: natural frequency (0: ideal step) ...
    "step_damping": 0.7,  # ... and damping ratio: ~4.6 % overshoot, within 2 % in ~9 ms (docs/rigs.md)
    "geometric_scale": 1.0,  # multiplies the geometric errors (Fig. 5.1)
    "gain_pct": 0.0,  # change of the stage's gain along each axis (ageing: calflow.nano.stage.aging)
    "offset_nm": (0.0, 0.0),  # shift of each sensor's zero (ageing: sensor drift, a re-mount)
    "stroke_margin_um": 5.0,  # commands may exceed the stroke by this much
    # thermal network (calflow.nano.stage.thermal_network) and expansion
    "stage_capacity_j_per_k": 270.0,  # ~0.3 kg of aluminium
    "base_capacity_j_per_k": 4500.0,  # ~5 kg aluminium base plate
    "air_capacity_j_per_k": 36.0,  # ~30 l of air under the shield
    "stage_air_w_per_k": 0.075,  # natural convection, h ~ 5 W/m2K over ~150 cm2
    "stage_base_w_per_k": 0.4,  # bolted contact, h_c ~ 1000 W/m2K over ~4 cm2
    "base_air_w_per_k": 0.5,  # natural convection over ~0.1 m2
    "base_room_w_per_k": 0.5,  # conduction through the table
    "air_room_w_per_k": 1.0,  # through the shield, U ~ 2 W/m2K over ~0.5 m2
    "optics_drift_um_per_c": 0.5,  # interferometer optics on the base (Table 3.4, U5)
    "expansion_ppm_per_c": 23.0,  # aluminium: the sensor's span grows with the stage's temperature
    "thermocouple_tau_s": (15.0, 30.0, 60.0, 120.0),  # sensor time constants
    "thermocouple_air_weight": (1.0, 1.0, 0.75, 0.5),  # around the stage (Sec. 5.3.1): air, or air and plate
    "thermocouple_offset_c": (0.02, -0.03, 0.01, -0.015),
    "thermocouple_noise_mk": 5.0,
    "thermocouple_resolution_mk": 1.0,
    "drift_walk_nm_per_sqrt_day": 0.0,  # a random walk with no physical source: off by default
    **UNSEEN,  # drift the thermocouples do not see (calflow.nano.stage.unseen.options)
    "unmodelled": True,  # False: every effect no calflow nano model represents is off
}
_POSITIVE = (
    "rise_time_s",
    "stream_rate_hz",
    "settle_tau_s",
    "interferometer_resolution_nm",
    "thermocouple_resolution_mk",
    "stroke_um",
    "stage_capacity_j_per_k",
    "base_capacity_j_per_k",
    "air_capacity_j_per_k",
    "pressure_pa",
    *UNSEEN_POSITIVE,
)
_NON_NEGATIVE = (
    *UNSEEN_NON_NEGATIVE,
    "seed",
    "world_seed",
    "interferometer_noise_nm",
    "repeatability_nm",
    "thermocouple_noise_mk",
    "drift_walk_nm_per_sqrt_day",
    "settle_fraction",
    "stroke_margin_um",
    "stage_air_w_per_k",
    "stage_base_w_per_k",
    "base_air_w_per_k",
    "base_room_w_per_k",
    "air_room_w_per_k",
    "wavelength_stability_ppm",
    "deadpath_m",
    "hysteresis_nm",
    "loop_residual_pct",
    "creep_pct_per_decade",
    "compensation_sensor_tau_s",
    "sensor_linearity_pct",
    "humidity_pct",
    "step_natural_hz",
)

# Each effect of the nano rigs: its option keys (all off = effect off), its source, and whether
# a calflow nano model represents it (single Eq. 5.3, KMZ Eq. 5.6, 2-DoF Eq. 5.10: polynomials
# in the position, linear in the thermocouples, an offset). docs/rigs.md has the laws and figures.
EFFECTS = Effects(
    {
        "geometry": Effect(("geometric_scale", "gain_pct", "offset_nm"), "Table 5.1, Fig. 5.1"),
        "coupling": Effect(("coupling_y_nm", "coupling_scale"), "Fig. 5.1 b; Sec. 5.4"),
        "sensor_nonlinearity": Effect(("sensor_linearity_pct",), "PI capacitive sensors: linearity 0.02 %"),
        "hysteresis": Effect(("hysteresis_nm",), "Sec. 5.3.3", modelled=False),
        "creep": Effect(
            ("creep_pct_per_decade",), "PI piezo tutorial: log creep 1-2 %/decade", modelled=False
        ),
        "stage_drift": Effect(("stage_coeff_um_per_c",), "Fig. 5.2, Sec. 5.1"),
        "expansion": Effect(("expansion_ppm_per_c",), "aluminium body, 23 ppm/degC", modelled=False),
        "optics_drift": Effect(("optics_drift_um_per_c",), "Table 3.4, U5"),
        "deadpath": Effect(("deadpath_m",), "Table 3.4; Sec. 3.5.2", modelled=False),
        "compensation": Effect(
            (
                "compensation_bias_k",
                "compensation_bias_pa",
                "compensation_bias_pct",
                "compensation_sensor_tau_s",
            ),
            "Table 3.4 bounds / sqrt(3)",
            modelled=False,
        ),
        "cosine": Effect(("cosine_deg",), "Table 3.4, U8"),
        "abbe": Effect(("abbe_pitch_urad",), "Table 3.4, U7"),
        "walk": Effect(
            ("drift_walk_nm_per_sqrt_day",), "no physical source: robustness studies", modelled=False
        ),
        "interferometer_noise": Effect(("interferometer_noise_nm",), "Table 3.4, U3"),
        "wavelength_stability": Effect(("wavelength_stability_ppm",), "Table 3.4, U1"),
        "repeatability": Effect(("repeatability_nm",), "Sec. 5.3.3: RP about 35 nm"),
        "settling": Effect(("settle_fraction",), "settled within the 4 s rise (Fig. 5.8)"),
        "step_response": Effect(("step_natural_hz",), "closed-loop step of PI piezo stages"),
        "thermocouple_noise": Effect(("thermocouple_noise_mk",), "K-type thermocouples and their logger"),
        **UNSEEN_EFFECTS.table,
    },
    kind="nano",
)
# noise and the transients of a move: not terms of effect_terms (the rig's _state adds them)
NOISE = (
    "interferometer_noise",
    "wavelength_stability",
    "repeatability",
    "settling",
    "step_response",
    "thermocouple_noise",
)
UNMODELLED = EFFECTS.unmodelled  # the effects no calflow nano model represents
without = EFFECTS.without  # (options, *effects): those effects switched off; keys a rig lacks skipped


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
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise TypeError
            return value
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
        kind = (
            "a list of finite numbers"
            if isinstance(default, tuple)
            else "a mapping"
            if isinstance(default, dict)
            else "a string"
            if isinstance(default, str)
            else "true or false"
            if isinstance(default, bool)
            else "an integer"
            if isinstance(default, int) and not isinstance(default, bool)
            else "a finite number"
        )
        raise OptionError(key, f"{kind} (like {default!r})", value) from None


def check_options(name: str, defaults: dict, n_sensors: int, options: dict) -> dict:
    """The options of nano rig ``name`` (``defaults`` are its own), checked and converted;
    raises :class:`~calflow.errors.OptionError` naming the option. ``aging`` is checked
    and dropped: the campaign loader resolves it for the campaign's start (:mod:`.aging`)."""
    if "aging" in options:
        options = dict(options)
        check_aging(options.pop("aging"))
    for key in options:
        if key not in defaults:
            raise UnknownOptionError(key, f"expected one of: {', '.join(sorted(defaults))}")
    o = {**defaults, **options}
    for key, default in defaults.items():
        o[key] = _coerce(name, key, o[key], default)
    if len(o["stage_coeff_um_per_c"]) != n_sensors:
        raise OptionError(
            "stage_coeff_um_per_c", f"{n_sensors} values, one per sensor", o["stage_coeff_um_per_c"]
        )
    if len(o["offset_nm"]) != n_sensors:
        raise OptionError("offset_nm", f"{n_sensors} values, one per sensor", o["offset_nm"])
    if not o["gain_pct"] > -100.0:
        raise OptionError("gain_pct", "a change of the gain > -100 %", o["gain_pct"])
    n_tc = len(o["thermocouple_tau_s"])
    for key in ("thermocouple_air_weight", "thermocouple_offset_c"):
        if len(o[key]) != n_tc:
            raise OptionError(key, f"{n_tc} values, as many as 'thermocouple_tau_s'", o[key])
    for key in _POSITIVE:
        if key in o and not o[key] > 0:
            raise OptionError(key, "a value > 0", o[key])
    for key in _NON_NEGATIVE:
        if key in o and o[key] < 0:
            raise OptionError(key, "a value >= 0", o[key])
    if not all(v > 0 for v in o["thermocouple_tau_s"]):
        raise OptionError("thermocouple_tau_s", "values > 0", o["thermocouple_tau_s"])
    if not all(0.0 <= v <= 1.0 for v in o["thermocouple_air_weight"]):
        raise OptionError("thermocouple_air_weight", "values in [0, 1]", o["thermocouple_air_weight"])
    swing = o["humidity_swing_pct"] + o["humidity_weather_pct"]
    if not (0.0 <= o["humidity_pct"] - swing and o["humidity_pct"] + swing <= 100.0):
        raise OptionError("humidity_pct", "humidity +- its swings within 0-100 %", o["humidity_pct"])
    o = EFFECTS.unmodelled_off(o)  # one key switches off every effect no calflow model represents
    from calflow.rigs.thermal import _DEFAULTS, PROFILES

    if o["profile"] not in PROFILES:
        raise OptionError("profile", f"one of {list(PROFILES)}", o["profile"])
    for key, value in o["profile_params"].items():
        if key not in _DEFAULTS[o["profile"]]:
            raise OptionError(
                "profile_params",
                f"parameters of profile {o['profile']!r} ({', '.join(sorted(_DEFAULTS[o['profile']]))})",
                {key: value},
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise OptionError("profile_params", "finite numbers", {key: value})
    for key in ("lights_on_h", "lights_off_h"):  # hours of the day (daily_window)
        if key in o and not 0.0 <= o[key] <= 24.0:
            raise OptionError(key, "an hour of the day, 0-24", o[key])
    if "lights_on_h" in o and not o["lights_on_h"] < o["lights_off_h"]:
        raise OptionError(
            "lights_off_h", f"an hour after lights_on_h ({o['lights_on_h']:g})", o["lights_off_h"]
        )
    if "people_visits_h" in o and not all(0.0 <= v < 24.0 for v in o["people_visits_h"]):
        raise OptionError("people_visits_h", "hours of the day, 0-24", list(o["people_visits_h"]))
    if not 0.0 < o["step_damping"] < 1.0:
        raise OptionError(
            "step_damping", "a damping ratio in (0, 1) (an underdamped closed loop)", o["step_damping"]
        )
    if not -1.0 < o["repeatability_correlation"] < 1.0:
        raise OptionError("repeatability_correlation", "a value in (-1, 1)", o["repeatability_correlation"])
    return o
