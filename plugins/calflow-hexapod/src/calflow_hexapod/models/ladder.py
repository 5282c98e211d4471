"""The hexapod's calibration models, a ladder like the XYΘ Models I–V.

Every model describes one pose k as a closed kinematic loop (Wampler, Hollerbach & Arai
1995): work frame → measurement frame F → measured target pose M_k → tool frame G⁻¹ →
platform pose P_k = F M_k G⁻¹; leg i must then join the base joint b_i to the platform
joint P_k p_i with the length the leg really has,

    l_ki = λ_ki + δl_i + s_i (λ_ki − λ₀_i) + α_T λ_ki (T_k − T_ref),

λ_ki the length the controller commands through its nominal geometry (the encoder-true leg
length; λ₀_i its value at the zero pose), δl_i the leg offset, s_i the leg scale (screw
pitch; 1 = 10⁶ ppm), α_T the legs' thermal expansion coefficient (1/K) at the temperature T_k
(degC, T_ref = 20 °C, ISO 1). The parameters (lengths µm, angles degree):

* ``frame_*``: F, the measurement frame in the work frame (x y z u v w, the C-887 pose convention);
* ``tool_*``: G, the measured target in the platform frame;
* ``b{i}_*``, ``p{i}_*``: base and platform joint centres of leg i (work and platform frame);
* ``dl{i}``, ``s{i}``, ``alpha_T``.

The ladder (:data:`LADDER`) frees more of them at each step:

``nominal``   the frames only: the nominal geometry, seen through an instrument set up anywhere;
``offsets``   + the six leg offsets δl_i (the zero of each leg's encoder);
``geometric`` + every joint centre: 12 + 36 + 6 = 54 parameters, of which 12 combinations
              are not identifiable — moving the work frame (6) or the platform frame (6) with
              the joints changes no reading. :func:`calflow_hexapod.models.identification.identifiable`
              reduces them to the identifiable 42 by the core's QR analysis;
``scale``     + the six leg scales s_i;
``thermal``   + α_T, identifiable only when the temperature changes during the run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow_hexapod.models.geometry import AXES, Geometry, h811

#: Reference temperature (degC) of dimensional metrology, ISO 1:2022.
T_REF_DEGC = 20.0

FRAME = tuple(f"frame_{a}" for a in AXES)
TOOL = tuple(f"tool_{a}" for a in AXES)
BASE = tuple(f"b{i}_{a}" for i in range(1, 7) for a in "xyz")
PLATFORM = tuple(f"p{i}_{a}" for i in range(1, 7) for a in "xyz")
OFFSET = tuple(f"dl{i}" for i in range(1, 7))
SCALE = tuple(f"s{i}" for i in range(1, 7))
THERMAL = ("alpha_T",)
#: Every parameter, in the order of the vector φ (frames first, so that the QR analysis keeps
#: the frames and fixes joint coordinates where the two are interchangeable).
NAMES = FRAME + TOOL + BASE + PLATFORM + OFFSET + SCALE + THERMAL

LADDER = {
    "nominal": FRAME + TOOL,
    "offsets": FRAME + TOOL + OFFSET,
    "geometric": FRAME + TOOL + BASE + PLATFORM + OFFSET,
    "scale": FRAME + TOOL + BASE + PLATFORM + OFFSET + SCALE,
    "thermal": FRAME + TOOL + BASE + PLATFORM + OFFSET + SCALE + THERMAL,
}


def unit(name: str) -> str:
    """CF unit of a parameter."""
    if name in SCALE:
        return "1"
    if name == "alpha_T":
        return "1/K"
    return "degree" if name[-2:] in ("_u", "_v", "_w") else "um"


def long_name(name: str) -> str:
    """What a parameter is, in words."""
    if name.startswith("frame_"):
        return f"measurement frame in the work frame, {name[-1]}"
    if name.startswith("tool_"):
        return f"measured target in the platform frame, {name[-1]}"
    if name in BASE:
        return f"base joint of leg {name[1]}, {name[-1]}"
    if name in PLATFORM:
        return f"platform joint of leg {name[1]}, {name[-1]}"
    if name in OFFSET:
        return f"length offset of leg {name[2]}"
    if name in SCALE:
        return f"length scale of leg {name[1]}"
    return "thermal expansion coefficient of the legs"


@dataclass(frozen=True)
class Parameters:
    """A value of every parameter of :data:`NAMES` (µm, degree, 1, 1/K)."""

    frame: np.ndarray
    tool: np.ndarray
    base: np.ndarray
    platform: np.ndarray
    offset: np.ndarray
    scale: np.ndarray
    thermal: float = 0.0

    @classmethod
    def nominal(cls, geometry: Geometry | None = None, frame=None, tool=None) -> Parameters:
        """The nominal geometry (default :func:`calflow_hexapod.models.geometry.h811`) with the frames
        given (default: the measurement frame is the work frame, the target at the platform origin)."""
        g = geometry or h811()
        z = np.zeros(6)
        frame = z if frame is None else np.asarray(frame, dtype=float)
        tool = z if tool is None else np.asarray(tool, dtype=float)
        return cls(frame, tool, g.base.copy(), g.platform.copy(), z.copy(), z.copy(), 0.0)

    def vector(self) -> np.ndarray:
        """φ, in the order of :data:`NAMES`."""
        return np.concatenate(
            [
                self.frame,
                self.tool,
                self.base.ravel(),
                self.platform.ravel(),
                self.offset,
                self.scale,
                [self.thermal],
            ]
        )

    @classmethod
    def from_vector(cls, phi) -> Parameters:
        phi = np.asarray(phi, dtype=float)
        if phi.shape != (len(NAMES),):
            raise ValueError(f"parameter vector: expected {len(NAMES)} values, got shape {phi.shape}")
        return cls(
            phi[0:6],
            phi[6:12],
            phi[12:30].reshape(6, 3),
            phi[30:48].reshape(6, 3),
            phi[48:54],
            phi[54:60],
            float(phi[60]),
        )

    def as_dict(self) -> dict[str, float]:
        return dict(zip(NAMES, (float(v) for v in self.vector())))

    def replace(self, **values: float) -> Parameters:
        """A copy with the named parameters (:data:`NAMES`) set."""
        phi = self.vector()
        for name, value in values.items():
            phi[NAMES.index(name)] = value
        return Parameters.from_vector(phi)

    def geometry(self, pivot=(0.0, 0.0, 0.0)) -> Geometry:
        """The joint centres as a :class:`Geometry` about ``pivot`` (µm)."""
        return Geometry(self.base, self.platform, np.asarray(pivot, dtype=float))

    def leg_lengths(self, commanded, zero_lengths, temperature=None) -> np.ndarray:
        """Real leg lengths l (n, 6) µm for commanded lengths λ (n, 6) µm: the model above,
        λ₀ = ``zero_lengths`` (6,) of the controller's geometry, T (n,) degC or None (T_ref)."""
        lam = np.asarray(commanded, dtype=float)
        dT = 0.0 if temperature is None else np.asarray(temperature, dtype=float)[..., None] - T_REF_DEGC
        return lam + self.offset + self.scale * (lam - zero_lengths) + self.thermal * lam * dT

    def commanded_lengths(self, lengths, zero_lengths, temperature=None) -> np.ndarray:
        """The inverse of :meth:`leg_lengths`: λ (n, 6) µm that gives real lengths ``lengths``."""
        l = np.asarray(lengths, dtype=float)
        dT = 0.0 if temperature is None else np.asarray(temperature, dtype=float)[..., None] - T_REF_DEGC
        return (l - self.offset + self.scale * zero_lengths) / (1.0 + self.scale + self.thermal * dT)
