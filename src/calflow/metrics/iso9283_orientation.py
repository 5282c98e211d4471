"""ISO 9283 orientation accuracy AP_a, AP_b, AP_c and repeatability RP_a, RP_b, RP_c.

ISO 9283:1998, 7.2.1 and 7.2.2: for each rotation a, b, c about the x, y and z axes, the
accuracy is the difference between the mean of the n attained orientations and the commanded
one, ``AP_a = ā − a_c``, and the repeatability ``RP_a = ±3 S_a`` with the sample standard
deviation ``S_a = sqrt(Σ (a_j − ā)² / (n − 1))``. The orientations' unit (degree, rad) is the
caller's; every result is in it. Angles are small differences about the command, so they are
taken as given (no wrapping): a caller whose readings can cross ±180° unwraps them first.
The position counterparts AP_p, RP_l are :func:`calflow.metrics.iso9283.iso9283`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OrientationResult", "iso9283_orientation"]


@dataclass(frozen=True)
class OrientationResult:
    """Per rotation axis (a, b, c): signed accuracy ``ap`` (ā − a_c), its magnitude ``ap_abs``,
    the repeatability ``rp`` (3 S) and the mean attained orientation ``mean``."""

    ap: tuple[float, ...]
    rp: tuple[float, ...]
    mean: tuple[float, ...]
    n: int

    @property
    def ap_abs(self) -> tuple[float, ...]:
        return tuple(abs(v) for v in self.ap)


def iso9283_orientation(command, attained) -> OrientationResult:
    """AP_a, AP_b, AP_c and RP_a, RP_b, RP_c of one command pose (ISO 9283, 7.2.1, 7.2.2).

    ``command``: the commanded orientation (k,), k = 1..3 rotations; ``attained``: the n ≥ 2
    attained orientations (n, k), in the same unit. Raises ValueError on NaN, a shape mismatch
    or n < 2 (RP needs a standard deviation with n − 1).
    """
    cmd = np.atleast_1d(np.asarray(command, dtype=float))
    att = np.asarray(attained, dtype=float)
    if att.ndim == 1:
        att = att[:, None]
    if att.ndim != 2 or att.shape[1] != cmd.shape[0] or not 1 <= cmd.shape[0] <= 3:
        raise ValueError(
            f"attained must have shape (n, k) with k = 1..3 matching command {cmd.shape}; got {att.shape}"
        )
    if att.shape[0] < 2:
        raise ValueError(f"ISO 9283 needs n >= 2 attained orientations; got n = {att.shape[0]}")
    if not (np.all(np.isfinite(att)) and np.all(np.isfinite(cmd))):
        raise ValueError("command or attained contains NaN or infinite values; remove them first")
    mean = att.mean(axis=0)
    s = att.std(axis=0, ddof=1)
    return OrientationResult(
        ap=tuple(float(v) for v in mean - cmd),
        rp=tuple(float(3.0 * v) for v in s),
        mean=tuple(float(v) for v in mean),
        n=int(att.shape[0]),
    )
