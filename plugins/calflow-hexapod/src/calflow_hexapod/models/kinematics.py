"""Inverse and forward kinematics of a 6-6 hexapod (Stewart–Gough platform).

Inverse kinematics is closed form: leg i joins the base joint b_i to the platform joint p_i
moved by the pose (:mod:`calflow_hexapod.models.geometry`), so its length is

    l_i = ‖R (p_i − c) + c + t − b_i‖        (Merlet, *Parallel Robots*, 2nd ed. 2006, Sec. 4.1)

vectorised over any number of poses. Forward kinematics (leg lengths → pose) has no closed
form for the general 6-6 platform (up to 40 assembly modes); it is solved by Newton's method on
the pose coordinates with the analytic Jacobian ∂l/∂pose (Merlet Sec. 4.2 and 5.3), started
from the zero pose or a given pose, and checked: a leg-length set whose Newton iteration does
not bring every leg to within ``tol_um`` raises :class:`ForwardKinematicsError` naming how
many sets failed and by how much, instead of returning a wrong pose.
"""

from __future__ import annotations

import numpy as np

from calflow.errors import CalflowError
from calflow_hexapod.models.geometry import Geometry, rotation, rotation_derivatives

#: Newton stops when every leg's length is within this (µm) of its target.
TOL_UM = 1e-7
#: ... and gives up after this many iterations.
MAX_ITER = 30


class ForwardKinematicsError(CalflowError):
    """Newton's method found no pose for some leg-length sets (outside the workspace, or too
    near a singularity or another assembly mode for the start given)."""


def _legs(geometry: Geometry, pose: np.ndarray):
    """Leg vectors d_i = x_i − b_i (n, 6, 3) µm, rotation R (n, 3, 3) and p_i − c (6, 3)."""
    R = rotation(pose[:, 3], pose[:, 4], pose[:, 5])
    arm = geometry.platform - geometry.pivot
    x = np.einsum("nab,ib->nia", R, arm) + (geometry.pivot + pose[:, :3])[:, None, :]
    return x - geometry.base, R, arm


def inverse(geometry: Geometry, pose) -> np.ndarray:
    """Leg lengths l (…, 6) µm of poses (…, 6) (X Y Z µm, U V W degree) about the geometry's pivot."""
    pose = np.asarray(pose, dtype=float)
    flat = pose.reshape(-1, 6)
    d, _, _ = _legs(geometry, flat)
    return np.linalg.norm(d, axis=-1).reshape(pose.shape[:-1] + (6,))


def jacobian(geometry: Geometry, pose) -> np.ndarray:
    """∂l_i/∂(X, Y, Z, U, V, W) (…, 6, 6): µm per µm and µm per degree.

    ∂l_i/∂t = n_iᵀ and ∂l_i/∂U = n_iᵀ (∂R/∂U)(p_i − c), n_i the unit vector of leg i: the rows
    of the inverse Jacobian of the platform (Merlet 2006, Sec. 5.3)."""
    pose = np.asarray(pose, dtype=float)
    flat = pose.reshape(-1, 6)
    d, _, arm = _legs(geometry, flat)
    n = d / np.linalg.norm(d, axis=-1, keepdims=True)
    dR = rotation_derivatives(flat[:, 3], flat[:, 4], flat[:, 5])  # (3, n, 3, 3)
    rot = np.einsum("nia,knab,ib->nik", n, dR, arm)
    return np.concatenate([n, rot], axis=-1).reshape(pose.shape[:-1] + (6, 6))


def forward(
    geometry: Geometry, lengths, start=None, tol_um: float = TOL_UM, max_iter: int = MAX_ITER
) -> np.ndarray:
    """Poses (…, 6) (µm, degree) whose legs have ``lengths`` (…, 6) µm, by Newton's method.

    ``start`` (broadcast to the poses; default the zero pose) selects the assembly mode. Raises
    :class:`ForwardKinematicsError` when any set does not converge within ``max_iter``
    iterations to ``tol_um`` on every leg (singular Jacobian, no real solution, divergence).
    """
    lengths = np.asarray(lengths, dtype=float)
    target = lengths.reshape(-1, 6)
    n = target.shape[0]
    q = (
        np.zeros((n, 6))
        if start is None
        else np.broadcast_to(np.asarray(start, dtype=float), lengths.shape).reshape(-1, 6).copy()
    )
    err = np.full(n, np.inf)
    active = np.all(np.isfinite(target), axis=1)
    failed = ~active
    for _ in range(max_iter):
        if not active.any():
            break
        idx = np.flatnonzero(active)
        f = inverse(geometry, q[idx]) - target[idx]
        err[idx] = np.max(np.abs(f), axis=1)
        done = err[idx] <= tol_um
        active[idx[done]] = False
        idx, f = idx[~done], f[~done]
        if idx.size == 0:
            break
        J = jacobian(geometry, q[idx])
        cond = np.linalg.cond(J)
        singular = ~np.isfinite(cond) | (cond > 1e12)
        failed[idx[singular]] = True
        active[idx[singular]] = False
        idx, f, J = idx[~singular], f[~singular], J[~singular]
        if idx.size:
            q[idx] -= np.linalg.solve(J, f[..., None])[..., 0]
            bad = ~np.all(np.isfinite(q[idx]), axis=1) | (
                np.abs(q[idx, 4]) > 89.0
            )  # V = ±90°: U and W lose meaning
            failed[idx[bad]] = True
            active[idx[bad]] = False
    failed |= active  # still iterating after max_iter
    if failed.any():
        worst = err[failed]
        worst = float(np.max(worst[np.isfinite(worst)])) if np.isfinite(worst).any() else float("nan")
        raise ForwardKinematicsError(
            f"forward kinematics: Newton's method did not converge for {int(failed.sum())} of {n} leg-length sets "
            f"(largest leg mismatch {worst:.3g} µm after {max_iter} iterations, tolerance {tol_um:g} µm): "
            "the lengths are outside the workspace or near a singularity"
        )
    return q.reshape(lengths.shape[:-1] + (6,))
