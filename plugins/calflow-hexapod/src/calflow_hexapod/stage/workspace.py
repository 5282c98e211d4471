"""The hexapod's workspace as its controller checks it: per-axis travel and the legs' stroke.

PI's hexapod datasheets give the travel of each coordinate alone (H-811.I2: ±17 mm in X and
Y, ±6.5 mm in Z, ±10° about X and Y, ±21° about Z, :data:`calflow_hexapod.models.geometry.H811_TRAVEL`)
and note that the travel ranges of the coordinates are interdependent: a pose is reachable
when every leg stays within its stroke. The stroke used here is the largest change of any
leg over the six single-coordinate extremes of the datasheet travel, so every datasheet
travel is reachable alone and combined extremes are refused, as on the real controller
(``MOV`` → GCS error 7, :mod:`calflow_hexapod.stage.c887`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from calflow_hexapod.models.geometry import H811_TRAVEL, Geometry, h811
from calflow_hexapod.models.kinematics import inverse


@lru_cache(maxsize=1)
def _stroke() -> float:
    g = h811()
    extremes = np.concatenate([np.diag(H811_TRAVEL), -np.diag(H811_TRAVEL)])
    return float(np.abs(inverse(g, extremes) - g.zero_lengths).max())


def leg_stroke_um() -> float:
    """Half the legs' stroke (µm): each leg may change by this much from its zero-pose length."""
    return _stroke()


def reachable(
    poses, geometry: Geometry | None = None, travel=H811_TRAVEL, margin_um: float = 0.0
) -> np.ndarray:
    """True per pose (…, 6) (µm, degree, about ``geometry``'s pivot; default the nominal
    H-811-class geometry) inside the per-axis travel and every leg's stroke less ``margin_um``."""
    g = h811() if geometry is None else geometry
    poses = np.asarray(poses, dtype=float)
    inside = np.all(np.abs(poses) <= np.asarray(travel, dtype=float), axis=-1)
    legs = inverse(g, poses) - g.zero_lengths
    return inside & np.all(np.abs(legs) <= leg_stroke_um() - float(margin_um) + 1e-9, axis=-1)
