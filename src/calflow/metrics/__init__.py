"""Positioning metrics: ISO 9283, intrinsic/extrinsic repeatability, ISO 230-2, robustness.

Every function takes numpy arrays in one consistent length unit and returns results in
that unit; docstrings cite the thesis equations.
"""

from .iso230_2 import ISO230_2Result, iso230_2
from .iso9283 import ISO9283Result, ISO9283TestResult, iso9283, iso9283_test
from .repeatability import (
    RepeatabilityDecomposition,
    accuracy_1d,
    decompose_repeatability,
    repeatability_1d,
)
from .robustness import Robustness, robustness, space_robustness, time_robustness

__all__ = [
    "ISO230_2Result",
    "ISO9283Result",
    "ISO9283TestResult",
    "RepeatabilityDecomposition",
    "Robustness",
    "accuracy_1d",
    "decompose_repeatability",
    "iso230_2",
    "iso9283",
    "iso9283_test",
    "repeatability_1d",
    "robustness",
    "space_robustness",
    "time_robustness",
]
