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
