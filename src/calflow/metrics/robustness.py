"""Space and time robustness of a calibration (thesis Sec. 5.2.5, Eq. 5.8 and 5.9).

A validation period is a series of n tests (thesis Sec. 5.3.3: one test = 15 forward and
backward cycles over the validation targets, about 1.25 h).  Test i gives one ISO 9283
accuracy AP per target pose; AP_i denotes that set of per-pose accuracies.

* Space robustness, Eq. (5.8): R_S = (1/n) sum_i [max(AP_i) - min(AP_i)], the mean over
  the tests of the spread of accuracy across the workspace.  Unit: the unit of AP.
* Time robustness, Eq. (5.9): R_T = [(1/n) sum_i max(AP_i)] / Time, the mean over the tests
  of the worst accuracy, divided by the duration of the period.  Unit: unit of AP per
  unit of time (e.g. µm/h).

Reading of the thesis, and choices made:

* In AP_i the index i runs over tests; Max and Min run over the poses of test i (the
  other reading, max over tests, makes the sum over i meaningless).
* The prose says both indices "evaluate the sum", the formulas carry 1/n: we follow the
  formulas (means over tests).
* "Time" is not defined further; we take the duration of the period covered by the n
  tests, given by the caller in the time unit they want R_T in.
* Table 5.2 prints no units.  R_S = 0.369 / 0.044 / 0.048 matches AP in µm (Fig. 5.14:
  max - min ≈ 0.3 µm in one test without calibration).  R_T = 0.018 / 0.002 / 0.004 has
  the order of magnitude of µm divided by tens of hours; the exact unit of Time cannot be
  recovered from the thesis.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .iso9283 import _finite

__all__ = ["Robustness", "space_robustness", "time_robustness", "robustness"]


def _tests(ap_per_test) -> list[np.ndarray]:
    """Per-test accuracy arrays: a (n_tests, n_poses) array or a sequence of 1-D arrays."""
    if isinstance(ap_per_test, np.ndarray) and ap_per_test.ndim == 2:
        tests = list(ap_per_test)
    elif isinstance(ap_per_test, np.ndarray) and ap_per_test.ndim != 2:
        raise ValueError(
            f"ap_per_test must be (n_tests, n_poses) or a sequence of per-test arrays; got shape {ap_per_test.shape}"
        )
    else:
        tests = list(ap_per_test)
    if not tests:
        raise ValueError("ap_per_test is empty; robustness needs at least one test")
    out = []
    for i, t in enumerate(tests):
        a = np.asarray(t, dtype=float)
        if a.ndim != 1 or a.size == 0:
            raise ValueError(
                f"test {i}: expected a non-empty 1-D array of per-pose AP values; got shape {a.shape}"
            )
        _finite(a, f"test {i} accuracies")
        if np.any(a < 0):
            raise ValueError(f"test {i}: accuracies AP are distances and cannot be negative")
        out.append(a)
    return out


def space_robustness(ap_per_test: Sequence | np.ndarray) -> float:
    """Space robustness R_S = (1/n) sum_i [max(AP_i) - min(AP_i)], Eq. (5.8).

    Parameters
    ----------
    ap_per_test : (n_tests, n_poses) array, or a sequence of n 1-D arrays
        For each test i, the ISO 9283 accuracy AP of each pose (number of poses may differ
        between tests).  Any length unit.

    Returns
    -------
    float
        R_S in the unit of AP (smaller is better).
    """
    tests = _tests(ap_per_test)
    return float(np.mean([t.max() - t.min() for t in tests]))


def time_robustness(ap_per_test: Sequence | np.ndarray, duration: float) -> float:
    """Time robustness R_T = [(1/n) sum_i max(AP_i)] / Time, Eq. (5.9).

    Parameters
    ----------
    ap_per_test : (n_tests, n_poses) array, or a sequence of n 1-D arrays
        Per-test, per-pose accuracies AP, any length unit.
    duration : float
        "Time" of Eq. (5.9): the duration of the period covered by the tests, > 0, in the
        time unit wanted for R_T (e.g. hours).

    Returns
    -------
    float
        R_T in (unit of AP) / (unit of duration) (smaller is better).
    """
    tests = _tests(ap_per_test)
    dur = float(duration)
    if not np.isfinite(dur) or dur <= 0:
        raise ValueError(f"duration must be a positive, finite time; got {duration!r}")
    return float(np.mean([t.max() for t in tests])) / dur


@dataclass(frozen=True)
class Robustness:
    """Both robustness indices of one validation period (Eq. 5.8, 5.9).

    ``space`` in the AP unit; ``time`` in AP unit per ``duration`` unit; ``n_tests`` tests.
    """

    space: float
    time: float
    n_tests: int
    duration: float


def robustness(ap_per_test: Sequence | np.ndarray, duration: float) -> Robustness:
    """R_S (Eq. 5.8) and R_T (Eq. 5.9) of one period; see the two functions for units."""
    tests = _tests(ap_per_test)
    return Robustness(
        space=space_robustness(tests),
        time=time_robustness(tests, duration),
        n_tests=len(tests),
        duration=float(duration),
    )
