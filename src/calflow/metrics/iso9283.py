"""ISO 9283 pose accuracy AP and pose repeatability RP (thesis Sec. 3.2.1, Eq. 3.5-3.8).

All lengths are in one consistent unit chosen by the caller (calflow uses micrometres for
micro-robots and nanometres for nano-stages); every result is in that same unit.

Thesis erratum: Eq. (3.7) is printed as
``l_j = sqrt((x_j - x̄)^2 + (x_j - ȳ)^2 + (x_j - z̄)^2)``; the y and z terms must use the
j-th attained ``y_j`` and ``z_j`` (ISO 9283, 7.2.2).  This module implements the correct
``l_j = sqrt(sum_k (x_jk - x̄_k)^2)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["ISO9283Result", "ISO9283TestResult", "iso9283", "iso9283_test"]


def _finite(a: np.ndarray, name: str) -> np.ndarray:
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values; remove or fill them first")
    return a


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)  # own copy, so the caller's array stays writable
    a.flags.writeable = False
    return a


def _pose_arrays(command, attained) -> tuple[np.ndarray, np.ndarray]:
    """Validate one pose: return command (d,) and attained (n, d) as float arrays."""
    att = np.asarray(attained, dtype=float)
    cmd = np.asarray(command, dtype=float)
    if att.ndim == 1:  # d = 1 given as a plain series of n attained positions
        att = att[:, None]
    if att.ndim != 2:
        raise ValueError(
            f"attained must have shape (n, d) with d in 1..3 (or (n,) for d = 1); got shape {att.shape}"
        )
    n, d = att.shape
    if d not in (1, 2, 3):
        raise ValueError(f"attained has d = {d} coordinates per pose; ISO 9283 position needs d = 1, 2 or 3")
    if cmd.ndim == 0:
        cmd = cmd[None]
    if cmd.shape != (d,):
        raise ValueError(
            f"command must have shape ({d},) to match attained {att.shape}; got shape {cmd.shape}"
        )
    if n < 2:
        raise ValueError(
            f"ISO 9283 needs n >= 2 attained poses (RP uses a standard deviation with n - 1); got n = {n}"
        )
    return _finite(cmd, "command"), _finite(att, "attained")


@dataclass(frozen=True, eq=False)
class ISO9283Result:
    """ISO 9283 accuracy and repeatability of one command pose (same length unit as inputs).

    Attributes
    ----------
    ap : float
        Pose accuracy AP = ||G - O_c|| (Sec. 3.2.1), distance from the command pose O_c
        to the barycentre G of the attained positions.
    rp : float
        Pose repeatability RP = l̄ + 3 S_l, Eq. (3.5).
    ap_components : ndarray (d,)
        Per-axis accuracy AP_x, AP_y, AP_z = barycentre - command (signed).
    barycentre : ndarray (d,)
        G = (x̄, ȳ, z̄), mean of the attained positions.
    l : ndarray (n,)
        Distances l_j of each attained position to the barycentre, Eq. (3.7) (corrected).
    l_mean : float
        l̄, Eq. (3.6).
    s_l : float
        S_l (printed δ in the thesis), Eq. (3.8), sample standard deviation (n - 1) of l_j.
    n : int
        Number of attained poses.
    """

    ap: float
    rp: float
    ap_components: np.ndarray
    barycentre: np.ndarray
    l: np.ndarray
    l_mean: float
    s_l: float
    n: int


def iso9283(command, attained) -> ISO9283Result:
    """ISO 9283 pose accuracy AP and repeatability RP of one command pose.

    Parameters
    ----------
    command : array_like, shape (d,)
        Command pose O_c = (x_c, y_c, z_c) for d = 3 (fewer coordinates for d = 1, 2;
        a scalar is accepted for d = 1).  Any length unit.
    attained : array_like, shape (n, d), or (n,) for d = 1
        The n attained positions (x_j, y_j, z_j) measured by an external sensor after n
        visits of the same command pose.  Same unit as ``command``.  n >= 2.

    Returns
    -------
    ISO9283Result
        ``ap`` = sqrt(sum_k (x̄_k - x_ck)^2) (Sec. 3.2.1); ``rp`` = l̄ + 3 S_l, Eq. (3.5),
        with l̄ from Eq. (3.6), l_j = sqrt(sum_k (x_jk - x̄_k)^2) (Eq. (3.7), corrected: the
        thesis prints x_j in the y and z terms) and S_l from Eq. (3.8) with n - 1.
        Outputs are in the unit of the inputs.

    For d = 1 this reduces to the 1-D formulas of Eq. (3.13) and (3.14):
    AP = |x̄_m - x_T| and RP = (1/n) sum_i |x_mi - x̄_m| + 3σ.

    Raises
    ------
    ValueError
        Bad shapes, d not in 1..3, n < 2, or NaN/inf in the inputs.
    """
    cmd, att = _pose_arrays(command, attained)
    n = att.shape[0]
    barycentre = att.mean(axis=0)
    ap_components = barycentre - cmd
    ap = float(np.sqrt(np.sum(ap_components**2)))
    # Eq. (3.7), corrected: distance of each attained position to the barycentre.
    l = np.sqrt(np.sum((att - barycentre) ** 2, axis=1))
    l_mean = float(l.mean())  # Eq. (3.6)
    s_l = float(np.sqrt(np.sum((l - l_mean) ** 2) / (n - 1)))  # Eq. (3.8)
    rp = l_mean + 3.0 * s_l  # Eq. (3.5)
    return ISO9283Result(
        ap=ap,
        rp=rp,
        ap_components=_readonly(ap_components),
        barycentre=_readonly(barycentre),
        l=_readonly(l),
        l_mean=l_mean,
        s_l=s_l,
        n=n,
    )


@dataclass(frozen=True, eq=False)
class ISO9283TestResult:
    """ISO 9283 metrics of a test made of M command poses (Sec. 3.2.3, "Summary").

    Attributes
    ----------
    ap, rp : ndarray (M,)
        AP_i and RP_i of each command pose i (unit of the inputs).
    ap_max, rp_max : float
        AP = max_i AP_i and RP = max_i RP_i, the accuracy and repeatability of the test.
    poses : tuple of ISO9283Result
        Full per-pose results, in the order of ``commands``.
    """

    ap: np.ndarray
    rp: np.ndarray
    ap_max: float
    rp_max: float
    poses: tuple[ISO9283Result, ...]

    @property
    def m(self) -> int:
        """Number of command poses M."""
        return len(self.poses)


def iso9283_test(commands, attained: Sequence | np.ndarray) -> ISO9283TestResult:
    """Accuracy and repeatability of a test of M command poses: the maxima over poses.

    Thesis Sec. 3.2.3 ("Summary"): AP = max(AP_i), RP = max(RP_i), i = 1..M, with AP_i
    and RP_i from ISO 9283 (Eq. 3.5-3.8) at each pose.

    Parameters
    ----------
    commands : array_like, shape (M, d), or (M,) for d = 1
        The M command poses.  Any length unit.
    attained : array_like, shape (M, n, d), or a length-M sequence of (n_i, d) arrays
        (n_i may differ between poses; (n_i,) accepted for d = 1).  Same unit as commands.

    Returns
    -------
    ISO9283TestResult
        Per-pose ``ap``/``rp`` arrays and their maxima ``ap_max``/``rp_max`` (input unit).
    """
    cmds = np.asarray(commands, dtype=float)
    if cmds.ndim == 1:
        cmds = cmds[:, None]
    if cmds.ndim != 2 or cmds.shape[0] < 1:
        raise ValueError(f"commands must have shape (M, d) with M >= 1; got shape {np.shape(commands)}")
    per_pose = list(attained)  # iterates the first axis of an (M, n, d) array too
    if len(per_pose) != cmds.shape[0]:
        raise ValueError(
            f"attained has {len(per_pose)} poses but commands has M = {cmds.shape[0]}; give one set per command"
        )
    poses = []
    for i, (c, a) in enumerate(zip(cmds, per_pose)):
        try:
            poses.append(iso9283(c, a))
        except ValueError as exc:
            raise ValueError(f"pose {i}: {exc}") from None
    ap = np.array([p.ap for p in poses])
    rp = np.array([p.rp for p in poses])
    return ISO9283TestResult(
        ap=_readonly(ap),
        rp=_readonly(rp),
        ap_max=float(ap.max()),
        rp_max=float(rp.max()),
        poses=tuple(poses),
    )
