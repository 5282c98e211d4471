"""Physics of the simulated 6-DoF hexapod (Stewart–Gough platform), one named term per effect.

The rig is a PI H-811 / H-824-class micro-positioning hexapod: six screw-driven legs
between base and platform joints, each leg a brushless motor with a rotary encoder
(actuator design resolution 5 nm, H-811.I2 datasheet), driven by a C-887-class controller
that computes leg lengths from its *nominal* geometry. What the platform really does
differs from the nominal by the effects below; each is switched off by setting its
amplitude to 0, and ``unmodelled=False`` switches off, in one key, every effect no hexapod
model of this family represents (marked *unmodelled*). The instrument that measures the
platform is :mod:`calflow_hexapod.stage.tracker`.

Effects (README.md lists them with their source, default and switch):

* ``joint_error_um`` — base and platform joint centres off their nominal positions,
  σ per coordinate (machining and assembly of the joints, ISO 2768-f class ±50 µm
  tolerances on 30–120 mm features: σ ≈ 17 µm).
* ``leg_offset_um`` — each leg's length at the reference switch off nominal (σ).
* ``leg_scale_ppm`` — screw-pitch scale of each leg (σ): ISO 3408-3 class 3–5 ball
  screws, 12–23 µm per 300 mm (40–77 ppm).
* ``joint_play_um`` — play of each leg's drive train and joints, taken up on the side of
  its last motion: ± half of it by the leg's approach direction. *Unmodelled*.
* ``payload_kg`` — leg compliance under the payload: the legs' static forces (Jacobian
  statics, Merlet 2006, *Parallel Robots*, Sec. 6.1) over a leg stiffness derived from
  the datasheet's Z stiffness (H-811.I2: 2 N/µm in Z, 0.2 N/µm in X, Y). *Unmodelled*.
* ``expansion_ppm_per_degC`` — thermal expansion of the legs (steel screws, 11.5 ppm/°C)
  from the leg temperature, a first-order lag of the room profile
  (:mod:`calflow.rigs.thermal`); thermometer ``T2`` sits on a leg, ``T1`` reads the air.
* ``encoder_resolution_um`` — the leg encoders' quantisation: the servo holds each leg at
  a whole count of its commanded length. *Unmodelled* (5 nm: far below the instrument).
* ``leg_repeatability_um`` — random leg positioning error per move (σ), the datasheet's
  unidirectional repeatability class (H-811.I2: ±0.06 µm in X, Y).

Geometry draws come from ``geometry_seed`` (the rig's identity, the same for every run);
noise from the rig's own seed. Lengths µm, angles degree, temperatures degC.
"""

from __future__ import annotations

import numpy as np

from calflow.rigs.simulated.checks import Bounds, check_physics
from calflow.rigs.simulated.effects import Effect, Effects, SwitchedTruth
from calflow_hexapod.models.geometry import Geometry, h811, rotation

G = 9.80665  # standard gravity, m/s²
EFFECTS = (
    Effects(  # each effect: the fields that switch it off, its source, whether a hexapod model represents it
        {
            "joint_errors": Effect(("joint_error_um",), "ISO 2768-f tolerances of the joints' features"),
            "leg_offsets": Effect(("leg_offset_um",), "each leg's length at its reference switch"),
            "leg_scale": Effect(("leg_scale_ppm",), "ISO 3408-3 class 3-5 ball screws"),
            "joint_play": Effect(("joint_play_um",), "play of the drive train and joints", modelled=False),
            "compliance": Effect(
                ("payload_kg",), "H-811.I2 stiffness; Merlet 2006, Sec. 6.1", modelled=False
            ),
            "expansion": Effect(("expansion_ppm_per_degC",), "steel screws, 11.5 ppm/degC"),
            # the encoders' rounding is a deterministic function of each pose, yet no model holds it
            "quantisation": Effect(
                ("encoder_resolution_um",), "H-811.I2: 5 nm design resolution", modelled=False
            ),
            "tracker_systematic": Effect(
                ("tracker_systematic_um",),
                "the tracker's systematic error (calflow_hexapod.stage.tracker)",
                modelled=False,
            ),
        }
    )
)


class HexapodTruth(SwitchedTruth, effects=EFFECTS):
    """True physics of the simulated hexapod, its effects those of :data:`EFFECTS` (units in the field names)."""

    # geometric errors about the nominal H-811-class geometry (calflow_hexapod.models.geometry.h811), drawn from geometry_seed
    geometry_seed: int = 811
    joint_error_um: float = 20.0
    leg_offset_um: float = 30.0
    leg_scale_ppm: float = 50.0
    # legs
    joint_play_um: float = 0.4
    payload_kg: float = 2.0
    payload_com_um: tuple[float, float, float] = (
        0.0,
        0.0,
        50000.0,
    )  # centre of mass, platform frame
    stiffness_z_n_per_um: float = 2.0
    expansion_ppm_per_degC: float = 11.5
    reference_temperature_degC: float = 20.0  # the nominal lengths hold at this leg temperature (ISO 1)
    leg_lag_s: float = 1800.0
    encoder_resolution_um: float = 0.005
    leg_repeatability_um: float = 0.03
    # room
    room_profile: str = "lab5day"
    room_base_degC: float = 21.0
    room_seed: int = 0
    start_offset_s: float = 0.0  # campaign (profile) time of the rig's time 0
    # instrument (calflow_hexapod.stage.tracker)
    tracker_distance_m: float = 1.5
    tracker_adm_um: float = 10.0
    tracker_adm_um_per_m: float = 0.3
    tracker_transverse_um: float = 15.0
    tracker_transverse_um_per_m: float = 6.0
    tracker_angle_mdeg: float = 10.0
    tracker_resolution_um: float = 0.1
    tracker_systematic_um: float = 3.0
    # the measurement frame in the base frame: the tracker's user frame, set up by probing the
    # base's reference features (a few 0.1 mm, a few 0.01°); the probe in the platform frame, as
    # mounted by hand on its 60 mm post (0.1 mm, tenths of a degree)
    frame_offset_um: tuple[float, float, float] = (250.0, -150.0, 80.0)
    frame_rotation_deg: tuple[float, float, float] = (0.03, -0.02, 0.1)
    tool_offset_um: tuple[float, float, float] = (150.0, -90.0, 60000.0)
    tool_rotation_deg: tuple[float, float, float] = (0.2, -0.1, 0.5)
    # timing
    velocity_um_s: float = 5000.0
    velocity_deg_s: float = 5.0
    settle_s: float = 0.3
    unmodelled: bool = True

    # ------------------------------------------------------------------ geometry
    @staticmethod
    def nominal() -> Geometry:
        """The nominal geometry, the controller's: :func:`calflow_hexapod.models.geometry.h811`."""
        return h811()

    def _draws(self) -> np.ndarray:
        """The standard normal draws (6·3 + 6·3 + 6 + 6 = 48) of the rig's geometric errors."""
        return np.random.default_rng(
            np.random.SeedSequence([int(self.geometry_seed), 6_811])
        ).standard_normal(48)

    def geometry(self) -> Geometry:
        """The true geometry: base and platform joints (6, 3) µm, nominal plus
        ``joint_error_um`` · N(0, 1) per coordinate; pivot at the platform frame's origin."""
        g, z = self.nominal(), self._draws()
        return Geometry(
            g.base + self.joint_error_um * z[:18].reshape(6, 3),
            g.platform + self.joint_error_um * z[18:36].reshape(6, 3),
        )

    def leg_offsets(self) -> np.ndarray:
        """Each leg's length error at the reference (µm, 6): ``leg_offset_um`` · N(0, 1)."""
        return self.leg_offset_um * self._draws()[36:42]

    def leg_scales(self) -> np.ndarray:
        """Each leg's screw-pitch scale error (dimensionless, 6): ``leg_scale_ppm`` · 1e-6 · N(0, 1)."""
        return self.leg_scale_ppm * 1e-6 * self._draws()[42:48]

    def home_lengths(self) -> np.ndarray:
        """Nominal leg lengths at the home pose (µm, 6): the encoders' zero."""
        return self.nominal().zero_lengths

    # ------------------------------------------------------------------ legs
    def quantise(self, legs):
        """Encoder lengths (µm) the servo holds for commanded leg lengths: a whole count of
        ``encoder_resolution_um`` of the stroke from home (no quantisation when 0)."""
        legs = np.asarray(legs, dtype=float)
        res = self.encoder_resolution_um
        if res <= 0:
            return legs
        l0 = self.home_lengths()
        return l0 + np.round((legs - l0) / res) * res

    def play(self, direction) -> np.ndarray:
        """Leg length from the play (µm): + half ``joint_play_um`` after an extension,
        − half after a retraction (``direction`` ±1 per leg). *Unmodelled*."""
        return 0.5 * self.joint_play_um * np.where(np.asarray(direction) < 0, -1.0, 1.0)

    def expansion(self, legs, leg_temperature_degC):
        """Thermal expansion of the legs (µm): ``expansion_ppm_per_degC`` of each length per
        degree of the leg temperature above ``reference_temperature_degC``."""
        dT = np.asarray(leg_temperature_degC, dtype=float)[..., None] - self.reference_temperature_degC
        return self.expansion_ppm_per_degC * 1e-6 * np.asarray(legs) * dT

    def leg_stiffness_n_per_um(self) -> float:
        """One leg's axial stiffness (N/µm) giving the datasheet's Z stiffness at home:
        k_z = k Σ n_iz² for unit leg vectors n_i (Merlet 2006, Sec. 6.1)."""
        g = self.nominal()
        n = (g.platform - g.base) / g.zero_lengths[:, None]
        return self.stiffness_z_n_per_um / float(np.sum(n[:, 2] ** 2))

    def leg_forces(self, pose, geometry: Geometry | None = None) -> np.ndarray:
        """Static axial forces of the legs (N, (..., 6), compression > 0) holding the payload
        at ``pose`` (..., 6): Σ f_i n_i = −W, Σ (P_i − C) × f_i n_i = 0 about the payload's
        centre of mass C, W = (0, 0, −m g) — Jacobian statics, f = J⁻ᵀ w (Merlet 2006, Sec. 6.1)."""
        g = self.geometry() if geometry is None else geometry
        a, b = g.base, g.platform
        pose = np.atleast_2d(np.asarray(pose, dtype=float))
        R = rotation(pose[:, 3], pose[:, 4], pose[:, 5])
        P = pose[:, None, :3] + np.einsum("nij,kj->nki", R, b)  # platform joints in the work frame
        C = pose[:, :3] + np.einsum("nij,j->ni", R, np.asarray(self.payload_com_um))
        L = P - a[None]
        n = L / np.linalg.norm(L, axis=2, keepdims=True)
        arm = (P - C[:, None, :]) * 1e-6  # m
        A = np.concatenate([n, np.cross(arm, n)], axis=2).transpose(0, 2, 1)  # (N, 6, 6): columns per leg
        w = np.zeros((len(pose), 6))
        w[:, 2] = self.payload_kg * G  # the legs carry the weight: Σ f n = +m g ẑ
        return np.linalg.solve(A, w[..., None])[..., 0]

    def compliance(self, pose, geometry: Geometry | None = None) -> np.ndarray:
        """Leg shortening under the payload (µm, (..., 6)): −f_i / k_leg. *Unmodelled*."""
        if self.payload_kg == 0:
            return np.zeros(np.atleast_2d(pose).shape[:-1] + (6,))
        return -self.leg_forces(pose, geometry) / self.leg_stiffness_n_per_um()

    def true_legs(self, encoder_legs, direction, leg_temperature_degC, pose_guess) -> np.ndarray:
        """True joint-to-joint leg lengths (µm, (n, 6)) for encoder lengths (n, 6): offset,
        scale of the stroke, play, thermal expansion and compliance at ``pose_guess`` (n, 6)."""
        enc = np.asarray(encoder_legs, dtype=float)
        l0 = self.home_lengths()
        legs = enc + self.leg_offsets() + self.leg_scales() * (enc - l0) + self.play(direction)
        return legs + self.expansion(legs, leg_temperature_degC) + self.compliance(pose_guess)


NOISE = (
    "leg_repeatability_um",
    "tracker_adm_um",
    "tracker_adm_um_per_m",
    "tracker_transverse_um",
    "tracker_transverse_um_per_m",
    "tracker_angle_mdeg",
    "tracker_resolution_um",
)  # random, not effects

BOUNDS = Bounds(
    positive=("stiffness_z_n_per_um", "leg_lag_s", "tracker_distance_m", "velocity_um_s", "velocity_deg_s"),
    signed=(
        "start_offset_s",
        "payload_com_um",
        "frame_offset_um",
        "frame_rotation_deg",
        "tool_offset_um",
        "tool_rotation_deg",
        "reference_temperature_degC",
        "room_base_degC",
    ),
    default=">=",  # magnitudes
    choices={"room_profile": ("constant", "metrology", "lab5day")},
)


def check_options(seed=0, stream: str = "", **physics) -> dict:
    """The options of the simulated hexapod checked and converted; raises :class:`OptionError`
    naming the option: unknown names, non-numbers, NaN/inf, negative magnitudes, non-positive
    sizes and velocities, switches that are not true/false, an unknown room profile."""
    return check_physics(HexapodTruth, BOUNDS, seed, stream, physics)


def truth_from_options(physics) -> HexapodTruth:
    """A :class:`HexapodTruth` with ``physics`` overrides, checked as the rig's options are."""
    o = check_options(**physics)
    del o["seed"], o["stream"]
    return HexapodTruth(**o)


def options_off(*effects: str) -> dict:
    """Rig options that switch off ``effects`` (names of :data:`EFFECTS`; all of them when
    none is named) — a rig whose only errors are those a model represents, and noise."""
    return EFFECTS.options_off(HexapodTruth().as_dict(), *effects)
