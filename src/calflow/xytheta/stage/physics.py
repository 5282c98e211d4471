"""Physics of the simulated XYΘ micro-robot (thesis Sec. 4.3–4.5), one named term per effect.

The rig is two PI M-111.1DG lead-screw stages (Table 4.1) under a SmarAct SR-3610-S
rotation stage (Table 4.2), seen by a microscope reading a pseudo-periodic pattern
(Sec. 3.3, Table 3.3). Every effect below is a term of its own with its source in its
docstring; each is switched off by setting its amplitude to 0, and ``unmodelled=False``
switches off, in one key, every effect that no calflow model represents (marked
*unmodelled*). docs/rigs.md lists them with the models that can compensate them.

Where an effect is in the thesis (geometry, lead screw, backlash, repeatability, drift)
it has the thesis's magnitude; otherwise the typical datasheet figure of that class of
stage. None is chosen to land on a result of the thesis.
"""

from __future__ import annotations

import numpy as np

from calflow.errors import OptionError
from calflow.rigs.simulated.checks import Bounds, check_physics
from calflow.rigs.simulated.effects import Effect, Effects, SwitchedTruth
from calflow.xytheta.models.kinematics import Parameters, forward, pattern_from_world

TRAVEL_UM = 15000.0  # Table 4.1: travel range of the M-111.1DG
SENSOR_OPTIONS = ("sensor", "camera", "pattern")  # how the vision sensor reads: stage.images

EFFECTS = Effects(  # each effect: the fields that switch it off, its source, whether a model represents it
    {
        "lead_screw": Effect(("lead_fwd_um", "lead_bwd_um"), "Table 4.1 pitch; Fig. 4.8; Sec. 4.4.2"),
        "backlash": Effect(("backlash_um",), "Table 4.1"),
        "coupling": Effect(("coupling_um",), "Fig. 4.9"),
        "scale": Effect(("scale_ppm",), "precision lead screws, ISO 3408 classes 3-5"),
        "straightness": Effect(("straightness_um",), "ball-guided miniature stages, class figure"),
        "yaw": Effect(("yaw_urad",), "Table 4.1", modelled=False),
        "expansion": Effect(("expansion_ppm_per_degC",), "aluminium carriages, 23 ppm/degC", modelled=False),
        "theta_scale": Effect(("theta_scale_ppm",), "rotary stick-slip stages, class figure"),
        "theta_periodic": Effect(("theta_periodic_mdeg",), "Table 4.2: one stick-slip step"),
        "theta_backlash": Effect(("theta_backlash_mdeg",), "Table 4.2: a stop within one step"),
        "axis_runout": Effect(("axis_runout_um",), "miniature rotary stages, class figure"),
        "decode": Effect(
            ("decode_error_um",), "per-pose phase error of the pattern (Sec. 3.3)", modelled=False
        ),
        "drift": Effect(("drift_um_per_degC",), "Table 3.3", modelled=False),
        "lost_motion": Effect(
            ("lost_motion",), "nut play taken up after a reversal (Table 4.1)", modelled=False
        ),
        "gross_errors": Effect(
            ("gross_error_rate",), "a misread LFSR bit of the pattern (Sec. 3.3)", modelled=False
        ),
    }
)


class XYThetaTruth(SwitchedTruth, effects=EFFECTS):
    """True physics of the simulated XYΘ rig, its effects those of :data:`EFFECTS` (units in the field names)."""

    # geometry: the real rig's, as the thesis identified it (Table 4.6, Model II)
    x_R_um: float = 9572.902
    y_R_um: float = 7795.830
    alpha_deg: float = 177.689
    beta_deg: float = -0.132
    # X and Y stages
    thread_pitch_um: float = 400.0
    lead_fwd_um: tuple[float, float] = (4.0, 3.0)
    lead_bwd_um: tuple[float, float] = (6.0, 4.5)
    lead_phase_rad: tuple[float, float] = (0.6, 2.1)
    coupling_um: tuple[float, float] = (1.5, 1.2)
    backlash_um: float = 2.0
    lost_motion: bool = True
    scale_ppm: tuple[float, float] = (40.0, 40.0)
    straightness_um: tuple[float, float] = (1.0, 1.0)
    yaw_urad: tuple[float, float] = (150.0, 150.0)
    expansion_ppm_per_degC: float = 23.0
    stage_repeatability_um: float = 0.5
    # Θ stage
    theta_scale_ppm: float = 1000.0
    theta_periodic_mdeg: float = 2.0
    theta_period_deg: float = 0.73
    theta_backlash_mdeg: float = 1.0
    axis_runout_um: float = 2.0
    # vision sensor
    camera_x_um: float = 20.0
    camera_y_um: float = 400.0
    pattern_range_um: tuple[float, float] = (9500.0, 4200.0)
    pattern_period_um: float = 8.0
    sensor_noise_um: float = 0.05
    sensor_resolution_um: float = 0.01
    sensor_theta_noise_deg: float = 2e-4
    decode_error_um: float = 0.05
    gross_error_rate: float = 0.001
    drift_um_per_degC: tuple[float, float] = (0.157, 1.357)
    # environment and timing
    room_temperature_degC: float = 21.0
    room_swing_degC: float = 0.3
    velocity_um_s: float = 1000.0
    velocity_deg_s: float = 10.0
    settle_s: float = 0.5
    unmodelled: bool = True

    @property
    def parameters(self) -> Parameters:
        return Parameters(self.x_R_um, self.y_R_um, self.alpha_deg, self.beta_deg)

    # ------------------------------------------------------------------ X and Y stages
    def lead_error(self, axis: int, q, direction):
        """Lead-screw error plus long-approach backlash of joint ``axis`` (0 X, 1 Y), µm.

        Periodic with the 400 µm thread pitch (Table 4.1, Fig. 4.8), of other size forward
        and backward (Fig. 4.8), ≈ 4 µm in the thesis's CD segment (Sec. 4.4.2); ± half the
        2 µm backlash of Table 4.1 by approach direction.
        """
        amp = np.where(np.asarray(direction) < 0, self.lead_bwd_um[axis], self.lead_fwd_um[axis])
        phase = 2 * np.pi * np.asarray(q) / self.thread_pitch_um + self.lead_phase_rad[axis]
        backlash = np.where(np.asarray(direction) < 0, -0.5, 0.5) * self.backlash_um
        return amp * np.sin(phase) + backlash

    def coupling_error(self, axis: int, q):
        """Error on the other axis during motion of joint ``axis``, same period (Fig. 4.9), µm."""
        phase = 2 * np.pi * np.asarray(q) / self.thread_pitch_um + self.lead_phase_rad[axis] + 0.8
        return self.coupling_um[axis] * np.sin(phase)

    def scale_error(self, axis: int, q):
        """Cumulative lead deviation of the screw, a scale error (µm): class figure of precision
        lead screws (ISO 3408 classes 3–5: ≈ 10 µm per 300 mm, 40 ppm)."""
        return self.scale_ppm[axis] * 1e-6 * np.asarray(q)

    def straightness_error(self, axis: int, q):
        """Straightness of the guide of joint ``axis`` (µm, across the motion): a bow of
        ``straightness_um`` at mid-travel, the ±1 µm class figure of ball-guided stages of
        the M-111 size."""
        u = np.asarray(q) / TRAVEL_UM
        return self.straightness_um[axis] * 4.0 * u * (1.0 - u)

    def yaw(self, axis: int, q):
        """Yaw of the carriage of joint ``axis`` (rad): ± ``yaw_urad`` over the travel
        (Table 4.1: ±150 µrad). *Unmodelled*: its lever to the tool turns with Θ."""
        return self.yaw_urad[axis] * 1e-6 * (2.0 * np.asarray(q) / TRAVEL_UM - 1.0)

    def expansion(self, q, temperature_degC):
        """Thermal expansion of the stage along its stroke (µm): aluminium, 23 ppm/°C, from
        the room's swing around its mean. *Unmodelled* (no model has time)."""
        return (
            self.expansion_ppm_per_degC
            * 1e-6
            * np.asarray(q)
            * (temperature_degC - self.room_temperature_degC)
        )

    def slide_errors(self, X, Y, temperature_degC):
        """Scale, straightness and expansion errors of the attained joints (µm), beyond the
        lead screw: what the carriages add to a command (X, Y) at a room temperature."""
        ex = self.scale_error(0, X) + self.straightness_error(1, Y) + self.expansion(X, temperature_degC)
        ey = self.scale_error(1, Y) + self.straightness_error(0, X) + self.expansion(Y, temperature_degC)
        return ex, ey

    def attained_joints(self, X, Y, lash_x, lash_y, temperature_degC=None):
        """Where the carriages are (µm) for commands X, Y whose nut play sits at ``lash_*``
        (± ``backlash_um``/2 after a long approach; in between after a short one)."""
        T = self.room_temperature_degC if temperature_degC is None else temperature_degC
        half = 0.5 * self.backlash_um
        lash_x, lash_y = np.asarray(lash_x, dtype=float), np.asarray(lash_y, dtype=float)
        dx, dy = np.where(lash_x < 0, -1, 1), np.where(lash_y < 0, -1, 1)
        ex, ey = self.slide_errors(X, Y, T)
        Xa = np.asarray(X) + self.lead_error(0, X, dx) - dx * half + lash_x + self.coupling_error(1, Y) + ex
        Ya = np.asarray(Y) + self.lead_error(1, Y, dy) - dy * half + lash_y + self.coupling_error(0, X) + ey
        return Xa, Ya

    # ------------------------------------------------------------------ Θ stage
    def theta_error(self, theta, direction=1):
        """Angular positioning error of the Θ stage (degree): a scale error (0.1 %, class
        figure of rotary stick-slip stages with an integrated sensor), a periodic error of
        one stick-slip step (Table 4.2: 0.3–3 m°) with a 0.73° period, not a multiple of
        any plan's Θ step, and a direction-dependent stop within one step (``theta_backlash``)."""
        theta = np.asarray(theta, dtype=float)
        periodic = self.theta_periodic_mdeg * 1e-3 * np.sin(2 * np.pi * theta / self.theta_period_deg + 0.3)
        side = np.where(np.asarray(direction) < 0, -0.5, 0.5) * self.theta_backlash_mdeg * 1e-3
        return self.theta_scale_ppm * 1e-6 * theta + periodic + side

    def axis_runout(self, theta_a):
        """Translation of the rotation axis with the angle (µm, world frame): radial runout
        of the bearing, once per revolution, ``axis_runout_um`` (class figure of miniature
        rotary stages: 1–3 µm)."""
        t = np.radians(np.asarray(theta_a, dtype=float)) + 0.9
        return (
            self.axis_runout_um * (np.cos(t) - np.cos(0.9)),
            self.axis_runout_um * (np.sin(t) - np.sin(0.9)),
        )

    # ------------------------------------------------------------------ the tool point
    def tool_point(self, X, Y, theta, dir_x=1, dir_y=1, dir_theta=1, lash=None, temperature_degC=None):
        """Noise-free tool point (µm, world frame) and the attained angle (degree).

        ``lash`` = (lash_x, lash_y), the nut play of each stage (µm); by default that of a
        long approach in ``dir_*``. Returns ``(x_P, y_P, theta_a)``.
        """
        if lash is None:
            lash = (
                np.where(np.asarray(dir_x) < 0, -0.5, 0.5) * self.backlash_um,
                np.where(np.asarray(dir_y) < 0, -0.5, 0.5) * self.backlash_um,
            )
        Xa, Ya = self.attained_joints(X, Y, lash[0], lash[1], temperature_degC)
        return self.tool_from_carriages(Xa, Ya, X, Y, theta, dir_theta)

    def tool_from_carriages(self, Xa, Ya, X, Y, theta, dir_theta=1):
        """Tool point (µm) and attained angle (degree) from the carriages' positions Xa, Ya,
        the commands X, Y (for the yaw along the travel) and the commanded Θ: Eq. (4.18)
        at the attained angle, plus the axis runout and the carriages' yaw."""
        theta_a = np.asarray(theta, dtype=float) + self.theta_error(theta, dir_theta)
        x_P, y_P = forward(Xa, Ya, theta_a, self.parameters)
        rx, ry = self.axis_runout(theta_a)
        x_P, y_P = x_P + rx, y_P + ry
        eps = self.yaw(0, X) + self.yaw(1, Y)  # a small rotation of everything above the carriages
        dx, dy = x_P - self.x_R_um, y_P - self.y_R_um
        return x_P - eps * dy, y_P + eps * dx, theta_a

    def exact_inverse(self, x_T, y_T, theta, dir_x, dir_y, dir_theta=1, iterations: int = 50):
        """Joint commands that put the noise-free tool point exactly on the targets after
        long approaches in ``dir_*``. For tests and the oracle validation only: it uses the
        rig's truth. Newton iteration on :meth:`tool_point`."""
        from calflow.xytheta.models.kinematics import inverse

        x_T, y_T = np.asarray(x_T, dtype=float), np.asarray(y_T, dtype=float)
        X, Y = inverse(x_T, y_T, theta, self.parameters)
        h = 1e-3
        for _ in range(iterations):
            px, py, _ = self.tool_point(X, Y, theta, dir_x, dir_y, dir_theta)
            rx, ry = x_T - px, y_T - py
            ax, ay, _ = self.tool_point(X + h, Y, theta, dir_x, dir_y, dir_theta)
            bx, by, _ = self.tool_point(X, Y + h, theta, dir_x, dir_y, dir_theta)
            jxx, jyx, jxy, jyy = (ax - px) / h, (ay - py) / h, (bx - px) / h, (by - py) / h
            det = jxx * jyy - jxy * jyx
            X, Y = X + (jyy * rx - jxy * ry) / det, Y + (-jyx * rx + jxx * ry) / det
            if np.max(np.abs(rx)) < 1e-9 and np.max(np.abs(ry)) < 1e-9:
                break
        return X, Y

    # ------------------------------------------------------------------ vision sensor
    def decode_error(self, x_m, y_m):
        """Per-pose pattern-decoding error (µm): a systematic function of where the camera
        looks on the pattern (the dots' fabrication and phase errors), so averaging frames
        at one pose does not remove it. *Unmodelled*."""
        p = self.pattern_period_um
        a = self.decode_error_um
        return (
            a * np.sin(2 * np.pi * (x_m / p + 0.37 * y_m / p) + 0.2),
            a * np.cos(2 * np.pi * (0.61 * x_m / p - y_m / p) + 1.3),
        )

    def camera_point(self, x_P, y_P, theta, temperature_degC):
        """Where the camera looks on the pattern (µm, pattern frame): the camera point M of
        Eq. (4.26) for the tool point (x_P, y_P) at angle Θ, shifted by the thermal drift of
        the camera mount (Table 3.3); what a frame shows, before any sensor noise."""
        x_m, y_m = pattern_from_world(x_P, y_P, theta, self.camera_x_um, self.camera_y_um)
        warm = np.asarray(temperature_degC) - self.room_temperature_degC
        return x_m + warm * self.drift_um_per_degC[0], y_m + warm * self.drift_um_per_degC[1]

    def vision(self, x_P, y_P, theta, temperature_degC, noise_um, gross=(0.0, 0.0)):
        """The vision reading (x_m, y_m) of the camera point in the pattern frame, µm.

        Eq. (4.26) for the tool point (x_P, y_P) at angle Θ, plus the thermal drift of
        Table 3.3, the decoding error, the given noise (two draws, or two arrays of draws)
        and gross error (a whole pattern period where an LFSR bit is misread), the
        resolution; NaN when the camera sees no pattern. Floats for scalar poses, arrays
        for arrays of poses (element by element the same numbers).
        """
        x_m, y_m = pattern_from_world(x_P, y_P, theta, self.camera_x_um, self.camera_y_um)
        warm = np.asarray(temperature_degC) - self.room_temperature_degC
        dx, dy = self.decode_error(x_m, y_m)
        res = self.sensor_resolution_um
        x_m = np.round((x_m + warm * self.drift_um_per_degC[0] + dx + noise_um[0] + gross[0]) / res) * res
        y_m = np.round((y_m + warm * self.drift_um_per_degC[1] + dy + noise_um[1] + gross[1]) / res) * res
        seen = (0 <= x_m) & (x_m <= self.pattern_range_um[0]) & (0 <= y_m) & (y_m <= self.pattern_range_um[1])
        x_m, y_m = np.where(seen, x_m, np.nan), np.where(seen, y_m, np.nan)
        return (float(x_m), float(y_m)) if x_m.ndim == 0 else (x_m, y_m)

    def gross_error(self, u, v):
        """A misread pattern period: with probability ``gross_error_rate`` (``u`` uniform in
        [0, 1)), ± one ``pattern_period_um`` on the axis ``v`` picks (µm). *Unmodelled*.
        Floats for scalar draws, arrays for arrays."""
        u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
        period = np.where((v * 4) % 2 < 1, 1.0, -1.0) * self.pattern_period_um
        hit = u < self.gross_error_rate
        gx, gy = np.where(hit & (v < 0.5), period, 0.0), np.where(hit & (v >= 0.5), period, 0.0)
        return (float(gx), float(gy)) if gx.ndim == 0 else (gx, gy)

    def room_temperature(self, t_s):
        """Room temperature (degC) at virtual time ``t_s``: a daily swing."""
        return self.room_temperature_degC + self.room_swing_degC * np.sin(
            2 * np.pi * np.asarray(t_s) / 86400.0
        )


BOUNDS = Bounds(
    non_negative=(
        "backlash_um",
        "stage_repeatability_um",
        "sensor_noise_um",
        "sensor_theta_noise_deg",
        "room_swing_degC",
        "settle_s",
        "decode_error_um",
        "gross_error_rate",
        "theta_backlash_mdeg",
    ),
    positive=(
        "thread_pitch_um",
        "sensor_resolution_um",
        "velocity_um_s",
        "velocity_deg_s",
        "pattern_range_um",
        "pattern_period_um",
        "theta_period_deg",
    ),
)


def check_options(seed=0, stream: str = "", **physics) -> dict:
    """The options of the simulated XYΘ rig checked and converted; raises :class:`OptionError`
    naming the option: unknown names, non-numbers, NaN/inf, negative magnitudes (noise,
    resolution, backlash, repeatability, rates), non-positive velocities, pitches, periods
    and ranges, switches that are not true/false. The vision sensor's options (``sensor``,
    ``camera``, ``pattern``: :mod:`calflow.xytheta.stage.images`), when given, come back
    checked under ``sensor``."""
    if "aging" in physics:  # checked here, resolved for the campaign's start by the loader (stage.aging)
        from calflow.xytheta.stage.aging import check as check_aging

        physics = dict(physics)
        check_aging(physics.pop("aging"))
    sensor = {k: physics[k] for k in SENSOR_OPTIONS if k in physics}
    physics = {k: v for k, v in physics.items() if k not in SENSOR_OPTIONS}
    out = check_physics(XYThetaTruth, BOUNDS, seed, stream, physics, also=SENSOR_OPTIONS)
    if sensor:  # how the vision sensor reads (stage.images): not physics
        from calflow.xytheta.stage.images import check as check_sensor

        range_um = out.get("pattern_range_um", XYThetaTruth.pattern_range_um)
        sensor = check_sensor(**sensor, range_um=range_um)
    if out.get("gross_error_rate", 0.0) > 1:
        raise OptionError("gross_error_rate", "a probability between 0 and 1", physics["gross_error_rate"])
    return {**out, **({"sensor": sensor} if sensor else {})}


def truth_from_options(physics) -> XYThetaTruth:
    """An :class:`XYThetaTruth` with ``physics`` overrides, checked as the simulated rig's
    options are (:func:`check_options`)."""
    o = check_options(**physics)
    del o["seed"], o["stream"]
    o.pop("sensor", None)
    return XYThetaTruth(**o)


def options_off(*effects: str) -> dict:
    """Rig options that switch off ``effects`` (names of :data:`EFFECTS`; all of them when none
    is named) — for tests and studies on a rig whose only errors are those a model represents."""
    return EFFECTS.options_off(XYThetaTruth().as_dict(), *effects)
