"""Simulated 1-DoF and 2-DoF nanopositioning rigs (thesis Chapter 5, Sec. 5.2-5.4).

Both rigs follow the rig protocol (docs/rigs.md: ``move``/``wait``/``read``/``close``) on a
virtual clock, plus ``stream`` (raw high-rate samples of a dwell), ``truth()``,
``true_position()`` and ``effect_terms()`` for tests and the summary step. Lengths in um,
temperatures in degC, time in s.

A reading of sensor k is the commanded position plus one named term per effect (geometry,
coupling, the piezo's and the sensor's, thermal, the air's, installation, the drift the
thermocouples do not see: :data:`calflow.nano.stage.options.EFFECTS`, with their sources,
each switched off in ``options``), plus per-move repeatability, the closed loop's step
response (``record_move`` sees it), the settling tail, white interferometer noise and the
laser's wavelength instability (noise), quantised to the interferometer resolution (0.3 nm).
Temperatures come from the lumped thermal network (:mod:`calflow.nano.stage.thermal_network`)
driven by the room profile; thermocouple j reads its own node plus its offset, the heat
sources' share and its own errors (calflow.nano.stage.unseen) and noise, quantised to 1 mK. Thermal terms are relative to the node temperatures at campaign time 0,
when the interferometer was zeroed (Sec. 5.3.1). The world (room, weather, walk) is fixed by
``world_seed`` and anchored in campaign time; ``seed`` drives only noise and repeatability.
"""

from __future__ import annotations

import numpy as np

from calflow.nano.stage.piezo import loop_residual_pct
from calflow.nano.stage.rig.base import NanoRig

__all__ = ["Nano1DRig", "Nano2DRig", "nano1d", "nano2d"]


class Nano1DRig(NanoRig):
    """P-625.1CD-like single-axis stage, 0-500 um, two interferometer beams (Sec. 5.3.1).

    Geometry of ``meas_x``: minus the cubic of Table 5.1 (the identified inverse model's
    deviation from q = x, two critical points inside the stroke, Fig. 5.1 a), unscaled.
    ``meas_y`` is the coupling seen by the second beam, ~75 nm over the stroke (Fig. 5.1 b).
    """

    joints = ("x",)
    _NAME = "nano1d"
    _EXTRA = {
        "stroke_um": 500.0,
        "coupling_y_nm": 75.0,
        "stage_coeff_um_per_c": (-1.5, 0.0),
        "loop_residual_pct": loop_residual_pct(10.0, 500.0),
    }
    _REP_FACTOR = (1.0, 0.25)
    _AXIS = (0, None)
    # um, s = x/500 um: -(Table 5.1 cubic - x) = -(2.454e-8 x^3 - 2.167e-5 x^2 + 0.005 x)
    _POLY = (0.0, -2.5, 5.4175, -3.0675)
    _COUPLING = (1.3, -0.3, 0.004)  # shape s(1.3 - 0.3 s), + 4 nm sin(2 pi s)

    def _geometry(self, cmds):
        s = cmds[0] / self.options["stroke_um"]
        p0, p1, p2, p3 = self._POLY
        g = self.options["geometric_scale"] * (p0 + s * (p1 + s * (p2 + s * p3)))
        c1, c2, wig = self._COUPLING
        y = 1e-3 * self.options["coupling_y_nm"] * s * (c1 + c2 * s) + wig * np.sin(2 * np.pi * s) * (
            self.options["coupling_y_nm"] > 0
        )
        return {"geometry": [g, 0.0], "coupling": [0.0, y]}

    def _geometry_truth(self):
        return {
            "meas_x": "geometric_scale * sum_i poly[i] s^i, s = x/stroke",
            "meas_y": "coupling_y*s*(c[0] + c[1] s) + c[2] sin(2 pi s)",
            "poly_um": list(self._POLY),
            "coupling": list(self._COUPLING),
        }


class Nano2DRig(NanoRig):
    """80 x 80 um two-axis nanocube (Sec. 5.4): per-axis cubic errors, cross-axis coupling.

    Each axis has a scale error and a cubic, and couples into the other through a linear
    term (axis non-orthogonality), a quadratic and a bilinear ``x*y`` term that Eq. 5.10
    cannot represent. The thesis gives only the resulting accuracy (1.2-1.4 um without
    calibration), not the shape: these coefficients are an assumption.
    """

    joints = ("x", "y")
    _NAME = "nano2d"
    _EXTRA = {
        "stroke_um": 80.0,
        "coupling_scale": 1.0,
        "stage_coeff_um_per_c": (-1.5, -1.5),
        "loop_residual_pct": loop_residual_pct(10.0, 80.0),
    }
    _REP_FACTOR = (1.0, 1.0)
    _AXIS = (0, 1)
    # own axis (um): scale*s + cubic*T3(2s-1) + quad*(2s-1)^2
    _OWN = {"meas_x": (0.30, 0.10, 0.03), "meas_y": (-0.20, 0.08, -0.03)}
    # other axis (um): lin*o + bilinear*s*o + quad*o^2, o = other axis / stroke
    _CROSS = {"meas_x": (0.75, 0.10, -0.06), "meas_y": (-0.55, 0.08, 0.05)}

    def _geometry(self, cmds):
        L = self.options["stroke_um"]
        G, C = self.options["geometric_scale"], self.options["coupling_scale"]
        geo, cpl = [], []
        for k, name in enumerate(self.sensors):
            s, o = cmds[k] / L, cmds[1 - k] / L
            u = 2 * s - 1
            a, b, c = self._OWN[name]
            lin, bil, quad = self._CROSS[name]
            geo.append(G * (a * s + b * (4 * u**3 - 3 * u) + c * u * u))
            cpl.append(C * (lin * o + bil * s * o + quad * o * o))
        return {"geometry": geo, "coupling": cpl}

    def _geometry_truth(self):
        return {
            "own_axis": "a s + b T3(2s-1) + c (2s-1)^2, s = own/stroke",
            "cross_axis": "lin o + bilinear s o + quad o^2, o = other/stroke",
            "own_um": {k: list(v) for k, v in self._OWN.items()},
            "cross_um": {k: list(v) for k, v in self._CROSS.items()},
        }


def nano1d(**options) -> Nano1DRig:
    """Factory of the simulated 1-DoF stage; options and defaults in ``_COMMON``/``_EXTRA``."""
    return Nano1DRig(**options)


def nano2d(**options) -> Nano2DRig:
    """Factory of the simulated 2-DoF stage; options and defaults in ``_COMMON``/``_EXTRA``."""
    return Nano2DRig(**options)


def check_nano1d(**options) -> dict:
    """The 1-DoF stage's options checked with its defaults (the family's option check)."""
    return Nano1DRig.check(**options)


def check_nano2d(**options) -> dict:
    """The 2-DoF stage's options checked with its defaults (the family's option check)."""
    return Nano2DRig.check(**options)


nano1d.check_options = check_nano1d  # the options with the rig's defaults (designed plans read them)
nano2d.check_options = check_nano2d
