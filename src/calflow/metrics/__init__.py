"""Positioning metrics: ISO 9283, intrinsic/extrinsic repeatability, ISO 230-2, robustness.

ISO 9283:1998 clauses: 7.2 AP/RP (:mod:`.iso9283`), 7.3 vAP (:mod:`.iso9283_directions`),
7.4 AD/RD (:mod:`.iso9283_distance`), 7.5/7.6 stabilisation time and overshoot
(:mod:`.iso9283_stabilisation`), 7.7 drift dAP/dRP (:mod:`.iso9283_drift`).

Every function takes numpy arrays in one consistent length unit and returns results in
that unit; docstrings cite the thesis equations.
"""

from .iso230_2 import ISO230_2Result, iso230_2
from .iso9283 import ISO9283Result, ISO9283TestResult, iso9283, iso9283_test
from .iso9283_directions import MultiDirectionalResult, iso9283_vap
from .iso9283_distance import DistanceResult, iso9283_distance
from .iso9283_drift import DriftResult, iso9283_drift
from .iso9283_stabilisation import StabilisationResult, iso9283_stabilisation
from .repeatability import (
    RepeatabilityDecomposition,
    accuracy_1d,
    decompose_repeatability,
    repeatability_1d,
)
from .robustness import Robustness, robustness, space_robustness, time_robustness

__all__ = [
    "DistanceResult",
    "DriftResult",
    "ISO230_2Result",
    "ISO9283Result",
    "ISO9283TestResult",
    "MultiDirectionalResult",
    "RepeatabilityDecomposition",
    "Robustness",
    "StabilisationResult",
    "accuracy_1d",
    "decompose_repeatability",
    "iso230_2",
    "iso9283",
    "iso9283_distance",
    "iso9283_drift",
    "iso9283_stabilisation",
    "iso9283_test",
    "iso9283_vap",
    "repeatability_1d",
    "robustness",
    "space_robustness",
    "time_robustness",
]
