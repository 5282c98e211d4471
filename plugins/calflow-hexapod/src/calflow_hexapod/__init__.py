"""calflow's hexapod family: 6-DoF Stewart–Gough platforms driven by a C-887-class controller.

A separate distribution, found by calflow only through the ``calflow.families`` entry point;
calflow's core never imports it. Lengths in µm, angles in degree, as in every calflow dataset.
"""
