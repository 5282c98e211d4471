"""Options of the drift the thermocouples do not see, in one table (docs/rigs.md has the sources).

Each effect is switched off by setting its option(s) in :data:`UNSEEN_EFFECTS` to 0 (the
rig's ``without``), and every one of them by ``unmodelled: false``: no calflow nano model
represents any of them. Defaults are physical figures of datasheets, application notes,
papers or the thesis's own records of its hardware, or a stated assumption where no source
gives the figure; none is chosen to land on a thesis accuracy. Units are in the names.

A later physical effect of the same kind (ageing of the piezo, calendar drift of a sensor)
belongs here too: add its defaults to :data:`UNSEEN`, its keys to :data:`UNSEEN_EFFECTS`
and, if it errs the thermocouples rather than the position, its name to :data:`TC_ERRORS`.
"""

from __future__ import annotations

from calflow.nano.stage.interferometer import HENE_VACUUM_UM
from calflow.rigs.simulated.effects import Effect, Effects

__all__ = ["UNSEEN", "UNSEEN_EFFECTS", "TC_ERRORS", "HEAT_SOURCES", "UNSEEN_POSITIVE", "UNSEEN_NON_NEGATIVE"]

UNSEEN = {
    # the campaign's history before its zero (campaign time 0)
    "mounted_h_before": 2.0,  # stage mounted and controller switched on this long before the zeroing
    # heat sources off the thermocouples' paths (calflow.nano.stage.unseen.heat)
    "piezo_capacitance_uf": 6.0,  # large-signal capacitance of the stage's stack(s)
    "piezo_loss_factor": 0.1,  # large-signal tan(delta): 7-10x the small-signal ~0.01-0.02
    "piezo_drive_span_v": 120.0,  # drive voltage over the stroke (PICMA: -20 .. 120 V)
    "electronics_w": 0.05,  # controller/amplifier heat reaching the base plate through the table
    "electronics_warmup_h": 1.0,  # time constant of the controller's housing after switch-on
    "lighting_w": 0.008,  # visible light absorbed by the stage through the shield, lights on
    "lights_on_h": 8.0,  # hours of the day (campaign time 0 = midnight, as the room profile)
    "lights_off_h": 19.0,
    "people_w": 0.04,  # a person's radiant heat absorbed by the shield and passed to its air
    "people_visits_h": (10.0, 16.0),  # hours of the day someone works at the bench ...
    "people_visit_h": 0.25,  # ... for this long
    # mechanics (calflow.nano.stage.unseen.mechanics)
    "mount_settling_nm_per_decade": 10.0,  # log-time relaxation since mounting
    "move_settling_ppm_per_decade": 10.0,  # log-time relaxation of each move, of its size (1 s .. 3 h)
    "humidity_weather_pct": 8.0,  # slow weather swing of the relative humidity (amplitude, 79 h)
    "bond_swelling_nm_per_pct": 2.0,  # bonded parts in the loop: hygroscopic swelling per %RH ...
    "bond_moisture_tau_h": 12.0,  # ... following the humidity with this diffusion lag
    "sensor_gap_um": 100.0,  # capacitive sensor's gap at x = 0: its air's permittivity scales it
    # the thermocouples' own errors (calflow.nano.stage.unseen.instruments)
    "thermocouple_drift_mk_per_day": 2.0,  # spread of each channel's calibration drift rate
    "cjc_lag_s": 1200.0,  # reference-junction sensor's lag behind the terminals (room-driven)
    "cjc_terminal_tau_s": 300.0,  # the terminals' lag behind the room
    "junction_glue_tau_s": 300.0,  # a junction glued/taped to its part lags it by this
    # the interferometer's non-thermal errors (calflow.nano.stage.unseen.instruments)
    "laser_wander_ppm": 0.3,  # slow wander of the vacuum wavelength (bound, periods 0.5-12 h)
    "periodic_error_nm": 3.0,  # first-order periodic nonlinearity (amplitude) ...
    "periodic_period_nm": HENE_VACUUM_UM * 1e3 / 4.0,  # ... one fringe of a plane-mirror double pass
    "turbulence_mk": 3.0,  # rms temperature fluctuation of the air along the beam (shielded)
}

# effect -> the option(s) that switch it off (all of them 0), its source; no calflow model
# represents any of them (docs/rigs.md has the laws and the figures)
UNSEEN_EFFECTS = Effects(
    {
        name: Effect(fields, source, modelled=False)
        for name, fields, source in (
            ("piezo_heating", ("piezo_loss_factor",), "dielectric loss of the piezo stack (Noliac tutorial)"),
            ("electronics_heating", ("electronics_w",), "a controller on the same table (assumption)"),
            ("lighting", ("lighting_w",), "500 lx on the work plane, EN 12464-1"),
            ("people", ("people_w",), "sensible heat of people, ASHRAE Handbook Fundamentals Ch. 18"),
            ("mount_settling", ("mount_settling_nm_per_decade",), "log-time relaxation of bolted joints"),
            ("move_settling", ("move_settling_ppm_per_decade",), "creep law of PI's piezo tutorial"),
            ("humidity_swelling", ("bond_swelling_nm_per_pct",), "hygroscopic swelling of epoxy bonds"),
            ("sensor_air", ("sensor_gap_um",), "refractivity of moist air, Smith & Weintraub 1953"),
            ("thermocouple_calibration", ("thermocouple_drift_mk_per_day",), "NIST Monograph 175"),
            ("reference_junction", ("cjc_lag_s",), "isothermal-block gradients of a logger's CJC"),
            ("junction_lag", ("junction_glue_tau_s",), "a glued junction's contact (assumption)"),
            ("laser_wander", ("laser_wander_ppm",), "Table 3.4, U1: its slow part"),
            ("periodic_nonlinearity", ("periodic_error_nm",), "Table 3.4, U3; Bobroff 1993"),
            ("turbulence", ("turbulence_mk",), "Bobroff, Appl. Opt. 26 (1987)"),
        )
    }
)
# effects that err the thermocouples' readings, not the position: the models see them
# through their regressors (the error budget treats them so)
TC_ERRORS = ("thermocouple_calibration", "reference_junction", "junction_lag")
HEAT_SOURCES = ("piezo_heating", "electronics_heating", "lighting", "people")
UNSEEN_POSITIVE = (
    "mounted_h_before",
    "electronics_warmup_h",
    "bond_moisture_tau_h",
    "cjc_terminal_tau_s",
    "periodic_period_nm",
    "piezo_drive_span_v",
)
UNSEEN_NON_NEGATIVE = tuple(
    k for k, v in UNSEEN.items() if not isinstance(v, tuple) and k not in UNSEEN_POSITIVE
)
