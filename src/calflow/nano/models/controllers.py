"""Run-time controllers of validation runs: the command of each row from a calibration
model and the latest reading (thesis Fig. 5.3 and 5.4).

* no calibration: the command is the target;
* single model, Eq. (5.3): the command from the target and the thermocouples read last;
* adaptive model with kilometre-zero, Eq. (5.6): at the start of each test the stage
  visits the KMZ and the reading there sets λ_KMZ for the test (Sec. 5.2.4);
* 2-DoF model, Eq. (5.10).

Controllers only see readings, never a simulator's truth.
"""

from __future__ import annotations

import numpy as np

from calflow.data.io import open_dataset
from calflow.errors import CalflowError
from calflow.plan import Plan


class NanoValidation:
    """Commands of a nano validation run, test by test in the plan's order of modes."""

    needs_initial_reading = True

    def __init__(self, plan: Plan, models: dict, thermometers: tuple[str, ...], kmz_command_um: float = 0.0):
        self.plan, self.models, self.thermometers = plan, models, thermometers
        self.axes = tuple(plan.commands)
        self.kmz_command_um = kmz_command_um
        self.last: dict = {}
        self.kmz = None
        missing = {m for m in plan.modes if m != "no_calibration"} - set(models)
        if missing:
            raise CalflowError(f"validation: tests {sorted(missing)} need their model files (--model)")

    def _temperatures(self):
        return np.array([self.last[t] for t in self.thermometers], dtype=float)

    def observe(self, i: int, reading: dict) -> None:
        self.last = reading
        if "kmz_measured" in reading:
            from calflow.nano.models.kmz import KMZReading

            self.kmz = KMZReading(
                reading["kmz_command"],
                reading["kmz_measured"],
                np.array([reading[f"kmz_{t}"] for t in self.thermometers]),
                reading["kmz_time"],
            )

    def command(self, i: int, visit) -> tuple[dict[str, float], dict]:
        plan = self.plan
        mode = plan.modes[int(plan.extra["mode"][i])]
        target = np.array([plan.targets[a][i] for a in self.axes])
        extra: dict = {}
        if mode == "no_calibration":
            q = target
        elif mode == "adaptive_kmz":
            first = i == 0 or plan.extra["test"][i] != plan.extra["test"][i - 1]
            if first:  # Sec. 5.2.4: reach the kilometre-zero and record the sensor
                at = visit({"x": self.kmz_command_um})
                extra = {
                    "kmz_time": at["time"],
                    "kmz_command": self.kmz_command_um,
                    "kmz_measured": at["meas_x"],
                    **{f"kmz_{t}": at[t] for t in self.thermometers},
                }
                self.observe(i, {**at, **extra})
            q = np.atleast_1d(self.models[mode].command(target[0], self._temperatures(), reference=self.kmz))
        elif len(self.axes) == 2:
            q = np.ravel(self.models[mode].command(target[None, :], self._temperatures()[None, :]))
        else:
            q = np.atleast_1d(self.models[mode].command(target[0], self._temperatures()))
        return {a: float(v) for a, v in zip(self.axes, q)}, extra


def nano_validation_controller(plan: Plan, model_paths: list[str], campaign: dict) -> NanoValidation:
    """The controller of a nano validation run, with the models of the given files."""
    from calflow.nano.models.registry import model_from_dataset

    kinds = {"single": "single", "two_dof": "single", "adaptive_kmz": "adaptive_kmz"}
    models = {}
    for path in model_paths:
        ds = open_dataset(path, kind="model")
        kind = ds.attrs.get("model")
        if kind not in kinds:
            raise CalflowError(f"{path}: attribute 'model': expected one of {sorted(kinds)}, got {kind!r}")
        models[kinds[kind]] = model_from_dataset(ds)
    thermometers = tuple(f"T{k + 1}" for k in range(4))
    return NanoValidation(plan, models, thermometers, campaign["validation"].get("kmz_command_um", 0.0))
