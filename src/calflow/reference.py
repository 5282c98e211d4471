"""The thesis's own results, put beside calflow's in summaries and reports (the ``reference``
block of ``summary.json``, docs/architecture.md)."""

from __future__ import annotations

XYTHETA = {
    "source": "Tan, Calibration of micro and nanorobotic systems, Table 4.8 and Table 4.6",
    "models": {
        "I": {"accuracy_um": 95.980},
        "II": {"accuracy_um": 34.338},
        "III": {"accuracy_um": 26.461},
        "IV": {"accuracy_um": 2.838},
        "V": {"accuracy_um": 2.568},
    },
    "parameters": {  # Table 4.6, Model II
        "x_R_um": 9572.902,
        "y_R_um": 7795.830,
        "alpha_deg": 177.689,
        "beta_deg": -0.132,
    },
    "lut_compensation_um": {"square": [22.0, 3.0], "random_points": [22.0, 7.0]},
    "observability_poses": {"O2_plateau": 400, "used": 1200},
}

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

BY_ROBOT = {"xytheta": XYTHETA, "stage1d": STAGE1D, "stage2d": STAGE2D}
