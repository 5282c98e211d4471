"""A simulated 1-axis linear stage: a scale error, an offset and Gaussian noise on each reading."""

from __future__ import annotations

import zlib

import numpy as np

from calflow.errors import OptionError

DEFAULTS = {"scale_ppm": 150.0, "offset_um": 2.0, "noise_um": 0.05}


def check_options(seed=0, stream="", **options) -> dict:
    """The stage's options checked without building it; OptionError names the one that is wrong."""
    for key, value in options.items():
        if key not in DEFAULTS:
            raise OptionError(key, f"one of {sorted(DEFAULTS)}", value, unknown=True)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise OptionError(key, "a finite number", value)
        if key == "noise_um" and value < 0:
            raise OptionError(key, "a number >= 0", value)
    return {**DEFAULTS, **options, "seed": int(seed), "stream": str(stream)}


class LinearStage:
    joints = ("x",)
    sensors = ("meas_x",)
    thermometers = ()

    def __init__(self, **options):
        o = check_options(**options)
        self.scale, self.offset, self.noise = o["scale_ppm"] * 1e-6, o["offset_um"], o["noise_um"]
        self._rng = np.random.default_rng([o["seed"], zlib.crc32(o["stream"].encode())])
        self.t, self.x = 0.0, 0.0

    def move(self, command):
        self.x = float(command["x"])
        self.t += 0.5

    def wait(self, seconds):
        self.t += seconds

    def read(self):
        meas = (1 + self.scale) * self.x + self.offset + self.noise * self._rng.standard_normal()
        return {"time": self.t, "meas_x": meas}

    def truth(self):
        return {"rig": "linear_stage", "scale_ppm": self.scale * 1e6, "offset_um": self.offset}

    def close(self):
        pass


def linear_stage(**options) -> LinearStage:
    return LinearStage(**options)
