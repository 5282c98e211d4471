"""Plans of the hexapod campaign: identification poses, held-out targets, ISO 9283 cycles.

Commands are the controller's pose axes ``x y z`` (µm) and ``u v w`` (degree) about its
pivot. *Targets* are poses of the measured target (the tracker's probe) in the measurement
frame — what the instrument reads — so a validation compares readings with targets without
any model's frames. A model commands a target through its inverse
(:func:`calflow_hexapod.models.calibration.command`); held-out and ISO 9283 targets are the readings
the campaign's nominal model predicts for drawn commands
(:func:`calflow_hexapod.models.calibration.predict`), the same targets for every model, drawn with a margin of the legs' stroke
(:data:`MARGIN_UM`) so that every model's command for them stays reachable.
"""

from __future__ import annotations

import numpy as np

from calflow.identification.design import latin_hypercube
from calflow.plan import Plan
from calflow_hexapod.models.geometry import AXES, H811_TRAVEL, Geometry, h811
from calflow_hexapod.models.ladder import Parameters
from calflow_hexapod.stage.workspace import reachable


def _plan(name: str, q: np.ndarray, targets: np.ndarray | None = None, cycle=None, pose=None, **kw) -> Plan:
    n = len(q)
    return Plan(
        name=name,
        commands={a: q[:, k] for k, a in enumerate(AXES)},
        pose=np.arange(n) if pose is None else np.asarray(pose),
        cycle=np.zeros(n, dtype=int) if cycle is None else np.asarray(cycle),
        direction=np.zeros(n, dtype=int),
        targets={} if targets is None else {a: targets[:, k] for k, a in enumerate(AXES)},
        **kw,
    )


def workspace_poses(
    n: int, fraction: float, rng: np.random.Generator, travel=H811_TRAVEL, margin_um: float = 0.0
) -> np.ndarray:
    """``n`` reachable command poses (n, 6): a Latin hypercube over ± ``fraction`` of the
    datasheet travel per axis (McKay et al. 1979, :func:`calflow.identification.design.latin_hypercube`),
    poses the legs cannot reach with ``margin_um`` to spare (:func:`calflow_hexapod.stage.workspace.reachable`)
    replaced by fresh draws of the same hypercube size until ``n`` are reachable."""
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction of the travel: expected a number in (0, 1], got {fraction}")
    half = fraction * np.asarray(travel, dtype=float)
    out = np.empty((0, 6))
    for _ in range(100):
        q = latin_hypercube(rng, max(n, 1), -half, half)
        out = np.vstack([out, q[reachable(q, margin_um=margin_um)]])
        if len(out) >= n:
            return out[:n]
    raise ValueError(f"no {n} reachable poses within {fraction} of the travel")


def identification(n_poses: int, fraction: float, seed: int, dwell_s: float = 1.0) -> Plan:
    """Home (the zero pose), then ``n_poses`` reachable poses over the workspace from their own
    random stream (:func:`workspace_poses`)."""
    if n_poses < 2:
        raise ValueError(f"identification.poses: expected at least 2, got {n_poses}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6_0]))
    q = np.vstack([np.zeros(6), workspace_poses(int(n_poses), fraction, rng)])
    return _plan("identification", q, dwell_s=dwell_s)


def target_of(commands, nominal: Parameters, controller: Geometry | None = None) -> np.ndarray:
    """Targets (n, 6): the readings the ``nominal`` parameters predict for commands (n, 6)."""
    from calflow_hexapod.models.calibration import predict  # xarray: not at the campaign's load

    return predict(nominal, h811() if controller is None else controller, np.atleast_2d(commands))


MARGIN_UM = 1000.0  # leg stroke kept free around held-out and ISO 9283 targets (µm)


def heldout_targets(
    n_targets: int, fraction: float, nominal: Parameters, seed: int, margin_um: float = MARGIN_UM
) -> np.ndarray:
    """Held-out validation targets (n, 6) in the measurement frame: command poses drawn
    continuously from their own random stream over ± ``fraction`` of the travel (never an
    identification pose), mapped by the campaign's nominal model (:func:`target_of`).

    Reaching a target in the instrument's frame moves the platform by the instrument's
    misalignment, which the nominal model does not know (tenths of a millimetre and of a
    degree for a frame set up on the base's features and a probe mounted by hand; the legs
    move by about as much): each drawn pose keeps ``margin_um`` of every leg's stroke free,
    so every model's command for it stays inside the workspace."""
    if n_targets < 1:
        raise ValueError(f"validation.heldout.targets: expected at least 1, got {n_targets}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 9_283]))
    return target_of(workspace_poses(int(n_targets), fraction, rng, margin_um=margin_um), nominal)


def iso9283_commands(fraction: float, orientation_deg=(0.0, 0.0, 0.0), travel=H811_TRAVEL) -> np.ndarray:
    """The five poses P1–P5 of ISO 9283:1998 Sec. 6.8.3 (n = 5, 6) as commands: P1 at the centre
    of the test cube (± ``fraction`` of the X, Y, Z travel), P2–P5 on the diagonals of its plane
    C1–C2–C7–C8 at 10 % of the diagonal's length from the corners; all at ``orientation_deg``."""
    h = fraction * np.asarray(travel[:3], dtype=float)
    corners = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, 1], [-1, 1, 1]], dtype=float) * h  # C1 C2 C7 C8
    pts = np.vstack([np.zeros(3), 0.8 * corners])
    q = np.column_stack([pts, np.tile(np.asarray(orientation_deg, dtype=float), (5, 1))])
    if not reachable(q, margin_um=MARGIN_UM).all():
        raise ValueError(
            f"iso9283.fraction: the test cube of {fraction} of the travel at {list(orientation_deg)} degree "
            f"leaves less than {MARGIN_UM:g} µm of a leg's stroke free; expected a smaller cube"
        )
    return q


def validation(
    inverse_of, targets, cycles: int, dwell_s: float = 1.0, name: str = "validation_heldout"
) -> Plan:
    """ISO 9283 cycles: home (pose 0), then ``cycles`` visits of the targets (poses 1..m) in
    sequence, each commanded through the model's inverse (``inverse_of(targets) -> commands``),
    as the XYΘ validation (ISO 9283:1998 Sec. 7.2.1: the poses visited in turn, cycle by cycle)."""
    if cycles < 2:
        raise ValueError(f"validation cycles: expected at least 2, got {cycles}")
    t = np.asarray(targets, dtype=float)
    m = len(t)
    tt = np.tile(t, (cycles, 1))
    q = np.vstack([np.zeros(6), np.tile(inverse_of(t), (cycles, 1))])
    targets_rows = np.vstack([np.full((1, 6), np.nan), tt])
    return _plan(
        name,
        q,
        targets_rows,
        cycle=np.concatenate([[0], np.repeat(np.arange(cycles), m)]),
        pose=np.concatenate([[0], np.tile(np.arange(1, m + 1), cycles)]),
        dwell_s=dwell_s,
    )
