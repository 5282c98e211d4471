"""The thesis's XYΘ results, put beside calflow's in summaries and reports
(:attr:`calflow.family.Family.reference`): Tan, Table 4.8 (accuracy of Models I–V), Table 4.6
(Model II's parameters), the table compensation of Sec. 4.4.2 and Fig. 4.21."""

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
