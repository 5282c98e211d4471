"""The thesis's nanopositioning results, put beside calflow's in summaries and reports
(:attr:`calflow.family.Family.reference`): Tan, Sec. 5.3.3 (Fig. 5.18, Table 5.2) for the
1-DoF stage and Sec. 5.4.2 for the 2-DoF stage."""

from __future__ import annotations

STAGE1D = {
    "source": "Tan, Calibration of micro and nanorobotic systems, Sec. 5.3.3, Fig. 5.18, Table 5.2",
    "intrinsic": {"accuracy_nm": 350.0, "repeatability_nm": 35.0},
    "tests": {
        "no_calibration": {"max_accuracy_nm": 1000.0},
        "single": {"max_accuracy_nm": 400.0},
        "adaptive_kmz": {"max_accuracy_nm": 200.0},
    },
    "robustness": {
        "no_calibration": {"space": 0.369, "time": 0.018},
        "adaptive_kmz": {"space": 0.044, "time": 0.002},
        "single": {"space": 0.048, "time": 0.004},
    },
    "interferometer_combined_nm": 40.6,
}

STAGE2D = {
    "source": "Tan, Calibration of micro and nanorobotic systems, Sec. 5.4.2",
    "tests": {"no_calibration": {"max_accuracy_nm": 1400.0}, "single": {"max_accuracy_nm": 200.0}},
}
