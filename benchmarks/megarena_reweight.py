"""calflow's Megarena pose over the central half with other weights than the lobe's power — a
measurement of a possible decoder change, made without editing the decoder.

calflow fits each lobe's plane by least squares weighted by the field's squared amplitude |z|²
(calflow.instruments.pattern.phase, step 6). On an undistorted frame the weights only change the
noise; on a distorted one they change *which* mean lattice the plane is, and |z|² follows the
code's rows and columns left out, so the plane moves with the part of the code in view. Here
the central-half refit (``PhaseFitter.refit``, what ``decode(…, fit_region < 1)`` calls) is
given ``keep`` = w/|z|² per lobe, so that its weights become w:

* ``uniform``: w constant — the library's weights (Eq. (1) of megarena_estimand);
* ``smoothed:N``: w = |z|² smoothed by a Gaussian of N periods — the illumination's and the
  focus's fall-off kept, the code's rows and columns smoothed away.

The envelope's regressors and everything else of the decoder are as they are.
"""

from __future__ import annotations

import contextlib

import numpy as np

from calflow.instruments.pattern.phase import PhaseFitter


def _target(fitter: PhaseFitter, power: np.ndarray, mode: str) -> np.ndarray:
    if mode == "uniform":
        return np.full_like(power, np.median(power))
    if mode.startswith("smoothed:"):
        from scipy.ndimage import gaussian_filter

        periods = float(mode.split(":", 1)[1])
        grid = power.reshape(fitter.ni, fitter.nj)
        step = (fitter.h / fitter.ni, fitter.w / fitter.nj)  # pixels between coarse samples
        sigma = tuple(periods / fitter.f0 / s for s in step)
        return gaussian_filter(grid, sigma, mode="nearest").ravel()
    raise ValueError(f"calflow weights: expected 'uniform' or 'smoothed:N', got {mode!r}")


@contextlib.contextmanager
def calflow_weights(mode: str):
    """Within the block, calflow's central-half planes are fitted with the weights ``mode``."""
    original = PhaseFitter.refit

    def refit(self, planes, k, keep):
        parts = []
        for lobe in (0, 1):
            power = np.abs(planes.fields[k, lobe].astype(complex)) ** 2
            w = _target(self, power, mode)
            parts.append(original(self, planes, k, keep * w / np.maximum(power, 1e-300)))
        return (
            np.array([parts[0][0][0], parts[1][0][1]]),
            np.array([parts[0][1][0], parts[1][1][1]]),
            np.array([parts[0][2][0], parts[1][2][1]]),
        )

    PhaseFitter.refit = refit
    try:
        yield
    finally:
        PhaseFitter.refit = original
