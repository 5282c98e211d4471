"""Plans: what a run does — which poses, in which order, how many cycles, dwell times."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Plan:
    """A sequence of settled poses to visit.

    ``commands`` maps each joint to its command per row (µm or degree). ``targets``
    maps axes to task-space targets per row (NaN where a row has none). ``pose``,
    ``cycle`` and ``direction`` index the rows as in the run dataset.
    """

    name: str
    commands: dict[str, np.ndarray]
    pose: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    targets: dict[str, np.ndarray] = field(default_factory=dict)
    dwell_s: float = 1.0
    average_last_s: float | None = None  # reading = mean of the dwell's last seconds (streams)
    start_s: float = 0.0  # campaign time at which the run starts (s)
    extra: dict[str, np.ndarray] = field(default_factory=dict)  # more per-row indices (test, mode)
    modes: tuple[str, ...] = ()  # names of the values of extra["mode"]

    def __post_init__(self) -> None:
        n = len(self.pose)
        for name, values in {**self.commands, **self.targets, **self.extra}.items():
            if len(values) != n:
                raise ValueError(f"plan {self.name!r}: {name} has {len(values)} rows, expected {n}")

    def __len__(self) -> int:
        return len(self.pose)

    def row(self, i: int) -> dict[str, float]:
        """The joint command of row ``i``."""
        return {joint: float(values[i]) for joint, values in self.commands.items()}


@dataclass
class Acquisition:
    """What ``calflow acquire`` runs: a plan, the run's name, and how to command it.

    A family's plan builder (:mod:`calflow.family`) returns one. ``run_id`` names the run
    for the rig (its noise stream, its replayed recording); ``model`` is the model whose
    inverse commands the run, if any; ``controller`` computes commands from live readings
    (run-time compensation, :func:`calflow.acquisition.runner.acquire`); ``attrs`` are extra
    attributes of the run dataset; ``runner``, with ``acquire``'s signature, replaces it (e.g.
    :func:`calflow.acquisition.recorded_moves.acquire_recorded_moves`).
    """

    plan: Plan
    run_id: str
    model: str | None = None
    controller: object | None = None
    attrs: dict[str, object] = field(default_factory=dict)
    runner: object | None = None  # acquires the plan instead of calflow.acquisition.runner.acquire
