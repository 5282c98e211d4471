"""A small rig defined outside calflow, loaded through ``rig.factory`` in the tests.

It is a noise-free XYΘ robot with exactly the kinematics of Eq. (4.18) and a camera
point M, so identification on it must recover its parameters to round-off.
"""

from __future__ import annotations

import math


class ToyXYTheta:
    joints = ("x", "y", "theta")
    sensors = ("meas_x", "meas_y", "meas_theta")
    thermometers = ()

    def __init__(self, x_R=5000.0, y_R=3000.0, alpha=178.0, beta=0.2, camera=(1000.0, 1500.0)):
        self.p = (x_R, y_R, alpha, beta)
        self.camera = camera
        self.t = 0.0
        self.q = (0.0, 0.0, 0.0)
        self.moves = 0

    def move(self, command):
        self.q = (command["x"], command["y"], command["theta"])
        self.t += 1.0
        self.moves += 1

    def wait(self, seconds):
        self.t += seconds

    def read(self):
        x_R, y_R, a, b = self.p
        X, Y, th = self.q
        ra, rab, rt = math.radians(a), math.radians(a + b), math.radians(th)
        x_P = X * math.cos(ra) - Y * math.sin(rab) + x_R - x_R * math.cos(rt) - y_R * math.sin(rt)
        y_P = X * math.sin(ra) + Y * math.cos(rab) + y_R + x_R * math.sin(rt) - y_R * math.cos(rt)
        dx, dy = self.camera[0] - x_P, self.camera[1] - y_P
        return {
            "time": self.t,
            "meas_x": dx * math.cos(rt) - dy * math.sin(rt),
            "meas_y": dx * math.sin(rt) + dy * math.cos(rt),
            "meas_theta": th,
        }

    def close(self):
        pass


def open_toy(**options):
    return ToyXYTheta(**options)


class Slow:
    """Wraps a rig and spends real time in every read, so a test can kill it mid-run."""

    def __init__(self, inner, seconds):
        self._inner, self._seconds = inner, seconds
        self.joints, self.sensors, self.thermometers = inner.joints, inner.sensors, inner.thermometers
        self.replayable = getattr(inner, "replayable", False)

    def move(self, command):
        self._inner.move(command)

    def wait(self, seconds):
        self._inner.wait(seconds)

    def read(self):
        import time

        time.sleep(self._seconds)
        return self._inner.read()

    def close(self):
        self._inner.close()


def slow_simulated(seconds=0.004, **options):
    """The simulated XYΘ rig, slowed down (replayable: resumed by replaying its rows)."""
    from calflow.xytheta.stage.rig import simulated_xytheta

    options.setdefault("seed", 11)
    options.setdefault("stream", "identification")
    return Slow(simulated_xytheta(**options), seconds)


def slow_toy(seconds=0.004, **options):
    """The noise-free toy rig, slowed down (not replayable: resumed by continuing)."""
    return Slow(ToyXYTheta(**options), seconds)
