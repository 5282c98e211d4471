"""Plans of the nanopositioning campaigns (thesis Sec. 5.3.2, Fig. 5.8, 5.9, 5.21, 5.22).

Each pose: the command rises in ``rise_s`` (the rig's move), is held ``dwell_s``, and
the reading is the mean of the last ``average_last_s`` seconds of the dwell (Sec. 5.3.2).
"""

from __future__ import annotations

import numpy as np

from calflow.plan import Plan

TESTS = ("no_calibration", "adaptive_kmz", "single")  # Sec. 5.3.3, in the thesis's repeating order
VALIDATION_2D = np.array(
    [[0, 0], [45, 45], [75, 15], [75, 75], [15, 75], [15, 15]], dtype=float
)  # Sec. 5.4.2


def _there_and_back(positions) -> tuple[np.ndarray, np.ndarray]:
    """Forward through ``positions`` then backward without repeating the turning point."""
    p = np.asarray(positions, dtype=float)
    back = p[-2::-1]
    return np.concatenate([p, back]), np.concatenate([np.ones(len(p), int), -np.ones(len(back), int)])


def sweep_1d(
    name: str, positions, cycles: int, dwell_s: float, average_last_s: float = 5.0, start_s: float = 0.0
) -> Plan:
    """Forward and backward cycles over ``positions`` (µm), Fig. 5.8 / 5.9."""
    one, dirs = _there_and_back(positions)
    n = len(one)
    x = np.tile(one, cycles)
    return Plan(
        name=name,
        commands={"x": x},
        targets={"x": x.copy()},
        pose=np.tile(np.arange(n), cycles),
        cycle=np.repeat(np.arange(cycles), n),
        direction=np.tile(dirs, cycles),
        dwell_s=dwell_s,
        average_last_s=average_last_s,
        start_s=start_s,
    )


def training_1d(
    positions=range(0, 481, 30),
    cycles: int = 67,
    dwell_s: float = 25.0,
    average_last_s: float = 5.0,
    start_s: float = 0.0,
) -> Plan:
    """Training run: 0:30:480 µm, forward and backward, 25 s dwell, 67 cycles (Sec. 5.3.2)."""
    return sweep_1d("training", positions, cycles, dwell_s, average_last_s, start_s)


def validation_1d(
    positions=range(0, 481, 80),
    cycles: int = 15,
    dwell_s: float = 19.0,
    tests: int = 96,
    order=TESTS,
    average_last_s: float = 5.0,
    start_s: float = 0.0,
) -> Plan:
    """Validation: tests of ``cycles`` cycles over 0:80:480 µm, repeating ``order`` (Sec. 5.3.3).

    With the rise of 4 s a pose takes 23 s and a 15-cycle test 1.25 h, as in the thesis;
    96 tests make five days. ``targets`` hold the task-space targets; the commands are
    computed at run time by each test's model. Row attribute ``test`` numbers the tests
    and ``mode`` indexes ``order``.
    """
    one = sweep_1d("validation", positions, cycles, dwell_s, average_last_s)
    per = len(one)
    plan = sweep_1d("validation", positions, cycles * tests, dwell_s, average_last_s, start_s)
    plan.cycle = np.tile(one.cycle, tests)
    plan.extra = {
        "test": np.repeat(np.arange(tests), per),
        "mode": np.repeat(np.arange(tests) % len(order), per),
    }
    plan.modes = tuple(order)
    return plan


def metrology_1d(
    positions=range(0, 481, 80), cycles: int = 15, dwell_s: float = 19.0, average_last_s: float = 5.0
) -> Plan:
    """The metrology-room run: the validation trajectory without calibration (Sec. 5.3.3)."""
    return sweep_1d("metrology", positions, cycles, dwell_s, average_last_s)


def training_2d(
    step_um: float = 10.0,
    stop_um: float = 80.0,
    cycles: int = 12,
    dwell_s: float = 10.0,
    average_last_s: float = 5.0,
    start_s: float = 0.0,
    start_um: float = 0.0,
) -> Plan:
    """Training grid start_um:step_um:stop_um in x and y (thesis 0:10:80 µm, 81 poses per cycle),
    back to start each cycle (Fig. 5.21)."""
    g = np.arange(start_um, stop_um + 1e-9, step_um)
    X, Y = np.meshgrid(g, g, indexing="ij")
    Y[1::2] = Y[1::2, ::-1]  # raster: y sweeps up on even x columns, down on odd ones
    return training_points_2d(
        np.column_stack([X.ravel(), Y.ravel()]), cycles, dwell_s, average_last_s, start_s
    )


def training_points_2d(
    points, cycles: int = 12, dwell_s: float = 10.0, average_last_s: float = 5.0, start_s: float = 0.0
) -> Plan:
    """Training over ``points`` (n, 2) µm in the given order, back to the first each cycle
    (Fig. 5.21's protocol on any set of positions, e.g. a designed one)."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    x, y = np.tile(p[:, 0], cycles), np.tile(p[:, 1], cycles)
    return Plan(
        name="training",
        commands={"x": x, "y": y},
        targets={"x": x.copy(), "y": y.copy()},
        pose=np.tile(np.arange(n), cycles),
        cycle=np.repeat(np.arange(cycles), n),
        direction=np.zeros(n * cycles, dtype=int),
        dwell_s=dwell_s,
        average_last_s=average_last_s,
        start_s=start_s,
    )


def validation_2d(
    points=VALIDATION_2D,
    cycles: int = 20,
    tests: int = 16,
    dwell_s: float = 20.0,
    order=("no_calibration", "single"),
    average_last_s: float = 5.0,
    start_s: float = 0.0,
) -> Plan:
    """Validation: P0 → P1 … P5 in turn and back to P0 each cycle (Fig. 5.22), tests alternating ``order``."""
    p = np.asarray(points, dtype=float)
    m = len(p)
    rows = np.tile(p, (cycles * tests, 1))
    per = m * cycles
    return Plan(
        name="validation",
        commands={"x": rows[:, 0].copy(), "y": rows[:, 1].copy()},
        targets={"x": rows[:, 0].copy(), "y": rows[:, 1].copy()},
        pose=np.tile(np.arange(m), cycles * tests),
        cycle=np.tile(np.repeat(np.arange(cycles), m), tests),
        direction=np.zeros(len(rows), dtype=int),
        dwell_s=dwell_s,
        average_last_s=average_last_s,
        start_s=start_s,
        extra={
            "test": np.repeat(np.arange(tests), per),
            "mode": np.repeat(np.arange(tests) % len(order), per),
        },
        modes=tuple(order),
    )


def step_response(
    steps_um,
    cycles: int = 3,
    base_um=(0.0,),
    record_s: float = 0.05,
    rate_hz: float = 1000.0,
    attained_last_s: float = 0.01,
    start_s: float = 0.0,
) -> Plan:
    """Recorded steps for ISO 9283 stabilisation time and overshoot (clauses 7.5, 7.6).

    Each cycle, for each step s of ``steps_um`` (µm, > 0): from ``base_um`` (one value per
    joint) a step of +s along the first joint (direction +1) and back to the base
    (direction -1), each move recorded for ``record_s`` s at ``rate_hz`` from its start; the
    attained position is the mean of the record's last ``attained_last_s`` s. Poses 2k and
    2k + 1 are the step k out and back; the standard averages over (at least) 3 cycles.
    """
    steps = np.asarray(steps_um, dtype=float)
    base = np.asarray(base_um, dtype=float)
    per = np.repeat(base[None, :], 2 * steps.size, axis=0)
    per[0::2, 0] += steps
    rows = np.tile(per, (cycles, 1))
    n = len(rows)
    return Plan(
        name="step_response",
        commands={j: rows[:, k].copy() for k, j in enumerate(("x", "y")[: base.size])},
        targets={j: rows[:, k].copy() for k, j in enumerate(("x", "y")[: base.size])},
        pose=np.tile(np.arange(2 * steps.size), cycles),
        cycle=np.repeat(np.arange(cycles), 2 * steps.size),
        direction=np.tile(np.array([1, -1] * steps.size), cycles),
        dwell_s=record_s,
        average_last_s=attained_last_s,
        start_s=start_s,
        extra={"record_s": np.full(n, float(record_s)), "record_rate_hz": np.full(n, float(rate_hz))},
    )
